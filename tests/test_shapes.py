"""Exact ray tests: inside, grazing, behind the origin, huge radii, leaving a surface by identity."""

import numpy as np
import pytest

from tracer.scene.shapes import on_tolerance, plane_t, sphere_t, triangle_t
from tracer.scene.surfaces import unit
from tracer.scene.vec import along, dot, minus

UP = np.array([0, 1.0, 0])
TRI = (np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0]))


def rays(origins, dirs):
    d = np.asarray(dirs, dtype=float)
    return np.asarray(origins, dtype=float), d / np.linalg.norm(d, axis=1, keepdims=True)


ORIGIN = np.zeros(3)


def sphere(o, d, center=ORIGIN, radius=1.0, **kw):
    mag = np.abs(o).max(axis=1)
    return sphere_t(o, d, center, radius, mag, np.abs(center).max() + radius, **kw)


def plane(o, d, **kw):
    return plane_t(o, d, np.zeros(3), UP, np.abs(o).max(axis=1), 0.0, **kw)


def triangle(o, d, **kw):
    return triangle_t(o, d, *TRI, np.abs(o).max(axis=1), 1.0, **kw)


def test_sphere_hit_from_outside_and_miss():
    o, d = rays([[0, 0, 5], [0, 3, 5]], [[0, 0, -1], [0, 0, -1]])
    t = sphere(o, d)
    assert t[0] == 4.0 and np.isinf(t[1])


def test_sphere_from_inside_hits_the_far_side():
    o, d = rays([[0, 0, 0.5]], [[0, 0, 1]])
    assert sphere(o, d)[0] == 0.5


def test_sphere_behind_the_origin_never_counts():
    o, d = rays([[0, 0, 5]], [[0, 0, 1]])
    assert np.isinf(sphere(o, d)[0])


def test_grazing_ray_touches_the_sphere_once_and_is_finite():
    o, d = rays([[-5, 1, 0], [-5, 1 + 1e-12, 0]], [[1, 0, 0], [1, 0, 0]])
    t = sphere(o, d)
    assert abs(t[0] - 5) < 1e-6 and np.isinf(t[1])


def test_huge_sphere_is_exact_near_its_surface():
    r = 1e9
    o, d = rays([[0, 1.0, 0]], [[0, -1, 0]])
    t = sphere(o, d, np.array([0, -r, 0]), r)
    assert abs(t[0] - 1.0) < 1e-6


def test_ray_leaving_a_sphere_outward_never_hits_it_inward_only_at_the_far_root():
    p = np.array([[0.6, 0.8, 0.0], [0.6, 0.8, 0.0]])
    o, d = rays(p, [[0.6, 0.8, 0.0], [-0.6, -0.8, 0.0]])
    t = sphere(o, d, leaving=np.array([True, True]))
    assert np.isinf(t[0]) and abs(t[1] - 2.0) < 1e-15


def test_origin_on_a_sphere_by_rounding_is_treated_as_leaving_it():
    p = np.array([[0.6, 0.8, 0.0]]) * (1 + 2**-50)
    o, d = rays(p, [[0.6, 0.8, 0.0]])
    assert np.isinf(sphere(o, d)[0])


def test_thin_shell_is_resolved_from_its_outer_surface():
    o, d = rays([[0, 0, 1.0 + 1e-6]], [[0, 0, -1]])
    t = sphere(o, d, radius=1.0)
    assert abs(t[0] - 1e-6) < 1e-15


def test_light_on_a_sphere_is_not_blocked_by_it_but_its_far_side_blocks():
    o, d = rays([[0, 3, 0], [0, -3, 0]], [[0, -1, 0], [0, 1, 0]])
    ends = np.array([[0, 1.0, 0], [0, 1.0, 0]])
    reach = np.array([2.0, 4.0])
    t = sphere(o, d, ends=ends, reach=reach, mag_end=np.ones(2))
    assert not t[0] < reach[0]  # from above: the light sits on the near side, the far side lies beyond it
    assert t[1] < reach[1]  # from below: the sphere's lower half is in the way


def test_plane_hit_parallel_and_behind():
    o, d = rays([[0, 1, 0], [0, 1, 0], [0, 1, 0]], [[0, -1, 0], [1, 0, 0], [0, 1, 0]])
    t = plane(o, d)
    assert t[0] == 1.0 and np.isinf(t[1]) and np.isinf(t[2])


def test_ray_starting_on_a_plane_never_hits_it_nor_one_ending_on_it():
    o, d = rays([[0, 0, 0], [0, 1, 0]], [[0, -1, 1], [0, -1, 1]])
    assert np.all(np.isinf(plane(o, d, ends=np.array([[5.0, 0, 1], [0, 0, 1]]), mag_end=np.ones(2))))


def test_triangle_hit_gives_barycentrics_on_the_triangle():
    o, d = rays([[0.25, 0.25, 1]], [[0, 0, -1]])
    t, u, v = triangle(o, d)
    assert t[0] == 1.0 and u[0] == 0.25 and v[0] == 0.25


