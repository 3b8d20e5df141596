"""Accepted variants: honest tracers' ray offsets pass, the classic mistakes still fail.

The students are tests/student.py's tracer, written from the scene format, in
the three common offset styles and with each classic mistake; the key cells of
the calibration (tests/offset_matrix.py) are checked here and in tests/test_rule.py.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import student

from schemas import load_scene
from service.classgrade.taskfile import load_tasks
from service.course.errors import ClassError
from service.diagnosis import accepting
from service.images.grading import grade
from service.work import pipeline
from tracer import Renderer, encode_png
from tracer.scene.variants import REFERENCE, Options, scene_size

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
WHITTED = EXAMPLES / "04_whitted.json"
CORNELL = EXAMPLES / "course" / "scenes" / "cornell.json"


def _scene(path: Path):  # noqa: ANN202
    return load_scene(path.read_bytes())


#: the images the tests share (a reference, a variant, a student's), each made once, read-only so that no test
#: changes another's: by the scene's JSON and how it was made
_MADE: dict[tuple[object, ...], np.ndarray] = {}


def _made(key: tuple[object, ...], make: Callable[[], np.ndarray]) -> np.ndarray:
    if key not in _MADE:
        image = make()
        image.setflags(write=False)
        _MADE[key] = image
    return _MADE[key]


def _rendered(scene, options: Options = REFERENCE) -> np.ndarray:  # noqa: ANN001
    """phongray's image of the scene, the reference or a variant."""
    return _made((scene.model_dump_json(), options), lambda: Renderer(scene, options).pixels())


def _student(scene, mistakes: tuple[str, ...] | list[str] = (), style: student.Offset | None = None) -> np.ndarray:  # noqa: ANN001
    """tests/student.py's image of the scene (:func:`student.render`)."""
    key = (scene.model_dump_json(), "student", tuple(mistakes), style)
    return _made(key, lambda: student.render(scene, mistakes, style))


def _graded(scene, image: np.ndarray, checks: pipeline.Checks | None = None) -> pipeline.Graded:  # noqa: ANN001
    reference = encode_png(_rendered(scene))
    return pipeline.grade_png(
        reference,
        encode_png(image),
        2.0,
        0.001,
        explaining=pipeline.Explaining(lambda: scene, checks or pipeline.Checks()),
    )


@pytest.fixture(scope="module")
def whitted():  # noqa: ANN201
    return _scene(WHITTED)


@pytest.fixture(scope="module")
def whitted_reference(whitted) -> np.ndarray:  # noqa: ANN001
    return _rendered(whitted)


def test_an_honest_normal_offset_fails_the_reference_and_passes_as_its_variant(whitted, whitted_reference):
    honest = _student(whitted, style=student.STYLES["offset 1e-3"])
    assert not grade(whitted_reference, honest, "").passed  # the reference alone fails it (0.37 % off)
    graded = _graded(whitted, honest)
    assert graded.grade.passed and graded.accepted == "a ray offset of 0.001 along the normal"  # as written
    assert graded.as_dict()["accepted"] == "a ray offset of 0.001 along the normal" and graded.diagnosis is None


@pytest.mark.parametrize("style", sorted(student.STYLES))
def test_each_honest_style_passes_the_whitted_example(whitted, style):
    assert _graded(whitted, _student(whitted, style=student.STYLES[style])).grade.passed


@pytest.mark.parametrize("amount", [1.5e-3, 4e-3, 7e-3, 0.013, 0.024])
def test_any_offset_up_to_the_largest_passes_as_the_amount_it_comes_closest_to(whitted, whitted_reference, amount):
    """The variant is rendered at a ladder of round amounts (0.001, 0.002, 0.003, 0.005, 0.01, 0.02 and its
    largest, 0.03 here); an amount between two rungs passes against their range, as the nearer one."""
    honest = _student(whitted, style=student.Offset(amount))
    assert not grade(whitted_reference, honest, "").passed
    graded = _graded(whitted, honest, pipeline.Checks(diagnose=False))
    assert graded.grade.passed and graded.accepted is not None and graded.accepted.endswith(" along the normal")
    said = float(graded.accepted.split()[4])
    assert amount / 2 <= said <= amount * 2


