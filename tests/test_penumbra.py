"""An area light's mixed points (tracer/proofs/penumbra.py): each shadow ray proven blocked or clear from its direction
and length decides as the brute force's ray does."""

import numpy as np
import pytest

import schemas
from tracer import Renderer
from tracer.proofs.bounds import SurfacePoints, bounds_of
from tracer.proofs.culling import MIXED, classify
from tracer.proofs.penumbra import Penumbra
from tracer.scene.kinds import PLANE

import reference


@pytest.mark.parametrize("seed", range(5))
def test_rays_decided_by_their_pairs_decide_as_the_brute_force(seed):
    rng = np.random.default_rng(seed)
    objects = [
        {
            "type": "sphere",
            "material": "m",
            "center": rng.uniform(-2, 2, 3).tolist(),
            "radius": float(rng.uniform(0.3, 0.8)),
        }
        for _ in range(5)
    ]
    objects.append({"type": "plane", "material": "m", "point": [0, -2.5, 0], "normal": [0, 1, 0]})
    scene = schemas.validate_scene(
        {
            "camera": {"position": [0, 0, 8], "look_at": [0, 0, 0]},
            "image": {"width": 4, "height": 4},
            "materials": {"m": {}},
            "objects": objects,
            "lights": [],
        }
    )
    world = Renderer(scene).world
    corners = np.array([[-1, 3, -1], [1, 3, -1], [1, 3, 1], [-1, 3, 1]], dtype=float) + rng.uniform(-1, 1, 3)
    x, z = np.meshgrid(np.linspace(-5, 5, 60), np.linspace(-5, 5, 60))
    points = np.stack([x.ravel(), np.full(x.size, -2.5), z.ravel()], axis=1)
    n = len(points)
    at = SurfacePoints(
        points - world.origin,
        np.full(n, PLANE, dtype=np.int8),
        np.zeros(n, dtype=np.int64),
        np.tile([0.0, 1.0, 0.0], (n, 1)),
    )
    b = bounds_of(world)
    culled = classify(b, at, corners - world.origin)
    mixed = np.flatnonzero(culled.state == MIXED)
    assert len(mixed) > 100
    sub = SurfacePoints(at.point[mixed], at.kind[mixed], at.index[mixed], at.outward[mixed])
    penumbra = Penumbra(b, sub, culled.may_block[:, mixed], corners - world.origin, True)
    surfaces, start = reference.surfaces_of(scene), np.full(len(mixed), 5)  # (leaving the floor)
    decided_blocked = decided_clear = 0
    for a in np.linspace(0, 1, 3):
        for c in np.linspace(0, 1, 3):
            q = corners[0] + a * (corners[1] - corners[0]) + c * (corners[3] - corners[0])
            to = q - points[mixed]
            dist = np.linalg.norm(to, axis=1)
            unit = to / dist[:, None]
            blocked, cast, _ = penumbra.decide(np.ones(len(mixed), dtype=bool), unit, dist)
            truth, unclear = reference.blocked(surfaces, points[mixed], unit, dist, start, q)
            clear = ~blocked & ~cast
            assert not np.any(blocked & ~truth & ~unclear)
            assert not np.any(clear & truth & ~unclear)
            decided_blocked += int(np.count_nonzero(blocked))
            decided_clear += int(np.count_nonzero(clear))
    assert decided_blocked > 0 and decided_clear > 0  # the proof decides rays both ways
