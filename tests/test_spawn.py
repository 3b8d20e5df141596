"""Where secondary rays are born: at the exact hit point, leaving its surface by identity, or moved off it by a
student's offset."""

import numpy as np

import schemas
from tracer import Renderer
from tracer.exact.intersect import SPHERE
from tracer.scene.rays import Hits, Rays, Work
from tracer.scene.variants import REFERENCE, Spawn
from tracer.shade.spawn import Spawner


def mirror_world():
    scene = schemas.validate_scene(
        {
            "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
            "image": {"width": 1, "height": 1},
            "materials": {"glass": {"reflectance": 0.5, "transmittance": 0.25, "ior": 1.5}},
            "objects": [{"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": 1}],
        }
    )
    return Renderer(scene).world


def sphere_hits(n):
    point = np.tile([0.0, 0.0, 1.0], (n, 1)) + 1e-3 * np.arange(n)[:, None]
    return Hits(
        np.ones(n),
        np.full(n, SPHERE, dtype=np.int8),
        np.zeros(n, dtype=np.int64),
        point,
        np.tile([0.0, 0.0, 1.0], (n, 1)),
        np.zeros((n, 2)),
        np.zeros(n, dtype=np.int64),
    )


def test_a_ray_starts_at_the_exact_hit_point_and_leaves_its_surface():
    world = mirror_world()
    hit = sphere_hits(3)
    dirs = np.tile([0.0, 0.0, 1.0], (2, 1))
    rays = Spawner(world, REFERENCE, None).spawn(hit, np.array([5.0, 6.0, 7.0]), np.array([2, 0]), dirs, hit.normal)
    assert np.array_equal(rays.origins, hit.point[[2, 0]])
    assert rays.from_kind.tolist() == [SPHERE, SPHERE] and rays.from_index.tolist() == [0, 0]
    assert rays.mag.tolist() == [7.0, 5.0]


def test_a_students_offset_moves_the_ray_off_the_surface_by_its_amount():
    hit = sphere_hits(1)
    dirs = np.array([[0.0, 0.0, -1.0]])  # into the sphere: moved to the inside
    rays = Spawner(mirror_world(), REFERENCE, Spawn(0.01, "normal")).spawn(hit, np.ones(1), None, dirs, hit.normal)
    np.testing.assert_allclose(rays.origins, [[0.0, 0.0, 0.99]])
    assert rays.from_index.tolist() == [-1]


def test_a_students_offset_goes_along_the_shading_normal_it_has():
    """On a mesh with normals the shading normal leans away from the face's: a student's ``p + ε·N`` moves along
    the one their tracer has, the interpolated one (to the side the ray leaves by)."""
    hit = sphere_hits(1)
    leaning = np.array([[0.6, 0.0, 0.8]])
    for direction, side in (([0.0, 0.0, 1.0], 1.0), ([0.0, 0.0, -1.0], -1.0)):
        spawner = Spawner(mirror_world(), REFERENCE, Spawn(0.01, "normal"))
        rays = spawner.spawn(hit, np.ones(1), None, np.array([direction]), leaning)
        np.testing.assert_allclose(rays.origins, hit.point + side * 0.01 * leaning)


def test_an_offset_along_the_geometric_normal_goes_along_the_faces_own():
    """A student who offsets by the face's own normal (many do, on a mesh) moves along it, not the leaning
    shading normal, to the side the ray leaves by."""
    hit = sphere_hits(1)
    leaning = np.array([[0.6, 0.0, 0.8]])
    for direction, side in (([0.0, 0.0, 1.0], 1.0), ([0.0, 0.0, -1.0], -1.0)):
        spawner = Spawner(mirror_world(), REFERENCE, Spawn(0.01, "geometric"))
        rays = spawner.spawn(hit, np.ones(1), None, np.array([direction]), leaning)
        np.testing.assert_allclose(rays.origins, hit.point + side * 0.01 * hit.normal)


def test_a_bounce_spawns_the_mirror_and_the_refracted_ray_with_their_weights():
    world = mirror_world()
    hit = sphere_hits(1)
    d = np.array([[0.0, 0.0, -1.0]])
    work = Work(Rays.leaving(np.array([[0.0, 0.0, 5.0]]), d, 0.0), np.array([4]), np.array([0.5]), 0)
    children = Spawner(world, REFERENCE, None).bounce(hit, np.zeros(1, dtype=np.int64), hit.normal, work)
    assert children.depth == 1 and children.sample.tolist() == [4, 4]
    np.testing.assert_allclose(children.weight, [0.25, 0.125])
    np.testing.assert_allclose(children.rays.dirs[0], [0, 0, 1])  # the mirror ray, straight back
    assert children.rays.dirs[1][2] < 0  # the refracted ray, on into the sphere
    assert np.array_equal(children.rays.origins, np.repeat(hit.point, 2, axis=0))
