"""One pair's fault in writing the report is that pair's row, never the class's lost report.

Before a report's files are written, every writer (report.json, report.csv, gradebook.csv, an LMS's import
file, a student's ``results.json``, index.html) is tried on each student's rows (:func:`isolated`), as it
writes them in the class's.  A row that any of them cannot write is replaced by a row of plain values
(:func:`unwritable`): who and what, the verdict and the score as they were decided, and a reason that says
what could not be written and why; the rest of the class is written as it is.  The grade itself is kept,
whole, in the report's resume folder (:mod:`service.classgrade.journal`), for a teaching assistant to read.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from .faults import one_line
from .forms import ReportRow

#: a report file's writer, given rows (a pair's alone, or the class's): it raises for a row it cannot write
Writer = Callable[[list[ReportRow]], object]
#: the columns an unwritable row keeps, when they hold text: who and what
WHO = ("student", "lms_id", "lms", "task", "scene", "file")
#: ... and when they hold finite numbers: the thresholds and the comparison's numbers
NUMBERS: tuple[str, ...] = ("tolerance", "max_fraction", "mean_abs_error", "rmse", "psnr", "max_error")
NUMBERS += ("fraction_off", "fraction_off_nearby", "width", "height")
#: the verdicts a row may have (any other is the row's fault)
STATUSES = ("pass", "fail", "missing", "invalid")


def isolated(
    rows: list[ReportRow], writers: dict[str, Writer], columns: list[str]
) -> tuple[list[ReportRow], list[str]]:
    """The rows every writer can write, tried a student at a time (each writer as it writes the class, with
    that student's rows alone): of a student whose rows one cannot write, each row at fault (the one it cannot
    write beside the others' :func:`unwritable` rows) replaced by its unwritable row, or, should the writers
    still refuse them, all of the student's by rows of who and what alone.  And a line per row replaced
    (``student/task: file: error``), for the teaching assistant."""
    out: list[ReportRow] = []
    faults: list[str] = []
    for student in dict.fromkeys(r["student"] for r in rows):
        out += _mended([r for r in rows if r["student"] == student], writers, columns, faults)
    return out, faults


def _mended(
    mine: list[ReportRow], writers: dict[str, Writer], columns: list[str], faults: list[str]
) -> list[ReportRow]:
    """One student's rows as :func:`isolated` writes them."""
    fault = _first_fault(mine, writers)
    if fault is None:
        return mine
    plain = [unwritable(r, columns, *fault) for r in mine]
    out, lines = [], []
    for k, row in enumerate(mine):
        own = _first_fault([*plain[:k], row, *plain[k + 1 :]], writers)
        out.append(row if own is None else unwritable(row, columns, *own))
        if own is not None:
            lines.append(f"{row['student']}/{row['task']}: {own[0]}: {one_line(own[1])}")
    if not lines or _first_fault(out, writers) is not None:  # (in no row alone, or in their plain rows too)
        out = [unwritable({k: r.get(k) for k in WHO}, columns, *fault) for r in mine]
        lines = [f"{r['student']}/{r['task']}: {fault[0]}: {one_line(fault[1])}" for r in mine]
    faults += lines
    return out


def noted(headline: str, faults: list[str]) -> str:
    """A report's headline, with the grades it could not write whole counted."""
    if not faults:
        return headline
    count, whose = (f"{len(faults)} grades", "their") if len(faults) > 1 else ("1 grade", "its")
    return f"{headline}; {count} could not be written whole (see {whose} reason)"


def _first_fault(rows: list[ReportRow], writers: dict[str, Writer]) -> tuple[str, Exception] | None:
    for name, write in writers.items():
        try:
            write(rows)
        except Exception as exc:  # (a fault of ours in a student's rows: never the class's report)
            return name, exc
    return None


def unwritable(row: ReportRow, columns: list[str], where: str, exc: BaseException) -> ReportRow:
    """A row of plain values in place of one the report could not write (or make) in ``where``: who and
    what, the verdict and score as decided, the thresholds and numbers, the reason it had and what went
    wrong; every other column empty.  A row whose verdict or score is not one (or a pass without its numbers)
    is not scored: invalid, 0."""
    safe: ReportRow = {c: None for c in columns}
    safe.update({k: row[k] if isinstance(row.get(k), str) else "" for k in WHO if k in safe})
    safe.update({k: row[k] for k in NUMBERS if k in safe and _number(row.get(k)) is not None})
    status, points, score = row.get("status"), _number(row.get("points")), _number(row.get("score"))
    decided = status in STATUSES and points is not None and score is not None
    if status == "pass":
        decided = decided and None not in (safe.get("fraction_off_nearby"), safe.get("max_fraction"))
    note = f"phongray could not write this grade whole ({where}: {one_line(exc)})"
    note += "; its verdict and score stand" if decided else "; it is not scored"
    reason = row.get("reason")
    safe.update(
        status=status if decided else "invalid",
        passed={"pass": True, "fail": False}.get(str(status)) if decided else None,
        points=points or 0.0,
        score=score if decided else 0.0,
        mistakes=[],
        reason=f"{reason} ({note})" if isinstance(reason, str) and reason else note,
    )
    return safe


def _number(value: Any) -> float | None:
    """A finite number as a float, else None."""
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None