def test_the_range_of_one_render_is_the_grades_own_measure(whitted, whitted_reference):
    honest = _student(whitted, style=student.STYLES["offset 1e-3"])
    verdict = grade(whitted_reference, honest, "")
    pixels = honest.shape[0] * honest.shape[1]
    assert accepting.envelope_off([whitted_reference], honest, 2.0) == round(verdict.fraction_off_nearby * pixels)
    counts = accepting.envelope_counts([whitted_reference], honest, 2.0)
    assert counts.grossly_off == verdict.grossly_off


@pytest.mark.parametrize(
    "made",
    [
        {"style": student.STYLES["offset 1e-3"]},
        {"mistakes": ["no-shadows"]},
        {"mistakes": ["offset-too-large"]},
        {"style": student.Offset(7e-3)},
    ],
)
def test_a_first_look_at_a_few_rows_bounds_the_whole_count(whitted, whitted_reference, made):
    image = _student(whitted, **made)
    pair = accepting.Failing(whitted_reference, image, grade(whitted_reference, image, ""))
    for rungs in accepting.accepted_ladders(whitted, None):
        for low, high in accepting.brackets(rungs)[:3]:
            parts = [r for r in (low, high) if r is not None]
            ranged = ([whitted_reference] if low is None else []) + [_rendered(whitted, r.options) for r in parts]
            whole = accepting.envelope_off(ranged, image, 2.0)
            bound = accepting.first_look(whitted, parts, pair, accepting.Look("", None, None), low is None)
            assert bound <= whole


def test_a_clearly_wrong_image_renders_no_whole_variant(whitted, whitted_reference, monkeypatch):
    wrong = _student(whitted, ["no-shadows"])
    monkeypatch.setattr(accepting, "KEPT_RENDERS", accepting._Kept())  # (none kept from the tests before)
    monkeypatch.setattr(accepting, "_render", lambda *a: pytest.fail("a whole variant was rendered"))
    failed = grade(whitted_reference, wrong, "")
    assert accepting.accept(whitted, accepting.Failing(whitted_reference, wrong, failed)) is None


def test_an_offset_far_too_large_fails_and_is_named_with_its_size_in_the_scenes_units(whitted):
    wrong = _student(whitted, ["offset-too-large"])  # (0.1, where at most 0.03 is accepted)
    graded = _graded(whitted, wrong)
    assert not graded.grade.passed and graded.accepted is None
    assert graded.diagnosis is not None and graded.diagnosis.causes[0].variant == "offset-too-large"
    assert graded.diagnosis.causes[0].passes and "about 0.1 in the scene's units" in graded.diagnosis.sentence()


def test_an_offset_too_large_of_a_round_amount_is_found_at_that_amount():
    """The Cornell homework 64 pixels across, as the confusion matrix grades pairs: the student's offset of 0.1
    is a rung of the ladder and matches it exactly, but the rows looked at leave every amount from 0.087 to 0.1
    alike, and narrowing took the first of equals: "about 0.092", 0.36 % off, no match and no deduction."""
    data = json.loads((EXAMPLES / "09_cornell_homework.json").read_text())
    data["image"].update(width=64, height=48)
    scene = load_scene(json.dumps(data).encode())
    graded = _graded(scene, _student(scene, ["offset-too-large"]))
    assert not graded.grade.passed and graded.diagnosis is not None
    cause = graded.diagnosis.causes[0]
    assert cause.variant == "offset-too-large" and cause.passes, graded.diagnosis.sentence()
    assert "about 0.1 in the scene's units" in graded.diagnosis.sentence()


