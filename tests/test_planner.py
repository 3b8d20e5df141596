"""Which proof spares which rays (tracer/proofs/planner.py): each condition decided once, from the scene and the
options."""

from dataclasses import replace

import numpy as np

import schemas
from tracer import Renderer
from tracer.proofs.planner import CONE_MAX, PROVEN_LIT, plan_proofs
from tracer.scene.variants import Options


def world_of(spheres: int):
    objects = [{"type": "sphere", "material": "m", "center": [3.0 * k, 0, 0], "radius": 1.0} for k in range(spheres)]
    data = {
        "camera": {"position": [0, 0, 8], "look_at": [0, 0, 0]},
        "image": {"width": 4, "height": 4},
        "materials": {"m": {}},
        "objects": objects,
        "lights": [{"type": "point", "color": 1.0, "position": [0, 5, 5]}],
    }
    return Renderer(schemas.validate_scene(data)).world


def test_the_format_gets_every_proof_in_a_scene_of_few_surfaces():
    plan = plan_proofs(world_of(3), Options(), None)
    assert plan.cone_bounds is not None and plan.light_bounds is not None
    assert plan.exact_shadows and plan.facing
    assert plan.lit_tile_bounds(PROVEN_LIT) is plan.light_bounds
    assert plan.lit_tile_bounds(PROVEN_LIT - 1) is None  # too few lit points to be worth the proof


def test_too_many_surfaces_for_the_cones_leave_every_ray_unpaired():
    plan = plan_proofs(world_of(CONE_MAX + 1), Options(), None)
    assert plan.cone_bounds is None
    assert plan.light_bounds is not None  # (the lights' proofs allow more: tracer.proofs.bounds.MAX_BOUNDS)


def test_a_variants_shadow_rays_get_no_proof_of_the_formats():
    world = world_of(3)
    acne = plan_proofs(world, Options(acne=True), None)
    assert acne.light_bounds is None and not acne.exact_shadows
    assert plan_proofs(world, Options(shadows=False), None).light_bounds is None


def test_points_lit_from_behind_get_no_tile_proof():
    plan = plan_proofs(world_of(3), Options(specular_behind=True), None)
    assert not plan.facing
    assert plan.lit_tile_bounds(10 * PROVEN_LIT) is None


def test_shadow_pairs_need_rays_from_the_exact_point():
    world = world_of(3)
    em = world.emitters[0]
    from tracer.scene.rays import Rays

    origins = np.zeros((2, 3))
    dirs = np.tile([0.0, 1.0, 0.0], (2, 1))
    rays = Rays(origins, dirs, np.zeros(2, dtype=np.int8), np.full(2, -1), np.zeros(2))
    reach = np.ones(2)
    assert plan_proofs(world, Options(), None).shadow_pairs(em, rays, reach) is not None
    assert plan_proofs(world, Options(acne=True), None).shadow_pairs(em, rays, reach) is None


def test_points_lit_from_behind_render_as_their_shadow_rays_show():
    """With the variant lighting points from behind, a sphere's own surface blocks some of its points' rays to
    an area light's samples: no proof that exempts it may decide them (two pixels differed here)."""
    data = {
        "camera": {"position": [3, -3, 3], "look_at": [0, 0, 0]},
        "image": {"width": 64, "height": 64},
        "materials": {"m": {}},
        "objects": [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1.0}],
        "lights": [{"type": "area", "color": 1.0, "corner": [-3, 0.5, -3], "edge_u": [6, 0, 0], "edge_v": [0, 0, 6]}],
    }
    scene = schemas.validate_scene(data)
    proven, unproven = Renderer(scene, Options(specular_behind=True)), Renderer(scene, Options(specular_behind=True))
    unproven.shadows.plan = replace(unproven.shadows.plan, light_bounds=None)
    assert np.array_equal(proven.pixels(), unproven.pixels())
