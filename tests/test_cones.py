"""Rays through a point or along a direction (tracer/proofs/cones.py): every surface an exact test finds hit is paired.

Each test builds a scene of spheres and triangles (slivers, specks, a planet, a triangle edge-on to the apex,
an apex inside a sphere), casts rays aimed at the surfaces, their rims and their edges, tests every ray
against every surface with the exact tests of tracer/scene/shapes.py, and asks that each hit be among the pairs
the cones give; and that the pairs are far fewer than every ray against every surface.
"""

import numpy as np
import pytest

import schemas
from tracer import Renderer
from tracer.proofs.bounds import bounds_of
from tracer.proofs.cones import along_direction, through_point
from tracer.scene.shapes import SPHERE, TRIANGLE, sphere_t, triangle_t
from tracer.scene.surfaces import unit


def scene_of(rng, scale=1.0, shift=0.0):
    objects = []
    for _ in range(6):
        objects.append(
            {
                "type": "sphere",
                "material": "m",
                "center": (rng.uniform(-3, 3, 3) * scale + shift).tolist(),
                "radius": float(rng.choice([1e-3, 0.05, 0.4, 1.2])) * scale,
            }
        )
    objects.append(
        {
            "type": "sphere",
            "material": "m",
            "center": [0.1 * scale + shift, shift, -0.2 * scale + shift],
            "radius": 0.5 * scale,
        }
    )  # the apex (the eye, at shift) inside it
    for _ in range(6):
        a = rng.uniform(-3, 3, 3)
        corners = [a, a + rng.normal(size=3), a + rng.normal(size=3) * rng.choice([1.0, 1e-3])]  # slivers too
        objects.append(
            {"type": "triangle", "material": "m", "vertices": [(c * scale + shift).tolist() for c in corners]}
        )
    # a triangle in a plane through the eye (edge-on to the apex)
    objects.append(
        {
            "type": "triangle",
            "material": "m",
            "vertices": [
                [shift + 1 * scale, shift, shift + 1 * scale],
                [shift + 2 * scale, shift, shift - 1 * scale],
                [shift - 1 * scale, shift, shift - 2 * scale],
            ],
        }
    )
    data = {
        "camera": {"position": [shift, shift, shift], "look_at": [shift, shift, shift - scale - abs(shift) * 1e-3]},
        "image": {"width": 2, "height": 2},
        "materials": {"m": {}},
        "objects": objects,
        "lights": [],
    }
    return Renderer(schemas.validate_scene(data)).world


