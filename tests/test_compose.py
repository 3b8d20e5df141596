"""Mistakes made together (service/compose.py): chosen on rows, confirmed by one render, ranked when none fits."""

from pathlib import Path

import numpy as np
import pytest
import student

import schemas
from service.diagnosis.combination import ALL, compatible, merged
from service.diagnosis.compose import Rows, chosen, compose, telling_rows
from service.diagnosis.records import Term
from service.diagnosis.tried import Looks, pointed
from service.images.grading import grade
from tracer import Renderer
from tracer.scene.shown import unchanged
from tracer.scene.variants import REFERENCE, Options

from helpers import scene_dict


def small(name: str, width: int = 64, height: int = 48) -> schemas.Scene:
    data = scene_dict(name)
    data["image"].update(width=width, height=height)
    return schemas.validate_scene(data)


class Counted:
    """:class:`Looks` of a scene from the tracer, counting the whole renders asked for."""

    def __init__(self, scene):  # noqa: ANN001
        self.scene, self.whole, self.made = scene, [], {}

    def rows(self, name: str, numbers: np.ndarray) -> np.ndarray:
        if name not in self.made:
            self.made[name] = Renderer(self.scene, ALL[name][0]).pixels()
        return self.made[name][numbers]

    def render(self, options: Options) -> np.ndarray:
        self.whole.append(options)
        return Renderer(self.scene, options).pixels()

    def looks(self) -> Looks:
        return Looks(
            self.rows,
            self.render,
            lambda name: not unchanged(name, self.scene),
            tuple(light.type for light in self.scene.lights),
        )


def test_options_merge_the_changed_fields_of_each_mistake():
    both = merged(("no-shadows", "blinn-phong", "grayscale"))
    assert both == Options(shadows=False, blinn=True, grayscale=True)
    assert merged(()) == REFERENCE
    assert not compatible(("depth-plus-one", "depth-minus-one"))
    with pytest.raises(ValueError, match="depth_offset"):
        merged(("depth-plus-one", "depth-minus-one"))


def test_the_fit_points_to_the_new_mistakes_it_can_see():
    lights = ("ambient", "spot", "point")
    found = pointed([Term("diffuse", 1, 2.0), Term("refraction", None, 0.5)], lights)
    assert "spot-exponent-ignored" in found and "exit-normal-not-flipped" in found
    assert "clamped-per-term" not in found  # (nothing too weak)
    assert "clamped-per-term" in pointed([Term("specular", 2, 0.5)], lights)


def test_telling_rows_span_the_image_and_find_a_departure():
    reference = np.zeros((64, 8, 3), dtype=np.uint8)
    submitted = reference.copy()
    submitted[37, 3] = 200
    rows = telling_rows(reference, submitted, 2)
    assert len(rows) == 8 and 37 in rows and np.all(np.diff(rows) > 0)


def test_the_differences_of_two_mistakes_add_up_on_rows():
    scene = small("02_all_lights")
    counted = Counted(scene)
    reference = Renderer(scene).pixels()
    submitted = Renderer(scene, merged(("no-shadows", "blinn-phong"))).pixels()
    numbers = telling_rows(reference, submitted, 2)
    deltas = {
        n: counted.rows(n, numbers).astype(float) - reference[numbers]
        for n in ("no-shadows", "blinn-phong", "no-ambient", "no-attenuation")
    }
    rows = Rows(reference[numbers], submitted[numbers], (), deltas)
    assert set(chosen(rows)) == {"no-shadows", "blinn-phong"}
    assert rows.error(("no-shadows", "blinn-phong")) < rows.error(("no-shadows",)) < rows.error(())


@pytest.mark.parametrize(
    "name, made",
    [
        ("01_three_spheres", ("no-shadows", "blinn-phong")),
        ("02_all_lights", ("no-attenuation", "gamma")),
        ("04_whitted", ("no-ambient", "no-specular")),
        ("05_mesh", ("no-shadows", "gamma")),
    ],
)
def test_two_mistakes_of_the_first_student_are_named_with_one_render(name, made):
    scene = small(name)
    counted = Counted(scene)
    reference = Renderer(scene).pixels()
    submitted = student.render(scene, made)
    verdict = grade(reference, submitted, "")
    assert not verdict.passed
    found = compose(reference, submitted, verdict, counted.looks(), [])
    assert found is not None and found.passes and set(found.names) == set(made)
    assert len(counted.whole) == 1
    assert all(0 < m.share <= 1 and m.evidence for m in found.members)


