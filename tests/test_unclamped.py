"""Colours not clamped behind another mistake (service/diagnosis/unclamped.py): the wrap's dark dots found where the
other mistake's render is white, and the two named together."""

import numpy as np
import pytest
import student
from test_compose import small

from service.diagnosis import diagnose, renders_of
from service.diagnosis.records import matched
from service.diagnosis.unclamped import DARKER, _wrap_signature
from service.images.grading import grade
from tracer import Renderer


@pytest.mark.parametrize(
    "other",
    [
        # no shadow rays light pixels past white that a shadow kept below it: the dots fall where the reference
        # has none, and no shadow rays alone only comes closest
        "no-shadows",
        # the half vector's highlights are wider: the dots lie beside a dark edge, and Blinn-Phong alone passes
        # with them off
        "blinn-phong",
        # with no mirror rays the mirror is darker, and the dots and the darker mirror both lie between the
        # reference and acne's far end: acne passed its test between bounds, and acne with the wrap was named,
        # where a render of the two mistakes the student made matches the image exactly
        "no-reflection",
    ],
)
def test_colours_not_clamped_behind_another_mistake_are_named_with_it(other):
    scene = small("02_all_lights")
    reference = Renderer(scene).pixels()
    made = student.render(scene, [other, "colours-not-clamped"])
    verdict = grade(reference, made, "")
    found = diagnose(reference, made, verdict, renders_of(scene, 1))
    assert [set(i.split("+")) for i in matched(found.as_dict())][:1] == [{other, "colours-not-clamped"}]


def white_disc() -> np.ndarray:
    image = np.full((20, 20, 3), 40, np.uint8)
    image[6:14, 6:14] = 255
    return image


def test_dark_dots_where_the_render_is_white_are_the_wraps_signature():
    image = white_disc()
    made = image.copy()
    made[9, 9] = 255 - DARKER - 10  # (a value a little past white, wrapped)
    made[10, 11, 0] = 30
    assert _wrap_signature(image, made, 2.0, None)


def test_a_dimmer_highlight_or_a_dot_away_from_white_is_not():
    image = white_disc()
    dimmer = image.copy()
    dimmer[6:14, 6:14] = 240  # (an honest tracer's highlight a little dimmer: nowhere near a wrap)
    assert not _wrap_signature(image, dimmer, 2.0, None)
    away = image.copy()
    away[9, 9] = 0
    away[2, 2] = 200  # (a pixel off far from any white one)
    assert not _wrap_signature(image, away, 2.0, None)
    assert not _wrap_signature(image, image.copy(), 2.0, None)  # (nothing off)
