"""Shadow acne made with a second mistake (service/diagnosis/speckled_with.py): both named, from the image of a
student tracer written from the scene format (tests/student.py), its acne in its own speckles."""

import json
from pathlib import Path

import numpy as np
import pytest
import student
from test_compose import small

from schemas import validate_scene
from service.diagnosis import diagnose, renders_of
from service.diagnosis.records import matched
from service.diagnosis.speckled_with import shows
from service.images.grading import grade
from tracer import Renderer


@pytest.fixture(scope="module")
def lights():
    scene = small("02_all_lights", 64, 48)
    return scene, Renderer(scene).pixels()


def _ids(scene, reference, mistakes):  # noqa: ANN001, ANN202
    made = student.render(scene, mistakes)
    verdict = grade(reference, made, "")
    assert not verdict.passed
    return matched(diagnose(reference, made, verdict, renders_of(scene, 1)).as_dict())


@pytest.mark.parametrize("other", ["blinn-phong", "no-ambient", "gamma", "image-flipped"])
def test_acne_with_another_mistake_names_both(lights, other):
    scene, reference = lights
    assert _ids(scene, reference, ["shadow-acne", other]) == [f"shadow-acne+{other}"]


def test_acne_with_a_mistake_that_only_darkens_names_both(lights):
    # no specular lies between the reference and acne's far end (no direct light): acne alone passed.  The
    # reflected vector with the wrong sign differs from it only where a light lies behind a surface, and acne
    # darkens those pixels as far: the image cannot tell the two apart, and says both, its own first
    scene, reference = lights
    assert _ids(scene, reference, ["shadow-acne", "no-specular"]) == [
        "shadow-acne+no-specular",
        "shadow-acne+reflect-sign",
    ]


@pytest.fixture(scope="module")
def cornell():
    data = json.loads((Path(__file__).resolve().parent.parent / "examples" / "09_cornell_homework.json").read_text())
    data["image"].update(width=64, height=48)
    scene = validate_scene(data)
    return scene, Renderer(scene).pixels()


def test_acne_with_the_reflected_vector_wrong_is_named_so_beside_its_twin(cornell):
    """In the Cornell homework, acne with the reflected vector's sign wrong was named as acne with no specular
    term, nothing more: a student with a specular term was told they had none.  Both readings are said now, the
    one the image comes nearer first."""
    scene, reference = cornell
    assert _ids(scene, reference, ["shadow-acne", "reflect-sign"]) == [
        "shadow-acne+reflect-sign",
        "shadow-acne+no-specular",
    ]


def test_acne_alone_is_still_acne_alone(lights):
    scene, reference = lights
    assert _ids(scene, reference, ["shadow-acne"]) == ["shadow-acne"]


def test_a_second_mistake_shows_only_where_the_pixels_acne_spares_show_it():
    reference = np.full((4, 4, 3), 200, np.uint8)
    darker = reference.copy()
    darker[:2] = 150  # the second mistake's render: the top rows darker
    acne_alone = reference.copy()
    acne_alone[0, ::2] = 40  # speckles; the pixels spared are the reference's
    assert not shows(reference, darker, acne_alone, 2.0)
    both = darker.copy()
    both[0, ::2] = 40
    assert shows(reference, darker, both, 2.0)


def test_acne_averaged_over_sub_samples_is_still_acne():
    """08_antialiased takes 4 × 4 sub-samples a pixel: acne's speckles average out to about half the light, varying
    from one pixel to the next by 0.14 of the way to the far end where one sample a pixel varies by 0.5.  The
    speckle test's threshold falls with the sub-samples, and acne is named (it was a light "half as bright")."""
    scene = small("08_antialiased")
    reference = Renderer(scene).pixels()
    made = student.render(scene, ["shadow-acne"])
    found = diagnose(reference, made, grade(reference, made, ""), renders_of(scene, 1))
    assert matched(found.as_dict())[:1] == ["shadow-acne"]


@pytest.mark.parametrize("mistake", ["no-specular", "blinn-phong"])
def test_a_smooth_departure_between_the_reference_and_acnes_far_end_is_not_acne(mistake):
    """No specular term lies between the reference and acne's far end everywhere; with 16 sub-samples its changes
    from a pixel to the next (0.03) stay under the threshold's floor: it is named as itself, not acne."""
    scene = small("08_antialiased")
    reference = Renderer(scene).pixels()
    made = student.render(scene, [mistake])
    found = diagnose(reference, made, grade(reference, made, ""), renders_of(scene, 1))
    assert "shadow-acne" not in matched(found.as_dict())
    assert matched(found.as_dict())[:1] == [mistake]


def test_acne_over_a_spots_wider_cone_names_both(cornell):
    """A spot's cutoff read in radians widens its cone across the walls, and acne speckles the very pixels it
    lights: few match the spot mistake's render as they are.  Between that render and its far end (acne made
    with it), and not between the reference and acne's own far end, lie more: both are named.  The cone read in
    radians (81°) covers what the spot lights here as a point light would: under acne's speckles the image cannot
    tell the two apart, and says both, its own first."""
    scene, reference = cornell
    assert _ids(scene, reference, ["shadow-acne", "spot-radians"]) == [
        "shadow-acne+spot-radians",
        "shadow-acne+spot-cone-ignored",
    ]
