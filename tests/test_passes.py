"""Render passes (tracer/shade/passes.py): the image taken apart term by term, and the debugging passes."""

import numpy as np
import pytest

import schemas
from tracer import Renderer
from tracer.shade.passes import ADDITIVE, NAMES

from helpers import scene_dict


def linear(renderer):
    img = renderer.scene.image
    return renderer.chunk(0, img.width * img.height).reshape(img.height, img.width, 3)


@pytest.mark.parametrize("name", ["02_all_lights", "04_whitted", "08_antialiased"])
def test_the_additive_passes_sum_to_the_images_linear_value(name):
    r = Renderer(schemas.validate_scene(scene_dict(name)))
    p = r.passes(list(ADDITIVE))
    total = sum(p[k] for k in ADDITIVE)
    assert np.abs(total - linear(r)).max() < 1e-7
    assert all(p[k].min() >= 0 for k in ADDITIVE)
    assert p["ambient"].max() > 0 and p["diffuse"].max() > 0 and p["specular"].max() > 0


def test_whitted_has_reflection_and_refraction_and_background():
    p = Renderer(schemas.validate_scene(scene_dict("04_whitted"))).passes(list(ADDITIVE))
    assert p["reflection"].max() > 0.05 and p["refraction"].max() > 0.05 and p["background"].max() > 0.05


def test_a_lights_own_terms_add_up_to_every_lights():
    r = Renderer(schemas.validate_scene(scene_dict("02_all_lights")))
    every = r.passes(["diffuse", "specular"])
    lights = r.scene.lights
    for term in ("diffuse", "specular"):
        own = sum(r.passes([term], light=k)[term] for k in range(len(lights)))
        assert np.abs(own - every[term]).max() < 1e-7
    assert r.passes(["diffuse"], light=0)["diffuse"].max() == 0  # light 0 is ambient: it has no diffuse term


def shadowed():
    return schemas.validate_scene(
        {
            "camera": {"position": [0, 4, 0.01], "look_at": [0, 0, 0], "fov": 60},
            "image": {"width": 32, "height": 32},
            "materials": {"m": {}},
            "objects": [
                {"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
                {"type": "sphere", "material": "m", "center": [0, 1, 0], "radius": 0.5},
            ],
            "lights": [
                {"type": "point", "color": 1, "position": [0, 3, 0]},
                {
                    "type": "area",
                    "color": 1,
                    "corner": [-1, 3, -1],
                    "edge_u": [2, 0, 0],
                    "edge_v": [0, 0, 2],
                    "samples": [4, 4],
                },
            ],
        }
    )


def test_the_shadow_pass_is_what_reaches_the_first_hit():
    r = Renderer(shadowed())
    hard = r.passes(["shadow"], light=0)["shadow"]
    soft = r.passes(["shadow"], light=1)["shadow"]
    assert hard[0, 0] == 1.0 and hard[16, 16] == 1.0  # the floor far out, the top of the ball
    assert set(np.unique(hard)) <= {0.0, 1.0}
    assert 0 < soft.min() < 1 and np.any((soft > 0) & (soft < 1))  # a penumbra
    ring = r.passes(["shadow", "object"], light=0)
    under = (ring["object"] == 0) & (ring["shadow"] == 0)  # floor pixels the ball hides from the light
    assert under.sum() > 0


def test_normal_depth_and_object_of_the_first_hit():
    r = Renderer(shadowed())
    p = r.passes(["normal", "depth", "object"])
    assert p["object"][16, 16] == 1 and p["object"][0, 0] == 0
    assert abs(p["depth"][16, 16] - 2.5) < 0.02  # from y = 4 down to near the ball's top at y = 1.5
    assert p["normal"][16, 16, 1] > 0.98 and abs(np.linalg.norm(p["normal"][16, 16]) - 1) < 1e-9


def test_passes_do_not_depend_on_threads_or_chunks():
    r = Renderer(schemas.validate_scene(scene_dict("08_antialiased")))
    a = r.passes(list(NAMES), threads=1)
    b = r.passes(list(NAMES), threads=2, chunk_rays=4096)
    for name in NAMES:
        assert np.array_equal(a[name], b[name]), name


def test_unknown_passes_and_lights_are_refused():
    r = Renderer(shadowed())
    with pytest.raises(ValueError, match="unknown pass 'albedo'"):
        r.passes(["albedo"])
    with pytest.raises(ValueError, match="2 lights"):
        r.passes(["diffuse"], light=2)


def test_the_passes_of_some_pixels_are_those_of_the_whole_render():
    data = scene_dict("02_all_lights")
    data["image"].update(width=48, height=36)
    scene = schemas.validate_scene(data)
    whole = Renderer(scene).diagnosis_passes()
    picked = np.random.default_rng(2).choice(48 * 36, 300, replace=False)
    some = Renderer(scene).diagnosis_passes(pixels=picked, chunk_rays=64)
    rows, cols = np.divmod(picked, 48)
    assert set(some) == set(whole)
    for name, plane in whole.items():
        assert np.array_equal(plane[rows, cols], some[name]), name
    assert all(len(v) == 0 for v in Renderer(scene).diagnosis_passes(pixels=np.zeros(0, int)).values())
    # the first hits' passes alone, from camera rays alone (the scene has a mirror: its rays are not traced)
    renderer = Renderer(scene)
    first = renderer.diagnosis_passes(pixels=picked, first_hits=True)
    assert set(first) == {"object", "diffuse", "specular"} | {
        f"{t}:{k}" for t in ("diffuse", "specular") for k in (1, 2, 3, 4)
    }
    assert renderer.counts["secondary"] == 0 and Renderer(scene).passes(["reflection"])["reflection"].max() > 0
    for name, values in first.items():
        assert np.array_equal(whole[name][rows, cols], values), name
