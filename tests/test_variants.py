"""Variants (tracer/scene/variants.py): a student's classic mistakes, as named options of a render."""

import numpy as np
import pytest

import schemas
from tracer import Renderer
from tracer.image import quantize
from tracer.scene.variants import MORE_VARIANTS, REFERENCE, VARIANTS, Options

from helpers import scene_dict, smooth_octahedron

#: a scene where every mistake shows: glass, a mirror, every light type, a spot with a hard edge, a deep tree, a sky
EVERYTHING = {
    "camera": {"position": [0.5, 2.2, 5.5], "look_at": [0, 0.6, 0], "fov": 45},
    "image": {"width": 48, "height": 36, "max_depth": 2, "background": [0.1, 0.15, 0.3]},
    "materials": {
        "m": {"diffuse": [0.6, 0.5, 0.4], "specular": 0.7, "shininess": 30},
        "glass": {"transmittance": 0.8, "reflectance": 0.1, "ior": 1.5},
        "mirror": {"reflectance": 0.7},
    },
    "objects": [
        {"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
        {"type": "sphere", "material": "glass", "center": [-0.9, 0.7, 0.5], "radius": 0.7},
        {"type": "sphere", "material": "mirror", "center": [0.9, 0.7, -0.5], "radius": 0.7},
        {"type": "sphere", "material": "m", "center": [0.2, 0.35, 1.4], "radius": 0.35},
        {"type": "triangle", "material": "m", "vertices": [[-2, 0, -2], [2, 0, -2], [0, 2.5, -2.2]]},
    ],
    "lights": [
        {"type": "ambient", "color": 0.2},
        {"type": "point", "color": 1.2, "position": [-3, 4, 3], "attenuation": [1, 0.05, 0.02]},
        {"type": "spot", "color": 1, "position": [2, 3, 2], "direction": [-1, -1.5, -1], "cutoff": 25},
        {
            "type": "area",
            "color": 0.8,
            "corner": [0, 3.5, -1],
            "edge_u": [1, 0, 0],
            "edge_v": [0, 0, 1],
            "samples": [2, 2],
        },
        {"type": "directional", "color": 0.3, "direction": [0.3, -1, 0.2]},
        {"type": "point", "color": 0.6, "position": [0, 0.4, 3]},
        {"type": "point", "color": 0.6, "position": [-1, -0.1, -3]},
    ],  # under the floor: N·L < 0 there
}


def pixels(options=REFERENCE, data=EVERYTHING):
    return Renderer(schemas.validate_scene(data), options).pixels()


def _bright():
    """EVERYTHING anti-aliased, with a coloured light bright enough that a term alone passes 1, a spot of a
    steep falloff and a soft edge, a checkerboard and a smooth mesh: every mistake of VARIANTS and MORE_VARIANTS
    shows in it."""
    import copy

    data = copy.deepcopy(EVERYTHING)
    data["image"].update(samples=2)
    data["lights"][1].update(color=[4.0, 2.0, 1.0])
    data["lights"][2].update(exponent=8, color=[0.6, 0.9, 1.4], inner_cutoff=12)
    data["materials"]["m"]["checker"] = {"size": 0.5, "material": "dark"}
    data["materials"]["dark"] = {"diffuse": [0.1, 0.1, 0.3], "specular": 0.5, "shininess": 10}
    data["objects"].append(smooth_octahedron((1.6, 0.45, 1.2), 0.45, "m"))
    return data


BRIGHT = _bright()


def test_the_reference_options_are_the_reference_render():
    data = scene_dict("04_whitted")
    assert np.array_equal(pixels(Options(), data), Renderer(schemas.validate_scene(data)).pixels())
    assert REFERENCE.reference and not VARIANTS["gamma"][0].reference
    assert VARIANTS["no-shadows"][0].changes() == ["shadows"]


@pytest.mark.parametrize("name", sorted(VARIANTS))
def test_every_variant_changes_the_image(name):
    assert np.mean(np.any(pixels(VARIANTS[name][0], BRIGHT) != pixels(data=BRIGHT), axis=2)) > 0.001


def test_variants_that_are_a_function_of_the_image():
    ref = pixels()
    assert np.array_equal(pixels(VARIANTS["image-flipped"][0]), ref[::-1])
    r = Renderer(schemas.validate_scene(EVERYTHING))
    img = EVERYTHING["image"]
    lin = r.chunk(0, img["width"] * img["height"]).reshape(img["height"], img["width"], 3)
    assert np.array_equal(pixels(VARIANTS["gamma"][0]), quantize(np.clip(lin, 0, None) ** (1 / 2.2)))


def test_variants_that_only_add_or_only_take_light():
    ref = pixels().astype(int)
    assert np.all(pixels(VARIANTS["no-shadows"][0]) >= ref)
    assert np.all(pixels(VARIANTS["no-ambient"][0]) <= ref)
    assert np.all(pixels(VARIANTS["no-specular"][0]) <= ref)
    assert np.all(pixels(VARIANTS["no-attenuation"][0]) >= ref)
    assert np.all(pixels(VARIANTS["area-not-divided"][0]) >= ref)


def test_the_far_end_of_acne_is_darker_than_acne_wherever_acne_shows():
    from tracer.scene.variants import BOUNDS

    ref, acne, far = (pixels(o).astype(int) for o in (REFERENCE, VARIANTS["shadow-acne"][0], BOUNDS["shadow-acne"]))
    assert np.all(far <= acne) and np.all(acne <= ref)
    assert np.mean(np.any(far < acne, axis=2)) > 0.05  # the far end shadows what acne leaves lit


# -- variants a scene cannot show (tracer.scene.shown.unchanged): the reference, bit for bit ------------------------


def _plain():
    """EVERYTHING stripped bare in turn: each rule of UNCHANGED holds for one of these, and renders as it says."""
    import copy

    out = {}
    dark = copy.deepcopy(EVERYTHING)
    dark["lights"] = [light for light in dark["lights"] if light["type"] == "ambient"]
    out["ambient light only"] = dark
    matte = copy.deepcopy(EVERYTHING)
    for m in matte["materials"].values():
        m["specular"] = 0.0
    out["every k_s zero"] = matte
    unlit = copy.deepcopy(EVERYTHING)
    unlit["lights"] = [light for light in unlit["lights"] if light["type"] != "ambient"]
    out["no ambient light"] = unlit
    square = copy.deepcopy(EVERYTHING)
    square["image"].update(width=36, height=36)
    out["a square image"] = square
    plain = copy.deepcopy(EVERYTHING)
    plain["lights"] = [
        {k: v for k, v in light.items() if k != "attenuation"}
        | ({"samples": [1, 1]} if light["type"] == "area" else {})
        for light in plain["lights"]
        if light["type"] != "spot"
    ]
    out["no attenuation, no spot, one area sample"] = plain
    dull = copy.deepcopy(EVERYTHING)
    for m in dull["materials"].values():
        m["reflectance"] = m["transmittance"] = 0.0
    out["no mirror, no glass"] = dull
    thin = copy.deepcopy(EVERYTHING)
    thin["materials"]["glass"]["ior"] = 1.0
    out["glass of index 1"] = thin
    flat = copy.deepcopy(EVERYTHING)
    flat["image"]["max_depth"] = 0
    out["no bounce"] = flat
    still = copy.deepcopy(dark)  # no shadow ray and no secondary ray: an offset moves nothing
    for m in still["materials"].values():
        m["reflectance"] = m["transmittance"] = 0.0
    out["ambient light only, no mirror, no glass"] = still
    level = copy.deepcopy(EVERYTHING)  # up ⟂ the view: u = r × f is up itself, and a student reading it as given agrees
    level["camera"]["look_at"] = [0, 2.2, 0]
    out["a camera that looks level"] = level
    return out


PLAIN = _plain()


@pytest.mark.parametrize("case", sorted(PLAIN))
def test_a_variant_the_scene_cannot_show_renders_as_the_reference(case):
    from tracer.scene.shown import unchanged
    from tracer.scene.variants import BOUNDS, MORE_VARIANTS

    scene = schemas.validate_scene(PLAIN[case])
    reference = Renderer(scene).pixels()
    every = {name: options for name, (options, _) in (VARIANTS | MORE_VARIANTS).items()} | BOUNDS
    said = [name for name in every if unchanged(name, scene)]
    assert said, f"no rule holds for {case}"
    for name in said:
        options = every[name]
        assert np.array_equal(Renderer(scene, options).pixels(), reference), name


def test_every_rule_holds_somewhere_and_every_variant_the_rules_allow_shows_in_everything():
    from tracer.scene.shown import UNCHANGED, unchanged

    held = {name for data in PLAIN.values() for name in UNCHANGED if unchanged(name, schemas.validate_scene(data))}
    assert held == set(UNCHANGED)
    scene = schemas.validate_scene(BRIGHT)
    assert not any(unchanged(name, scene) for name in VARIANTS)  # (each changes it: the test above)


# -- more mistakes (MORE_VARIANTS): each the render of a student's tracer that makes it (tests/student_oop.py) ----


@pytest.fixture(scope="module")
def bright():
    scene = schemas.validate_scene(BRIGHT)
    return scene, Renderer(scene).pixels()


def _combined(*names):
    from dataclasses import replace

    from tracer.scene.variants import MORE_VARIANTS

    every = VARIANTS | MORE_VARIANTS
    changes = {field: getattr(every[name][0], field) for name in names for field in every[name][0].changes()}
    return replace(REFERENCE, **changes)


@pytest.mark.parametrize("name", sorted(MORE_VARIANTS))
def test_a_new_variant_is_the_image_of_a_student_who_makes_the_mistake(bright, name):
    import student_oop

    from service.images.grading import grade
    from tracer.scene.variants import MORE_VARIANTS, SENTENCES

    scene, reference = bright
    variant = Renderer(scene, MORE_VARIANTS[name][0]).pixels()
    made = student_oop.render(scene, [name])
    assert np.mean(np.any(variant != reference, axis=2)) > 0.001
    assert not grade(reference, made, "").passed  # the mistake shows
    assert grade(variant, made, "").passed  # and the variant is it
    assert name not in VARIANTS and SENTENCES[name].endswith(".")


@pytest.mark.parametrize(
    "pair",
    [
        ("no-shadows", "blinn-phong"),
        ("no-attenuation", "gamma"),
        ("reflection-blended", "camera-left-handed"),
        ("light-colour-ignored", "grayscale"),
        ("clamped-per-term", "spot-exponent-ignored"),
    ],
)
def test_two_mistakes_together_are_the_variants_options_together(bright, pair):
    import student_oop

    from service.images.grading import grade

    scene, reference = bright
    made = student_oop.render(scene, list(pair))
    assert grade(Renderer(scene, _combined(*pair)).pixels(), made, "").passed
    for one in pair:
        assert not grade(Renderer(scene, _combined(one)).pixels(), made, "").passed


def test_the_stored_variants_are_pillows_grey_and_bgr():
    from PIL import Image as PILImage

    rgb = np.random.default_rng(7).integers(0, 256, (9, 11, 3), dtype=np.uint8)
    grey = np.asarray(PILImage.fromarray(rgb, "RGB").convert("L"))
    assert np.array_equal(Options(grayscale=True).stored(rgb), np.repeat(grey[..., None], 3, axis=2))
    assert np.array_equal(Options(channels_swapped=True).stored(rgb), rgb[..., ::-1])
    assert REFERENCE.stored(rgb) is rgb


def test_the_mirrored_camera_is_the_image_mirrored(bright):
    from tracer.scene.variants import MORE_VARIANTS

    scene, reference = bright
    mirrored = Renderer(scene, MORE_VARIANTS["camera-left-handed"][0]).pixels()
    assert np.mean(np.any(mirrored != reference[:, ::-1], axis=2)) < 0.01  # (edge pixels: rounding)


def test_a_variant_that_misreads_the_scene_reads_a_copy():
    scene = schemas.validate_scene(BRIGHT)
    assert REFERENCE.read(scene) is scene
    read = Options(samples_read=False, light_colour=False, spot_exponent=False).read(scene)
    assert read.image.samples == 1 and scene.image.samples == 2
    assert all(light.color == (1.0, 1.0, 1.0) for light in read.lights if light.type != "ambient")
    assert [light.exponent for light in read.lights if light.type == "spot"] == [0.0]
    assert read.lights[0] == scene.lights[0]  # the ambient light as it is


# -- the mistakes an image may not tell from another, and more that tracers written from the format make ---------

#: classic mistakes each a switch of both students' tracers (tests/student.py, tests/student_oop.py), made their own way
BOTH_STUDENTS = (
    "reflect-sign",
    "checker-ignored",
    "checker-truncated",
    "area-samples-at-corners",
    "camera-up-as-given",
    "bounce-miss-black",
    "colours-not-clamped",
    "ambient-from-diffuse",
    "spot-ramp-angle",
    "transparent-no-shadows",
)


@pytest.mark.parametrize("name", BOTH_STUDENTS)
def test_a_variant_is_the_image_of_either_student_who_makes_the_mistake(bright, name):
    import student
    import student_oop

    from service.images.grading import grade

    scene, reference = bright
    variant = Renderer(scene, VARIANTS[name][0]).pixels()
    for made in (student.render(scene, [name]), student_oop.render(scene, [name])):
        assert not grade(reference, made, "").passed  # the mistake shows
        assert grade(variant, made, "").passed  # and the variant is it


def test_colours_not_clamped_are_kept_modulo_256():
    from tracer.image import wrapped

    assert wrapped(np.array([0.5, 1.0, 1.5, 2.0, np.nan])).tolist() == [128, 255, 127, 254, 0]
    scene = schemas.validate_scene(BRIGHT | {"image": BRIGHT["image"] | {"samples": 1}})
    renderer = Renderer(scene, VARIANTS["colours-not-clamped"][0])
    img = scene.image
    linear = renderer.chunk(0, img.width * img.height)
    # brighter than the reference's film keeps a pixel of one sample (it saturates it at 2): a student wraps it
    assert Renderer(scene).chunk(0, img.width * img.height).max() <= 2.0 < linear.max()
    assert np.array_equal(renderer.pixels().reshape(-1, 3), wrapped(linear))


def test_a_spot_ramped_in_the_angle_is_half_way_at_the_middle_angle():
    from tracer.scene.lights import Emitter, spot_factor

    outer, inner = np.radians(30.0), np.radians(10.0)
    spot = Emitter(
        "point",
        np.ones(3),
        np.zeros(3),
        np.array([0.0, 0.0, -1.0]),
        np.array([1.0, 0.0, 0.0]),
        cos_outer=float(np.cos(outer)),
        cos_inner=float(np.cos(inner)),
        exponent=0.0,
    )
    angled = Emitter(**{**spot.__dict__, "ramp_in_angle": True})
    off = np.radians([0.0, 5.0, 20.0, 25.0, 35.0])
    rays = np.stack([np.sin(off), np.zeros(5), -np.cos(off)], axis=1)
    assert np.allclose(spot_factor(angled, rays), [1.0, 1.0, 0.5, 0.25, 0.0], atol=1e-12)
    cosine = (np.cos(off[2:4]) - np.cos(outer)) / (np.cos(inner) - np.cos(outer))  # the format's ramp
    assert np.allclose(spot_factor(spot, rays)[2:4], cosine, atol=1e-12)


def _glass_over_floor(opaque_ball: bool):
    objects = [
        {"type": "plane", "material": "floor", "point": [0, 0, 0], "normal": [0, 1, 0]},
        {"type": "sphere", "material": "glass", "center": [-0.6, 0.6, 0], "radius": 0.5},
    ]
    if opaque_ball:
        objects.append({"type": "sphere", "material": "floor", "center": [0.7, 0.5, 0], "radius": 0.4})
    return schemas.validate_scene(
        {
            "camera": {"position": [0, 2.5, 4], "look_at": [0, 0.3, 0], "fov": 50},
            "image": {"width": 40, "height": 30},
            "materials": {"floor": {}, "glass": {"transmittance": 0.9, "specular": 0.0}},
            "objects": objects,
            "lights": [{"type": "point", "color": 1, "position": [3, 3, 3]}, {"type": "ambient", "color": 0.2}],
        }
    )


def test_transparent_objects_that_cast_no_shadow_leave_the_opaque_ones_theirs():
    alone, both = _glass_over_floor(False), _glass_over_floor(True)
    through, unshadowed = VARIANTS["transparent-no-shadows"][0], VARIANTS["no-shadows"][0]
    # glass alone: its shadow is gone, as if nothing cast one (the same numbers, to the byte)
    assert np.array_equal(Renderer(alone, through).pixels(), Renderer(alone, unshadowed).pixels())
    assert not np.array_equal(Renderer(alone, through).pixels(), Renderer(alone).pixels())
    # an opaque ball beside it keeps its shadow
    assert np.any(Renderer(both, through).pixels() != Renderer(both, unshadowed).pixels())


def test_the_ambient_from_k_d_and_the_checker_ignored_are_the_scene_so_changed():
    import copy

    data = copy.deepcopy(BRIGHT)
    plain = copy.deepcopy(data)
    plain["materials"]["m"].pop("checker")
    assert np.array_equal(pixels(VARIANTS["checker-ignored"][0], data), pixels(data=plain))
    swapped = copy.deepcopy(data)
    for m in swapped["materials"].values():
        m["ambient"] = m.get("diffuse", 0.5)
    assert np.array_equal(pixels(VARIANTS["ambient-from-diffuse"][0], data), pixels(data=swapped))
