"""The second student's tracer (tests/student_oop.py): honest when no switch is on, each switch a visible mistake.

Its images are the diagnosis's held-out set: these tests check the student, never the diagnosis.
"""

import numpy as np
import pytest
import student_oop
from test_variants import BRIGHT

import schemas
from service.images.grading import grade
from tracer import Renderer
from tracer.scene.variants import MORE_VARIANTS, VARIANTS

from helpers import scene_dict

EXAMPLES = [
    "01_three_spheres",
    "02_all_lights",
    "03_soft_shadows",
    "04_whitted",
    "05_mesh",
    "06_orthographic",
    "07_spotlights",
    "08_antialiased",
]


def small(name: str) -> schemas.Scene:
    data = scene_dict(name)
    data["image"].update(width=64, height=48)
    return schemas.validate_scene(data)


@pytest.mark.parametrize("name", EXAMPLES)
def test_the_honest_students_image_passes_the_grader_on_every_example(name):
    scene = small(name)
    assert grade(Renderer(scene).pixels(), student_oop.render(scene), "").passed


def test_the_switches_are_the_variants_names():
    assert set(student_oop.CLASSIC) == set(VARIANTS)
    assert set(student_oop.NEW) == set(MORE_VARIANTS)


@pytest.fixture(scope="module")
def bright():
    scene = schemas.validate_scene(BRIGHT)
    return scene, student_oop.render(scene)


@pytest.mark.parametrize("mistake", student_oop.MISTAKES)
def test_each_mistake_shows_in_a_scene_that_has_everything(bright, mistake):
    scene, honest = bright
    assert not grade(honest, student_oop.render(scene, [mistake]), "").passed


def test_two_mistakes_compose():
    scene = small("02_all_lights")
    both = student_oop.render(scene, ["no-shadows", "gamma"])
    no_shadows = student_oop.render(scene, ["no-shadows"])
    linear = no_shadows.astype(np.float64) / 255  # gamma of the no-shadow image, up to the 8-bit rounding
    assert np.max(np.abs(both - np.floor(255 * linear ** (1 / 2.2) + 0.5))) <= 8
    assert not grade(no_shadows, both, "").passed
