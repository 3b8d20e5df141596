"""The BVH walk finds exactly what testing every surface in float64 would find.

Most tests here are about the walk through the cells, and so make every BVH walk its cells (no walk of a few
primitives, no direct tests beyond two surfaces); :func:`test_a_few_primitives_agree_with_brute_force_as_rendering_
tests_them` checks the shortcuts rendering takes for small scenes against the same brute force."""

import numpy as np
import pytest

import schemas
import tracer.exact.intersect
import tracer.exact.walk
from tracer.exact.intersect import MISS, PLANE, SPHERE, TRIANGLE, Intersector
from tracer.exact.walk import Best
from tracer.scene.rays import Shadows
from tracer.scene.shapes import plane_t, sphere_t, triangle_t
from tracer.scene.surfaces import max_abs
from tracer.scene.world import build_world


@pytest.fixture(autouse=True)
def cell_walk(request, monkeypatch):
    """Every BVH walks its cells, unless a test is marked ``as_rendered`` (the settings rendering uses)."""
    if "as_rendered" not in request.keywords:
        monkeypatch.setattr(tracer.exact.walk, "FEW", 0)
        monkeypatch.setattr(tracer.exact.intersect, "DIRECT_MAX", 2)


def scene_with(objects, camera=None):
    return schemas.validate_scene(
        {
            "camera": camera or {"position": [0, 0, 30], "look_at": [0, 0, 0]},
            "image": {"width": 1, "height": 1},
            "materials": {"m": {}},
            "objects": objects,
        }
    )


def random_field(rng, count, big=False):
    objs = [
        {
            "type": "sphere",
            "material": "m",
            "center": list(map(float, rng.uniform(-5, 5, 3))),
            "radius": float(rng.uniform(0.05, 1.5)),
        }
        for _ in range(count)
    ]
    objs.append({"type": "plane", "material": "m", "point": [0, -4, 0], "normal": [0.1, 1, 0]})
    objs.append({"type": "triangle", "material": "m", "vertices": [[-6, -3, -6], [6, -2, -6], [0, 6, -5]]})
    verts = rng.uniform(-5, 5, (30, 3))
    objs.append(
        {"type": "mesh", "material": "m", "vertices": verts.tolist(), "faces": rng.integers(0, 30, (40, 3)).tolist()}
    )
    if big:
        objs.append({"type": "sphere", "material": "m", "center": [0, -1e6 - 4.5, 0], "radius": 1e6})
    return objs


def brute_force(world, o, d, fk, fi, reach=None, ends=None):
    """Every surface tested against every ray: best t, kind and index (the least key on a tie).  A member of a
    coplanar group is left by a ray that leaves any member, and its closest hits are timed on the group's plane
    (tracer.scene.coplanar)."""
    n = len(o)
    isect = Intersector(world)
    best = Best(np.full(n, np.inf) if reach is None else reach, isect.ties)
    mag_o = max_abs(o) + world.origin_mag
    mag_e = None if ends is None else max_abs(ends) + world.origin_mag
    rows = np.arange(n)
    sp, pl, tr, groups = world.spheres, world.planes, world.triangles, world.coplanar
    from_group = None if groups is None else groups.of(fk, fi)

    def leaving(kind, k, group):
        own = (fk == kind) & (fi == k)
        return own if from_group is None else own | groups.leaving(from_group, group)

    def timed(t, group):
        return t if groups is None or reach is not None else groups.retime(t, o, d, group)

    for k in range(len(sp.radius)):
        t = sphere_t(o, d, sp.center[k], sp.radius[k], mag_o, sp.mag[k], (fk == SPHERE) & (fi == k), ends, reach, mag_e)
        best.offer(rows, t, SPHERE, np.full(n, k))
    for k in range(len(pl.normal)):
        g = -1 if groups is None else int(groups.plane[k])
        t = plane_t(o, d, pl.point[k], pl.normal[k], mag_o, pl.mag[k], leaving(PLANE, k, g), ends, mag_e)
        best.offer(rows, timed(t, g), PLANE, np.full(n, k))
    for k in range(len(tr.v0)):
        g = -1 if groups is None else int(groups.triangle[k])
        t, u, v = triangle_t(
            o,
            d,
            tr.v0[k],
            tr.e1[k],
            tr.e2[k],
            tr.normal[k],
            mag_o,
            tr.mag[k],
            leaving(TRIANGLE, k, g),
            ends,
            mag_e,
        )
        best.offer(rows, timed(t, g), TRIANGLE, np.full(n, k), u, v)
    return best


