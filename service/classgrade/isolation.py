"""One pair's fault in writing the report is that pair's row, never the class's lost report.

Before a report's files are written, every writer (report.json, report.csv, gradebook.csv, an LMS's
import file, a student's ``results.json``, index.html) is tried on each pair's row alone (:func:`isolated`).  A row that any of them
cannot write is replaced by a row of plain values (:func:`unwritable`): who and what, the verdict and the
score as they were decided, and a reason that says what could not be written and why; the rest of the class
is written as it is.  The grade itself is kept, whole, in the report's resume folder
(:mod:`service.classgrade.journal`), for a teaching assistant to read.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from .faults import one_line

#: a report file's writer, given rows (a pair's alone, or the class's): it raises for a row it cannot write
Writer = Callable[[list[dict[str, Any]]], object]
#: the columns an unwritable row keeps, when they hold plain values
KEPT = ("student", "lms_id", "lms", "task", "scene", "file")
#: the verdicts a row may have (any other is the row's fault)
STATUSES = ("pass", "fail", "missing", "invalid")


def isolated(
    rows: list[dict[str, Any]], writers: dict[str, Writer], columns: list[str]
) -> tuple[list[dict[str, Any]], list[str]]:
    """The rows every writer can write, each row that one cannot replaced by its :func:`unwritable` row; and
    a line per row replaced (``student/task: file: error``), for the teaching assistant."""
    out, faults = [], []
    for row in rows:
        fault = _first_fault(row, writers)
        if fault is not None:
            where, exc = fault
            row = unwritable(row, columns, where, exc)
            faults.append(f"{row['student']}/{row['task']}: {where}: {one_line(exc)}")
        out.append(row)
    return out, faults


def noted(headline: str, faults: list[str]) -> str:
    """A report's headline, with the grades it could not write whole counted."""
    if not faults:
        return headline
    count, whose = (f"{len(faults)} grades", "their") if len(faults) > 1 else ("1 grade", "its")
    return f"{headline}; {count} could not be written whole (see {whose} reason)"


def _first_fault(row: dict[str, Any], writers: dict[str, Writer]) -> tuple[str, Exception] | None:
    for name, write in writers.items():
        try:
            write([row])
        except Exception as exc:  # (a fault of ours in one pair's row: never the class's report)
            return name, exc
    return None


def unwritable(row: dict[str, Any], columns: list[str], where: str, exc: BaseException) -> dict[str, Any]:
    """A row of plain values in place of one the report could not write (or make) in ``where``: who and
    what, the verdict and score as decided (a verdict or a score that is not one: failed, 0), the reason
    it had and what went wrong; every other column empty."""
    safe: dict[str, Any] = {c: None for c in columns}
    safe.update({k: row[k] if isinstance(row.get(k), str) else "" for k in KEPT if k in safe})
    status = str(row["status"]) if row.get("status") in STATUSES else "fail"
    points, score = _number(row.get("points")), _number(row.get("score"))
    note = f"phongray could not write this grade whole ({where}: {one_line(exc)})"
    if score is None or points is None:
        note += "; it is not scored"
    else:
        note += "; its verdict and score stand"
    reason = row.get("reason")
    safe.update(
        status=status,
        passed={"pass": True, "fail": False}.get(status),
        points=points or 0.0,
        score=score if score is not None and points is not None else 0.0,
        mistakes=[],
        reason=f"{reason} ({note})" if isinstance(reason, str) and reason else note,
    )
    return safe


def _number(value: Any) -> float | None:
    """A finite number as a float, else None."""
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None
