"""What a student reads of their grade: Gradescope's ``results.json`` (:func:`gradescope`), a test per task, each
test's output as the task's ``show`` (tasks.json) allows (:func:`test_output`).

A program's task is graded on a scene the student has not seen, and a program chooses how its run ends: so a
run that failed is told to a student only as ``timed out`` or ``crashed`` (:func:`service.programs.outcome.told`),
never with its exit status, its signal or its output (the TA's report keeps them).  A task whose visibility is
``hidden`` is never shown; Gradescope still shows a student their total, which holds its score, unless a test is
not yet shown (a ``hidden`` test does not count: Gradescope means it for tests worth no points), so the results
of a student with a hidden task worth points carry one more test, worth nothing, shown once the grades are
published: until then the student sees no total, and so nothing of the hidden task.  A pair flagged for the TA
(:mod:`service.classgrade.copied`) carries its flag in the test's ``extra_data``, which Gradescope keeps and does
not show; a student reads of it only the zero it costs, where the task says so.
"""

from __future__ import annotations

from ..images.figures import percent
from ..programs.outcome import Reason, told
from .forms import ReportRow, Results
from .gradebook import late_note, partial
from .taskfile import TaskSettings

#: the test that keeps a student's total unseen until the grades are published (see the module's docstring)
WITHHELD = {
    "name": "tasks graded later",
    "score": 0.0,
    "max_score": 0.0,
    "status": "passed",
    "output": "Some tasks are graded on scenes you have not seen; your total is shown once the grades are published.",
    "visibility": "after_published",
}


#: what a student reads of a task scored nothing for phongray's own code in the program (tasks.json's
#: ``"phongray_code": "zero"``)
ZEROED = "Scored 0: your program holds phongray's own code, which this course does not accept as your work."


def run_failed(row: ReportRow) -> str:
    """A program's failed run (or build) as a student is told it: ``the run failed: crashed``."""
    what = "build" if row["reason"].startswith("the build failed") else "run"
    try:
        return f"the {what} failed: {told(Reason(row['run']))}"
    except ValueError:
        return f"the {what} failed"


def test_output(row: ReportRow, show: str = "images") -> str:
    """What a student reads of one task, as its ``show`` (tasks.json) allows: the verdict alone
    (``verdict-only``); with its reason or numbers (``verdict``); and the likely mistake, what a program's
    probes found and the partial credit (``diagnosis``, ``images``).  Never a program's output, nor how its
    run ended beyond timed out or crashed."""
    if show == "verdict-only":
        return "passed" if row["status"] == "pass" else ("failed" if row["status"] == "fail" else row["status"])
    if row["status"] == "pass":
        how = f", {row['reason']}" if row.get("reason") else ""  # (as rendered with an accepted variant)
        return (
            f"passed{how}: {percent(row['fraction_off_nearby'])} of the pixels off even nearby "
            f"(at most {percent(row['max_fraction'])} may be)"
        )
    reason = run_failed(row) if row.get("run") not in (None, "ok") else row["reason"]
    if show == "verdict":
        return f"{row['status']}: {reason}"
    likely = f"\nLikely: {row['likely']}" if row.get("likely") else ""
    found = row.get("experiment")
    probes = f"\nBy experiment: {found}" if found and found != row.get("likely") else ""
    credit = f"\n{partial(row)}" if row.get("deducted") else ""
    return f"{row['status']}: {reason}{likely}{probes}{credit}"


def gradescope(rows: list[ReportRow], tasks: dict[str, TaskSettings]) -> Results:
    """One student's results in Gradescope's autograder format (``results.json``): the total ``score`` and a
    test per task with its ``name``, ``score``, ``max_score``, ``status``, ``output`` and ``visibility`` (and
    :data:`WITHHELD` after them, for a hidden task worth points)."""
    tests = [
        {
            "name": r["task"],
            "score": r["score"],
            "max_score": r["points"],
            "status": "passed" if r["status"] == "pass" else "failed",
            "output": test_output(r, tasks[r["task"]].show) + (f"\n{late_note(r)}" if r.get("late") else ""),
            "visibility": tasks[r["task"]].visibility,
        }
        for r in rows
    ]
    for test, r in zip(tests, rows, strict=True):
        if r.get("flag"):  # (the TA's, in Gradescope's stored data; a student reads only a zero it costs)
            test["extra_data"] = {"flag": r["flag"], "flag_reason": r.get("flag_reason")}
            if r["flag"] == "phongray-code" and tasks[r["task"]].phongray_code == "zero":
                test["output"] = f"{test['output']}\n{ZEROED}"
    total = sum(t["score"] for t in tests)
    if any(t["visibility"] == "hidden" and t["max_score"] > 0 for t in tests):
        tests.append(dict(WITHHELD))
    return {"score": total, "visibility": "visible", "tests": tests}


def printed(test: Results) -> str:
    """A test's line in what ``run_autograder`` prints (the instructors' to read): its score, its output's first
    line, and its flag for the TA."""
    flag = (test.get("extra_data") or {}).get("flag_reason")
    line = f"{test['name']}: {test['score']:g}/{test['max_score']:g} {test['output'].splitlines()[0]}"
    return f"{line} [flagged for review: {flag}]" if flag else line
