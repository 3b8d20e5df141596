"""A pair's grade from what a backend returns to the report's row, in one place each: :func:`kept_row` makes a
backend's :class:`~.records.Marked` the row a run keeps (in its resume journal, as JSON), and :func:`report_row`
makes the report's :class:`~.records.Row` of a pair and its kept row (just graded, or kept by an earlier run)."""

from __future__ import annotations

from dataclasses import asdict, astuple
from pathlib import Path

from ..diagnosis import headline
from ..diagnosis.records import matched
from .forms import ReportRow
from .gradebook import late_policy, score
from .records import Marked, Pair, Row
from .report import COLUMNS
from .taskfile import TaskSettings


def kept_row(marked: Marked, file: Path | None) -> ReportRow:
    """The row kept of a backend's grade (plain values, as the journal writes them): an invalid pair's reason
    naming its ``file`` (a program's image as the program's, its run kept); else the grade's numbers, its
    reason, the likely mistake (a program's experiment's, where no mistake matched) and the ids of those it
    matches, and a program's run, experiment and flag."""
    if marked.status == "invalid" and marked.run is None:
        return {"status": "invalid", "reason": f"{file}: {marked.reason}"}
    if marked.status == "invalid":  # (a program's output: named as such, never by the TA's folder; its run kept)
        return {"status": "invalid", "reason": f"the program's image: {marked.reason}", **_run_of(marked)}
    graded = marked.graded
    row: ReportRow = {"status": marked.status, "passed": False, "reason": marked.reason}
    found = None
    if graded is not None:  # (a passed accepted variant's reason says which)
        reason = f"as rendered with {graded.accepted}" if graded.accepted else graded.grade.reason
        row = {**graded.grade.as_dict(), "reason": reason, "status": marked.status}
        found = graded.diagnosis
    row.update(_run_of(marked))
    for key in ("experiment", "flag", "flag_reason"):
        if getattr(marked, key) is not None:
            row[key] = getattr(marked, key)
    row["likely"] = headline(found)
    row["mistakes"] = matched(None if found is None else found.as_dict())
    if not row["mistakes"] and marked.experiment:  # a program's mistake its probes found instead
        row["likely"] = marked.experiment.split("; ")[0]
    return row


def _run_of(marked: Marked) -> ReportRow:
    """A program's run as its row keeps it (none for an uploaded image)."""
    if marked.run is None:
        return {}
    run = asdict(marked.run)
    del run["run_busy"]  # (said to the TA as it came, never kept)
    return run


def has_image(row: ReportRow) -> bool:
    """A graded image's row (with its heat-map and copy), not an invalid one or a program's failed run."""
    return row["status"] in ("pass", "fail") and row.get("run") in (None, "ok")


def files(pair: Pair, report: Path) -> tuple[Path, Path]:
    """A graded pair's heat-map and copy of the submission, in the report's folder."""
    return (
        report / "heatmaps" / pair.student / f"{pair.task}.png",
        report / "submissions" / pair.student / f"{pair.task}.png",
    )


def report_row(pair: Pair, reference: Path | None, report: Path, task: TaskSettings) -> Row:
    """A pair's grade as the report writes it: its kept row (just graded, or kept by an earlier run) with who,
    what, the points (and the late policy's), the task's ``reference`` and the report's files."""
    row: ReportRow = {c: None for c in COLUMNS}
    row.update({k: v for k, v in pair.row.items() if k in row})
    row.update(student=pair.student, task=pair.task, scene="own" if pair.own else "shared")
    row["reason"] = row["reason"] or ""
    row["points"] = task.points
    row["mistakes"] = row["mistakes"] or []
    row["score"], row["deducted"] = astuple(score(row, task))
    row["file"], row["lms_id"], row["lms"], row["late"] = pair.file, pair.lms_id, pair.lms, pair.late
    if pair.late:  # the late policy, on what the pair earned
        row["late_deducted"] = late_policy(row["score"], task)
        row["score"] -= row["late_deducted"]
    if reference is not None and reference.exists():
        row["reference"] = str(reference.relative_to(report))
    if has_image(row):
        heat, copy = files(pair, report)
        row["heatmap"], row["submission"] = str(heat.relative_to(report)), str(copy.relative_to(report))
    return Row(**row)
