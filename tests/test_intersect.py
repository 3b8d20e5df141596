"""The BVH walk finds exactly what testing every surface would find."""

import numpy as np
import pytest

import schemas
from tracer.intersect import MISS, PLANE, SPHERE, TRIANGLE, Intersector
from tracer.shapes import plane_t, sphere_t, triangle_hit
from tracer.world import build_world


def scene_with(objects):
    return schemas.validate_scene({"camera": {"position": [0, 0, 30], "look_at": [0, 0, 0]},
                                   "image": {"width": 1, "height": 1}, "materials": {"m": {}}, "objects": objects})


def random_field(rng, count, big=False):
    objs = [{"type": "sphere", "material": "m", "center": list(map(float, rng.uniform(-5, 5, 3))),
             "radius": float(rng.uniform(0.05, 1.5))} for _ in range(count)]
    objs.append({"type": "plane", "material": "m", "point": [0, -4, 0], "normal": [0.1, 1, 0]})
    objs.append({"type": "triangle", "material": "m", "vertices": [[-6, -3, -6], [6, -2, -6], [0, 6, -5]]})
    if big:
        objs.append({"type": "sphere", "material": "m", "center": [0, -1e6 - 4.5, 0], "radius": 1e6})
    return objs


def brute_force(world, origins, dirs):
    best = np.full(len(origins), np.inf)
    kind = np.zeros(len(origins), dtype=np.int8)
    for k in range(len(world.spheres.radius)):
        t = sphere_t(origins, dirs, world.spheres.center[k], world.spheres.radius[k])
        kind[t < best], best = SPHERE, np.minimum(best, t)
    for k in range(len(world.planes.normal)):
        t = plane_t(origins, dirs, world.planes.point[k], world.planes.normal[k])
        kind[t < best], best = PLANE, np.minimum(best, t)
    tr = world.triangles
    for k in range(len(tr.v0)):
        n = len(origins)
        v0, e1, e2 = (np.repeat(a[k:k + 1], n, 0) for a in (tr.v0, tr.e1, tr.e2))
        t, u, v = triangle_hit(origins, dirs, v0, e1, e2)
        on_plane = origins + np.where(np.isfinite(t), t, 0)[:, None] * dirs
        clamped = v0 + u[:, None] * e1 + v[:, None] * e2  # differs from the plane point outside the triangle
        t = np.where(np.linalg.norm(on_plane - clamped, axis=1) < 1e-9, t, np.inf)
        kind[t < best], best = TRIANGLE, np.minimum(best, t)
    return best, kind


@pytest.mark.parametrize("count, big", [(3, False), (60, False), (300, True)])
def test_walk_agrees_with_brute_force_for_rays_from_anywhere(count, big):
    rng = np.random.default_rng(count)
    world = build_world(scene_with(random_field(rng, count, big)))
    isect = Intersector(world)
    origins = rng.uniform(-6, 6, (20_000, 3))  # many start inside spheres and inside proxies
    dirs = rng.normal(size=(20_000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    hits = isect.closest(origins, dirs)
    best, kind = brute_force(world, origins, dirs)
    np.testing.assert_array_equal(np.isfinite(hits.t), np.isfinite(best))
    finite = np.isfinite(best)
    np.testing.assert_allclose(hits.t[finite], best[finite], rtol=1e-9)
    t_max = np.where(finite, best, 1e3) * rng.uniform(0.5, 1.5, len(best))
    np.testing.assert_array_equal(isect.occluded(origins, dirs, t_max), best < t_max)


def test_huge_sphere_is_tested_directly_not_through_the_bvh():
    world = build_world(scene_with(random_field(np.random.default_rng(1), 10, big=True)))
    isect = Intersector(world)
    assert len(isect.direct_spheres) == 1 and len(isect.proxied) == 10


def test_no_bvh_without_triangles_or_small_spheres():
    isect = Intersector(build_world(scene_with([{"type": "plane", "material": "m", "point": [0, 0, 0],
                                                 "normal": [0, 1, 0]}])))
    assert isect.bvh is None
    hits = isect.closest(np.array([[0.0, 1, 0], [0, 1, 0]]), np.array([[0.0, -1, 0], [0, 1, 0]]))
    assert list(hits.kind) == [PLANE, MISS]


def test_spawn_offset_scales_with_the_point():
    isect = Intersector(build_world(scene_with([{"type": "sphere", "material": "m", "center": [0, 0, 0],
                                                 "radius": 1}, {"type": "sphere", "material": "m",
                                                                "center": [1e5, 0, 0], "radius": 1}])))
    hits = isect.closest(np.array([[0.0, 0, 30], [1e5, 0, 30]]), np.array([[0.0, 0, -1], [0, 0, -1]]))
    assert hits.offset[1] > 1e4 * hits.offset[0] > 0
