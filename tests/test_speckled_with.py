"""Shadow acne made with a second mistake (service/diagnosis/speckled_with.py): both named, from the image of a
student tracer written from the scene format (tests/student.py), its acne in its own speckles."""

import numpy as np
import pytest
import student
from test_compose import small

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
    # no specular lies between the reference and acne's far end (no direct light): acne alone passed
    scene, reference = lights
    assert _ids(scene, reference, ["shadow-acne", "no-specular"]) == ["shadow-acne+no-specular"]


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
