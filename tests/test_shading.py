"""Phong, checker, mirror and refraction through whole (one-pixel) scenes, against hand-computed values.

Each scene looks straight down at the floor y = 0 through an orthographic
1×1 camera, so the single primary ray hits P = (0, 0, 0) with D = (0, −1, 0).
"""

import math

import numpy as np
import pytest

import schemas
from tracer import Renderer
from tracer.shade.shading import refract

MAT = {"ambient": 0.1, "diffuse": 0.5, "specular": 0.8, "shininess": 2}


def colour(lights, material=MAT, objects=(), at=(0, 0, 0), max_depth=4, background=0, materials=None):
    mats = {"m": material, **(materials or {})}
    scene = schemas.validate_scene(
        {
            "camera": {
                "type": "orthographic",
                "position": [at[0], 5, at[2]],
                "look_at": list(at),
                "up": [0, 0, -1],
                "height": 1e-6,
            },
            "image": {"width": 1, "height": 1, "max_depth": max_depth, "background": background},
            "materials": mats,
            "objects": [{"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]}, *objects],
            "lights": list(lights),
        }
    )
    return Renderer(scene).chunk(0, 1)[0]


def test_ambient_only():
    np.testing.assert_allclose(colour([{"type": "ambient", "color": [1, 0.5, 0]}]), [0.1, 0.05, 0])


def test_phong_with_attenuated_point_light():
    # L = (0.6, 0.8, 0), N·L = 0.8, R = (−0.6, 0.8, 0), R·V = 0.8, I = 1 / (1 + 0.5 + 0.25)
    got = colour([{"type": "point", "color": 1, "position": [3, 4, 0], "attenuation": [1, 0.1, 0.01]}])
    np.testing.assert_allclose(got, [(0.5 * 0.8 + 0.8 * 0.8**2) / 1.75] * 3, rtol=1e-12)


def test_shininess_zero_gives_full_specular_only_where_r_dot_v_is_positive():
    mat = {**MAT, "shininess": 0}
    got = colour([{"type": "directional", "color": 1, "direction": [-3, -4, 0]}], material=mat)
    np.testing.assert_allclose(got, [0.5 * 0.8 + 0.8] * 3, rtol=1e-12)


def test_light_below_the_surface_gives_nothing():
    got = colour([{"type": "point", "color": 1, "position": [3, -4, 0]}])
    np.testing.assert_allclose(got, [0, 0, 0])


def test_light_on_the_surface_gives_nothing_and_no_nan():
    got = colour(
        [{"type": "point", "color": 1, "position": [0, 0, 0]}, {"type": "point", "color": 1, "position": [2, 0, 0]}]
    )
    np.testing.assert_allclose(got, [0, 0, 0])


def test_shadowed_point_keeps_only_ambient():
    blocker = {"type": "sphere", "material": "m", "center": [1.5, 2, 0], "radius": 0.5}
    got = colour(
        [{"type": "ambient", "color": 1}, {"type": "point", "color": 1, "position": [3, 4, 0]}], objects=[blocker]
    )
    np.testing.assert_allclose(got, [0.1] * 3)


def test_occluder_beyond_the_light_does_not_shadow():
    beyond = {"type": "sphere", "material": "m", "center": [4.5, 6, 0], "radius": 0.5}
    got = colour([{"type": "point", "color": 1, "position": [3, 4, 0]}], objects=[beyond])
    np.testing.assert_allclose(got, [0.5 * 0.8 + 0.8 * 0.8**2] * 3, rtol=1e-12)


def test_light_on_an_occluding_surface_is_not_blocked_by_it():
    # the light sits exactly on the sphere's surface, facing the floor point
    sphere = {"type": "sphere", "material": "m", "center": [3, 5, 0], "radius": 1}
    got = colour([{"type": "point", "color": 1, "position": [3, 4, 0]}], objects=[sphere])
    np.testing.assert_allclose(got, [0.5 * 0.8 + 0.8 * 0.8**2] * 3, rtol=1e-12)


def test_checker_odd_cell_uses_the_other_material():
    mats = {"other": {"ambient": 0.7, "diffuse": 0, "specular": 0}}
    mat = {**MAT, "checker": {"size": 1, "material": "other"}}
    amb = [{"type": "ambient", "color": 1}]
    # (0.5, 0, 0.5): cells 0+0+0 even; (1.5, 0, 0.5): 1+0+0 odd; y = 0 lies exactly on a boundary
    np.testing.assert_allclose(colour(amb, material=mat, materials=mats, at=(0.5, 0, 0.5)), [0.1] * 3)
    np.testing.assert_allclose(colour(amb, material=mat, materials=mats, at=(1.5, 0, 0.5)), [0.7] * 3)
    np.testing.assert_allclose(colour(amb, material=mat, materials=mats, at=(-0.5, 0, 0.5)), [0.7] * 3)


def test_mirror_adds_the_reflected_background():
    mat = {**MAT, "reflectance": 0.5}
    got = colour([{"type": "ambient", "color": 1}], material=mat, background=[0.2, 0.4, 0.6])
    np.testing.assert_allclose(got, [0.1 + 0.1, 0.1 + 0.2, 0.1 + 0.3])


def test_max_depth_zero_casts_no_secondary_rays():
    mat = {**MAT, "reflectance": 0.5}
    got = colour([{"type": "ambient", "color": 1}], material=mat, background=1, max_depth=0)
    np.testing.assert_allclose(got, [0.1] * 3)


def test_clear_glass_of_index_one_shows_what_is_behind_it():
    glass = {"ambient": 0, "diffuse": 0, "specular": 0, "transmittance": 1, "ior": 1}
    floor = {"ambient": 0.4, "diffuse": 0, "specular": 0}
    ball = {"type": "sphere", "material": "glass", "center": [0, 2, 0], "radius": 1}
    amb = [{"type": "ambient", "color": 1}]
    got = colour(amb, material=floor, materials={"glass": glass}, objects=[ball], at=(0, 0, 0))
    np.testing.assert_allclose(got, [0.4] * 3, rtol=1e-12)
    # one bounce enters the ball; its far side has no depth left and adds only its own (black) shading
    got = colour(amb, material=floor, materials={"glass": glass}, objects=[ball], at=(0, 0, 0), max_depth=1)
    np.testing.assert_allclose(got, [0, 0, 0])


def test_refraction_follows_snell():
    d = np.array([[math.sin(math.radians(30)), -math.cos(math.radians(30)), 0]])
    t = refract(d, np.array([[0.0, 1, 0]]), np.array([1.5]))
    assert math.sin(math.atan2(t[0, 0], -t[0, 1])) == pytest.approx(0.5 / 1.5)


def test_total_internal_reflection_mirrors():
    d = np.array([[math.sin(math.radians(60)), math.cos(math.radians(60)), 0]])  # leaving: D·n > 0
    t = refract(d, np.array([[0.0, 1, 0]]), np.array([1.5]))
    np.testing.assert_allclose(t, [[d[0, 0], -d[0, 1], 0]], atol=1e-15)


# -- which emitters a flat surface's plane holds: where light_in_plane need not be called ---------------------------


def test_an_emitter_no_plane_holds_leaves_every_n_dot_l_as_it_is():
    """planes_holding decides per surface what light_in_plane decides per hit: where it says no flat surface
    holds an emitter, light_in_plane changes no N·L of any hit; and it finds the lights that do lie in one."""
    from tracer.scene.vec import dot
    from tracer.shade.shading import light_in_plane, planes_holding

    import generator

    held = 0
    for seed in range(120):
        _, data = generator.scene(seed, 12, 9, family="lights" if seed % 2 else None)
        r = Renderer(schemas.validate_scene(data))
        cam = r.camera.rays(0, 12 * 9)
        hits = r.intersector.closest(r.intersector.rays(*cam))
        hits = hits.take(np.flatnonzero(hits.kind != 0))
        holds = planes_holding(r.world, r.world.emitters)
        held += int(holds.sum())
        for e, em in enumerate(r.world.emitters):
            to_light = em.position - hits.point if em.kind != "directional" else -em.direction[None]
            dist = np.sqrt(dot(to_light, to_light)) if em.kind != "directional" else np.full(len(hits.t), np.inf)
            nl = dot(hits.normal, to_light / (dist[:, None] if em.kind != "directional" else 1.0))
            if not holds[e]:
                assert light_in_plane(r.world, hits, em, nl, dist) is nl
    assert held > 0


def test_odd_cells_are_those_np_mod_finds_odd():
    from tracer.shade.shading import odd_cells

    cells = np.array(
        [
            -5.0,
            -4,
            -3,
            -1,
            -0.0,
            0,
            1,
            2,
            3,
            2**52 + 1,
            -(2**52 + 1),
            2**53,
            2**53 + 2,
            -(2.0**60),
            1e300,
            np.inf,
            -np.inf,
            np.nan,
            7.0e15 + 1,
        ]
    )
    rng = np.random.default_rng(0)
    cells = np.concatenate([cells, np.floor(rng.uniform(-1e6, 1e6, 1000)), np.floor(rng.normal(size=1000) * 1e15)])
    with np.errstate(invalid="ignore"):
        assert np.array_equal(odd_cells(cells), np.mod(cells, 2.0) == 1.0)
    assert odd_cells(cells).sum() > 500
