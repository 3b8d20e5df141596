"""A mistake behind another (service/diagnosis/behind.py): a camera mistake, or the mistake the diagnosis names
first, made the reference, the other mistake found behind it, both named and matched."""

import pytest
import student
from test_compose import small

from service.diagnosis import Cached, behind
from service.diagnosis.behind import camera_named
from service.diagnosis.combination import on_base
from service.diagnosis.records import Cause, Diagnosis, matched
from service.work import pipeline
from tracer import RenderCancelled, Renderer, encode_png
from tracer.scene.variants import REFERENCE, Options


def graded(scene, mistakes: list[str]) -> pipeline.Graded:  # noqa: ANN001
    reference = encode_png(Renderer(scene).pixels())
    made = encode_png(student.render(scene, mistakes))
    explaining = pipeline.Explaining(lambda: scene, pipeline.Checks(), pipeline.Checking(threads=1, cache=Cached()))
    return pipeline.grade_png(reference, made, 2.0, 0.001, explaining=explaining)


def test_a_highlight_mistake_behind_a_horizontal_fov_is_named_with_it():
    """On 04_whitted the fov across the width moves every highlight: the missing specular term's difference,
    measured on the reference's pixels, does not add to it, and the fov alone only comes closest.  Behind the
    camera's mistake, the other matches: both are named, matched, so both deductions apply."""
    found = graded(small("04_whitted"), ["horizontal-fov", "no-specular"])
    assert not found.grade.passed and found.diagnosis is not None
    said = found.diagnosis.as_dict()
    assert [set(i.split("+")) for i in matched(said)][:1] == [{"horizontal-fov", "no-specular"}]
    assert not said["closest"] and said["sentence"].startswith("Likely two mistakes together")


def test_a_camera_mistake_the_diagnosis_does_not_name_is_tried_where_it_helps_on_the_rows():
    """A spot's cutoff in radians relights most of 07_spotlights: the pixel centres' shift hides behind it, and
    the spot's mistake alone only comes closest.  Made with it on a few rows, the shift leaves far fewer pixels
    off, so the diagnosis is made behind it too: both are named, matched."""
    found = graded(small("07_spotlights"), ["no-half-pixel", "spot-radians"])
    assert found.diagnosis is not None
    assert [set(i.split("+")) for i in matched(found.diagnosis.as_dict())][:1] == [{"no-half-pixel", "spot-radians"}]


@pytest.mark.parametrize(
    "mistakes",
    [
        # no shadow rays light the back of a surface whose normal is not turned to face the ray: no sum of the two
        # differences models it, and no shadow rays only leads the nearest explanations (99 % of the difference)
        ["no-shadows", "normals-not-flipped"],
        # with no mirror rays the highlights a mirror showed are gone with them: no reflection only comes closest
        ["no-specular", "no-reflection"],
    ],
)
def test_a_mistake_behind_the_one_the_diagnosis_names_first_is_named_with_it(mistakes):
    found = graded(small("04_whitted"), mistakes)
    assert found.diagnosis is not None
    assert [set(i.split("+")) for i in matched(found.diagnosis.as_dict())][:1] == [set(mistakes)]


def test_a_camera_mistake_made_alone_is_named_alone():
    found = graded(small("04_whitted"), ["horizontal-fov"])
    assert found.diagnosis is not None
    assert matched(found.diagnosis.as_dict())[:1] == ["horizontal-fov"]


def test_a_camera_mistake_is_found_among_the_causes_and_those_made_with_them():
    alone = Diagnosis(True, [Cause("no-half-pixel", "", 0.1, False)])
    made_with = Diagnosis(False, [Cause("no-shadows", "", 0.1, False, ["horizontal-fov"])])
    assert camera_named(alone) == "no-half-pixel" and camera_named(made_with) == "horizontal-fov"
    assert camera_named(Diagnosis(True, [Cause("no-shadows", "", 0.1, False)])) is None


def test_a_base_changes_what_a_mistake_leaves_as_the_reference():
    """A camera mistake's base is made with every other mistake; an honest offset's base keeps its meaning: its
    offset is taken unless the mistake sets one of its own (an offset too large)."""
    camera = Options(vertical_fov=False)
    assert on_base(Options(shadows=False), camera) == Options(shadows=False, vertical_fov=False)
    assert on_base(REFERENCE, camera) == camera
    assert on_base(camera, camera) == camera
    offset = Options(offset=1e-3, offset_along="ray")
    assert on_base(Options(blinn=True), offset) == Options(blinn=True, offset=1e-3, offset_along="ray")
    assert on_base(Options(offset=2e-2), offset) == Options(offset=2e-2)


def test_time_running_out_behind_a_mistake_keeps_the_diagnosis_made(monkeypatch):
    """The look behind a mistake is a second diagnosis: where the time runs out in it, the first one (the fov
    coming closest) is the answer, not "no diagnosis"."""

    def cancelled(*_args: object) -> None:
        raise RenderCancelled("out of time")

    monkeypatch.setattr(behind, "diagnose", cancelled)
    found = graded(small("04_whitted"), ["horizontal-fov", "no-specular"])
    assert found.diagnosis is not None and found.diagnosis.unavailable is None
    said = found.diagnosis.as_dict()
    assert said["closest"] and said["causes"][0]["variant"] == "horizontal-fov"
