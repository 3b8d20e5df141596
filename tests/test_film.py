"""The film: fixed-point sums that no order changes, clamped where a pixel saturates, and the bytes stored."""

import numpy as np

from tracer.film import Film, stored
from tracer.scene.variants import REFERENCE, VARIANTS


def test_sums_do_not_depend_on_the_order_contributions_come_in():
    rng = np.random.default_rng(1)
    index, values = rng.integers(0, 8, 200), rng.random((200, 3)) * 0.01
    a, b = Film(4, 2, 1024), Film(4, 2, 1024)
    a.add(index, values)
    order = rng.permutation(200)
    for part in np.array_split(order, 7):
        b.add(index[part], values[part])
    assert np.array_equal(a.colour(), b.colour())
    np.testing.assert_allclose(a.colour().sum(), values.sum() / 2, rtol=1e-9)


def test_nan_counts_as_nothing_and_a_bright_sample_saturates_its_pixel():
    film = Film(2, 1, 1024)
    film.add(np.array([0, 1]), np.array([[np.nan, 0.5, np.inf], [-1.0, 0.25, 1e300]]), fresh=True)
    colour = film.colour()
    assert colour[0, 0] == 0.0 and colour[1, 0] == 0.0
    assert colour[0, 1] == 0.5 and colour[1, 1] == 0.25
    assert colour[0, 2] == film.ceiling and colour[1, 2] == film.ceiling
    assert stored(colour, REFERENCE).tolist() == [[0, 128, 255], [0, 64, 255]]


def test_the_unit_is_the_same_for_every_slice_up_to_a_chunk():
    assert Film(1, 4, 1 << 10).fixed == Film(1, 4, 1 << 16).fixed
    assert Film(1, 4, 1 << 18).fixed < Film(1, 4, 1 << 16).fixed  # (room for a larger slice's sums)


def test_the_gamma_variant_is_applied_before_quantisation():
    colour = np.array([[0.25, 0.5, 1.0]])
    # 255·0.25^(1/2.2) = 135.3…, 255·0.5^(1/2.2) = 186.0…
    assert stored(colour, VARIANTS["gamma"][0]).tolist() == [[136, 186, 255]]
    assert stored(colour, REFERENCE).tolist() == [[64, 128, 255]]
