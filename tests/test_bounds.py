"""What the proofs share (tracer/proofs/bounds.py): the plane rule and a sphere seen from inside."""

import numpy as np

from tracer.proofs.bounds import centre_side, plane_clear


def test_the_plane_rule_clears_points_on_the_far_points_side_beyond_the_margin():
    side = np.array([2.0, 0.5, -2.0, np.nan])
    clear = plane_clear(side, 1.0, np.array([3.0, 4.0]), 0.25)
    assert clear.tolist() == [True, False, False, False]  # within margin + reach; other side; not known


def test_the_plane_rule_clears_nothing_when_the_far_points_straddle_or_touch_the_plane():
    side = np.array([5.0, -5.0])
    assert not plane_clear(side, 0.0, np.array([1.0, -1.0]), 0.0).any()
    assert not plane_clear(side, 0.0, np.array([1.0, 0.1]), 0.5).any()  # a far point within the margin


def test_a_sphere_is_seen_from_inside_where_the_normal_heads_into_it():
    points = np.array([[1.0, 0, 0], [1.0, 0, 0], [np.nan, 0, 0]])
    outward = np.array([[1.0, 0, 0], [-1.0, 0, 0], [1.0, 0, 0]])
    side = centre_side(outward, points, np.zeros((3, 3)))
    assert side[0] > 0 and side[1] < 0
    assert not (side[2] < 0) and not (side[2] >= 0)  # neither proven
