"""A class's report whatever one pair's row holds (service/classgrade/isolation.py): every combination of
deducted mistakes grades, in grade-class and in the autograder; a fault of a report writer for one pair is
that pair's row, with its reason, and the rest of the class is written."""

from __future__ import annotations

import csv
import itertools
import json
import shutil
from pathlib import Path
from typing import Any

import pytest

import schemas
from service import classgrade
from service.classgrade import ClassRun, journal, writing
from service.classgrade import report as report_module
from service.classgrade import rows as rows_module
from service.classgrade.gradebook import MISTAKES, partial, score
from service.classgrade.taskfile import TaskSettings
from service.cli import main
from service.diagnosis.combination import merged
from tracer import Renderer, encode_png

from helpers import run_autograder, scene_dict

DEDUCTIONS = {"no-shadows": 4, "blinn-phong": 2}
#: each student's mistakes in the one task, cornell (none: right)
CLASS = {"ann": (), "bo": ("no-shadows", "blinn-phong"), "cy": ("no-shadows",)}


def test_every_combination_of_deductions_scores_and_is_named():
    ids = sorted(MISTAKES)
    task = TaskSettings(points=10, deductions=dict.fromkeys(ids, 1.0))
    tasks = {"t": task}
    combinations = [*itertools.combinations(ids, 2), *itertools.combinations(ids[:5], 3)]
    for together in combinations:
        mistake = "+".join(together)
        row = {"status": "fail", "reason": "off", "mistakes": [mistake], "points": 10.0}
        row["score"], row["deducted"] = score(row, task).score, score(row, task).deducted
        assert (row["score"], row["deducted"]) == (10 - len(together), mistake)
        credit = partial(row)
        assert all(MISTAKES[m] in credit for m in together) and credit.endswith(f": -{len(together)})"), credit
        assert report_module.test_output(row, "diagnosis").endswith(credit)
        assert report_module.gradescope([{**row, "task": "t"}], tasks)["score"] == row["score"]


def _scene() -> dict[str, Any]:
    data = scene_dict("01_three_spheres")
    data["image"].update(width=64, height=48)
    return data


