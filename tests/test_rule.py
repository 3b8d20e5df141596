"""The grade's rule, cell by cell: a vanished highlight and wrapped colours fail, pixels left open do not count, the
offsets accepted are measured against what the camera sees, and a mistake behind an honest offset keeps its name.

The students are tests/student.py (float64) and tests/student_f32.py (float32, its own intersections); the whole
calibration is tests/offset_matrix.py, whose key cells these are.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import student
import student_f32

from schemas import load_scene
from service.classgrade.gradebook import score
from service.classgrade.taskfile import TaskSettings
from service.images.grading import GROSS_LEVELS, grade
from service.images.nearby import gap, planes
from service.work import pipeline
from tracer import Renderer, encode_png
from tracer.scene.variants import scene_size

ROOT = Path(__file__).resolve().parent.parent
HARD = Path(__file__).resolve().parent / "hard_scenes"


def _scene(path: Path):  # noqa: ANN202
    return load_scene(path.read_bytes())


#: each scene's reference PNG, rendered once for every image graded against it: by the scene's JSON
_REFERENCES: dict[str, bytes] = {}


def _graded(scene, image: np.ndarray, diagnose: bool = True) -> pipeline.Graded:  # noqa: ANN001
    key = scene.model_dump_json()
    if key not in _REFERENCES:
        _REFERENCES[key] = encode_png(Renderer(scene).pixels())
    reference = _REFERENCES[key]
    checks = pipeline.Checks(diagnose=diagnose)
    return pipeline.grade_png(
        reference, encode_png(image), 2.0, 0.001, explaining=pipeline.Explaining(lambda: scene, checks)
    )


def _one_way(reference: np.ndarray, submitted: np.ndarray, tolerance: float) -> int:
    """The pixels a one-way measure counts: submitted pixels no reference pixel around matches."""
    h, w, _ = reference.shape
    padded = planes(np.pad(reference, ((1, 1), (1, 1), (0, 0)), mode="edge"))
    best = np.full((h, w), 255, dtype=np.uint8)
    for dy in range(3):
        for dx in range(3):
            window = padded[:, dy : dy + h, dx : dx + w]
            best = np.minimum(best, gap(window, window, planes(submitted)))
    return int(np.count_nonzero(best > tolerance))


def test_a_thin_highlight_that_vanished_fails():
    """The reflected vector's sign flipped on the orthographic example takes its 2–3-pixel highlights away (the
    image is the no-specular one): every changed pixel finds a dark reference pixel near it, so only the
    reference's highlight, which nothing near it in the submission matches, makes it fail."""
    scene = _scene(ROOT / "examples" / "06_orthographic.json")
    reference = Renderer(scene).pixels()
    vanished = student.render(scene, ["no-specular"])
    verdict = grade(reference, vanished, "")
    assert not verdict.passed and verdict.fraction_off_nearby > 2 * verdict.max_fraction
    assert _one_way(reference, vanished, 2.0) <= verdict.max_fraction * reference[..., 0].size


def test_a_one_pixel_shift_and_its_anti_aliased_edge_still_pass():
    scene = _scene(ROOT / "examples" / "08_antialiased.json")
    reference = Renderer(scene).pixels()
    shifted = np.concatenate([reference[:, :1], reference[:, :-1]], axis=1)
    verdict = grade(reference, shifted, "")
    assert verdict.passed and verdict.fraction_off > 0.01 and verdict.grossly_off == 0


@pytest.mark.parametrize("name", ["01_three_spheres", "02_all_lights", "04_whitted", "05_mesh", "07_spotlights"])
def test_colours_that_wrap_around_instead_of_clamping_fail(name):
    """A student who stores 255·v in a byte without clamping turns a highlight brighter than 1 into a dark dot:
    a few pixels, far within the fraction allowed off, but grossly off (more than half the range from everything
    around them)."""
    renderer = Renderer(_scene(ROOT / "examples" / f"{name}.json"))
    reference = renderer.pixels()
    linear = renderer.diagnosis_passes()["colour"]
    wrapped = (np.floor(255 * np.clip(linear, 0, None) + 0.5).astype(np.int64) % 256).astype(np.uint8)
    verdict = grade(reference, wrapped, "")
    assert verdict.fraction_off_nearby <= verdict.max_fraction  # (the fraction alone would pass it)
    assert not verdict.passed and verdict.grossly_off >= 1
    assert "grossly off" in verdict.reason and f"more than {GROSS_LEVELS} levels" in verdict.reason


def test_a_pixel_left_open_is_not_counted():
    reference = np.full((20, 30, 3), 100, dtype=np.uint8)
    speckled = reference.copy()
    speckled[5, 5] = speckled[12, 20] = (240, 10, 10)
    assert not grade(reference, speckled, "").passed
    left_open = np.zeros((20, 30), dtype=bool)
    left_open[5, 5] = left_open[12, 20] = True
    verdict = grade(reference, speckled, "", open_pixels=left_open)
    assert verdict.passed and verdict.fraction_off_nearby == 0 and verdict.open_pixels == 2


