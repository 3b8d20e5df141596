"""Grading a whole class: every (student, task) pair, each distinct scene rendered once, and a report.

Layout: ``SCENES/<task>.json`` are the tasks; ``SUBMISSIONS/<student>/<task>.png`` the images, and a
``SUBMISSIONS/<student>/<task>.json`` is that student's own scene for that task.  References are kept
in ``REPORT/references/<scene key>.png`` (the service's canonical scene hash), so a re-run renders only
what it does not have.  Renders and comparisons are tasks (bytes in, bytes out) run in a pool of
processes (every core), on a Dask cluster with ``cluster``, or as requests to a running service with
``server``.  Every file of the report is written here, whole or not at all.
"""

from __future__ import annotations

import concurrent.futures as futures
import csv
import html
import io
import json
import multiprocessing
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import quote

#: the columns of report.csv (and the keys of each row of report.json), in order
NUMBERS = ["mean_abs_error", "rmse", "psnr", "max_error", "fraction_off", "fraction_off_nearby", "width", "height",
           "reference_sha256"]
COLUMNS = ["student", "task", "status", "reason", "scene", "passed", "tolerance", "max_fraction", *NUMBERS,
           "reference", "submission", "heatmap"]
STATUSES = ("pass", "fail", "missing", "invalid")


class ClassError(Exception):
    """Input the batch cannot use at all (no scenes, an unreadable directory)."""


@dataclass
class Pair:
    student: str
    task: str
    image: Path | None  # None: missing
    scene: Path  # the student's own scene, or the task's
    own: bool
    key: str | None = None  # the canonical scene hash, once the scene is valid
    row: dict[str, Any] = field(default_factory=dict)


@dataclass
class Batch:
    tasks: dict[str, Path]
    students: list[str]
    pairs: list[Pair]
    ignored: list[str]


def discover(scenes: Path, submissions: Path) -> Batch:
    try:
        scene_files = sorted(p for p in scenes.iterdir() if p.is_file())
        student_dirs = sorted(p for p in submissions.iterdir() if p.is_dir())
        loose = sorted(p for p in submissions.iterdir() if not p.is_dir())
    except OSError as exc:
        raise ClassError(f"{exc.filename}: cannot read: {exc.strerror or exc}") from None
    tasks = {p.stem: p for p in scene_files if p.suffix == ".json"}
    if not tasks:
        raise ClassError(f"{scenes}: no task scenes (<task>.json)")
    ignored = [str(p.relative_to(scenes.parent)) for p in scene_files if p.suffix != ".json"]
    ignored += [str(p.relative_to(submissions.parent)) for p in loose]
    pairs = []
    for folder in student_dirs:
        try:
            files = {p.name: p for p in folder.iterdir()}
        except OSError as exc:
            raise ClassError(f"{folder}: cannot read: {exc.strerror or exc}") from None
        for task, shared in tasks.items():
            own = files.get(f"{task}.json")
            pairs.append(Pair(folder.name, task, files.get(f"{task}.png"), own or shared, own is not None))
        known = {f"{t}.{ext}" for t in tasks for ext in ("png", "json")}
        ignored += [str(p.relative_to(submissions.parent)) for name, p in sorted(files.items()) if name not in known]
    return Batch(tasks, [p.name for p in student_dirs], pairs, ignored)


# -- the tasks: bytes in, bytes out, so that they run alike in a local pool and on Dask workers ---------------

def render_task(scene: bytes) -> tuple[bytes | None, str]:
    """The reference PNG of a scene's text, or (None, the reason it cannot be rendered)."""
    from schemas import load_scene
    from tracer import ImageTooLarge, encode_png, render

    try:
        return encode_png(render(load_scene(scene), threads=1)), ""
    except ImageTooLarge as exc:
        return None, str(exc)


def grade_task(reference: bytes, image: bytes, tolerance: float, max_fraction: float) -> dict[str, Any]:
    """The grade of a submission against a reference PNG, with its heat-map PNG under ``"heatmap_png"``; or an
    invalid row whose reason lacks only the file's name."""
    import hashlib

    from tracer import decode_png

    from . import grading

    pixels = decode_png(reference)
    try:
        submitted = grading.read_submission(image, (pixels.shape[1], pixels.shape[0]))
    except grading.ImageError as exc:
        return {"status": "invalid", "reason": str(exc)}
    result = grading.grade(pixels, submitted, hashlib.sha256(reference).hexdigest(), tolerance, max_fraction)
    return {**result.as_dict(), "status": "pass" if result.passed else "fail", "reason": "",
            "heatmap_png": grading.heatmap(pixels, submitted)}


