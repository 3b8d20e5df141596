"""Tiles of neighbouring hit points (tracer/proofs/tiles.py): a tile proven lit by a point or directional light is lit
from every point of it, against the brute force's shadow rays."""

import numpy as np
import pytest

import schemas
from tracer import Renderer
from tracer.proofs.bounds import SurfacePoints, bounds_of
from tracer.proofs.tiles import TILE, lit_tiles, tiles_of
from tracer.scene.kinds import PLANE

import reference


def floor_under_spheres(seed):
    """Four spheres over a floor, and points on the floor row by row (as a camera's hits come), facing up."""
    rng = np.random.default_rng(seed)
    objects = [
        {
            "type": "sphere",
            "material": "m",
            "center": rng.uniform(-2, 2, 3).tolist(),
            "radius": float(rng.uniform(0.2, 0.5)),
        }
        for _ in range(4)
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
    x, z = np.meshgrid(np.linspace(-6, 6, 160), np.linspace(-6, 6, 30))
    points = np.stack([x.ravel(), np.full(x.size, -2.5), z.ravel()], axis=1)
    return scene, points


def surface_points(world, points):
    n = len(points)
    return SurfacePoints(
        points - world.origin,
        np.full(n, PLANE, dtype=np.int8),
        np.zeros(n, dtype=np.int64),
        np.tile([0.0, 1.0, 0.0], (n, 1)),
    )


@pytest.mark.parametrize("seed", range(6))
def test_a_tile_proven_lit_by_a_point_light_is_lit_from_every_point(seed):
    scene, points = floor_under_spheres(seed)
    world = Renderer(scene).world
    light = np.array([0.5, 4.0, -0.5])
    lit = lit_tiles(bounds_of(world), surface_points(world, points), light - world.origin, None)
    whole = np.repeat(lit, TILE)[: len(points)]
    to = light - points
    dist = np.linalg.norm(to, axis=1)
    blocked, _ = reference.blocked(
        reference.surfaces_of(scene), points, to / dist[:, None], dist, np.full(len(points), 4), light
    )
    assert not np.any(blocked[whole])
    assert whole.sum() > len(points) // 2  # the proof spares most points their rays
    assert np.any(blocked)  # (the spheres do shade some of the floor)


@pytest.mark.parametrize("seed", range(6))
def test_a_tile_proven_lit_by_a_directional_light_is_lit_from_every_point(seed):
    scene, points = floor_under_spheres(seed)
    world = Renderer(scene).world
    direction = np.array([0.3, -1.0, 0.2]) / np.linalg.norm([0.3, -1.0, 0.2])
    lit = lit_tiles(bounds_of(world), surface_points(world, points), None, direction)
    whole = np.repeat(lit, TILE)[: len(points)]
    to = np.tile(-direction, (len(points), 1))
    blocked, _ = reference.blocked(
        reference.surfaces_of(scene), points, to, np.full(len(points), np.inf), np.full(len(points), 4), None
    )
    assert not np.any(blocked[whole])
    assert whole.sum() > len(points) // 2
    assert np.any(blocked)


def test_a_tiles_ball_holds_each_of_its_points():
    scene, points = floor_under_spheres(0)
    world = Renderer(scene).world
    at = surface_points(world, points[: TILE * 5 + 3])  # the last tile partial
    centre, reach, scale, one, kind, index = tiles_of(at)
    assert centre.shape[1] == len(reach) == 6
    for t in range(6):
        rows = at.point[t * TILE : (t + 1) * TILE]
        assert np.all(np.linalg.norm(rows - centre[:, t], axis=1) <= reach[t])
    assert np.all(one) and np.all(kind == PLANE) and np.all(index == 0)