def aimed(rng, world, apex, n):
    """Directions from ``apex`` at random points of the surfaces: inside, near rims and edges, and anywhere."""
    sp, tr = world.spheres, world.triangles
    targets = [rng.normal(size=(n, 3)) * 4 + apex]
    k = rng.integers(0, len(sp.radius), n)
    rim = unit(rng.normal(size=(n, 3))) * (sp.radius[k] * (1 + rng.choice([0, 1e-12, -1e-12, 1e-6], n)))[:, None]
    targets.append(sp.center[k] + rim)
    k = rng.integers(0, len(tr.v0), n)
    u, v = rng.uniform(0, 1, n), rng.uniform(0, 1, n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    edge = rng.random(n) < 0.5
    u[edge] = 0.0  # on an edge (and a vertex, now and then)
    targets.append(tr.v0[k] + u[:, None] * tr.e1[k] + v[:, None] * tr.e2[k])
    return unit(np.concatenate(targets) - apex)


def exact_hits(world, origins, dirs, ends=None, reach=None):
    """Every (ray, surface) the exact tests find hit (before ``reach``, towards ``ends``): a set of
    (ray, kind, index)."""
    mag = np.max(np.abs(origins), axis=1) + float(np.max(np.abs(world.origin)))
    mag_e = None if ends is None else np.full(1, float(np.max(np.abs(ends))) + float(np.max(np.abs(world.origin))))
    with np.errstate(all="ignore"):  # (as the renderer computes: inf and NaN are no hit)
        return _hits_of(world, origins, dirs, ends, reach, mag, mag_e)


def _hits_of(world, origins, dirs, ends, reach, mag, mag_e):
    n, sp, tr = len(origins), world.spheres, world.triangles
    out = set()
    for k in range(len(sp.radius)):
        t = sphere_t(origins, dirs, sp.center[k], sp.radius[k], mag, sp.mag[k], np.zeros(n, bool), ends, reach, mag_e)
        out |= {(int(r), SPHERE, k) for r in np.flatnonzero(t < (np.inf if reach is None else reach))}
    for k in range(len(tr.v0)):
        t, _, _ = triangle_t(
            origins, dirs, tr.v0[k], tr.e1[k], tr.e2[k], tr.normal[k], mag, tr.mag[k], np.zeros(n, bool), ends, mag_e
        )
        out |= {(int(r), TRIANGLE, k) for r in np.flatnonzero(t < (np.inf if reach is None else reach))}
    return out


def paired(among):
    return set(zip(among.rows.tolist(), among.kind.tolist(), among.index.tolist()))


@pytest.mark.parametrize("scale, shift", [(1.0, 0.0), (1e-20, 0.0), (1e20, 0.0), (1.0, 1e6), (1e-3, -1e5)])
def test_rays_from_the_eye_meet_only_their_pairs(scale, shift):
    rng = np.random.default_rng(int(np.log10(scale) + 40) * 7 + int(abs(shift) > 0))
    world = scene_of(rng, scale, shift)
    apex = np.zeros(3)  # local: the eye
    dirs = aimed(rng, world, apex, 4000)
    origins = np.zeros_like(dirs)
    hits = exact_hits(world, origins, dirs)
    among = through_point(bounds_of(world), world.triangles, apex, dirs, True)
    assert hits and hits <= paired(among)
    k = len(world.spheres.radius) + len(world.triangles.v0)
    assert len(among.rows) < 0.35 * len(dirs) * k  # the proof spares most tests


@pytest.mark.parametrize("scale", [1.0, 1e-15, 1e15])
def test_shadow_rays_towards_a_point_light_meet_only_their_pairs(scale):
    rng = np.random.default_rng(11)
    world = scene_of(rng, scale)
    light = np.array([0.3, 5.0, -0.4]) * scale
    # from points on the surfaces (their own blocking aside) and anywhere, towards the light
    from_light = aimed(rng, world, light, 3000)
    points = light + from_light * (rng.uniform(0.5, 12, len(from_light)) * scale)[:, None]
    to = light - points
    reach = np.sqrt(np.sum(to * to, axis=1))
    dirs = to / reach[:, None]
    hits = exact_hits(world, points, dirs, light[None], reach)
    among = through_point(bounds_of(world), world.triangles, light, dirs, False, float(reach.max()))
    assert hits and hits <= paired(among)
    assert len(among.rows) < 0.35 * len(dirs) * (len(world.spheres.radius) + len(world.triangles.v0))


@pytest.mark.parametrize("scale, shift", [(1.0, 0.0), (1e-18, 0.0), (1e18, 3e20)])
def test_rays_along_one_direction_meet_only_their_pairs(scale, shift):
    rng = np.random.default_rng(5)
    world = scene_of(rng, scale, shift)
    direction = unit(np.array([0.2, -1.0, 0.35]))
    # origins on a plane across the direction, above the scene, and some aimed through surfaces
    u = unit(np.cross(direction, [1.0, 0, 0]))
    v = np.cross(direction, u)
    grid = rng.uniform(-5, 5, (4000, 2)) * scale
    origins = -6 * scale * direction + grid[:, :1] * u + grid[:, 1:] * v
    targets = aimed(rng, world, np.zeros(3), 1000) * (rng.uniform(0.1, 3, 3000) * scale)[:, None]
    origins = np.concatenate([origins, targets - 8 * scale * direction])
    dirs = np.broadcast_to(direction, origins.shape).copy()
    hits = exact_hits(world, origins, dirs)
    among = along_direction(bounds_of(world), world.triangles, origins, direction)
    assert hits and hits <= paired(among)
    assert len(among.rows) < 0.35 * len(dirs) * (len(world.spheres.radius) + len(world.triangles.v0))


def test_pairs_come_surface_by_surface():
    rng = np.random.default_rng(2)
    world = scene_of(rng)
    dirs = aimed(rng, world, np.zeros(3), 500)
    among = through_point(bounds_of(world), world.triangles, np.zeros(3), dirs, True)
    key = among.kind.astype(np.int64) * 1000 + among.index
    runs = key[np.r_[True, key[1:] != key[:-1]]]
    assert len(runs) == len(set(runs.tolist()))  # each surface's pairs in one run
    for k in set(runs.tolist()):
        rows = among.rows[key == k]
        assert len(rows) == len(set(rows.tolist()))  # each ray once per surface


@pytest.mark.parametrize("ratio", [1e-3, 1e-6, 1e-9, 1e-11])
def test_a_triangles_edge_planes_keep_their_direction_far_from_the_apex(ratio):
    # a triangle ``ratio`` of its distance from the apex: each plane through the apex and an edge is the
    # cross product of the apex-to-corner vector and the edge itself, within NORMAL_ERROR of the exact one
    from fractions import Fraction

    from tracer.proofs.cones import _edge_plane
    from tracer.proofs.margins import NORMAL_ERROR

    rng = np.random.default_rng(int(-np.log10(ratio)))
    apex = rng.normal(size=3) * 1e3
    far = apex + unit(rng.normal(size=(1, 3)))[0] * 1e6
    corners = far + rng.normal(size=(8, 3, 3)) * 1e6 * ratio  # eight triangles
    for i in range(3):
        start, end, third = corners[:, i], corners[:, (i + 1) % 3], corners[:, (i + 2) % 3]
        m, turn = _edge_plane(start - apex, end - start, third - start)
        for k in range(len(corners)):
            P = [Fraction(x) for x in apex]
            u = [Fraction(x) - q for x, q in zip(start[k], P)]
            w = [Fraction(x) - q for x, q in zip(end[k], P)]
            n = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]]
            side = sum((Fraction(x) - q) * c for x, q, c in zip(third[k], P, n))
            want = np.array([float(c if side > 0 else -c) for c in n])
            assert np.isfinite(turn[k])
            assert np.linalg.norm(m[k] * turn[k] - want / np.linalg.norm(want)) <= NORMAL_ERROR