def check_agrees(world, o, d, rng):
    """Closest hits, then rays leaving those hits (by identity) towards random points, against brute force."""
    isect = Intersector(world)
    none_k, none_i = np.zeros(len(o), np.int8), np.full(len(o), -1)
    hits = isect.closest(isect.rays(o, d, none_k, none_i))
    ref = brute_force(world, o, d, none_k, none_i)
    np.testing.assert_array_equal(hits.t, np.where(ref.kind == MISS, np.inf, ref.t))
    np.testing.assert_array_equal(hits.kind, ref.kind)
    np.testing.assert_array_equal(hits.index, ref.index)
    # secondary and shadow rays from the exact hit points
    rows = np.flatnonzero(hits.kind != MISS)
    p, fk, fi = hits.point[rows], hits.kind[rows], hits.index[rows]
    target = rng.uniform(-6, 6, (len(rows), 3))
    v = target - p
    dist = np.linalg.norm(v, axis=1)
    d2 = v / dist[:, None]
    second = isect.closest(isect.rays(p, d2, fk, fi))
    ref2 = brute_force(world, p, d2, fk, fi)
    np.testing.assert_array_equal(second.kind, ref2.kind)
    np.testing.assert_array_equal(second.index, ref2.index)
    blocked = isect.occluded(Shadows.towards(isect.rays(p, d2, fk, fi), dist, target, world.origin_mag))
    ref3 = brute_force(world, p, d2, fk, fi, dist, target)
    np.testing.assert_array_equal(blocked, ref3.t < dist)
    return hits


