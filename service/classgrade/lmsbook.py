"""The class's grades as each learning-management system imports them, written beside ``gradebook.csv``.

**Canvas** (``canvas-gradebook.csv``, for *Grades → Import*), as Canvas's own gradebook export lays it out and
its importer reads it: the columns ``Student``, ``ID`` (the Canvas user id, from the export's file names),
``SIS User ID``, ``SIS Login ID`` and ``Section``, then a column per assignment named as Canvas names it,
``Homework 3 (12345)`` (its title, a space and its id in parentheses: the importer takes the assignment by that
id); a second row ``    Points Possible`` (four spaces first, as the export writes it) with each assignment's
points; then a row per student.  The importer matches a student by ``ID`` first, then by the SIS ids, then by
name.  A task's score goes to its assignment (tasks.json's ``canvas``, or the task's own name, a column Canvas
makes a new assignment of); tasks of one assignment share its column, which holds their sum: one assignment
for the homework gives one column with each student's total.  No other column is written: the importer would
make a new assignment of any column it does not know.

**Moodle** (``moodle-grading-worksheet.csv``, for the assignment's *Upload grading worksheet*), as its grading
worksheet lays it out: ``Identifier`` (``Participant 100001``: the number is the one Moodle puts in each
submission's folder name, ``Ada Adams_100001_assignsubmission_file_``), ``Full name``, ``Email address``,
``Status``, ``Grade``, ``Maximum Grade``, ``Grade can be changed``, ``Last modified (submission)``, ``Last
modified (grade)`` and ``Feedback comments``.  The upload reads ``Identifier``, ``Grade`` and ``Last modified
(grade)`` (it refuses a worksheet without them, and skips a grade changed in Moodle since that time) and the
feedback columns; it skips a grade above the assignment's maximum grade, so the assignment's maximum grade is
the tasks' points.  A row per student of the Moodle export: the others have no participant number.

Numbers are written as each LMS writes them (Canvas: at most two decimals; Moodle: two decimals); a name
keeps the report's protection against spreadsheet formulas.  A late student's score is the late policy's
(:func:`~.gradebook.late_policy`); Canvas knows itself which submissions were late, and Moodle's feedback
comment says it.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable
from datetime import datetime
from typing import Any

from .forms import ReportRow
from .taskfile import TaskSettings

#: the files written (when the class holds such students, or a Canvas assignment is named)
CANVAS_FILE, MOODLE_FILE = "canvas-gradebook.csv", "moodle-grading-worksheet.csv"
#: Canvas's columns before the assignments', in its export's order (its importer reads ID, the SIS ids, Section)
CANVAS_STUDENT = ["Student", "ID", "SIS User ID", "SIS Login ID", "Section"]
#: the first cell of Canvas's row of each assignment's points (its importer looks for "Points Possible")
POINTS_POSSIBLE = "    Points Possible"
#: the columns of Moodle's grading worksheet (an assignment that takes files, feedback comments on)
MOODLE_COLUMNS = [
    "Identifier",
    "Full name",
    "Email address",
    "Status",
    "Grade",
    "Maximum Grade",
    "Grade can be changed",
    "Last modified (submission)",
    "Last modified (grade)",
    "Feedback comments",
]
#: what Moodle calls a participant in a worksheet (its "hiddenuser" string), before the participant's number
PARTICIPANT = "Participant "
DAYS = ("Monday", "Tuesday", "Wednesday", "Thursday", "Friday", "Saturday", "Sunday")
MONTHS = "January February March April May June July August September October November December".split()

Cell = Callable[[Any], Any]


def lms_books(
    rows: list[ReportRow], students: list[str], tasks: dict[str, TaskSettings], cell: Cell
) -> dict[str, str | None]:
    """Each LMS's file and its text, None where the class needs none (an earlier run's is then removed):
    Canvas's when a student came from a Canvas export or a task names a Canvas assignment, Moodle's when a
    student came from a Moodle export."""
    lms = {r["lms"] for r in rows}
    canvas = "canvas" in lms or any(t.canvas for t in tasks.values())
    return {
        CANVAS_FILE: canvas_csv(rows, students, tasks, cell) if canvas else None,
        MOODLE_FILE: moodle_csv(rows, students, cell) if "moodle" in lms else None,
    }


def _writerow(buf: io.StringIO, cells: list[Any]) -> None:
    """One row, each cell quoted when one holds a carriage return (which only a writer that quotes every cell
    quotes, its line ending being a newline)."""
    every = any("\r" in str(c) for c in cells)
    csv.writer(buf, lineterminator="\n", quoting=csv.QUOTE_ALL if every else csv.QUOTE_MINIMAL).writerow(cells)


def _students(rows: list[ReportRow], students: list[str]) -> list[list[ReportRow]]:
    """Each student's rows, in the students' order."""
    by: dict[str, list[ReportRow]] = {s: [] for s in students}
    for r in rows:
        by[r["student"]].append(r)
    return [by[s] for s in students if by[s]]


def _canvas_number(x: float) -> str:
    """As Canvas's export writes a score: at most two decimals, no trailing zeros (``8.5``, ``10``)."""
    return f"{x:.2f}".rstrip("0").rstrip(".")


