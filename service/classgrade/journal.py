"""The resume journal of a class run: each finished grade, kept as ``REPORT/resume/<student>/<task>.json`` so
that a run stopped by a fault resumes where it stopped.

A journal is the file of an earlier run, which anyone who could write to the report folder may have changed:
it is read as an untrusted file (:func:`~service.course.untrusted.read_untrusted`: never through a link, a FIFO
never opened, at most :data:`LIMIT` bytes), and its row is taken only when its stamp is this run's (the same
reference, submitted bytes and thresholds, written by this version of phongray in this format) and the row
is one this version writes (:func:`valid_row`: the keys, their types, a status of the known set).  Anything
else is graded again, never a traceback.
"""

from __future__ import annotations

import json
import math
from functools import cache
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as of
from pathlib import Path
from typing import Any

from tracer.scene.variants import VARIANTS

from ..course.untrusted import UntrustedFileError, read_untrusted
from .forms import ReportRow, Stamp
from .records import RunInfo
from .report import write_atomic

#: the folder of a report where each finished grade is kept
RESUME = "resume"
#: the journal's format: a journal of another format is graded again
FORMAT = 2
#: the most bytes of a journal read (a row is a few hundred)
LIMIT = 1 << 16
#: the statuses a journal's row may have (a missing pair is never graded, so never kept)
KEPT = ("pass", "fail", "invalid")
#: the numbers of a graded row, by type
FLOATS = ("tolerance", "max_fraction", "mean_abs_error", "rmse", "fraction_off", "fraction_off_nearby")
INTS = ("max_error", "width", "height")
TEXTS = ("reason", "likely", "reference_sha256")
GRADED = {"status", "passed", "psnr", "mistakes", *FLOATS, *INTS, *TEXTS}


@cache
def version() -> str:
    """This phongray's version (a journal of another is graded again)."""
    try:
        return of("phongray")
    except PackageNotFoundError:
        return "unknown"


def stamp(reference: str, image_sha256: str, tolerance: float, max_fraction: float) -> Stamp:
    """What a kept grade is the grade of: the reference's key, the submitted bytes' hash and the thresholds,
    with the version and format that kept it."""
    return {
        "phongray": version(),
        "format": FORMAT,
        "reference": reference,
        "image_sha256": image_sha256,
        "tolerance": tolerance,
        "max_fraction": max_fraction,
    }


def path(report: Path, student: str, task: str) -> Path:
    return report / RESUME / student / f"{task}.json"


def keep(file: Path, mark: Stamp, row: ReportRow) -> None:
    write_atomic(file, (json.dumps({"stamp": mark, "row": row}) + "\n").encode())


def kept(file: Path, mark: Stamp) -> ReportRow | None:
    """The row kept in ``file`` for the grade ``mark`` stamps, or None (none, another's, or not one this
    version writes)."""
    try:
        data = json.loads(read_untrusted(file, LIMIT))
    except (UntrustedFileError, ValueError, RecursionError):
        return None
    if not isinstance(data, dict) or data.get("stamp") != mark:
        return None
    row = data.get("row")
    return row if valid_row(row) else None


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


#: the keys a program's run adds to its row (:class:`~.records.RunInfo`; ``run_busy`` is said, never kept)
RUN_KEYS = frozenset(RunInfo.__dataclass_fields__) - {"run_busy"}


def _scalar(value: Any) -> bool:
    return value is None or isinstance(value, str | bool) or _number(value)


def valid_row(row: Any) -> bool:
    """A row as a grade of this version keeps it: ``{"status": "invalid", "reason": text}`` (with a program's
    run, its plain values), or a graded one
    with every number of its type, ``passed`` agreeing with its status, and known mistake ids (``a+b`` for
    mistakes made together; a key of its own, such as a newer grade may give, only as a plain value); or a
    program's failed run: a failing row of plain values and no numbers."""
    if not isinstance(row, dict) or row.get("status") not in KEPT:
        return False
    if row["status"] == "invalid":  # (a program's image that is none keeps its run's plain values beside)
        return (
            {"status", "reason"} <= set(row) <= {"status", "reason", *RUN_KEYS}
            and isinstance(row["reason"], str)
            and all(_scalar(row[k]) for k in row)
        )
    if row.get("run") not in (None, "ok"):  # a program's run that failed: its reason and the run's end, no numbers
        return (
            row["status"] == "fail"
            and row.get("passed") is False
            and isinstance(row.get("reason"), str)
            and row.get("mistakes") == []
            and all(_scalar(row[k]) for k in set(row) - {"mistakes"})
        )
    return (
        GRADED <= set(row)
        and all(_scalar(row[k]) for k in set(row) - GRADED)
        and row["passed"] is (row["status"] == "pass")
        and all(_number(row[k]) for k in FLOATS)
        and all(isinstance(row[k], int) and not isinstance(row[k], bool) for k in INTS)
        and all(isinstance(row[k], str) for k in TEXTS)
        and (row["psnr"] is None or _number(row["psnr"]))
        and isinstance(row["mistakes"], list)
        and all(isinstance(m, str) and all(part in VARIANTS for part in m.split("+")) for m in row["mistakes"])
    )
