"""Exact ray tests: inside, grazing, behind the origin, huge radii."""

import numpy as np

from tracer.shapes import plane_t, sphere_t, triangle_hit


def rays(origins, dirs):
    d = np.asarray(dirs, dtype=float)
    return np.asarray(origins, dtype=float), d / np.linalg.norm(d, axis=1, keepdims=True)


def test_sphere_hit_from_outside_and_miss():
    o, d = rays([[0, 0, 5], [0, 3, 5]], [[0, 0, -1], [0, 0, -1]])
    t = sphere_t(o, d, np.zeros(3), 1.0)
    assert t[0] == 4.0 and np.isinf(t[1])


def test_sphere_from_inside_hits_the_far_side():
    o, d = rays([[0, 0, 0.5]], [[0, 0, 1]])
    assert sphere_t(o, d, np.zeros(3), 1.0)[0] == 0.5


def test_sphere_behind_the_origin_never_counts():
    o, d = rays([[0, 0, 5]], [[0, 0, 1]])
    assert np.isinf(sphere_t(o, d, np.zeros(3), 1.0)[0])


def test_grazing_ray_touches_the_sphere_once_and_is_finite():
    o, d = rays([[-5, 1, 0], [-5, 1 + 1e-12, 0]], [[1, 0, 0], [1, 0, 0]])
    t = sphere_t(o, d, np.zeros(3), 1.0)
    assert abs(t[0] - 5) < 1e-6 and np.isinf(t[1])


def test_huge_sphere_is_exact_near_its_surface():
    r = 1e9
    o, d = rays([[0, 1.0, 0]], [[0, -1, 0]])
    t = sphere_t(o, d, np.array([0, -r, 0]), r)
    assert abs(t[0] - 1.0) < 1e-6


def test_ray_leaving_a_sphere_does_not_hit_it_again():
    p = np.array([[0.6, 0.8, 0.0]])
    offset = p * (1 + 2**-40)
    o, d = rays(offset, [[0.6, 0.8, 0.0]])
    assert np.isinf(sphere_t(o, d, np.zeros(3), 1.0)[0])


def test_plane_hit_parallel_and_behind():
    o, d = rays([[0, 1, 0], [0, 1, 0], [0, 1, 0]], [[0, -1, 0], [1, 0, 0], [0, 1, 0]])
    t = plane_t(o, d, np.zeros(3), np.array([0, 1.0, 0]))
    assert t[0] == 1.0 and np.isinf(t[1]) and np.isinf(t[2])


def test_triangle_refinement_gives_barycentrics_on_the_triangle():
    o, d = rays([[0.25, 0.25, 1]], [[0, 0, -1]])
    t, u, v = triangle_hit(o, d, np.zeros((1, 3)), np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    assert t[0] == 1.0 and u[0] == 0.25 and v[0] == 0.25


def test_triangle_behind_or_parallel_is_no_hit():
    o, d = rays([[0.25, 0.25, 1], [0.25, 0.25, 0]], [[0, 0, 1], [1, 0, 0]])
    t, u, v = triangle_hit(o, d, np.zeros((2, 3)), np.array([[1.0, 0, 0]] * 2), np.array([[0, 1.0, 0]] * 2))
    assert np.all(np.isinf(t)) and np.all(np.isfinite(u)) and np.all(np.isfinite(v))
