"""What an image cannot tell apart (service/diagnosis/records.py, words.py, classgrade/gradebook.py): where two
mistakes give the same image, the diagnosis says both readings, and a deduction applies to what the image shows."""

from pathlib import Path

import numpy as np
import pytest
import student
import student_oop
from test_variants import _glass_over_floor

import schemas
from service.classgrade.gradebook import partial, score
from service.classgrade.taskfile import TaskSettings
from service.diagnosis import Cause, Diagnosis, diagnose, renders_of
from service.diagnosis.records import matched
from service.images.grading import grade
from tracer import Renderer
from tracer.scene.variants import VARIANTS

from helpers import scene_dict


@pytest.fixture(scope="module")
def spotlights():
    """The spotlights example, small: a reflected vector of the wrong sign gives exactly its no-specular image."""
    data = scene_dict("07_spotlights")
    data["image"].update(width=64, height=48)
    scene = schemas.validate_scene(data)
    return scene, Renderer(scene).pixels(), renders_of(scene)


def test_the_two_mistakes_render_the_same_image_there(spotlights):
    scene, reference, _ = spotlights
    flipped = Renderer(scene, VARIANTS["reflect-sign"][0]).pixels()
    assert np.array_equal(flipped, Renderer(scene, VARIANTS["no-specular"][0]).pixels())
    assert not grade(reference, flipped, "").passed


@pytest.mark.parametrize("mistake", ["reflect-sign", "no-specular"])
def test_a_student_with_either_mistake_is_told_both_readings(spotlights, mistake):
    scene, reference, renders = spotlights
    made = student.render(scene, [mistake])
    verdict = grade(reference, made, "")
    assert not verdict.passed
    found = diagnose(reference, made, verdict, renders)
    assert {c.variant for c in found.readings} == {"reflect-sign", "no-specular"}
    sentence = found.sentence()
    assert sentence.startswith(
        "Likely: no specular term, or the reflected vector R with the wrong sign (L − 2(N·L)N) — the image cannot "
        "tell them apart (it shows no specular highlight): the submission matches the reference rendered with either"
    ), sentence
    assert found.headline() == "no specular term or the reflected vector R with the wrong sign (L − 2(N·L)N)"


def test_glass_that_casts_no_shadow_where_only_glass_could_is_no_shadows_either():
    scene = _glass_over_floor(False)
    reference = Renderer(scene).pixels()
    made = student.render(scene, ["transparent-no-shadows"])
    verdict = grade(reference, made, "")
    assert not verdict.passed
    found = diagnose(reference, made, verdict, renders_of(scene))
    assert {c.variant for c in found.readings} == {"no-shadows", "transparent-no-shadows"}
    assert "the image cannot tell them apart (it shows no shadows)" in found.sentence()
    # with an opaque ball beside the glass, its shadow tells them apart: one mistake, named alone
    scene = _glass_over_floor(True)
    reference = Renderer(scene).pixels()
    made = student.render(scene, ["transparent-no-shadows"])
    found = diagnose(reference, made, grade(reference, made, ""), renders_of(scene))
    assert found.readings == [] and found.causes[0].variant == "transparent-no-shadows"
    assert found.sentence().startswith("Likely: transparent objects cast no shadows")


def test_the_honest_students_image_still_passes(spotlights):
    scene, reference, renders = spotlights
    right = student.render(scene)
    verdict = grade(reference, right, "")
    assert verdict.passed and diagnose(reference, right, verdict, renders).causes == []


def _readings(*names: str, fraction: float = 0.0) -> Diagnosis:
    return Diagnosis(causes=[Cause(n, VARIANTS[n][1], fraction, True) for n in names])


def test_readings_are_the_single_mistakes_passed_against_when_there_are_several():
    one = _readings("no-shadows")
    assert one.readings == [] and one.sentence().startswith("Likely: no shadow rays — the submission matches")
    three = _readings("no-attenuation", "area-not-divided", "gamma", fraction=0.0004)
    assert three.sentence() == (
        "Likely: no attenuation of point, spot and area lights, an area light not divided by nu·nv, or gamma 1/2.2 "
        "applied to the output — the image cannot tell them apart: the submission matches the reference rendered "
        "with any of them (0.04 % of pixels off)"
    )
    together = Diagnosis(
        causes=[Cause("no-shadows", "no shadow rays", 0.0, True, ["gamma"]), Cause("gamma", "g", 0.0, True)]
    )
    assert together.readings == []  # mistakes made together are one reading, not two
    closest = Diagnosis(
        causes=[Cause("no-shadows", "no shadow rays", 0.01, False), Cause("gamma", "g", 0.02, False)], closest=True
    )
    assert closest.readings == []


# -- a deduction applies to what the image shows ------------------------------------------------------------------


@pytest.fixture(scope="module")
def alike_row(spotlights):
    """The class report's row of a student whose image shows no specular highlight (a reflected vector of the
    wrong sign): its mistakes are both readings."""
    scene, reference, renders = spotlights
    made = student.render(scene, ["reflect-sign"])
    verdict = grade(reference, made, "")
    mistakes = matched(diagnose(reference, made, verdict, renders).as_dict())
    assert sorted(mistakes) == ["no-specular", "reflect-sign"]
    return {"status": "fail", "mistakes": mistakes, "points": 2.0}


