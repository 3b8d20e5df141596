"""The stored image's mistakes (service/diagnosis/stored.py): tried on the reference's pixels, with no render."""

from pathlib import Path

import numpy as np
import offset_matrix
import pytest
import student
from test_compose import small

from schemas import load_scene
from service.diagnosis.records import matched
from service.diagnosis.stored import flipped_edges, image_level, outer, undone
from service.work import pipeline
from tracer import Renderer, encode_png
from tracer.scene.variants import Options


def test_undone_inverts_the_stored_images_flips_and_channel_swap():
    image = np.random.default_rng(3).integers(0, 256, (6, 5, 3), dtype=np.uint8)
    names = ("image-flipped", "camera-left-handed", "channels-swapped")
    assert np.array_equal(undone(outer(image, names), names), image)
    grey = outer(image, ("grayscale",))
    assert np.array_equal(grey, Options(grayscale=True).stored(image))


@pytest.mark.parametrize(
    "names", [("camera-left-handed",), ("grayscale",), ("channels-swapped",), ("image-flipped", "channels-swapped")]
)
def test_image_level_mistakes_are_found_on_the_references_pixels(names):
    reference = Renderer(small("01_three_spheres")).pixels()
    assert set(image_level(reference, outer(reference, names))) == set(names)
    assert image_level(reference, reference) == {}


def _example(name: str):  # noqa: ANN202
    """An example scene 64 pixels across, as the confusion matrix grades pairs (tests/offset_matrix.py)."""
    path = Path(__file__).resolve().parent.parent / "examples" / f"{name}.json"
    return offset_matrix._sized(load_scene(path.read_bytes()), 64)


#: mistakes that change every pixel's brightness more than a flip moves them (gamma, a light too bright, an
#: ambient term of another colour): the flip beside them is found by the outlines
BRIGHTER = ("gamma", "area-not-divided", "ambient-from-diffuse", "no-attenuation")


@pytest.mark.parametrize("name", ["02_all_lights", "09_cornell_homework"])
def test_a_flip_behind_a_change_of_brightness_is_found_by_its_outlines(name):
    scene = _example(name)
    reference = Renderer(scene).pixels()
    for mistake in BRIGHTER:
        made = student.render(scene, [mistake, "image-flipped"])
        alone = student.render(scene, [mistake])
        if np.array_equal(made[::-1], alone) and np.array_equal(alone, reference):
            continue  # (the scene does not show it)
        assert "image-flipped" in image_level(reference, made), mistake
        assert "image-flipped" not in image_level(reference, alone), mistake


@pytest.mark.parametrize(
    "name", ["01_three_spheres", "02_all_lights", "04_whitted", "07_spotlights", "09_cornell_homework"]
)
def test_no_flip_is_seen_in_an_upright_image(name):
    """Every mistake of the student tracer but the flip, alone, and a zoomed camera with a change of brightness
    (on the spotlights, whose outlines then share 0.22 with the flipped reference's, 0.14 with its own): the
    outlines never say flipped."""
    scene = _example(name)
    reference = Renderer(scene).pixels()
    for mistake in student.MISTAKES:
        if mistake != "image-flipped":
            assert not flipped_edges(reference, student.render(scene, [mistake])), mistake
    for pair in (["horizontal-fov", "gamma"], ["horizontal-fov", "ambient-from-diffuse"]):
        assert not flipped_edges(reference, student.render(scene, pair)), pair


def test_a_flip_behind_an_area_light_not_divided_is_named_with_it():
    """The whole diagnosis: the submission matches the reference rendered with both (it was "comes closest to
    an area light not divided", the flip unseen behind an image four times too bright)."""
    scene = _example("02_all_lights")
    submitted = student.render(scene, ["image-flipped", "area-not-divided"])
    reference = encode_png(Renderer(scene).pixels())
    found = pipeline.grade_png(
        reference, encode_png(submitted), 2.0, 0.001, explaining=pipeline.Explaining(lambda: scene)
    )
    assert not found.grade.passed and found.diagnosis is not None
    assert matched(found.diagnosis.as_dict())[:1] == ["area-not-divided+image-flipped"]
