"""The diagnosis's last steps (service/diagnosis/together.py): mistakes made together named, and the nearest
explanations when nothing fits; how a report and the command line show them."""

import numpy as np
import pytest
import student
from test_compose import small

from service.cli.display import explained
from service.diagnosis import diagnose, renders_of
from service.diagnosis.combination import Combination, Member, merged
from service.diagnosis.records import Cause, matched
from service.diagnosis.together import closer, together_causes
from service.images.grading import grade
from tracer import Renderer

BOTH = Combination(
    (
        Member("no-shadows", "no shadow rays", 0.6, "the mistake accounts for 60 % of the difference"),
        Member("gamma", "gamma 1/2.2 applied to the output", 0.4, "the mistake accounts for 40 %"),
    ),
    0.0,
    True,
)


def test_a_combinations_causes_name_each_other():
    causes = together_causes(BOTH)
    assert [c.variant for c in causes] == ["no-shadows", "gamma"]
    assert causes[0].together == ["gamma"] and causes[1].together == ["no-shadows"]
    assert all(c.passes and c.evidence for c in causes)


def test_a_combination_is_named_closest_only_when_closer_than_the_single_mistake():
    verdict = grade(np.zeros((4, 4, 3), np.uint8), np.full((4, 4, 3), 90, np.uint8), "")
    single = [Cause("no-shadows", "no shadow rays", 0.2, False)]
    near = Combination(BOTH.members, 0.1, False)
    assert closer(near, single, True, verdict)[0][0].together
    far = Combination(BOTH.members, 0.3, False)
    assert closer(far, single, True, verdict) == (single, True)
    assert closer(None, [], False, verdict) == ([], False)


def test_mistakes_made_together_are_one_id_for_a_deduction():
    found = {"causes": [c.as_dict() for c in together_causes(BOTH)], "closest": False}
    assert matched(found) == ["no-shadows+gamma"]
    assert matched({"causes": [{"variant": "no-shadows", "passes": True}]}) == ["no-shadows"]


@pytest.fixture(scope="module")
def spheres():
    scene = small("01_three_spheres")
    return scene, Renderer(scene).pixels(), renders_of(scene)


def test_two_mistakes_are_diagnosed_together_in_words(spheres):
    scene, reference, renders = spheres
    submitted = Renderer(scene, merged(("no-shadows", "blinn-phong"))).pixels()
    found = diagnose(reference, submitted, grade(reference, submitted, ""), renders)
    assert {c.variant for c in found.causes} == {"no-shadows", "blinn-phong"} and all(c.passes for c in found.causes)
    assert found.sentence().startswith("Likely two mistakes together:") and found.terms == []
    lines = explained(found.as_dict())
    assert any("the mistake accounts for" in line for line in lines)
    assert not any("objects[" in line or "lights[" in line for line in lines)
    assert any("the first sphere" in line or "the first plane" in line for line in lines)


def test_a_new_mistake_alone_is_named_with_advice(spheres):
    scene, reference, renders = spheres
    submitted = Renderer(scene, merged(("grayscale",))).pixels()
    found = diagnose(reference, submitted, grade(reference, submitted, ""), renders)
    assert found.causes[0].variant == "grayscale" and found.causes[0].passes
    assert found.sentence().endswith("Your image has no colour: save it as RGB, not in grayscale.")


def test_nothing_that_fits_still_has_causes_ranked_by_share(spheres):
    scene, reference, renders = spheres
    noise = np.random.default_rng(5).integers(0, 256, reference.shape, dtype=np.uint8)
    found = diagnose(reference, noise, grade(reference, noise, ""), renders)
    assert found.causes and found.nearest and not any(c.passes for c in found.causes)
    shares = [c.share for c in found.causes]
    assert all(s is not None for s in shares) and shares == sorted(shares, reverse=True)
    # (noise is no mistake's: the first explains far less than most of it, and is not named)
    assert shares[0] < 0.6 and found.sentence().startswith("No known mistake fits: compare the heat-map")


def test_mistakes_made_together_lose_each_ones_deduction():
    from service.classgrade.gradebook import score
    from service.classgrade.taskfile import TaskSettings

    task = TaskSettings(points=10, deductions={"no-shadows": 3, "gamma": 2})
    assert score({"status": "fail", "mistakes": ["no-shadows+gamma"]}, task).score == 5
    assert score({"status": "fail", "mistakes": ["no-shadows+gamma"]}, task).deducted == "no-shadows+gamma"
    # one of the two without a deduction: the image scores nothing, as a fault the task does not forgive
    assert score({"status": "fail", "mistakes": ["no-shadows+blinn-phong"]}, task).score == 0


@pytest.fixture(scope="module")
def all_lights():
    scene = small("02_all_lights", 64, 48)
    return scene, Renderer(scene).pixels()


@pytest.mark.parametrize(
    ("mistakes", "named"),
    [
        # no ambient darkens: alone it helps nothing against gamma's (or a wider highlight's) brighter image
        (["gamma", "no-ambient"], "gamma+no-ambient"),
        (["blinn-phong", "no-ambient"], "no-ambient+blinn-phong"),
        # an area light not divided saturates: the other's difference does not add on the rows, a render tells
        (["no-ambient", "area-not-divided"], "area-not-divided+no-ambient"),
    ],
)
def test_a_pair_of_a_student_tracer_is_named_both(all_lights, mistakes, named):
    scene, reference = all_lights
    made = student.render(scene, mistakes)
    verdict = grade(reference, made, "")
    assert not verdict.passed
    assert matched(diagnose(reference, made, verdict, renders_of(scene, 1)).as_dict()) == [named]


@pytest.mark.parametrize("other", ["no-shadows", "gamma", "transparent-no-shadows"])
def test_a_second_mistake_on_few_pixels_is_chosen_on_the_rows_the_closest_leaves_off(other):
    """On 04_whitted no specular term shows on a few highlight pixels; made with a mistake that changes most rows
    (shadows, gamma), it lies on none of the rows the submission departs most from the reference on, and the
    other mistake alone only comes closest.  On the rows the submission departs most from that mistake's render,
    the highlights are seen: both are named."""
    scene = small("04_whitted")
    reference = Renderer(scene).pixels()
    made = student.render(scene, [other, "no-specular"])
    found = diagnose(reference, made, grade(reference, made, ""), renders_of(scene, 1))
    assert [set(i.split("+")) for i in matched(found.as_dict())][:1] == [{other, "no-specular"}]
    assert not found.closest