def canvas_csv(rows: list[ReportRow], students: list[str], tasks: dict[str, TaskSettings], cell: Cell) -> str:
    """``canvas-gradebook.csv``: the students' scores in Canvas's gradebook import format: where some came from
    a Canvas export, those and the others of no LMS (a student found in a Moodle export is in Moodle's
    worksheet); where none did (a task names a Canvas assignment), every student, with no id."""
    columns: dict[str, list[str]] = {}  # assignment column → its tasks
    for task, settings in tasks.items():
        columns.setdefault(settings.canvas or task, []).append(task)
    buf = io.StringIO()
    _writerow(buf, [*CANVAS_STUDENT, *map(cell, columns)])
    points = [_canvas_number(sum(tasks[t].points for t in mine)) for mine in columns.values()]
    _writerow(buf, [POINTS_POSSIBLE, "", "", "", "", *points])
    from_canvas = any(r["lms"] == "canvas" for r in rows)
    for mine in _students(rows, students):
        if from_canvas and mine[0]["lms"] == "moodle":  # (beside Canvas's own: Moodle's, in its worksheet)
            continue
        score = {r["task"]: r["score"] for r in mine}
        canvas_id = mine[0]["lms_id"] if mine[0]["lms"] == "canvas" else ""
        scores = [_canvas_number(sum(score[t] for t in each)) for each in columns.values()]
        _writerow(buf, [cell(mine[0]["student"]), canvas_id, "", "", "", *scores])
    return buf.getvalue()


def moodle_time(when: datetime) -> str:
    """A time as Moodle writes one in a worksheet (its ``strftimedatetime``, English): ``Tuesday, 5 March 2024,
    9:05 AM``; its upload reads it back with PHP's ``strtotime``."""
    hour = when.hour % 12 or 12
    return (
        f"{DAYS[when.weekday()]}, {when.day} {MONTHS[when.month - 1]} {when.year}, {hour}:{when.minute:02d} "
        f"{'AM' if when.hour < 12 else 'PM'}"
    )


def _feedback(mine: list[ReportRow]) -> str:
    """A student's feedback comment: each task's score and status, and what lateness cost (no more of a task
    than the least a task's ``show`` lets a student read: passed or failed, and the score)."""
    parts = [f"{r['task']}: {r['score']:g} of {r['points']:g} ({r['status']})" for r in mine]
    late = [r for r in mine if r.get("late")]
    if late:
        lost = sum(r["late_deducted"] or 0.0 for r in late)
        parts.append(f"handed in late: {', '.join(r['task'] for r in late)} (-{lost:g} by the late policy)")
    return "; ".join(parts)


def moodle_csv(rows: list[ReportRow], students: list[str], cell: Cell, now: datetime | None = None) -> str:
    """``moodle-grading-worksheet.csv``: the Moodle students' totals as Moodle's grading worksheet; ``now`` the
    time of the grades (Moodle skips a grade changed in Moodle after it)."""
    stamp = moodle_time(now or datetime.now())
    buf = io.StringIO()
    _writerow(buf, MOODLE_COLUMNS)
    for mine in _students(rows, students):
        if mine[0]["lms"] != "moodle":
            continue
        total, out_of = sum(r["score"] for r in mine), sum(r["points"] for r in mine)
        _writerow(
            buf,
            [
                PARTICIPANT + mine[0]["lms_id"],
                cell(mine[0]["student"]),
                "",
                "Submitted for grading",
                f"{total:.2f}",
                f"{out_of:.2f}",
                "Yes",
                "-",
                stamp,
                cell(_feedback(mine)),
            ],
        )
    return buf.getvalue()