def test_triangle_edge_is_decided_in_float64_not_clamped():
    o, d = rays([[0.5, -1e-12, 1], [0.5, 1e-12, 1]], [[0, 0, -1], [0, 0, -1]])
    t, _, _ = triangle(o, d)
    assert np.isinf(t[0]) and t[1] == 1.0


def test_triangle_behind_or_parallel_is_no_hit():
    o, d = rays([[0.25, 0.25, 1], [0.25, 0.25, 0]], [[0, 0, 1], [1, 0, 0]])
    t, u, v = triangle(o, d)
    assert np.all(np.isinf(t)) and np.all(np.isfinite(u)) and np.all(np.isfinite(v))


def test_ray_leaving_a_triangle_or_lying_in_its_plane_misses_it():
    o, d = rays([[0.2, 0.2, 0], [-1, 0.2, 0]], [[0, 0.1, -1], [1, 0, 0]])
    t, _, _ = triangle(o, d)
    assert np.all(np.isinf(t))


def test_a_plane_separates_a_segment_exactly_when_its_ends_lie_on_opposite_sides():
    from tracer.scene.shapes import Segments, plane_separates

    point, normal = np.zeros(3), np.array([0.0, 1.0, 0.0])
    origins = np.array([[0.0, 1e-3, 0.0], [0.0, 1e-3, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 0.0], [5.0, -1.0, 0.0]])
    ends = np.array(
        [
            [1e6, -1e-3, 0.0],  # nearly parallel to the plane and a million long: crosses it
            [1e6, 1e-3, 0.0],  # parallel, on one side: does not
            [0.0, 0.0, 0.0],  # ends on the plane: a light in a surface is not blocked by it
            [0.0, -3.0, 0.0],  # starts on the plane (the surface it leaves)
            [5.0, 1.0, 0.0],
        ]
    )  # straight through
    mag_o, mag_e = np.max(np.abs(origins), axis=1), np.max(np.abs(ends), axis=1)
    got = plane_separates(Segments(origins, ends, mag_o, mag_e), point, normal, 0.0)
    assert got.tolist() == [True, False, False, False, True]
    leaving = np.array([False, False, False, False, True])
    assert plane_separates(Segments(origins, ends, mag_o, mag_e), point, normal, 0.0, leaving).tolist()[-1] is False
    # one light shared by every row
    one = Segments(origins, np.array([[0.0, -1.0, 0.0]]), mag_o, np.array([1.0]))
    shared = plane_separates(one, point, normal, 0.0)
    assert shared.tolist() == [True, True, True, False, False]


@pytest.mark.parametrize("light", [None, 2.0, 1.0])
def test_sphere_roots_of_the_rays_that_may_hit_are_those_of_every_ray(light):
    """sphere_t finds the roots only for rays whose line meets the sphere or that start or end on it; the
    others are inf either way, and the rest carry the same bits as roots found for every ray."""
    from tracer.scene.shapes import _roots

    rng = np.random.default_rng(5)
    shadow = light is not None
    n = 4000
    center, radius = np.array([0.3, -0.2, 0.1]), 0.7
    on_surface = center + radius * unit(rng.normal(size=(n, 3)))
    origins = np.where(rng.random((n, 1)) < 0.2, on_surface, rng.uniform(-3, 3, (n, 3)))
    dirs = unit(rng.normal(size=(n, 3)))
    leaving = rng.random(n) < 0.05
    mag_o, mag_s = np.max(np.abs(origins), axis=1), float(np.max(np.abs(center)) + radius)
    ends = reach = mag_e = None
    if shadow:  # shadow rays to a light off the sphere, or on it (which the identity rule must handle)
        ends = (center + light * radius * unit(np.array([1.0, 2.0, 2.0])))[None]
        reach = np.sqrt(np.sum((ends - origins) ** 2, axis=1))
        dirs = (ends - origins) / reach[:, None]
        mag_e = np.max(np.abs(ends))
    t = sphere_t(origins, dirs, center, radius, mag_o, mag_s, leaving, ends, reach, mag_e)
    if light != 1.0:  # (so both the gathered and the skipped rays are many; on it, every ray may hit)
        assert 0.05 < np.mean(np.isfinite(t)) < 0.5
    oc = minus(origins, center)  # (the steps of sphere_t up to the roots, for every ray)
    b = dot(oc, dirs)
    perp = along(oc, -b, dirs)
    h = np.sqrt(dot(perp, perp))
    dist = np.sqrt(dot(oc, oc))
    on = (np.abs(dist - radius) <= on_tolerance(mag_o, mag_s)) | leaving
    at_end = None
    if shadow:
        ec = minus(ends, center)
        at_end = np.broadcast_to(np.abs(np.sqrt(dot(ec, ec)) - radius) <= on_tolerance(mag_e, mag_s), (n,))
    every = _roots(b, (radius - h) * (radius + h), dist, np.full(n, radius), on, at_end, reach)
    assert t.tobytes() == every.tobytes()
