"""What the files of a class report say: report.json, report.csv, gradebook.csv (and the LMSs' own,
:mod:`.lmsbook`), index.html and Gradescope's results.json per student (:mod:`.writing` writes them).

Every file is written whole or not at all (:func:`write_atomic`), so an interrupted run leaves the previous
report readable.  A student's name (and a file's) is the students' text: in the CSV files and the HTML its
bidirectional-text controls are shown escaped (``\\u202e``), so that it cannot reorder what is shown around it,
and a CSV cell never begins as a formula.
"""

from __future__ import annotations

import contextlib
import csv
import html
import io
import os
import re
import threading
from collections import Counter
from pathlib import Path
from typing import Any
from urllib.parse import quote

from ..images.figures import counted
from ..images.heatmap import LEGEND
from .feedback import gradescope, test_output  # noqa: F401  (test_output: what a student reads, here too)
from .forms import ReportRow
from .gradebook import late_note, partial, totals

#: the numbers of a graded pair, in report.csv's order
NUMBERS = [
    "mean_abs_error",
    "rmse",
    "psnr",
    "max_error",
    "fraction_off",
    "fraction_off_nearby",
    "width",
    "height",
    "reference_sha256",
]
#: the columns of a program's run (grade-class --run; empty for an image)
PROGRAM_COLUMNS = ["experiment", "run", "run_seconds", "run_output", "flag", "flag_reason"]
#: the columns of report.csv (and the keys of each row of report.json), in order
COLUMNS = [
    "student",
    "lms_id",
    "lms",
    "task",
    "status",
    "reason",
    "likely",
    "mistakes",
    "scene",
    "file",
    "passed",
    "points",
    "score",
    "deducted",
    "late",
    "late_deducted",
    "tolerance",
    "max_fraction",
    *NUMBERS,
    "reference",
    "submission",
    "heatmap",
    *PROGRAM_COLUMNS,
]
STATUSES = ("pass", "fail", "missing", "invalid")