def test_an_image_a_mistake_matches_climbs_no_offset_ladder(whitted, monkeypatch):
    """The ladder of offsets too large is scored last in the first round, and only where no mistake passes: an
    image with no shadows is named as before without it (it cost 1.3 s of 4.8 in bench.pricing's class)."""
    from service.diagnosis import too_large

    wrong = _student(whitted, ["no-shadows"])
    monkeypatch.setattr(too_large, "score", lambda *a: pytest.fail("the offset ladder was climbed"))
    graded = _graded(whitted, wrong)
    assert graded.diagnosis is not None and graded.diagnosis.causes[0].variant == "no-shadows"
    assert graded.diagnosis.causes[0].passes


@pytest.mark.parametrize("amount", [0.06, 0.1])
def test_rays_started_too_far_along_themselves_are_named_as_that_with_their_size(amount):
    """A student's ``p + ε·d``, ε 0.06 or 0.1, where a t_min of at most 0.049 is accepted (the Cornell homework, 64
    pixels across): a shadow ray as long as from the hit point to the light passes it by ε and reaches the
    ceiling just above, and most of the room goes dark.  It was "no known mistake fits"; the ladder along the
    ray names it, with its size.  (0.06 lies just above the ladder's lowest rungs, 0.049 and 0.05, which leave
    the ceiling out of reach alike: with both rungs, no range held 0.06.)"""
    data = json.loads((EXAMPLES / "09_cornell_homework.json").read_text())
    data["image"].update(width=64, height=48)
    scene = load_scene(json.dumps(data).encode())
    graded = _graded(scene, _student(scene, style=student.Offset(amount, "ray")))
    assert not graded.grade.passed and graded.diagnosis is not None
    cause = graded.diagnosis.causes[0]
    assert cause.variant == "offset-too-large" and cause.passes, graded.diagnosis.sentence()
    said = re.search(r"too far along their own direction: about ([0-9.e-]+) in the scene's units", cause.mistake)
    assert said and abs(float(said.group(1)) - amount) <= 0.1 * amount, cause.mistake


@pytest.mark.parametrize("mistake", student.MISTAKES)
def test_no_classic_mistake_is_turned_into_a_pass(whitted, whitted_reference, mistake):
    """The verdict with the accepted variants is the reference's: a mistake the scene shows fails, one it cannot
    show (no spot: a spot's cutoff in radians) passed already."""
    wrong = _student(whitted, [mistake])
    alone = grade(whitted_reference, wrong, "").passed
    assert _graded(whitted, wrong, pipeline.Checks(diagnose=False)).grade.passed == alone


def test_the_cornell_homework_passes_an_honest_offset_and_fails_a_large_one():
    scene = _scene(CORNELL)
    honest = _graded(scene, _student(scene, style=student.STYLES["offset 1e-3"]))
    assert honest.grade.passed and honest.accepted in (None, "a ray offset of 0.001 along the normal")
    assert not _graded(scene, _student(scene, ["offset-too-large"]), pipeline.Checks(diagnose=False)).grade.passed


def test_a_task_narrows_and_widens_its_accepted_variants(whitted):
    honest = _student(whitted, style=student.STYLES["offset 1e-3"])
    assert not _graded(whitted, honest, pipeline.Checks(accepted={}, diagnose=False)).grade.passed
    wider = _student(whitted, style=student.Offset(0.05))  # (8e-3 of the visible size, 6.06)
    assert not _graded(whitted, wider, pipeline.Checks(diagnose=False)).grade.passed
    widened = _graded(whitted, wider, pipeline.Checks(accepted={"normal-offset": 1e-2}, diagnose=False))
    assert widened.grade.passed and widened.accepted == "a ray offset of 0.05 along the normal"
    only_t_min = _graded(whitted, honest, pipeline.Checks(accepted={"t-min": 1e-2}, diagnose=False))
    assert not only_t_min.grade.passed


def test_a_passing_image_renders_no_variant(whitted, whitted_reference, monkeypatch):
    def refuse(*args, **kw):  # noqa: ANN002, ANN003, ANN202
        raise AssertionError("an accepted variant was rendered for a passing image")

    monkeypatch.setattr(accepting, "accept", refuse)
    assert _graded(whitted, whitted_reference).grade.passed


