"""Area lights by proof (tracer/culling.py): points proven to see every sample, or none, against every sample."""

import numpy as np
import pytest

import schemas
from tracer import Renderer
from tracer.culling import HIDDEN, MIXED, SEEN, bounds_of, classify

import generator
import reference


def with_area_light(seed):
    family, data = generator.scene(seed, 24, 18)
    rng = np.random.default_rng(seed)
    centre = np.mean([o.get("center", o.get("point", [0, 0, 0])) for o in data["objects"]
                      if "center" in o or "point" in o] or [[0, 0, 0]], axis=0)
    size = float(np.max(np.abs(data["camera"]["position"])) or 1.0)
    data["lights"].append({"type": "area", "color": 1.0, "corner": (centre + rng.normal(size=3) * size).tolist(),
                           "edge_u": (rng.normal(size=3) * size * 0.3).tolist(),
                           "edge_v": (rng.normal(size=3) * size * 0.3).tolist(), "samples": [3, 3]})
    return data


@pytest.mark.parametrize("seed", range(40))
def test_proofs_change_no_byte(seed):
    scene = schemas.validate_scene(with_area_light(seed))
    proven, unproven = Renderer(scene), Renderer(scene)
    unproven.shading.bounds = None
    assert np.array_equal(proven.pixels(), unproven.pixels())
    assert proven.counts["shadow"] <= unproven.counts["shadow"]


def test_proofs_hold_against_every_sample_of_the_brute_force():
    rng = np.random.default_rng(3)
    counts = np.zeros(3, dtype=int)
    spared = 0
    for _ in range(12):
        objects = [{"type": "sphere", "material": "m", "center": rng.uniform(-2, 2, 3).tolist(),
                    "radius": float(rng.uniform(0.2, 0.8))} for _ in range(6)]
        objects.append({"type": "plane", "material": "m", "point": [0, -2.5, 0], "normal": [0, 1, 0]})
        objects.append({"type": "triangle", "material": "m", "vertices": rng.uniform(-2, 2, (3, 3)).tolist()})
        data = {"camera": {"position": [0, 0, 8], "look_at": [0, 0, 0]}, "image": {"width": 4, "height": 4},
                "materials": {"m": {}}, "objects": objects, "lights": []}
        scene = schemas.validate_scene(data)
        r = Renderer(scene)
        corners = np.array([[-1, 3, -1], [1, 3, -1], [1, 3, 1], [-1, 3, 1]], dtype=float) + rng.uniform(-1, 1, 3)
        points = rng.uniform(-3, 3, (3000, 3))
        points[:, 1] = rng.uniform(-2.4, 2.5, 3000)
        none = np.zeros(len(points), dtype=np.int8)
        culled = classify(bounds_of(r.world), points - r.world.origin, none, np.full(len(points), -1),
                          np.tile([0.0, 1.0, 0.0], (len(points), 1)), corners - r.world.origin)
        state = culled.state
        counts += np.bincount(state, minlength=3)
        surfaces = reference.surfaces_of(scene)
        # the bounds are the spheres, then the triangle; the brute force's surfaces are in object order
        by_bound = [surfaces[k] for k in range(6)] + [surfaces[7]]
        assert [s.kind for s in by_bound] == ["sphere"] * 6 + ["triangle"] and surfaces[6].kind == "plane"
        u, v = np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 9))
        for a, b in zip(u.ravel(), v.ravel()):  # every sample a light of any nu x nv could have, corners too
            q = corners[0] + a * (corners[1] - corners[0]) + b * (corners[3] - corners[0])
            to = q - points
            dist = np.linalg.norm(to, axis=1)
            start = np.full(len(points), -1)
            blocked, unclear = reference.blocked(surfaces, points, to / dist[:, None], dist, start, q)
            assert not np.any(blocked[state == SEEN])
            assert np.all(blocked[state == HIDDEN] | unclear[state == HIDDEN])
            for k, s in enumerate(by_bound):  # a bound that may not block a point's samples blocks none
                alone, unsure = reference.blocked([s], points, to / dist[:, None], dist, start, q)
                assert not np.any((alone | unsure) & ~culled.may_block[k])
                spared += np.count_nonzero(~culled.may_block[k] & (state == MIXED))
    assert counts[SEEN] > 3000 and counts[HIDDEN] > 300 and counts[MIXED] > 3000  # the proofs are not vacuous
    assert spared > 10 * 3000  # and a mixed point's rays are spared most bounds


def test_tiles_of_neighbouring_points_proven_seen_see_every_sample():
    """Points in the order a render makes them (rows of neighbours), so that whole tiles are proven SEEN
    (tracer.culling._seen_tiles): every SEEN point is blocked by no sample of the brute force, and the tiles
    spare the per-point proofs most points."""
    from tracer.culling import TILE, _classify, _seen_tiles

    rng = np.random.default_rng(8)
    objects = [{"type": "sphere", "material": "m", "center": rng.uniform(-2, 2, 3).tolist(),
                "radius": float(rng.uniform(0.2, 0.5))} for _ in range(4)]
    objects.append({"type": "plane", "material": "m", "point": [0, -2.5, 0], "normal": [0, 1, 0]})
    scene = schemas.validate_scene({"camera": {"position": [0, 0, 8], "look_at": [0, 0, 0]},
                                    "image": {"width": 4, "height": 4}, "materials": {"m": {}},
                                    "objects": objects, "lights": []})
    r = Renderer(scene)
    corners = np.array([[-1, 3.5, -1], [1, 3.5, -1], [1, 3.5, 1], [-1, 3.5, 1]], dtype=float)
    # the floor under the light, row by row: points on the plane (PLANE 0), as a camera's hits would come
    x, z = np.meshgrid(np.linspace(-6, 6, 320), np.linspace(-6, 6, 60))
    points = np.stack([x.ravel(), np.full(x.size, -2.5), z.ravel()], axis=1)
    kind, index = np.full(len(points), 2, dtype=np.int8), np.zeros(len(points), dtype=np.int64)
    up = np.tile([0.0, 1.0, 0.0], (len(points), 1))
    b = bounds_of(r.world)
    tiles = _seen_tiles(b, points - r.world.origin, kind, index, up, corners - r.world.origin)
    culled = classify(b, points - r.world.origin, kind, index, up, corners - r.world.origin)
    seen = culled.state == SEEN
    whole = np.repeat(tiles, TILE)[:len(points)]
    assert np.all(seen[whole])
    # most points the per-point proofs find SEEN are proven a tile at a time
    assert whole.sum() > 0.6 * np.count_nonzero(_classify(b, points - r.world.origin, kind, index, up,
                                                          corners - r.world.origin).state == SEEN)
    surfaces = reference.surfaces_of(scene)
    start = np.full(len(points), 5)  # (leaving the floor, the sixth object)
    for a in np.linspace(0, 1, 5):
        for c in np.linspace(0, 1, 5):
            q = corners[0] + a * (corners[1] - corners[0]) + c * (corners[3] - corners[0])
            to = q - points
            dist = np.linalg.norm(to, axis=1)
            blocked, _ = reference.blocked(surfaces, points, to / dist[:, None], dist, start, q)
            assert not np.any(blocked[seen])
            assert np.any(blocked)  # (the spheres do shade some of the floor)