@pytest.fixture(scope="module")
def course(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The one task, cornell (10 points, two mistakes with deductions), and a student per entry of CLASS."""
    root = tmp_path_factory.mktemp("deducted")
    (root / "scenes").mkdir()
    (root / "scenes" / "cornell.json").write_text(json.dumps(_scene()))
    scene = schemas.validate_scene(_scene())
    for student, mistakes in CLASS.items():
        (root / "subs" / student).mkdir(parents=True)
        pixels = Renderer(scene, merged(mistakes)).pixels() if mistakes else Renderer(scene).pixels()
        (root / "subs" / student / "cornell.png").write_bytes(encode_png(pixels))
    (root / "tasks.json").write_text(json.dumps({"cornell": {"points": 10, "deductions": DEDUCTIONS}}))
    return root


def _graded(course: Path, report: Path) -> classgrade.Outcome:
    return classgrade.grade_class(
        ClassRun(course / "scenes", course / "subs", report, jobs=1, tasks_file=course / "tasks.json")
    )


@pytest.fixture(scope="module")
def graded(course: Path) -> tuple[Path, dict[str, dict[str, Any]]]:
    outcome = _graded(course, course / "report")
    return course / "report", {r["student"]: r for r in outcome.rows}


BOTH = (
    "Partial credit: 4 of 10 points (no shadow rays and the Blinn–Phong half vector instead of the reflected "
    "vector: -6)"
)


def test_two_deducted_mistakes_grade_the_class_whole(graded: tuple[Path, dict[str, dict[str, Any]]]):
    report, rows = graded
    assert rows["bo"]["mistakes"] == ["no-shadows+blinn-phong"] and rows["bo"]["deducted"] == "no-shadows+blinn-phong"
    assert [rows[s]["score"] for s in CLASS] == [10.0, 4.0, 6.0]
    results = json.loads((report / "gradescope" / "bo" / "results.json").read_text())
    assert results["score"] == 4.0 and results["tests"][0]["output"].endswith(BOTH)
    assert BOTH in (report / "index.html").read_text()
    with open(report / "gradebook.csv", newline="") as f:
        assert [r["total"] for r in csv.DictReader(f)] == ["10", "4", "6"]
    # the grade is kept for a run that resumes, rather than graded again each time
    kept = json.loads(journal.path(report, "bo", "cornell").read_text())
    assert journal.valid_row(kept["row"])


def test_a_rerun_of_two_deducted_mistakes_resumes_and_writes_the_report(graded, course: Path):
    report, rows = graded
    again = _graded(course, report)
    assert again.renders == 0 and {r["student"]: r for r in again.rows}["bo"] == rows["bo"] and not again.unwritten


def test_two_deducted_mistakes_grade_in_the_autograder(course: Path, tmp_path: Path):
    bundle = tmp_path / "autograder.zip"
    assert main(["autograder", str(course / "scenes"), "-o", str(bundle), "--tasks", str(course / "tasks.json")]) == 0
    done, results = run_autograder(bundle, tmp_path / "root", {"cornell.png": course / "subs" / "bo" / "cornell.png"})
    assert done.returncode == 0, done.stderr
    assert results["score"] == 4.0 and results["tests"][0]["output"].endswith(BOTH)


# -- a fault of a writer, injected ----------------------------------------------------------------------------


def _faulty(real: Any, rows_of: Any) -> Any:
    """``real``, raising for bo's row as graded (with its mistakes), as a writer's fault would."""

    def broken(*args: Any, **kwargs: Any) -> Any:
        if any(r.get("student") == "bo" and r.get("mistakes") for r in rows_of(args)):
            raise KeyError("a fault of the writer")
        return real(*args, **kwargs)

    return broken


WRITERS = {  # the writer broken (in the module that calls it), and where its rows are in its arguments
    "gradescope": (writing, lambda args: args[0]),
    "gradebook_csv": (writing, lambda args: args[0]),
    "lms_books": (writing, lambda args: args[0]),
    "render_html": (writing, lambda args: args[0]),
    "_cell": (report_module, lambda args: [args[0]]),
    "_detail": (report_module, lambda args: [args[0]]),
    "safe_cell": (
        report_module,
        lambda args: [{"student": "bo", "mistakes": args[0]}] if args[0] == ["no-shadows+blinn-phong"] else [],
    ),
    "_json": (writing, lambda args: args[0] if isinstance(args[0], list) else []),
}


@pytest.mark.parametrize("writer", sorted(WRITERS))
def test_a_writers_fault_for_one_pair_is_that_pairs_row(graded, tmp_path: Path, monkeypatch, writer: str):
    _, rows = graded
    module, rows_of = WRITERS[writer]
    monkeypatch.setattr(module, writer, _faulty(getattr(module, writer), rows_of))
    tasks = {"cornell": TaskSettings(points=10, deductions=DEDUCTIONS)}
    written, faults = writing.write_report(tmp_path, list(rows.values()), [], list(CLASS), tasks, "a class")
    assert len(faults) == 1 and faults[0].startswith("bo/cornell: ") and "KeyError" in faults[0]
    mine = {r["student"]: r for r in json.loads((tmp_path / "report.json").read_text())}
    assert mine["ann"] == rows["ann"] and mine["cy"] == rows["cy"]
    bo = mine["bo"]
    assert (bo["status"], bo["score"], bo["points"]) == ("fail", 4.0, 10.0)
    assert "phongray could not write this grade whole" in bo["reason"] and "a fault of the writer" in bo["reason"]
    assert bo["reason"].startswith(rows["bo"]["reason"]) and written[1] == bo
    results = json.loads((tmp_path / "gradescope" / "bo" / "results.json").read_text())
    assert results["score"] == 4.0 and "could not write this grade whole" in results["tests"][0]["output"]
    assert json.loads((tmp_path / "gradescope" / "cy" / "results.json").read_text())["score"] == 6.0
    page = (tmp_path / "index.html").read_text()
    assert "a class; 1 grade could not be written whole (see its reason)" in page and "a fault of the writer" in page
    with open(tmp_path / "gradebook.csv", newline="") as f:
        assert [r["total"] for r in csv.DictReader(f)] == ["10", "4", "6"]
    assert "a fault of the writer" in (tmp_path / "report.csv").read_text()


def test_a_row_no_writer_can_write_is_that_pairs_row(graded, tmp_path: Path):
    _, rows = graded
    broken = [dict(r) for r in rows.values()]
    broken[1]["likely"], broken[1]["score"] = object(), float("nan")  # (not text, not a number)
    tasks = {"cornell": TaskSettings(points=10, deductions=DEDUCTIONS)}
    written, faults = writing.write_report(tmp_path, broken, [], list(CLASS), tasks, "a class")
    assert [f.split(":")[0] for f in faults] == ["bo/cornell"]
    assert written[1]["score"] == 0.0 and written[1]["reason"].endswith("; it is not scored)")
    assert json.loads((tmp_path / "gradescope" / "ann" / "results.json").read_text())["score"] == 10.0


def test_a_row_that_cannot_be_made_is_that_pairs_row(graded, course: Path, tmp_path: Path, monkeypatch):
    report, rows = tmp_path / "report", graded[1]
    shutil.copytree(graded[0], report)  # (the class graded again, resumed from its grades)

    def faulty(row: dict[str, Any], task: TaskSettings) -> Any:
        if row["student"] == "cy":
            raise ValueError("a fault of the score")
        return score(row, task)

    monkeypatch.setattr(rows_module, "score", faulty)
    outcome = _graded(course, report)
    mine = {r["student"]: r for r in outcome.rows}
    assert mine["ann"] == rows["ann"] and mine["bo"] == rows["bo"]
    assert (mine["cy"]["status"], mine["cy"]["score"]) == ("invalid", 0.0)  # (not scored, and says so)
    assert "a fault of the score" in mine["cy"]["reason"] and mine["cy"]["reason"].endswith("it is not scored)")
    assert outcome.unwritten == ["cy/cornell: its row: ValueError: a fault of the score"]
    assert json.loads((report / "gradescope" / "cy" / "results.json").read_text())["score"] == 0.0


def test_only_the_pair_at_fault_is_replaced_and_a_writer_sees_the_students_whole_rows():
    from service.classgrade.isolation import isolated
    from service.classgrade.report import COLUMNS

    def row(student: str, task: str, bad: bool = False) -> dict[str, Any]:
        return {**dict.fromkeys(COLUMNS), "student": student, "task": task, "status": "fail", "reason": "off"} | {
            "points": 2.0,
            "score": 1.0,
            "mistakes": ["gamma"] if bad else [],
        }

    def whole(rows: list[dict[str, Any]]) -> None:  # (a writer of every task's column: each student's rows whole)
        assert {r["task"] for r in rows} == {"a", "b"}

    def breaks(rows: list[dict[str, Any]]) -> None:
        if any(r["mistakes"] == ["gamma"] for r in rows):
            raise KeyError("gamma")

    rows = [row("ann", "a"), row("ann", "b"), row("bo", "a"), row("bo", "b", bad=True)]
    written, faults = isolated(rows, {"whole.csv": whole, "broken.html": breaks}, COLUMNS)
    assert written[:3] == rows[:3] and faults == ["bo/b: broken.html: KeyError: 'gamma'"]
    mended = written[3]
    assert (mended["student"], mended["task"], mended["score"], mended["mistakes"]) == ("bo", "b", 1.0, [])