def write_atomic(path: Path, data: bytes) -> None:
    """Write a file whole or not at all: a temporary file beside it, then one rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except BaseException as exc:  # a full disk, an interruption: no partial temporary file is left to fill it
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and exc.filename is None:  # (a failed write names no file of its own)
            exc.filename = str(path)
        raise


def _text(text: str) -> bytes:
    """A report file's text as UTF-8; a name that is not valid UTF-8 (a student's folder of stray bytes, kept
    by Python as lone surrogates) is written as its escapes (``\\udcff``), never stopping the report."""
    return text.encode("utf-8", "backslashreplace")


#: what a spreadsheet runs as a formula at the start of a cell (OWASP's list for CSV injection)
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


#: the controls that reorder bidirectional text (embeddings, overrides, isolates, marks)
BIDI = re.compile("[\u061c\u200e\u200f\u202a-\u202e\u2066-\u2069]")


def visible(text: str) -> str:
    """A name with its bidirectional-text controls escaped (``\\u202e``): shown, not obeyed."""
    return BIDI.sub(lambda m: f"\\u{ord(m.group()):04x}", text)


def safe_cell(value: Any) -> Any:
    """A CSV cell of the students' text made safe to open: controls shown (:func:`visible`), no formula
    (:func:`neutral_cell`); a list (the mistakes) as its items, space-separated."""
    if isinstance(value, list):
        value = " ".join(map(str, value))
    return neutral_cell(visible(value)) if isinstance(value, str) else value


def neutral_cell(value: Any) -> Any:
    """A report.csv cell that a spreadsheet shows as text: a string that begins as a formula would gets a
    single quote in front (OWASP's advice); every other value is kept."""
    if isinstance(value, str) and value.startswith(FORMULA_STARTS):
        return "'" + value
    return value


def summary(rows: list[ReportRow], renders: int, seconds: float) -> str:
    """The run in a line: its pairs by status, those flagged for the TA (a program holding phongray's code, or
    rendering the references byte for byte), the references rendered and the time."""
    counts = {s: sum(r["status"] == s for r in rows) for s in STATUSES}
    flagged = sum(bool(r.get("flag")) for r in rows)
    return (
        f"{counted(len(rows), 'pair')}: {counts['pass']} passed, {counts['fail']} failed, {counts['missing']} "
        f"missing, {counts['invalid']} invalid; "
        + (f"{flagged} flagged for review (⚑); " if flagged else "")
        + f"{counted(renders, 'reference')} rendered; {seconds:.1f} s"
    )


#: a task of at least this many students, most of whom share one reason not to pass, is worth a word to the TA
ALIKE_STUDENTS = 3


#: a run's reason when it ran out of memory, and what most of a task's students doing so asks of the TA: a runtime
#: (Node's, Java's) reserves hundreds of MiB of address space just to start
MEMORY_FAILED = "the run failed: memory"
RUNTIME_MEMORY = "is --memory enough for the programs' language to start (Node's and Java's need 1G or more)?"


def alike(rows: list[ReportRow]) -> list[str]:
    """Per task, a warning where more than half its students (at least :data:`ALIKE_STUDENTS`) are not passed for
    one same reason, their file's name aside ("image is 160×120 pixels, the scene is 40×30"; "no spheres.png
    found"; a run that crashed): a task scene of the wrong size, a task named as no student names the file, or a
    run template that cannot work is the TA's to look at, before anyone's grade is taken as it is."""
    out = []
    for task in dict.fromkeys(r["task"] for r in rows):
        mine = [r for r in rows if r["task"] == task]
        reasons = Counter((r["status"], _without_file(r["reason"])) for r in mine if r["status"] != "pass")
        if not reasons or len(mine) < ALIKE_STUDENTS:
            continue
        (status, reason), count = reasons.most_common(1)[0]
        if 2 * count > len(mine) and reason:
            said = {"fail": "failed"}.get(status, status)
            asked = RUNTIME_MEMORY if reason.startswith(MEMORY_FAILED) else "is the task right?"
            out.append(f"{task}: {count} of {len(mine)} students {said} for one reason, {reason!r}: {asked}")
    return out


def report_csv(rows: list[ReportRow]) -> str:
    """``report.csv``: a row per pair, its cells made safe to open (:func:`safe_cell`)."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    # a carriage return in a cell (a student's name can hold one) is quoted only by a writer that quotes all
    quoted = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n", quoting=csv.QUOTE_ALL)
    writer.writeheader()
    for row in rows:
        cells = {k: safe_cell(v) for k, v in row.items()}
        (quoted if any(isinstance(v, str) and "\r" in v for v in cells.values()) else writer).writerow(cells)
    return buf.getvalue()


def likely_by_task(rows: list[ReportRow], tasks: list[str]) -> dict[str, list[tuple[str, int, int]]]:
    """Per task, its failing pairs' likely mistakes, most common first: (mistake, pairs, failing pairs)."""
    out: dict[str, list[tuple[str, int, int]]] = {}
    for task in tasks:
        failing = [r for r in rows if r["task"] == task and r["status"] == "fail"]
        counts: dict[str, int] = {}
        for r in failing:
            said = r["likely"] or _run_failed(r) or "not diagnosed"
            counts[said] = counts.get(said, 0) + 1
        out[task] = [(m, n, len(failing)) for m, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))]
    return out


def _legend() -> str:
    items = "".join(
        f'<li><span class="swatch" style="background: rgb{colour}"></span>{html.escape(text)}</li>'
        for colour, text in LEGEND
    )
    return f'<ul class="legend">{items}</ul>'


def esc(text: str) -> str:
    """The students' text (or ours) for HTML: escaped, its bidirectional-text controls shown (:func:`visible`)."""
    return html.escape(visible(text))


#: a task's likely mistakes shown beneath its column; the others are behind "… and N more"
SHOWN_MISTAKES = 3


def _run_failed(r: ReportRow) -> str:
    """How a program's run ended when it made no image to grade (``run: timeout``), else ''."""
    return f"run: {r['run']}" if r.get("run") not in (None, "ok") else ""