def write_atomic(path: Path, data: bytes) -> None:
    """Write a file whole or not at all: a temporary file beside it, then one rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


# -- the batch ---------------------------------------------------------------------------------------------

@dataclass
class Outcome:
    rows: list[dict[str, Any]]
    ignored: list[str]
    renders: int  # references rendered by this run (the others were already in the report)
    seconds: float

    def count(self, status: str) -> int:
        return sum(r["status"] == status for r in self.rows)

    def summary(self) -> str:
        return (f"{len(self.rows)} pairs: {self.count('pass')} passed, {self.count('fail')} failed, "
                f"{self.count('missing')} missing, {self.count('invalid')} invalid; {self.renders} references "
                f"rendered; {self.seconds:.1f} s")


def _keys(batch: Batch) -> dict[str, str]:
    """Validate every scene once: scene file → canonical key; the pairs of invalid scenes become invalid rows."""
    from schemas import SceneError, load_scene
    from schemas.locate import as_lines

    from .jobs import scene_key

    keys: dict[str, str] = {}
    reasons: dict[str, str] = {}
    for pair in batch.pairs:
        name = str(pair.scene)
        if name not in keys and name not in reasons:
            try:
                text = pair.scene.read_bytes()
                keys[name] = scene_key(load_scene(text))
            except SceneError as exc:
                reasons[name] = "; ".join(as_lines(name, exc.problems, text))
            except OSError as exc:
                reasons[name] = f"{name}: cannot read: {exc.strerror or exc}"
        if name in reasons:
            pair.row = {"status": "invalid", "reason": reasons[name]}
        else:
            pair.key = keys[name]
        if pair.image is None and pair.row.get("status") != "invalid":
            pair.row = {"status": "missing", "reason": f"no {pair.task}.png"}
    return {k: name for name, k in keys.items()}


def grade_class(scenes: Path, submissions: Path, report: Path, tolerance: float = 2.0, max_fraction: float = 0.001,
                jobs: int | None = None, server: str | None = None, cluster: str | None = None,
                progress: Callable[[int, int], None] | None = None, api_key: str | None = None) -> Outcome:
    """Grade the class; ``server`` (a URL) or ``cluster`` (a Dask scheduler address) send the work away."""
    started = time.perf_counter()
    batch = discover(scenes, submissions)
    scene_of_key = _keys(batch)
    todo = [p for p in batch.pairs if not p.row]
    refs = {k: report / "references" / f"{k}.png" for k in scene_of_key}
    needed = {k: Path(scene_of_key[k]) for k, path in refs.items() if not path.exists()}
    done = len(batch.pairs) - len(todo)
    total = len(batch.pairs)
    if progress:
        progress(done, total)
    def tick() -> None:
        if progress:
            progress(sum(bool(p.row) for p in batch.pairs), total)

    if server:
        renders = _on_server(server, todo, needed, refs, report, tolerance, max_fraction, jobs or 4, tick, api_key)
    elif cluster:
        from .cluster import connect

        with connect(cluster) as client:
            renders = _in_pool(client.get_executor(retries=2), todo, needed, refs, report, tolerance,
                               max_fraction, tick)
    elif todo or needed:
        workers = max(1, min(jobs or os.cpu_count() or 1, len(todo) + len(needed)))
        context = multiprocessing.get_context("spawn")  # no fork of a process that may hold threads
        with futures.ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
            renders = _in_pool(pool, todo, needed, refs, report, tolerance, max_fraction, tick)
    else:
        renders = 0
    rows = [_row(p, refs, report) for p in batch.pairs]
    outcome = Outcome(rows, batch.ignored, renders, time.perf_counter() - started)
    write_report(report, outcome, batch)
    return outcome


def _paths(pair: Pair, report: Path) -> tuple[Path, Path]:
    return report / "heatmaps" / pair.student / f"{pair.task}.png", report / "submissions" / pair.student / f"{pair.task}.png"


def _in_pool(pool: futures.Executor, todo: list[Pair], needed: dict[str, Path], refs: dict[str, Path],
             report: Path, tolerance: float, max_fraction: float, tick: Callable[[], Any]) -> int:
    """Render what is missing, then grade, on ``pool`` (processes here, or Dask workers); a pair is graded as soon
    as its reference is in.  Files are written here, never by the tasks."""
    waiting: dict[str, list[Pair]] = {}
    for pair in todo:
        waiting.setdefault(pair.key or "", []).append(pair)
    pending: dict[Any, tuple[str, Any]] = {}
    references: dict[str, bytes] = {}

    def grade(pairs: list[Pair]) -> None:
        for pair in pairs:
            assert pair.image is not None and pair.key is not None
            if pair.key not in references:
                references[pair.key] = refs[pair.key].read_bytes()
            fut = pool.submit(grade_task, references[pair.key], pair.image.read_bytes(), tolerance, max_fraction)
            pending[fut] = ("grade", pair)

    for key, scene in needed.items():
        pending[pool.submit(render_task, scene.read_bytes())] = ("render", key)
    for key, pairs in waiting.items():
        if key not in needed:
            grade(pairs)
    while pending:
        finished, _ = futures.wait(list(pending), return_when=futures.FIRST_COMPLETED)
        for fut in finished:
            kind, what = pending.pop(fut)
            if kind == "render":
                png, failure = fut.result()
                if png is None:
                    for pair in waiting.get(what, []):
                        pair.row = {"status": "invalid", "reason": f"{needed[what]}: {failure}"}
                else:
                    write_atomic(refs[what], png)
                    references[what] = png
                    grade(waiting.get(what, []))
            else:
                _graded(what, fut.result(), report)
        tick()
    return len(needed)


def _graded(pair: Pair, result: dict[str, Any], report: Path) -> None:
    """Keep a grade task's row; write its heat-map and the copy of the submission."""
    if result["status"] == "invalid":
        pair.row = {"status": "invalid", "reason": f"{pair.image}: {result['reason']}"}
        return
    result = dict(result)  # a cluster gives identical tasks (the same image graded twice) one shared result
    heat, copy = _paths(pair, report)
    write_atomic(heat, result.pop("heatmap_png"))
    assert pair.image is not None
    write_atomic(copy, pair.image.read_bytes())
    pair.row = result


