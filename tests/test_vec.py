"""Column-wise vector arithmetic (tracer/scene/vec.py) against plain NumPy broadcasting."""

import numpy as np

from tracer.scene.vec import along, cross, divided, dot, minus, plus, rows_of, scaled


def test_each_operation_matches_numpy_broadcasting_bit_for_bit():
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(1000, 3)) * 1e3, rng.normal(size=(1000, 3))
    s = rng.normal(size=1000)
    assert np.array_equal(along(a, s, b), a + s[:, None] * b)
    assert np.array_equal(scaled(a, s), a * s[:, None])
    assert np.array_equal(divided(a, s), a / s[:, None])
    assert np.array_equal(dot(a, b), (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]) + a[:, 2] * b[:, 2])
    np.testing.assert_allclose(dot(a, b), np.einsum("ij,ij->i", a, b), rtol=1e-12, atol=1e-9)
    assert np.array_equal(cross(a, b), np.cross(a, b))
    assert np.array_equal(cross(a, b[0]), np.cross(a, b[0]))


def test_one_shared_vector_broadcasts_over_the_rows():
    rng = np.random.default_rng(3)
    rows, one = rng.normal(size=(50, 3)), rng.normal(size=3)
    s = rng.normal(size=50)
    np.testing.assert_allclose(dot(rows, one), rows @ one, rtol=1e-13, atol=1e-15)
    assert np.array_equal(along(one, s, rows), one + s[:, None] * rows)
    assert np.array_equal(along(one[None], s, rows), one + s[:, None] * rows)
    assert np.array_equal(scaled(one, s), s[:, None] * one)


def test_empty_batches_stay_empty():
    e = np.zeros((0, 3))
    assert along(e, np.zeros(0), e).shape == (0, 3)
    assert dot(e, e).shape == (0,)


def test_minus_and_plus_are_the_broadcast_ones_in_columns():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(1000, 3)) * 10.0 ** rng.integers(-8, 8, size=(1000, 1))
    p = np.array([0.1, -3e5, 7.0])
    out = minus(p, points)
    assert out.tobytes(order="C") == (p - points).tobytes()
    assert out.flags.f_contiguous  # and its columns contiguous, for the column-wise functions that read it
    s = rng.uniform(0.5, 2.0, size=1000)
    quotient = divided(out, s)
    assert quotient.flags.f_contiguous and np.array_equal(quotient, (p - points) / s[:, None])
    for a, b in ((points, p), (points, p[None]), (points, points[::-1]), (p, points), (points[:0], p)):
        assert np.array_equal(minus(a, b), a - b) and np.array_equal(plus(a, b), a + b)
        assert np.array_equal(np.signbit(minus(a, b)), np.signbit(a - b))


def test_rows_of_gathers_rows_of_either_layout():
    rng = np.random.default_rng(4)
    a = rng.normal(size=(500, 3))
    index = rng.integers(-500, 500, size=300)
    for layout in (a, np.asfortranarray(a), np.asfortranarray((a * 100).astype(np.int64))):
        got = rows_of(layout, index)
        assert got.dtype == layout.dtype and np.array_equal(got, layout[index])
    assert rows_of(np.asfortranarray(a), index[:0]).shape == (0, 3)