def _cell(r: ReportRow, anchor: str) -> str:
    """A pair's cell of the table: the status and, without the file it names, the reason (or the error), whole:
    a long text wraps within the cell's width (``overflow-wrap``), never cut."""
    if r["status"] == "pass":
        note = _percent(r["fraction_off_nearby"])
    elif r["status"] == "fail":  # the likely mistake, when one was named, or how a program's run ended
        note = esc(r.get("likely") or _run_failed(r)) or _percent(r["fraction_off_nearby"])
        note += f" · {r['score']:g}/{r['points']:g}" if r.get("deducted") else ""
    else:
        note = esc(_without_file(r["reason"]))
    own = ' <span class="own" title="the student\'s own scene">●</span>' if r["scene"] == "own" else ""
    own += f' <span class="flag" title="{esc(r["flag_reason"] or "")}">⚑</span>' if r.get("flag") else ""
    lost = f" −{r['late_deducted']:g}" if r.get("late_deducted") else ""  # (what the late policy took)
    late = f' <span class="late">late{lost}</span>' if r.get("late") else ""
    status = esc(r["status"])
    kind = f"{status} partial" if r.get("deducted") else status
    return f'<td class="{kind}"><a href="#{anchor}">{status}{own}{late}<small>{note}</small></a></td>'


def _detail(r: ReportRow, anchor: str) -> str:
    """A pair's detail: the reason, the likely mistake (and a program's probes' findings), the score's
    deduction, the end of a program's output, the three images, the numbers."""
    images = "".join(
        f'<figure><img src="{_url(r[k])}" alt="{k}"><figcaption>{k}</figcaption></figure>'
        if r[k]
        else f"<figure><div class=none>no {k}</div><figcaption>{k}</figcaption></figure>"
        for k in ("reference", "submission", "heatmap")
    )
    legend = _legend() if r["heatmap"] else ""
    numbers = "".join(f"<tr><td>{k}</td><td>{esc(str(r[k]))}</td></tr>" for k in NUMBERS if r[k] is not None)
    likely = f'<p class="likely">Likely: {esc(r["likely"])}</p>' if r.get("likely") else ""
    found = r.get("experiment")
    probes = f"<p>By experiment: {esc(found)}</p>" if found and found != r.get("likely") else ""
    output = f"<pre>{esc(r['run_output'])}</pre>" if r.get("run_output") else ""  # (the TA's page only)
    credit = f"<p>{esc(partial(r))}</p>" if r.get("deducted") else ""
    credit += f'<p class="likely">⚑ {esc(r["flag"])}: {esc(r["flag_reason"] or "")}</p>' if r.get("flag") else ""
    credit += f'<p class="late">{esc(late_note(r))}</p>' if r.get("late") else ""
    return (
        f'<section class="pair" id="{anchor}"><h2>{esc(r["student"])} · {esc(r["task"])}: {esc(r["status"])}'
        f'</h2><p>{esc(r["reason"])}</p>{likely}{probes}{credit}{output}<div class="images">{images}</div>'
        f'{legend}<table class="numbers">{numbers}</table>'
        f'<p><a href="#">close</a> (or the browser\'s back)</p></section>'
    )


def _mistakes(rows: list[ReportRow], tasks: list[str]) -> tuple[str, str]:
    """The table's row of each task's likely mistakes (the first :data:`SHOWN_MISTAKES`, then "… and N more"
    linking to the full list), and the full lists."""
    cells, lists = [], []
    for task, found in likely_by_task(rows, tasks).items():
        items = [f"<li>{n} of {failing}: {esc(m)}</li>" for m, n, failing in found]
        more = len(items) - SHOWN_MISTAKES
        link = f'<li><a href="#likely-{_url(task)}">… and {more} more</a></li>' if more > 0 else ""
        cells.append(
            f'<td><ul class="likely">{"".join(items[:SHOWN_MISTAKES])}{link}</ul></td>' if items else "<td></td>"
        )
        if items:
            lists.append(f'<h3 id="likely-{_url(task)}">{esc(task)}</h3><ul>{"".join(items)}</ul>')
    return "".join(cells), "".join(lists) or "<p>none</p>"