def _on_server(server: str, todo: list[Pair], needed: dict[str, Path], refs: dict[str, Path], report: Path,
               tolerance: float, max_fraction: float, jobs: int, tick: Callable[[], Any],
               api_key: str | None = None) -> int:
    """The same work as requests to a running service: at most ``jobs`` at once, waiting out its 503s."""
    from .client import ServerError, post_form, post_json

    def call(func: Callable[..., bytes], *args: Any, **kw: Any) -> bytes:
        deadline = time.monotonic() + 600
        while True:
            try:
                return func(server, *args, api_key=api_key, **kw)
            except ServerError as exc:
                if exc.status != 503 or time.monotonic() > deadline:
                    raise
                time.sleep(exc.retry_after if exc.retry_after is not None else 1.0)

    failed: dict[str, str] = {}

    def render(key: str) -> None:
        try:
            write_atomic(refs[key], call(post_json, "/render", needed[key].read_bytes()))
        except ServerError as exc:
            if exc.status == 0:
                raise
            failed[key] = f"{needed[key]}: {exc.detail}"

    def grade(pair: Pair) -> None:
        if pair.key in failed:
            pair.row = {"status": "invalid", "reason": failed[pair.key or ""]}
            return
        assert pair.image is not None
        fields = {"scene": pair.scene.read_bytes(), "tolerance": str(tolerance), "max_fraction": str(max_fraction)}
        files = {"image": (f"{pair.task}.png", pair.image.read_bytes(), "image/png")}
        try:
            result = json.loads(call(post_form, "/grade", fields, files))
            heat = call(post_form, "/grade", fields, files, {"format": "png"})
        except ServerError as exc:
            if exc.status == 0:
                raise
            text = exc.detail
            where = pair.image if text.startswith("image: ") else pair.scene
            pair.row = {"status": "invalid", "reason": f"{where}: {text.removeprefix('image: ')}"}
            return
        _graded(pair, {**result, "status": "pass" if result["passed"] else "fail", "reason": "", "heatmap_png": heat},
                report)

    with futures.ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        for fut in futures.as_completed([pool.submit(render, k) for k in needed]):
            fut.result()
        for fut in futures.as_completed([pool.submit(grade, p) for p in todo]):
            fut.result()
            tick()
    return len(needed)


def _row(pair: Pair, refs: dict[str, Path], report: Path) -> dict[str, Any]:
    row = {c: None for c in COLUMNS}
    row.update({k: v for k, v in pair.row.items() if k in row})
    row.update(student=pair.student, task=pair.task, scene="own" if pair.own else "shared")
    row["reason"] = row["reason"] or ""
    ref = refs.get(pair.key or "")
    if ref is not None and ref.exists():
        row["reference"] = str(ref.relative_to(report))
    if row["status"] in ("pass", "fail"):
        heat, copy = _paths(pair, report)
        row["heatmap"], row["submission"] = str(heat.relative_to(report)), str(copy.relative_to(report))
    return row


# -- the report ----------------------------------------------------------------------------------------------