@pytest.mark.parametrize(
    ("deductions", "expected"),
    [
        ({"no-specular": 1}, (1.0, "no-specular")),  # only what the image shows has one: it is taken
        ({"reflect-sign": 0.5}, (1.5, "reflect-sign")),
        ({"no-specular": 1, "reflect-sign": 0.5}, (1.5, "reflect-sign")),  # two that differ: the smaller
        ({"no-shadows": 1}, (0.0, None)),  # none for either reading: an unnamed fault, nothing
    ],
)
def test_the_deduction_is_the_smallest_of_the_readings(alike_row, deductions, expected):
    got = score(alike_row, TaskSettings(points=2, deductions=deductions))
    assert (got.score, got.deducted) == expected


def test_the_partial_credit_names_every_reading(alike_row):
    got = score(alike_row, TaskSettings(points=2, deductions={"no-specular": 1}))
    row = alike_row | {"score": got.score, "deducted": got.deducted}
    assert partial(row) == (
        "Partial credit: 1 of 2 points (no specular term, or the reflected vector R with the wrong sign "
        "(L − 2(N·L)N): -1)"
    )
    alone = {"status": "fail", "mistakes": ["no-shadows"], "points": 2.0, "score": 1.0, "deducted": "no-shadows"}
    assert partial(alone) == "Partial credit: 1 of 2 points (no shadow rays: -1)"


# -- mistakes made together, read two ways ------------------------------------------------------------------------

GLASS = Path(__file__).parent / "programs" / "glass.json"
#: the task of the glass scene: 10 points, a deduction for two of its mistakes
TWO_DEDUCTED = {"no-shadows": 4, "no-refraction": 2}


@pytest.fixture(scope="module")
def glass():
    scene = schemas.load_scene(GLASS.read_bytes())
    return scene, Renderer(scene).pixels()


def _together_row(glass, mistakes: list[str]) -> dict:
    """The class report's row of a glass student with ``mistakes``, and its diagnosis."""
    scene, reference = glass
    made = student.render(scene, mistakes)
    verdict = grade(reference, made, "")
    assert not verdict.passed
    found = diagnose(reference, made, verdict, renders_of(scene))
    return {"status": "fail", "mistakes": matched(found.as_dict()), "points": 10.0, "found": found}


def _scored(row: dict, deductions: dict[str, float]) -> tuple[float, str | None]:
    got = score(row, TaskSettings(points=10, deductions=deductions))
    return got.score, got.deducted


def test_no_shadows_and_no_refraction_are_the_pair_and_keep_their_credit(glass):
    """No shadow rays and no refraction: the pair, not a third mistake the rows cannot tell from no refraction
    (the normal leaving glass not flipped: made with no refraction it has nothing to do) joined to it."""
    row = _together_row(glass, ["no-shadows", "no-refraction"])
    assert row["mistakes"] == ["no-refraction+no-shadows"]
    assert row["found"].sentence().startswith("Likely two mistakes together: no refraction")
    assert _scored(row, TWO_DEDUCTED) == (4.0, "no-refraction+no-shadows")
    # the other reading is not this image's: made with no shadow rays, light that cannot leave the glass ball
    # lights its inside (5 % of the pixels off that render), so a deduction for it is no deduction for this image
    assert _scored(row, {"no-shadows": 4, "exit-normal-not-flipped": 2}) == (0.0, None)


@pytest.mark.parametrize("mistakes", [["gamma", "no-refraction"], ["no-ambient", "no-refraction"]])
def test_a_pair_the_image_cannot_tell_from_another_is_read_both_ways(glass, mistakes):
    """A pair with no refraction, where the normal leaving glass not flipped gives the same image: both pairs
    are named, and a deduction applies to either reading, the smaller taken (as for one mistake of two alike)."""
    row = _together_row(glass, mistakes)
    other, twin = mistakes[0], "exit-normal-not-flipped"
    assert sorted(row["mistakes"]) == sorted([f"{other}+no-refraction", f"{other}+{twin}"])
    assert "; or " in row["found"].sentence() and "the image cannot tell them apart" in row["found"].sentence()
    assert row["found"].headline().count(" or ") == 1 and row["found"].headline().count(" + ") == 2
    assert _scored(row, {other: 3, twin: 2})[0] == 5.0  # the other reading
    assert _scored(row, {other: 3, "no-refraction": 1})[0] == 6.0
    assert _scored(row, {other: 3, "no-refraction": 4, twin: 2})[0] == 5.0  # both: the smaller
    assert _scored(row, {"no-refraction": 1, twin: 2}) == (0.0, None)  # the first mistake has none: nothing
    got = score(row, TaskSettings(points=10, deductions={other: 3, twin: 2}))
    credit = partial(row | {"score": got.score, "deducted": got.deducted})
    assert credit.startswith("Partial credit: 5 of 10 points (") and credit.endswith(": -5)")
    assert "refracted rays never traced" in credit and "with the outward normal" in credit, credit


def test_no_shadows_with_glass_left_by_the_outward_normal_is_that_pair(glass):
    """The other student (tests/student_oop.py: one ray at a time, its own code): no shadow rays, and glass left
    by the outward normal.  Its image is not the no-refraction one (the ball's inside is lit): that pair is
    named alone, and a deduction for it is taken."""
    scene, reference = glass
    made = student_oop.render(scene, ["no-shadows", "exit-normal-not-flipped"])
    verdict = grade(reference, made, "")
    found = diagnose(reference, made, verdict, renders_of(scene))
    row = {"status": "fail", "mistakes": matched(found.as_dict()), "points": 10.0}
    assert [sorted(m.split("+")) for m in row["mistakes"]] == [["exit-normal-not-flipped", "no-shadows"]]
    assert _scored(row, {"no-shadows": 4, "exit-normal-not-flipped": 2})[0] == 4.0
    assert _scored(row, TWO_DEDUCTED) == (0.0, None)