def render_html(
    rows: list[ReportRow], ignored: list[tuple[str, str]], students: list[str], tasks: list[str], headline: str
) -> str:
    by = {(r["student"], r["task"]): r for r in rows}
    head = "".join(f"<th>{esc(t)}</th>" for t in tasks) + "<th>total</th>"
    body, details = [], []
    for total in totals(rows, students):
        cells = []
        for task in tasks:
            anchor = f"p-{_url(total.student)}/{_url(task)}"  # (a "/" is in no name: no two pairs share one)
            cells.append(_cell(by[(total.student, task)], anchor))
            details.append(_detail(by[(total.student, task)], anchor))
        cells.append(f'<td class="total">{total.total:g} / {total.out_of:g}</td>')
        late = f' <span class="late">late: {esc(", ".join(total.late))}</span>' if total.late else ""
        body.append(f"<tr><th>{esc(total.student)}{late}</th>{''.join(cells)}</tr>")
    rates = []
    for task in tasks:
        mine = [by[(s, task)] for s in students]
        passed = sum(r["status"] == "pass" for r in mine)
        rates.append(f"<td>{passed}/{len(mine)}<small>{_percent(passed / len(mine) if mine else None)}</small></td>")
    common, every = _mistakes(rows, tasks)
    skipped = "".join(f"<li>{esc(name)}: {esc(why)}</li>" for name, why in ignored) or "<li>none</li>"
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>phongray class report</title>
<style>
body {{ font: 14px/1.4 system-ui, sans-serif; margin: 1.5em; color: #222; }}
table.grid {{ border-collapse: collapse; }}
.grid th, .grid td {{ border: 1px solid #ccc; padding: 4px 8px; text-align: center; }}
.grid td a {{ color: inherit; text-decoration: none; display: block; }}
.grid small {{ display: block; font-size: 11px; color: #555; max-width: 14em; overflow-wrap: anywhere; }}
td.pass {{ background: #d8f5d8; }} td.fail {{ background: #f8d4d4; }}
td.missing {{ background: #eee; color: #777; }} td.invalid {{ background: #fbe7c2; }}
td.partial {{ background: #fbe3cf; }} td.total {{ font-weight: bold; white-space: nowrap; }}
.own {{ color: #36c; }} .flag {{ color: #c60; }} .late {{ color: #a33f00; font-size: 11px; font-weight: bold; }}
.pair {{ display: none; }}
.pair:target {{ display: block; position: fixed; top: 4%; left: 4%; right: 4%; max-height: 88%; overflow: auto;
               border: 1px solid #888; padding: 0 1.5em 1em; background: #fff; box-shadow: 0 4px 30px #0006; }}
.images {{ display: flex; gap: 1em; flex-wrap: wrap; }}
figure {{ margin: 0; }} figure img {{ width: 320px; image-rendering: pixelated; border: 1px solid #999; }}
.none {{ width: 320px; height: 240px; display: flex; align-items: center; justify-content: center;
         border: 1px dashed #999; color: #777; }}
.legend {{ list-style: none; padding: 0; display: flex; flex-wrap: wrap; gap: 0.3em 1.5em; font-size: 12px; }}
.swatch {{ display: inline-block; width: 12px; height: 12px; border: 1px solid #000; margin-right: 6px;
           vertical-align: -2px; }}
.numbers td {{ padding: 1px 10px 1px 0; }}
ul.likely {{ margin: 0; padding-left: 1.1em; text-align: left; font-size: 12px; max-width: 16em; }}
p.likely {{ background: #fff7e0; border-left: 4px solid #d89b00; padding: 4px 10px; font-weight: bold; }}
</style></head><body>
<h1>phongray class report</h1>
<p>{esc(headline)}. Click a cell for the reference, the submission and the heat-map side by side;
● marks a student's own scene.</p>
<table class="grid"><thead><tr><th>student</th>{head}</tr></thead>
<tbody>{"".join(body)}</tbody>
<tfoot><tr><th>passed</th>{"".join(rates)}<td></td></tr>
<tr><th>likely mistakes<small>of the failing pairs</small></th>{common}<td></td></tr></tfoot></table>
{"".join(details)}
<h2>Likely mistakes of each task</h2>{every}
<h2>Ignored files</h2><ul>{skipped}</ul>
</body></html>
"""


#: the file a reason begins with (``subs/frank/mirror.jpg: ``), left out of a cell (its detail shows it whole)
_FILE = re.compile(r"^.*?\.[A-Za-z0-9]{2,5}: ")


def _url(text: str) -> str:
    """Percent-encoded, a name of stray bytes (lone surrogates) by its own bytes."""
    return quote(text, errors="surrogateescape")


def _without_file(reason: str) -> str:
    return _FILE.sub("", reason, count=1)


def _percent(x: float | None) -> str:
    return "" if x is None else f"{100 * x:.2f} %"
