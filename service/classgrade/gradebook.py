"""A class's scores: partial credit by the likely mistake, each student's total, and ``gradebook.csv``.

A pair that passes scores its task's points, a missing or invalid one 0.  A failing one scores 0, unless the
tasks file gives its task ``deductions`` by mistake id (``{"no-shadows": 1}``) and the image's one fault is
such a mistake: it passes against the reference rendered with that mistake (:mod:`service.diagnosis`).  It
then scores the points less the deduction (at most the points, :mod:`service.classgrade.taskfile`).  An image
that several mistakes explain alike (it passes against the reference rendered with each: the image cannot tell
them apart) is graded on what it shows: it gets the smallest of the deductions the task has for them.  So is
an image of mistakes made together that another combination explains alike (no shadow rays with no refraction,
or with the normal leaving glass not flipped): each reading is deducted as the sum of its mistakes' deductions,
and the smallest is taken.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from typing import Any

from tracer.scene.variants import MORE_VARIANTS, VARIANTS

from ..diagnosis.words import listed
from .forms import ReportRow
from .taskfile import TaskSettings

#: the ids a deduction may name: the diagnosis's classic mistakes (tracer.scene.variants), with what each is
MISTAKES = {name: words for name, (_, words) in VARIANTS.items()}
#: every id a diagnosis names, with what each is: the classic mistakes and the new ones
KNOWN = {name: words for name, (_, words) in {**VARIANTS, **MORE_VARIANTS}.items()}


@dataclass(frozen=True)
class Score:
    score: float
    deducted: str | None = None  # the mistake whose deduction was taken: a partial credit


def score(row: ReportRow, task: TaskSettings) -> Score:
    """What a pair scores of its task's points (nothing for a program holding phongray's code, where the task
    says ``"phongray_code": "zero"``)."""
    if row.get("flag") == "phongray-code" and task.phongray_code == "zero":
        return Score(0.0)
    if row["status"] == "pass":
        return Score(task.points)
    if row["status"] != "fail":
        return Score(0.0)
    options = sorted((less, m) for m in row.get("mistakes") or [] if (less := _deduction(m, task)) is not None)
    if not options:
        return Score(0.0)
    least, mistake = options[0]
    return Score(max(0.0, task.points - least), mistake)


def _deduction(mistake: str, task: TaskSettings) -> float | None:
    """What the task deducts for a mistake, or for mistakes made together (``a+b``) the sum of each one's: None
    when one of them has no deduction (the image then scores nothing, as an unnamed fault does)."""
    parts = mistake.split("+")
    if any(part not in task.deductions for part in parts):
        return None
    return sum(task.deductions[part] for part in parts)


def late_policy(earned: float, task: TaskSettings) -> float:
    """The points the late policy takes from a late pair's ``earned`` score: the task's ``late_penalty`` of its
    points (as Canvas's late policy takes a percentage of the points possible), never below 0."""
    return min(earned, task.late_penalty * task.points)


def late_note(row: ReportRow) -> str:
    """What a student reads of a late pair: ``Late: handed in late (the late policy took 1 of its points)``."""
    if not row.get("late"):
        return ""
    took = f"the late policy took {row['late_deducted']:g} of its points" if row.get("late_deducted") else "no penalty"
    return f"Late: handed in late ({took})"


def partial(row: ReportRow) -> str:
    """``Partial credit: 1 of 2 points (no shadow rays: -1)`` for a row scored by a deduction, else empty; for an
    image several mistakes explain alike, each of them: ``(no specular term, or the reflected vector R with the
    wrong sign: -1)`` (the deduction is for what the image shows); for mistakes made together
    (``no-shadows+gamma``), each one: ``(no shadow rays and gamma …: -3)``."""
    if not row.get("deducted"):
        return ""
    lost = row["points"] - row["score"]
    readings = [m for m in row.get("mistakes") or [] if all(part in KNOWN for part in m.split("+"))]
    shown = readings if row["deducted"] in readings and len(readings) > 1 else [row["deducted"]]
    what = listed([" and ".join(KNOWN.get(part, part) for part in m.split("+")) for m in shown], "or")
    return f"Partial credit: {row['score']:g} of {row['points']:g} points ({what}: -{lost:g})"


@dataclass(frozen=True)
class Total:
    student: str
    lms_id: str  # the student's id in the LMS's export ("" for none)
    scores: dict[str, float]  # task → score
    total: float
    out_of: float
    late: list[str]  # the tasks the LMS marked late


def totals(rows: list[ReportRow], students: list[str]) -> list[Total]:
    """Each student's scores and total, in the students' order."""
    out = []
    for student in students:
        mine = [r for r in rows if r["student"] == student]
        out.append(
            Total(
                student,
                mine[0]["lms_id"] if mine else "",
                {r["task"]: r["score"] for r in mine},
                sum(r["score"] for r in mine),
                sum(r["points"] for r in mine),
                [r["task"] for r in mine if r.get("late")],
            )
        )
    return out


def gradebook_csv(rows: list[ReportRow], students: list[str], tasks: list[str], cell: Any = lambda v: v) -> str:
    """``gradebook.csv``: a row per student (their name and, from a Canvas or Moodle export, the LMS's id, to
    match on import), a column per task (its score), the total and the tasks handed in late; ``cell`` makes a
    text cell safe to open (:func:`service.classgrade.report.safe_cell`)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n", quoting=csv.QUOTE_MINIMAL)
    writer.writerow(["student", "id", *map(cell, tasks), "total", "late"])
    for t in totals(rows, students):
        name = cell(t.student)
        late = cell(" ".join(t.late))
        row = [name, t.lms_id, *(f"{t.scores[task]:g}" for task in tasks), f"{t.total:g}", late]
        (csv.writer(buf, lineterminator="\n", quoting=csv.QUOTE_ALL) if "\r" in name else writer).writerow(row)
    return buf.getvalue()