def test_the_variant_is_the_reference_with_its_rays_moved_off_the_surface(whitted, whitted_reference):
    """An offset of 0 is the reference itself; the variants move rays by exactly their amount × the visible size,
    the size of what the camera sees (not the box around the scene, 4.3 here)."""
    assert np.array_equal(Renderer(whitted, Options(offset=0.0)).pixels(), whitted_reference)
    assert scene_size(whitted) == pytest.approx(4.3)  # the two balls' box: z from −2.7 to 1.6, its widest side
    size = Renderer(whitted).visible_size()
    assert size == pytest.approx(6.06, abs=0.01)  # the view's height at the median depth of what it shows
    for style, along in (("offset 1e-3", "normal"), ("t_min 1e-3", "ray")):
        variant = Renderer(whitted, Options(offset=1e-3 / size, offset_along=along)).pixels()
        assert grade(variant, _student(whitted, style=student.STYLES[style]), "").fraction_off_nearby == 0


def test_a_tasks_file_names_the_accepted_variants_it_knows(tmp_path):
    tasks = {"cornell": CORNELL}
    good = tmp_path / "tasks.json"
    good.write_text('{"cornell": {"accepted": {"t-min": 0.002}}}')
    assert load_tasks(good, tasks)["cornell"].accepted == {"t-min": 0.002}
    bad = tmp_path / "bad.json"
    bad.write_text('{"cornell": {"accepted": {"epsilon": 0.002}}}')
    with pytest.raises(ClassError, match="bad.json"):
        load_tasks(bad, tasks)


def test_grade_says_which_variant_it_passed_as_even_without_a_diagnosis(whitted, tmp_path, capsys):
    from service.cli import main

    honest = tmp_path / "honest.png"
    honest.write_bytes(encode_png(_student(whitted, style=student.STYLES["offset 1e-3"])))
    for extra in ([], ["--no-diagnosis"]):
        assert main(["grade", str(WHITTED), str(honest), *extra]) == 0
        assert (
            capsys.readouterr().out.splitlines()[0] == "PASS, as rendered with a ray offset of 0.001 along the normal"
        )


def test_post_grade_gives_the_accepted_variant(whitted):
    from fastapi.testclient import TestClient

    from service.http.app import create_app
    from service.settings import Settings

    honest = encode_png(_student(whitted, style=student.STYLES["offset 1e-3"]))
    api = TestClient(create_app(Settings()))
    spec = api.get("/openapi.json").json()
    assert "accepted" in spec["components"]["schemas"]["GradeAnswer"]["properties"]
    body = api.post(
        "/grade",
        files={"scene": ("s.json", WHITTED.read_bytes(), "application/json"), "image": ("i.png", honest, "image/png")},
    ).json()
    assert body["passed"] is True and body["accepted"] == "a ray offset of 0.001 along the normal"
    assert body["diagnosis"] is None


def test_a_class_task_takes_its_accepted_variants_from_the_tasks_file(whitted, tmp_path):
    import json
    import shutil

    from service.classgrade import ClassRun, grade_class

    (tmp_path / "scenes").mkdir()
    shutil.copyfile(WHITTED, tmp_path / "scenes" / "whitted.json")
    (tmp_path / "subs" / "ada").mkdir(parents=True)
    (tmp_path / "subs" / "ada" / "whitted.png").write_bytes(
        encode_png(_student(whitted, style=student.STYLES["offset 1e-3"]))
    )
    rows = {}
    for name, accepted in (("defaults", None), ("none", {})):
        tasks = tmp_path / f"{name}.json"
        tasks.write_text(json.dumps({"whitted": {} if accepted is None else {"accepted": accepted}}))
        run = ClassRun(tmp_path / "scenes", tmp_path / "subs", tmp_path / name, jobs=1, tasks_file=tasks)
        (row,) = grade_class(run).rows
        rows[name] = row
    expected = ("pass", "as rendered with a ray offset of 0.001 along the normal")
    assert (rows["defaults"]["status"], rows["defaults"]["reason"]) == expected
    assert rows["none"]["status"] == "fail"