@pytest.mark.parametrize("count, big", [(3, False), (60, False), (300, True)])
def test_walk_agrees_with_brute_force_for_rays_from_anywhere(count, big):
    rng = np.random.default_rng(count)
    world = build_world(scene_with(random_field(rng, count, big)))
    origins = rng.uniform(-6, 6, (3000, 3))  # many start inside spheres and inside proxies
    dirs = rng.normal(size=(3000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    check_agrees(world, origins, dirs, rng)


def test_walk_agrees_with_brute_force_in_a_dense_soup_of_small_spheres_and_triangles():
    # a walk ends early when its hit lies before the exit of the part of a cell it tested last: here boxes
    # overlap everywhere, touching and nested ones among them
    rng = np.random.default_rng(11)
    objs = [
        {
            "type": "sphere",
            "material": "m",
            "center": list(map(float, rng.uniform(-3, 3, 3))),
            "radius": float(rng.uniform(0.05, 0.3)),
        }
        for _ in range(1200)
    ]
    corners = rng.uniform(-3, 3, (400, 1, 3)) + rng.uniform(-0.3, 0.3, (400, 3, 3))
    objs += [{"type": "triangle", "material": "m", "vertices": c.tolist()} for c in corners]
    world = build_world(scene_with(objs))
    origins = rng.uniform(-4, 4, (2500, 3)) - world.origin  # local coordinates
    dirs = rng.normal(size=(2500, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    hits = check_agrees(world, origins, dirs, rng)
    assert np.mean(hits.kind != MISS) > 0.3


def test_a_walk_resumes_where_it_leaves_a_part_and_passes_no_small_proxy_beyond_it():
    # a ray through the proxy of sphere A, missing A itself, then meets sphere B: so small, and just beyond the
    # reach of A's box, that B is registered in other parts of cells than A; a walk that resumed any later than
    # where the ray leaves the part it tested would step over B
    off = 0.105  # outside A (radius 0.1) but inside its icosahedral proxy

    def built(xb):
        objs = [
            {"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 0.1},
            {"type": "sphere", "material": "m", "center": [xb, off, 0], "radius": 0.002},
            {"type": "sphere", "material": "m", "center": [3, 0, 0], "radius": 0.1},
        ]  # fixes the BVH's frame
        return Intersector(build_world(scene_with(objs)))

    trial = built(1.0)
    p, a, b = trial.walker.proxies, trial.walker.sphere_prim[0], trial.walker.sphere_prim[1]
    for step in (2, 4, 8):
        isect = built(float(trial.world.origin[0] + p.hi[a, 0] + step * p.reach + (p.hi[b, 0] - p.lo[b, 0]) / 2))
        assert isect.bvh.half_size == trial.bvh.half_size
        o = np.array([[-1.0, off, 0.0]]) - isect.world.origin
        d = np.array([[1.0, 0.0, 0.0]])
        hits = isect.closest(isect.rays(o, d))
        assert (hits.kind[0], hits.index[0]) == (SPHERE, 1)
        assert isect.occluded(Shadows.towards(isect.rays(o, d), np.array([2.5]), None, 0.0))[0]


def concentric(radii):
    return [{"type": "sphere", "material": "m", "center": [0.3, 0.2, 0.1], "radius": r} for r in radii]


HARD_FIELDS = {
    "glass shell 1e-6 thick": concentric([1.0, 1.0 + 1e-6]),
    "shells 1e-9 apart": concentric([1.0, 1.0 + 1e-9, 1.0 + 2e-9, 2.0]),
    "column of 150 spheres": [
        {"type": "sphere", "material": "m", "center": [0, 0, -k * 0.1], "radius": 0.06} for k in range(150)
    ],
    "coplanar mesh floor": [
        {
            "type": "mesh",
            "material": "m",
            "vertices": [[x, 0, z] for z in range(5) for x in range(5)],
            "faces": [
                f
                for z in range(4)
                for x in range(4)
                for f in ([z * 5 + x, z * 5 + x + 1, z * 5 + x + 6], [z * 5 + x, z * 5 + x + 6, z * 5 + x + 5])
            ],
        },
        {"type": "triangle", "material": "m", "vertices": [[0, 0, 0], [4, 0, 0], [0, 0, 4]]},
    ],
    "closed box of 2e-5": [
        {
            "type": "mesh",
            "material": "m",
            "vertices": [[x * 2e-5, y * 2e-5, z * 2e-5] for x in (0, 1) for y in (0, 1) for z in (0, 1)],
            "faces": [
                [0, 1, 3],
                [0, 3, 2],
                [4, 6, 7],
                [4, 7, 5],
                [0, 4, 5],
                [0, 5, 1],
                [2, 3, 7],
                [2, 7, 6],
                [0, 2, 6],
                [0, 6, 4],
                [1, 5, 7],
                [1, 7, 3],
            ],
        },
        {"type": "sphere", "material": "m", "center": [1e-5, 1e-5, 1e-5], "radius": 5e-6},
    ],
}


@pytest.mark.parametrize("name", sorted(HARD_FIELDS))
def test_walk_agrees_with_brute_force_on_hard_geometry(name):
    rng = np.random.default_rng(5)
    objs = HARD_FIELDS[name]
    world = build_world(scene_with(objs))
    lo = np.min([np.min(np.asarray(o.get("vertices", [o.get("center", [0, 0, 0])]), float), axis=0) for o in objs], 0)
    hi = np.max([np.max(np.asarray(o.get("vertices", [o.get("center", [0, 0, 0])]), float), axis=0) for o in objs], 0)
    size = max(float(np.max(hi - lo)), 1e-5)
    origins = (lo + hi) / 2 - world.origin + rng.uniform(-2, 2, (2000, 3)) * size
    dirs = rng.normal(size=(2000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    # aim half the rays at the geometry itself: at corners and centres, give or take a little
    marks = np.concatenate([np.asarray(o.get("vertices", [o.get("center")]), float) for o in objs])
    jitter = min(float(np.min([o.get("radius", 0.1 * size) for o in objs])) * 1.5, 0.1 * size)
    aim = marks[rng.integers(0, len(marks), 1000)] + rng.uniform(-jitter, jitter, (1000, 3)) - world.origin
    aim -= origins[:1000]
    dirs[:1000] = aim / np.linalg.norm(aim, axis=1, keepdims=True)
    hits = check_agrees(world, origins, dirs, rng)
    assert np.mean(hits.kind != MISS) > 0.2


def test_orthographic_rays_along_a_column_of_spheres_hit_the_first():
    objs = HARD_FIELDS["column of 150 spheres"]
    world = build_world(scene_with(objs))
    o = np.array([[0.0, 0.0, 5.0], [0.0, 0.0, -20.0]]) - world.origin
    d = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    isect = Intersector(world)
    hits = isect.closest(isect.rays(o, d))
    assert list(hits.index) == [0, 149]


def test_huge_surfaces_are_tested_directly_not_through_the_bvh():
    objs = random_field(np.random.default_rng(1), 10, big=True)
    objs.append({"type": "triangle", "material": "m", "vertices": [[-1e5, -5, -1e5], [1e5, -5, -1e5], [0, -4, 1e5]]})
    isect = Intersector(build_world(scene_with(objs)))
    assert len(isect.direct_spheres) == 1 and len(isect.direct_triangles) == 1


def test_no_bvh_without_triangles_or_small_spheres():
    isect = Intersector(
        build_world(scene_with([{"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]}]))
    )
    assert isect.bvh is None
    hits = isect.closest(isect.rays(np.array([[0.0, 1, 0], [0, 1, 0]]), np.array([[0.0, -1, 0], [0, 1, 0]])))
    assert list(hits.kind) == [PLANE, MISS]


@pytest.mark.as_rendered
def test_three_spheres_are_tested_directly_and_four_go_into_the_bvh():
    balls = [{"type": "sphere", "material": "m", "center": [x, 0, 0], "radius": 0.4} for x in (-1, 0, 1, 2)]
    three, four = (Intersector(build_world(scene_with(balls[:k]))) for k in (3, 4))
    assert three.bvh is None and list(three.direct_spheres) == [0, 1, 2]
    assert four.bvh is not None and len(four.direct_spheres) == 0 and four.walker.few
    o = np.array([[-1.0, 0, 5], [0.0, 0, 5], [3.0, 0, 5]])
    d = np.array([[0.0, 0, -1]] * 3)
    assert list(three.closest(three.rays(o - three.world.origin, d)).kind) == [SPHERE, SPHERE, MISS]
    assert list(four.closest(four.rays(o - four.world.origin, d)).index) == [0, 1, -1]


@pytest.mark.as_rendered
@pytest.mark.parametrize("spheres, triangles", [(1, 0), (3, 0), (4, 0), (6, 0), (2, 2), (0, 3), (7, 0), (3, 2)])
def test_a_few_primitives_agree_with_brute_force_as_rendering_tests_them(spheres, triangles):
    """Direct tests (at most three surfaces), the walk of a few primitives (Embree's broad phase, then every
    primitive) and, past that, the cell walk: closest hits, secondary rays and shadow rays from anywhere,
    many of them inside spheres and proxies, exactly as brute force finds them."""
    rng = np.random.default_rng(100 * spheres + triangles)
    objs = [
        {
            "type": "sphere",
            "material": "m",
            "center": list(map(float, rng.uniform(-2, 2, 3))),
            "radius": float(rng.uniform(0.05, 1.2)),
        }
        for _ in range(spheres)
    ]
    objs += [
        {
            "type": "triangle",
            "material": "m",
            "vertices": (rng.uniform(-2, 2, (1, 3)) + rng.uniform(-1, 1, (3, 3))).tolist(),
        }
        for _ in range(triangles)
    ]
    objs.append({"type": "plane", "material": "m", "point": [0, -3, 0], "normal": [0.1, 1, 0]})
    world = build_world(scene_with(objs))
    isect = Intersector(world)
    few = spheres + 2 * triangles
    assert (isect.walker is None) == (spheres + triangles <= 3)
    assert isect.walker is None or isect.walker.few == (few <= tracer.exact.walk.FEW)
    origins = rng.uniform(-3, 3, (3000, 3)) - world.origin
    dirs = rng.normal(size=(3000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    check_agrees(world, origins, dirs, rng)


def test_precision_does_not_depend_on_where_look_at_is():
    objs = random_field(np.random.default_rng(2), 20)
    near = build_world(scene_with(objs, {"position": [0, 0, 30], "look_at": [0, 0, 0]}))
    far = build_world(scene_with(objs, {"position": [0, 0, 30], "look_at": [0, 0, -1e6]}))
    assert np.array_equal(near.origin, far.origin)
    assert np.array_equal(Intersector(near).walker.proxies.vertices, Intersector(far).walker.proxies.vertices)


def test_slab_enters_and_leaves_a_box_along_every_axis_and_never_when_beside_it():
    from tracer.exact.walk import slab

    o = np.array([[0.5, 2.0, 0.5], [0.5, 0.5, 0.5], [-1, 0.5, 0.5], [0.5, 0.5, -3], [2, 2, 2]])
    d = np.array([[1.0, 0, 0], [0, 0, 1.0], [1, 0, 0], [0, 0, -1.0], [-1, -1, -1]])
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    near, far = slab(o, d, np.zeros(3), np.ones(3))
    assert near[0] > far[0]  # beside the box along an axis it does not move on
    assert (near[1], far[1]) == (-0.5, 0.5)
    assert (near[2], far[2]) == (1.0, 2.0)
    assert (near[3], far[3]) == (-4.0, -3.0)  # behind the origin
    assert np.isclose(near[4], np.sqrt(3)) and np.isclose(far[4], 2 * np.sqrt(3))
