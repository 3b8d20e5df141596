"""A class report's files written (their contents are :mod:`service.classgrade.report`'s): report.json,
report.csv, gradebook.csv, an LMS's import file, each student's Gradescope results.json and index.html,
every file whole or not at all.

One pair's fault in writing them is that pair's row, never the class's lost report: each pair's row is tried
in every writer first (:mod:`service.classgrade.isolation`).
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .feedback import gradescope
from .forms import ReportRow
from .gradebook import gradebook_csv
from .isolation import isolated, noted
from .lmsbook import lms_books
from .report import COLUMNS, _text, render_html, report_csv, safe_cell, write_atomic
from .taskfile import TaskSettings


def write_report(
    report: Path,
    rows: list[ReportRow],
    ignored: list[tuple[str, str]],
    students: list[str],
    tasks: dict[str, TaskSettings],
    headline: str,
) -> tuple[list[ReportRow], list[str]]:
    """Write the report's files; a pair's row that one of them cannot write is written as its
    :func:`~service.classgrade.isolation.unwritable` row, the rest of the class as it is.  The rows as
    written, and a line per row replaced."""
    rows, faults = isolated(rows, _writers(tasks), COLUMNS)
    write_atomic(report / "report.json", _text(_json(rows)))
    write_atomic(report / "report.csv", _text(report_csv(rows)))
    write_atomic(report / "gradebook.csv", _text(gradebook_csv(rows, students, list(tasks), safe_cell)))
    for name, text in lms_books(rows, students, tasks, safe_cell).items():  # (Canvas's and Moodle's import files)
        if text is not None:
            write_atomic(report / name, _text(text))
        else:  # none for this class: an earlier run's is not imported by mistake
            with contextlib.suppress(OSError):
                (report / name).unlink()
    for student in students:
        mine = [r for r in rows if r["student"] == student]
        write_atomic(report / "gradescope" / student / "results.json", _text(_json(gradescope(mine, tasks))))
    _drop_stale_results(report / "gradescope", set(students))
    page = render_html(rows, ignored, students, list(tasks), noted(headline, faults))
    write_atomic(report / "index.html", _text(page))
    return rows, faults


def _writers(tasks: dict[str, TaskSettings]) -> dict[str, Callable[[list[ReportRow]], object]]:
    """Each file's writer, for one student's rows (:func:`isolated` tries each student's), as it writes the
    class's."""

    def who(rows: list[ReportRow]) -> list[str]:
        return list(dict.fromkeys(r["student"] for r in rows))

    return {
        "report.json": _json,
        "report.csv": report_csv,
        "gradebook.csv": lambda rows: gradebook_csv(rows, who(rows), list(tasks), safe_cell),
        "the LMS's gradebook": lambda rows: lms_books(rows, who(rows), tasks, safe_cell),
        "results.json": lambda rows: _json(gradescope(rows, tasks)),
        "index.html": lambda rows: render_html(rows, [], who(rows), list(tasks), ""),
    }


def _json(value: Any) -> str:
    return json.dumps(value, indent=1, ensure_ascii=False, allow_nan=False) + "\n"


def _drop_stale_results(folder: Path, students: set[str]) -> None:
    """Remove the ``results.json`` an earlier run into this report wrote for a student who is not in this one
    (another class's, or a name since changed), lest it be uploaded with this class's."""
    with contextlib.suppress(OSError), os.scandir(folder) as entries:
        stale = [e.name for e in entries if e.name not in students and e.is_dir(follow_symlinks=False)]
    for name in stale:
        with contextlib.suppress(OSError):
            (folder / name / "results.json").unlink()
            (folder / name).rmdir()