def write_report(report: Path, outcome: Outcome, batch: Batch) -> None:
    rows = outcome.rows
    write_atomic(report / "report.json", (json.dumps(rows, indent=1, ensure_ascii=False) + "\n").encode())
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(report / "report.csv", buf.getvalue().encode())
    write_atomic(report / "index.html", render_html(outcome, batch).encode())


def _percent(x: float | None) -> str:
    return "" if x is None else f"{100 * x:.2f} %"


def render_html(outcome: Outcome, batch: Batch) -> str:
    esc = html.escape
    by = {(r["student"], r["task"]): r for r in outcome.rows}
    tasks = list(batch.tasks)
    head = "".join(f"<th>{esc(t)}</th>" for t in tasks)
    body, details = [], []
    for student in batch.students:
        cells = []
        for task in tasks:
            r = by[(student, task)]
            anchor = f"p-{quote(student)}-{quote(task)}"
            label = {"pass": "pass", "fail": "fail", "missing": "missing", "invalid": "invalid"}[r["status"]]
            # the cell shows the reason without the file it names (the detail shows it whole)
            note = (_percent(r["fraction_off_nearby"]) if r["status"] in ("pass", "fail")
                    else esc(r["reason"].rsplit(".png: ", 1)[-1].rsplit(".json: ", 1)[-1])[:80])
            own = ' <span class="own" title="the student\'s own scene">●</span>' if r["scene"] == "own" else ""
            cells.append(f'<td class="{r["status"]}"><a href="#{anchor}">{label}{own}<small>{note}</small></a></td>')
            images = "".join(
                f'<figure><img src="{quote(r[k])}" alt="{k}"><figcaption>{k}</figcaption></figure>'
                if r[k] else f"<figure><div class=none>no {k}</div><figcaption>{k}</figcaption></figure>"
                for k in ("reference", "submission", "heatmap"))
            numbers = "".join(f"<tr><td>{k}</td><td>{esc(str(r[k]))}</td></tr>" for k in NUMBERS if r[k] is not None)
            details.append(f'<section class="pair" id="{anchor}"><h2>{esc(student)} · {esc(task)}: {label}</h2>'
                           f'<p>{esc(r["reason"])}</p><div class="images">{images}</div>'
                           f'<table class="numbers">{numbers}</table><p><a href="#">close</a> (or the browser\'s back)</p>'
                           f'</section>')
        body.append(f"<tr><th>{esc(student)}</th>{''.join(cells)}</tr>")
    rates = []
    for task in tasks:
        rows = [by[(s, task)] for s in batch.students]
        passed = sum(r["status"] == "pass" for r in rows)
        rates.append(f"<td>{passed}/{len(rows)}<small>{_percent(passed / len(rows) if rows else None)}</small></td>")
    ignored = "".join(f"<li>{esc(i)}</li>" for i in outcome.ignored) or "<li>none</li>"
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>phongray class report</title>
<style>
body {{ font: 14px/1.4 system-ui, sans-serif; margin: 1.5em; color: #222; }}
table.grid {{ border-collapse: collapse; }}
.grid th, .grid td {{ border: 1px solid #ccc; padding: 4px 8px; text-align: center; }}
.grid td a {{ color: inherit; text-decoration: none; display: block; }}
.grid small {{ display: block; font-size: 11px; color: #555; max-width: 14em; overflow: hidden; }}
td.pass {{ background: #d8f5d8; }} td.fail {{ background: #f8d4d4; }}
td.missing {{ background: #eee; color: #777; }} td.invalid {{ background: #fbe7c2; }}
.own {{ color: #36c; }}
.pair {{ display: none; }}
.pair:target {{ display: block; position: fixed; top: 4%; left: 4%; right: 4%; max-height: 88%; overflow: auto;
               border: 1px solid #888; padding: 0 1.5em 1em; background: #fff; box-shadow: 0 4px 30px #0006; }}
.images {{ display: flex; gap: 1em; flex-wrap: wrap; }}
figure {{ margin: 0; }} figure img {{ width: 320px; image-rendering: pixelated; border: 1px solid #999; }}
.none {{ width: 320px; height: 240px; display: flex; align-items: center; justify-content: center;
         border: 1px dashed #999; color: #777; }}
.numbers td {{ padding: 1px 10px 1px 0; }}
</style></head><body>
<h1>phongray class report</h1>
<p>{esc(outcome.summary())}. Click a cell for the reference, the submission and the heat-map side by side;
● marks a student's own scene.</p>
<table class="grid"><thead><tr><th>student</th>{head}</tr></thead>
<tbody>{''.join(body)}</tbody>
<tfoot><tr><th>passed</th>{''.join(rates)}</tr></tfoot></table>
{''.join(details)}
<h2>Ignored files</h2><ul>{ignored}</ul>
</body></html>
"""
