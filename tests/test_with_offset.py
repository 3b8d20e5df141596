"""An offset too large made with another mistake (service/diagnosis/with_offset.py): the other mistake found with
the offset at its own amount, both named, the offset with its size."""

import pytest
import student
from test_compose import cornell, small

from service.diagnosis import diagnose, renders_of
from service.diagnosis.records import matched
from service.diagnosis.with_offset import with_offset
from service.images.grading import grade
from tracer import Renderer


@pytest.fixture(scope="module")
def homework():
    scene = cornell()
    return scene, Renderer(scene).pixels(), renders_of(scene, 1)


@pytest.mark.parametrize(
    "mistakes",
    [
        # the pair comes out first on the rows, but one render at the variant's own amount (2e-2 of the visible
        # size, 0.098) leaves 4 pixels too many off against a student's 0.1
        ["horizontal-fov", "offset-too-large"],
        # no shadow rays leave no shadow to detach: the differences do not add, and the rows choose no shadows alone
        ["no-shadows", "offset-too-large"],
        # a transparent object's shadow left out, and detached: the rows choose the offset alone
        ["offset-too-large", "transparent-no-shadows"],
    ],
)
def test_an_offset_too_large_and_another_mistake_are_named_with_its_size(homework, mistakes):
    scene, reference, renders = homework
    made = student.render(scene, mistakes)
    verdict = grade(reference, made, "")
    assert not verdict.passed
    found = diagnose(reference, made, verdict, renders)
    assert [set(i.split("+")) for i in matched(found.as_dict())][:1] == [set(mistakes)]
    offset = next(c for c in found.causes if c.variant == "offset-too-large")
    assert "about 0.1 in the scene's units" in offset.mistake


@pytest.mark.parametrize("mistake", ["no-shadows", "no-half-pixel"])
def test_no_offset_is_named_with_a_mistake_made_alone(homework, mistake):
    """The offset's ladder starts at the largest offset accepted: made with it, a mistake made alone is not."""
    scene, reference, renders = homework
    made = student.render(scene, [mistake])
    verdict = grade(reference, made, "")
    assert with_offset(reference, made, verdict, renders, ["no-shadows", "horizontal-fov", "no-half-pixel"]) is None


@pytest.mark.parametrize(
    "mistakes",
    [
        # the image flipped is a change of the stored image: made with the offset, it is rendered as any other
        ["image-flipped", "offset-too-large"],
        # an area light not divided saturates the image: the offset's rungs tie on the rows, and the rung the rows
        # the submission is most off on tell leaves no pixel off at all
        ["area-not-divided", "offset-too-large"],
    ],
)
def test_an_offset_too_large_is_named_with_a_mistake_the_sum_cannot_model(mistakes):
    scene = small("02_all_lights")
    reference = Renderer(scene).pixels()
    made = student.render(scene, mistakes)
    verdict = grade(reference, made, "")
    found = diagnose(reference, made, verdict, renders_of(scene, 1))
    assert [set(i.split("+")) for i in matched(found.as_dict())][:1] == [set(mistakes)]


def test_a_mistake_away_from_the_detached_shadows_is_named_with_the_offset():
    """On 04_whitted the offset too large alone (0.1) explains the rows the submission departs most from the
    reference on (its detached shadows); no specular term shows only in the highlights, on other rows.  The
    partner is chosen on the rows the submission departs most from the offset's render: both are named."""
    scene = small("04_whitted")
    reference = Renderer(scene).pixels()
    made = student.render(scene, ["no-specular", "offset-too-large"])
    verdict = grade(reference, made, "")
    found = diagnose(reference, made, verdict, renders_of(scene, 1))
    assert [set(i.split("+")) for i in matched(found.as_dict())][:1] == [{"no-specular", "offset-too-large"}]
