"""The proofs' margins (tracer/proofs/margins.py): the relations between them that their docstrings state, and the
float32 error one of them bounds, measured."""

import numpy as np

from tracer.proofs import margins
from tracer.scene.shapes import UV_TOL

ULP = 2.0**-53  # the relative rounding of float64


def test_a_face_normals_error_is_under_a_quarter_of_the_margin():
    assert (margins.NORMAL_ERROR + 2.0**-50) * np.sqrt(3) < margins.MARGIN / 4


def test_the_margin_leaves_a_factor_of_a_million_over_a_few_roundings():
    assert margins.MARGIN >= 2**20 * 8 * ULP
    assert margins.SLACK >= 2**10 * 8 * ULP  # a handful of operations, each a few ULP of the result


def test_the_float32_slack_is_eight_times_the_error_of_a_cosine():
    assert margins.SLACK32 >= 8 * 2.0**-21


def test_a_float32_cosine_of_unit_vectors_lies_within_its_bound():
    rng = np.random.default_rng(5)
    for scale in (1e-30, 1.0, 1e30):
        u = rng.normal(size=(20000, 3)) * scale
        v = rng.normal(size=(20000, 3)) * scale
        u /= np.linalg.norm(u, axis=1)[:, None]
        v /= np.linalg.norm(v, axis=1)[:, None]
        exact = np.einsum("ij,ij->i", u, v)
        single = np.einsum("ij,ij->i", u.astype(np.float32), v.astype(np.float32), dtype=np.float32)
        assert np.max(np.abs(single.astype(np.float64) - exact)) <= 2.0**-21


def test_a_triangles_growth_covers_the_exact_tests_allowance():
    assert margins.GROWTH > UV_TOL * 4


def test_plain_triangles_keep_clear_of_their_crossings_error():
    assert margins.CROSSING_SLACK == margins.LINE_ERROR / margins.MIN_SINE
    assert margins.NEAR > margins.CROSSING_SLACK