@pytest.mark.parametrize("made", [("grayscale",), ("camera-left-handed",), ("channels-swapped",)])
def test_an_image_level_mistake_alone_needs_no_render(made):
    scene = small("01_three_spheres")
    counted = Counted(scene)
    reference = Renderer(scene).pixels()
    submitted = Renderer(scene, merged(made)).pixels()
    verdict = grade(reference, submitted, "")
    found = compose(reference, submitted, verdict, counted.looks(), [])
    assert found is not None and found.passes and found.names == made
    assert counted.whole == []


def test_a_classic_mistake_alone_is_left_to_the_single_mistake_diagnosis():
    scene = small("01_three_spheres")
    reference = Renderer(scene).pixels()
    submitted = Renderer(scene, merged(("no-shadows",))).pixels()
    assert compose(reference, submitted, grade(reference, submitted, ""), Counted(scene).looks(), []) is None


def test_a_mistake_the_rows_cannot_tell_from_another_is_never_made_with_it():
    """On a glass ball's rows (rendered with shadows) no refraction and the normal leaving glass not flipped
    change alike; with no shadow rays they part (light reaches the ball's inside).  The pair is no shadows and
    no refraction, the third never joined to it; each reading costs one render, and the one that fails is none."""
    scene = schemas.load_scene((Path(__file__).parent / "programs" / "glass.json").read_bytes())
    counted = Counted(scene)
    reference = Renderer(scene).pixels()
    submitted = student.render(scene, ["no-shadows", "no-refraction"])
    found = compose(reference, submitted, grade(reference, submitted, ""), counted.looks(), [])
    assert found is not None and found.passes
    assert sorted(found.names) == ["no-refraction", "no-shadows"] and found.readings == ()
    assert len(counted.whole) == 2


def cornell() -> schemas.Scene:
    scene = schemas.load_scene((Path(__file__).parent.parent / "examples" / "09_cornell_homework.json").read_bytes())
    return scene.model_copy(update={"image": scene.image.model_copy(update={"width": 64, "height": 48})})


def test_a_mistake_the_rows_are_as_near_with_is_a_reading_rendered_too():
    """On the Cornell homework's rows the reflected vector with the wrong sign and no specular term leave the
    submission (the first with no reflection) as near; the rows miss the few pixels where a light behind a
    surface lights a highlight.  Both pairs are rendered: the one the submission passes against is named."""
    scene = cornell()
    counted = Counted(scene)
    reference = Renderer(scene).pixels()
    submitted = student.render(scene, ["reflect-sign", "no-reflection"])
    found = compose(reference, submitted, grade(reference, submitted, ""), counted.looks(), [])
    assert found is not None and found.passes
    assert sorted(found.names) == ["no-reflection", "reflect-sign"]
    assert len(counted.whole) == 2


def test_a_third_mistake_whose_difference_did_not_add_is_dropped_when_two_pass():
    """With the ambient scaled by k_d, the rows add Blinn–Phong to the reflected vector's wrong sign (their
    differences do not add: the half vector uses no R); the three fail, the first two pass and are named."""
    scene = cornell()
    counted = Counted(scene)
    reference = Renderer(scene).pixels()
    submitted = student.render(scene, ["reflect-sign", "ambient-from-diffuse"])
    found = compose(reference, submitted, grade(reference, submitted, ""), counted.looks(), [])
    assert found is not None and found.passes
    assert sorted(found.names) == ["ambient-from-diffuse", "reflect-sign"]


def test_the_runner_up_on_the_rows_is_rendered_when_nothing_passes():
    """With the pixel centres moved, the rows are a little nearer no specular term than the reflected vector
    with the wrong sign (the differences of a moved image do not add exactly); no specular term fails its
    render, and the runner-up, one mistake swapped, passes and is named."""
    data = scene_dict("02_all_lights")
    data["image"].update(width=64, height=48)
    scene = schemas.validate_scene(data)
    counted = Counted(scene)
    reference = Renderer(scene).pixels()
    submitted = student.render(scene, ["no-half-pixel", "reflect-sign"])
    found = compose(reference, submitted, grade(reference, submitted, ""), counted.looks(), [])
    assert found is not None and found.passes
    assert sorted(found.names) == ["no-half-pixel", "reflect-sign"]