@pytest.mark.parametrize("name", ["ground_sphere", "far_tiny_sphere"])
def test_the_offsets_accepted_are_measured_against_what_the_camera_sees(name):
    """A radius-1000 ground sphere, or a tiny sphere 2000 units away out of view, makes the scene's box 2000
    units wide; an offset of 10⁻³ of that starts shadow rays above the spheres, and a student with no shadow rays
    would pass as it.  The visible size is a few units: no shadows fail, an honest offset passes."""
    scene = _scene(HARD / f"{name}.json")
    size = Renderer(scene).visible_size()
    assert scene_size(scene) > 2000 and 3 < size < 5
    wrong = _graded(scene, student.render(scene, ["no-shadows"]))
    assert not wrong.grade.passed and wrong.accepted is None
    assert wrong.diagnosis is not None and wrong.diagnosis.causes[0].variant == "no-shadows"
    assert _graded(scene, student.render(scene, style=student.Offset(3e-3 * size)), diagnose=False).grade.passed


def test_the_cornell_homework_passes_a_float32_tracers_textbook_offsets():
    """The textbook's 3e-3 and 1e-2 along the normal (the normal turned to face the ray, in single precision), and
    a t_min of 1e-2, in the Cornell-box homework: each passes, as the amount the student wrote."""
    scene = _scene(ROOT / "examples" / "09_cornell_homework.json")
    for eps, along in ((3e-3, "normal"), (1e-2, "normal"), (1e-2, "ray")):
        graded = _graded(scene, student_f32.render(scene, student_f32.Style(eps, along)), diagnose=False)
        assert graded.grade.passed, (eps, along, graded.grade.reason)


def test_a_mistake_behind_an_honest_offset_keeps_its_name_and_its_deduction():
    """A student who offsets by 3e-3 of the visible size (0.018 in the Whitted example, accepted) and applies
    gamma fails every accepted variant and the gamma variant; the offset, fitted with the mistake made, leaves
    only gamma: named as matched, and its deduction taken, as a class grades an upload or a program's image."""
    from service.classgrade.rows import kept_row
    from service.classgrade.tasks import grade_task

    path = ROOT / "examples" / "04_whitted.json"
    scene = _scene(path)
    size = Renderer(scene).visible_size()
    image = student.render(scene, ["gamma"], style=student.Offset(3e-3 * size))
    graded = _graded(scene, image)
    found = graded.diagnosis
    assert not graded.grade.passed and found is not None
    assert found.causes[0].variant == "gamma" and found.causes[0].passes and not found.closest
    assert found.offset is not None and found.offset.endswith("along the normal")
    assert "matches the reference rendered with that mistake and a ray offset of" in found.sentence()
    marked = grade_task(encode_png(Renderer(scene).pixels()), encode_png(image), 2.0, 0.001, path.read_bytes())
    row = kept_row(marked, path)
    assert row["status"] == "fail" and row["mistakes"] == ["gamma"]
    assert score(row, TaskSettings(points=2, deductions={"gamma": 1})).score == 1


@pytest.mark.parametrize(
    ("example", "mistake"), [("04_whitted", "no-reflection"), ("02_all_lights", "area-not-divided")]
)
def test_a_mistake_behind_an_offset_that_shows_on_few_rows_keeps_its_name(example, mistake):
    """Behind an honest offset of 3e-3 of the visible size, a Whitted scene with no reflection, or an area light not
    divided by nu·nv, differs from the mistake's own render only on a glass ball or a few shadow edges, which the
    evenly sampled rows miss: the offset is fitted on the rows the submission departs most from that render on, and
    the mistake is named as matched."""
    scene = _scene(ROOT / "examples" / f"{example}.json")
    image = student.render(scene, [mistake], style=student.Offset(3e-3 * Renderer(scene).visible_size()))
    found = _graded(scene, image).diagnosis
    assert found is not None and not found.closest, found
    assert [c.variant for c in found.causes] == [mistake] and found.causes[0].passes
    assert found.offset is not None and found.offset.endswith("along the normal")


@pytest.mark.parametrize("example", ["05_mesh", "02_all_lights"])
def test_a_mistake_behind_an_accepted_offset_is_never_told_its_offset_is_too_large(example):
    """A camera's up vector used as given, behind an honest offset of 3e-3 of the visible size (the largest accepted
    is 5e-3): the offset ladder's first rung is the largest accepted amount, and the pair "that mistake and an
    offset too large" matched there, worded "about 0.027 (at most 0.027 is accepted)".  An amount no larger than
    the accepted is an honest student's: the mistake is named behind it, as matched, with no offset too large."""
    scene = _scene(ROOT / "examples" / f"{example}.json")
    image = student.render(scene, ["camera-up-as-given"], style=student.Offset(3e-3 * Renderer(scene).visible_size()))
    found = _graded(scene, image).diagnosis
    assert found is not None and not found.closest, found
    assert [c.variant for c in found.causes] == ["camera-up-as-given"] and found.causes[0].passes, found.sentence()
    assert found.offset is not None and found.offset.endswith("along the normal")
    assert "too far" not in found.sentence()
