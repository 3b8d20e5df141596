"""Proxies (tracer/exact/proxies.py): each closed stand-in holds its surface grown by the margin, as the walk
assumes."""

import numpy as np
import pytest

from tracer.exact.proxies import MARGIN, build_proxies
from tracer.scene.vec import cross


def inside_convex(point, vertices, faces):
    """Whether ``point`` lies inside the closed convex polyhedron (vertices, faces), by its face planes."""
    centre = vertices.mean(axis=0)
    for a, b, c in faces:
        n = np.cross(vertices[b] - vertices[a], vertices[c] - vertices[a])
        side = np.dot(point - vertices[a], n)
        inner = np.dot(centre - vertices[a], n)
        if side * inner < 0 and abs(side) > 1e-12 * np.linalg.norm(n):
            return False
    return True


def proxy_of(p, k):
    faces = p.faces[p.owner == k]
    used = np.unique(faces)
    return p.vertices[used], np.searchsorted(used, faces)


@pytest.mark.parametrize("seed", range(4))
def test_every_point_within_the_margin_of_a_surface_lies_in_its_proxy(seed):
    rng = np.random.default_rng(seed)
    v0 = rng.uniform(-1, 1, (20, 3))
    e1, e2 = rng.uniform(-0.5, 0.5, (20, 3)), rng.uniform(-0.5, 0.5, (20, 3))
    e2[:4] = e1[:4] * 0.999 + 1e-4  # slivers get boxes of their own
    normal = cross(e1, e2)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    center, radius = rng.uniform(-1, 1, (10, 3)), rng.uniform(0.01, 0.5, 10)
    half = 2.0
    p = build_proxies(v0, e1, e2, normal, center, radius, half)
    m = MARGIN * half
    for k in range(20):  # points of the triangle, moved by up to 0.99 m in any direction
        verts, faces = proxy_of(p, k)
        for _ in range(40):
            u, v = rng.random(2)
            if u + v > 1:
                u, v = 1 - u, 1 - v
            x = v0[k] + u * e1[k] + v * e2[k] + _ball(rng) * 0.99 * m
            assert inside_convex(x, verts, faces)
            assert np.all(p.lo[k] <= x) and np.all(x <= p.hi[k])
    for k in range(10):
        verts, faces = proxy_of(p, 20 + k)
        for _ in range(40):
            d = rng.normal(size=3)
            x = center[k] + d / np.linalg.norm(d) * (radius[k] + rng.uniform(-0.99, 0.99) * m)
            assert inside_convex(x, verts, faces)


def _ball(rng):
    d = rng.normal(size=3)
    return d / np.linalg.norm(d) * rng.random() ** (1 / 3)


def test_the_margins_cover_float32_rounding_of_any_walk_query():
    # In the BVH's frame (centred, scaled by a power of two to half-size 1), a walk query starts inside the box
    # (|x| <= ~1 per axis) and runs at most its diagonal (2·sqrt(3)).  Rounding the origin to float32 moves it by
    # 2^-24 per axis, the direction by 2^-24 per axis over that length, and Embree's float32 crossing errs by a
    # few ulps: the float32 ray strays from the float64 one by at most DRIFT anywhere in the box.
    from tracer.exact.proxies import REACH, STEP, TRIANGLE_MARGIN
    from tracer.proofs.margins import CROSSING_SLACK

    ulp = 2.0**-24
    drift = np.sqrt(3) * ulp * 1.01 + 2 * np.sqrt(3) * np.sqrt(3) * ulp + 4 * ulp
    assert MARGIN >= 8 * drift  # a ray that hits a surface in float64 crosses its proxy in float32
    assert REACH >= STEP + 2 * drift + MARGIN  # a crossing near a part's border still finds its proxy registered
    assert TRIANGLE_MARGIN >= CROSSING_SLACK + 2 * drift  # a stray plain-face crossing still enters a proxied neighbour
