"""Grading a whole class: every (student, task) pair, each distinct scene rendered once, and a report.

The folders are described in :mod:`service.submissions`.  A run checks everything of the teaching assistant's
before it grades anyone (:func:`grade_class`): the task scenes and students' own scenes, the tasks file, the
report folder, and the server or cluster the work goes to; any fault there stops the run with
:class:`ClassError`, and no student is marked for it.  Then the references are rendered, and only then is
each submission graded.  References are kept in ``REPORT/references/<scene key>.png`` (the service's
canonical scene hash), so a re-run renders only what it does not have.  Renders and comparisons are tasks
(bytes in, bytes out) run in a pool of processes (every core), on a Dask cluster with ``cluster``, or as
requests to a running service with ``server``: the same tasks, the same pipeline
(:mod:`service.pipeline`), the same report.
"""

from __future__ import annotations

import concurrent.futures as futures
import contextlib
import multiprocessing
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from .diagnosis import headline
from .report import COLUMNS, NUMBERS, STATUSES, summary, write_atomic, write_report
from .settings import Settings
from .submissions import SCENE_IGNORED, Batch, ClassError, Pair, UntrustedFileError, discover, read_untrusted
from .taskfile import TaskSettings, load_tasks

__all__ = ["COLUMNS", "NUMBERS", "SCENE_IGNORED", "STATUSES", "ClassError", "Outcome", "grade_class", "grade_task",
           "render_task"]

# -- the tasks: bytes in, bytes out, so that they run alike in a local pool and on Dask workers ---------------


def render_task(scene: bytes) -> tuple[bytes | None, str]:
    """The reference PNG of a scene's text, or (None, the reason it cannot be rendered)."""
    from schemas import load_scene
    from tracer import ImageTooLarge, encode_png, render

    try:
        return encode_png(render(load_scene(scene), threads=1)), ""
    except ImageTooLarge as exc:
        return None, str(exc)


def grade_task(reference: bytes, image: bytes, tolerance: float, max_fraction: float,
               scene: bytes | None = None) -> dict[str, Any]:
    """The grade of a submission against a reference PNG, with its heat-map PNG under ``"heatmap_png"`` and,
    given the reference's ``scene`` text, the likely mistake of a failing one; or an invalid row whose reason
    lacks only the file's name."""
    from schemas import load_scene

    from . import grading, pipeline

    try:
        graded = pipeline.grade_png(reference, image, tolerance, max_fraction, heatmap="verdict",
                                    scene=None if scene is None else load_scene(scene), threads=1)
    except grading.ImageError as exc:
        return {"status": "invalid", "reason": str(exc)}
    return {**graded.as_dict(), "status": "pass" if graded.grade.passed else "fail", "heatmap_png": graded.heatmap}


def _local_grade(scene: bytes, reference: bytes, image: bytes, tolerance: float, max_fraction: float
                 ) -> dict[str, Any]:
    """:func:`grade_task` with the scene's text first, as the service's grade task takes it (the reference is
    already rendered: the scene is for the diagnosis of a failing pair)."""
    return grade_task(reference, image, tolerance, max_fraction, scene)


def _server_render(server: str, api_key: str | None, scene: bytes) -> tuple[bytes | None, str]:
    """:func:`render_task` by a running service; a refusal of the scene (its limits) is the reason."""
    from .client import ServerError, post_json

    try:
        return _patient(post_json, server, "/render", scene, api_key=api_key), ""
    except ServerError as exc:
        if exc.ta_side or exc.status == 503:
            raise
        return None, f"the server refuses it: {exc.detail}"


def _server_grade(server: str, api_key: str | None, scene: bytes, reference: bytes, image: bytes,
                  tolerance: float, max_fraction: float) -> dict[str, Any]:
    """:func:`grade_task` by a running service (which renders the same reference, from its cache)."""
    import json

    from .client import ServerError, post_form

    fields = {"scene": scene, "tolerance": repr(tolerance), "max_fraction": repr(max_fraction)}
    files = {"image": ("submission.png", image, "image/png")}
    try:
        result = json.loads(_patient(post_form, server, "/grade", fields, files, api_key=api_key))
        query = {"format": "png", "heatmap": "verdict", "legend": "false"}  # as grade_task draws it
        heat = _patient(post_form, server, "/grade", fields, files, query, api_key=api_key)
    except ServerError as exc:
        if exc.status in (413, 422) and exc.part == "image":
            return {"status": "invalid", "reason": exc.detail.removeprefix("image: ")}
        raise
    return {**result, "status": "pass" if result["passed"] else "fail", "heatmap_png": heat}


def _patient(func: Callable[..., bytes], server: str, *args: Any, **kw: Any) -> bytes:
    """A request to the service that waits out its 503s (for at most 10 minutes)."""
    from .client import ServerError

    deadline = time.monotonic() + 600
    while True:
        try:
            return func(server, *args, **kw)
        except ServerError as exc:
            if exc.status != 503 or time.monotonic() > deadline:
                raise
            time.sleep(exc.retry_after if exc.retry_after is not None else 1.0)


# -- the batch ---------------------------------------------------------------------------------------------

@dataclass
class Outcome:
    rows: list[dict[str, Any]]
    ignored: list[tuple[str, str]]
    renders: int  # references rendered by this run (the others were already in the report)
    seconds: float

    def count(self, status: str) -> int:
        return sum(r["status"] == status for r in self.rows)

    def summary(self) -> str:
        return summary(self.rows, self.renders, self.seconds)


def _scene_keys(batch: Batch) -> dict[str, Path]:
    """Validate every scene of the TA's once (the tasks' and the students' own): key → scene file.  An invalid
    one stops the run, every problem named by file and line."""
    from schemas import SceneError

    from .jobs import scene_key
    from .pipeline import load_scene

    keys: dict[Path, str] = {}
    problems: list[str] = []
    for pair in batch.pairs:
        if pair.scene in keys:
            pair.key = keys[pair.scene]
            continue
        try:
            text = pair.scene.read_bytes()
            pair.key = keys[pair.scene] = scene_key(load_scene(str(pair.scene), text))
        except SceneError as exc:
            keys[pair.scene] = ""
            problems.extend(exc.lines)  # type: ignore[attr-defined]
        except OSError as exc:
            keys[pair.scene] = ""
            problems.append(f"{pair.scene}: cannot read: {exc.strerror or exc}")
    if problems:
        raise ClassError("; ".join(problems))
    return {key: scene for scene, key in keys.items()}


def _writable(report: Path) -> None:
    """The report folder can be made and written to (else the run stops before any grading)."""
    try:
        report.mkdir(parents=True, exist_ok=True)
        write_atomic(report / ".phongray-write-check", b"")
        (report / ".phongray-write-check").unlink()
    except OSError as exc:
        raise ClassError(f"{report}: cannot write the report there: {exc.strerror or exc}") from None


@contextlib.contextmanager
def _backend(server: str | None, cluster: str | None, jobs: int | None, work: int, api_key: str | None,
             cluster_wait: float) -> Iterator[tuple[futures.Executor | None, Callable[..., Any], Callable[..., Any]]]:
    """Where the tasks run, checked before any is sent: (an executor, the render task, the grade task)."""
    if server:
        from .client import ServerError, check

        try:
            check(server, api_key)
        except ServerError as exc:
            raise ClassError(f"--server {server}: {exc}") from None
        with futures.ThreadPoolExecutor(max_workers=jobs or 4) as pool:
            yield pool, partial(_server_render, server, api_key), partial(_server_grade, server, api_key)
    elif cluster:
        from .cluster import connect

        with connect(cluster, wait=cluster_wait) as client:
            yield client.get_executor(retries=2), render_task, _local_grade
    elif work:
        workers = max(1, min(jobs or os.cpu_count() or 1, work))
        context = multiprocessing.get_context("spawn")  # no fork of a process that may hold threads
        with futures.ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
            yield pool, render_task, _local_grade
    else:
        yield None, render_task, _local_grade


def grade_class(scenes: Path, submissions: Path, report: Path, tolerance: float = 2.0, max_fraction: float = 0.001,
                jobs: int | None = None, server: str | None = None, cluster: str | None = None,
                progress: Callable[[int, int], None] | None = None, api_key: str | None = None,
                student_scenes: Path | None = None, tasks_file: Path | None = None,
                cluster_wait: float = 30.0) -> Outcome:
    """Grade the class; ``server`` (a URL) or ``cluster`` (a Dask scheduler address) send the work away.
    Raises :class:`ClassError` (or :class:`service.cluster.ClusterError`) for a fault of the TA's."""
    started = time.perf_counter()
    batch = discover(scenes, submissions, student_scenes)
    tasks = load_tasks(tasks_file, batch.tasks)
    scene_of_key = _scene_keys(batch)
    made = not report.exists()
    _writable(report)
    try:
        return _run(batch, tasks, scene_of_key, report, tolerance, max_fraction, jobs, server, cluster, progress,
                    api_key, cluster_wait, started)
    except Exception:
        if made:  # a run stopped by a fault of the TA's leaves no empty report folder behind
            with contextlib.suppress(OSError):
                report.rmdir()
        raise


def _run(batch: Batch, tasks: dict[str, TaskSettings], scene_of_key: dict[str, Path], report: Path,
         tolerance: float, max_fraction: float, jobs: int | None, server: str | None, cluster: str | None,
         progress: Callable[[int, int], None] | None, api_key: str | None, cluster_wait: float,
         started: float) -> Outcome:
    """:func:`grade_class` once the TA's input has been checked: render what is missing, grade, report."""
    for pair in batch.pairs:
        if not pair.row and pair.image is None:
            pair.row = {"status": "missing", "reason": f"no {pair.task}.png"}
    todo = [p for p in batch.pairs if not p.row]
    refs = {k: report / "references" / f"{k}.png" for k in scene_of_key}
    needed = {k: scene_of_key[k] for k, path in refs.items() if not path.exists()}
    total = len(batch.pairs)

    def tick() -> None:
        if progress:
            progress(sum(bool(p.row) for p in batch.pairs), total)

    tick()
    from .client import ServerError

    try:
        with _backend(server, cluster, jobs, len(todo) + len(needed), api_key, cluster_wait) as (pool, render, grade):
            references = _render_all(pool, render, needed, refs)
            _grade_all(pool, grade, todo, references, refs, report, tasks, tolerance, max_fraction, tick)
    except ServerError as exc:  # the service went away, or stopped taking the key, in the middle of the batch
        raise ClassError(f"--server {server}: {exc}") from None
    rows = [_row(p, refs, report, tasks) for p in batch.pairs]
    outcome = Outcome(rows, batch.ignored, len(needed), time.perf_counter() - started)
    write_report(report, rows, batch.ignored, batch.students, tasks, outcome.summary())
    return outcome


def _render_all(pool: futures.Executor | None, render: Callable[..., Any], needed: dict[str, Path],
                refs: dict[str, Path]) -> dict[str, bytes]:
    """Every reference the batch lacks, rendered and kept; one that cannot be rendered stops the run."""
    done: dict[str, bytes] = {}
    if not needed:
        return done
    assert pool is not None
    pending = {pool.submit(render, scene.read_bytes()): key for key, scene in needed.items()}
    failures = []
    for fut in futures.as_completed(pending):
        key = pending[fut]
        png, failure = fut.result()
        if png is None:
            failures.append(f"{needed[key]}: {failure}")
        else:
            write_atomic(refs[key], png)
            done[key] = png
    if failures:
        raise ClassError("; ".join(sorted(failures)))
    return done


def _grade_all(pool: futures.Executor | None, grade: Callable[..., Any], todo: list[Pair],
               references: dict[str, bytes], refs: dict[str, Path], report: Path, tasks: dict[str, TaskSettings],
               tolerance: float, max_fraction: float, tick: Callable[[], None]) -> None:
    """Grade every pair on ``pool``; the submissions are read here (:func:`read_untrusted`), and every file is
    written here, never by the tasks."""
    limit = Settings.from_env().max_image_bytes
    pending: dict[Any, tuple[Pair, bytes]] = {}
    for pair in todo:
        assert pair.key is not None and pair.image is not None and pool is not None
        try:
            image = read_untrusted(pair.image, limit)
        except UntrustedFileError as exc:
            pair.row = {"status": "invalid", "reason": f"{pair.image}: {exc}"}
            continue
        if pair.key not in references:
            references[pair.key] = refs[pair.key].read_bytes()
        own = tasks[pair.task]
        pending[pool.submit(grade, pair.scene.read_bytes(), references[pair.key], image,
                            tolerance if own.tolerance is None else own.tolerance,
                            max_fraction if own.max_fraction is None else own.max_fraction)] = (pair, image)
    for fut in futures.as_completed(pending):
        pair, image = pending[fut]
        _graded(pair, fut.result(), image, report)
        tick()


def _graded(pair: Pair, result: dict[str, Any], image: bytes, report: Path) -> None:
    """Keep a grade task's row; write its heat-map and the copy of the submission."""
    if result["status"] == "invalid":
        pair.row = {"status": "invalid", "reason": f"{pair.image}: {result['reason']}"}
        return
    result = dict(result)  # a cluster gives identical tasks (the same image graded twice) one shared result
    result["likely"] = headline(result.pop("diagnosis", None))
    heat, copy = _paths(pair, report)
    write_atomic(heat, result.pop("heatmap_png"))
    write_atomic(copy, image)
    pair.row = result


def _paths(pair: Pair, report: Path) -> tuple[Path, Path]:
    return (report / "heatmaps" / pair.student / f"{pair.task}.png",
            report / "submissions" / pair.student / f"{pair.task}.png")


def _row(pair: Pair, refs: dict[str, Path], report: Path, tasks: dict[str, TaskSettings]) -> dict[str, Any]:
    row: dict[str, Any] = {c: None for c in COLUMNS}
    row.update({k: v for k, v in pair.row.items() if k in row})
    row.update(student=pair.student, task=pair.task, scene="own" if pair.own else "shared")
    row["reason"] = row["reason"] or ""
    row["points"] = tasks[pair.task].points
    row["score"] = row["points"] if row["status"] == "pass" else 0.0
    row["file"] = pair.file
    ref = refs.get(pair.key or "")
    if ref is not None and ref.exists():
        row["reference"] = str(ref.relative_to(report))
    if row["status"] in ("pass", "fail"):
        heat, copy = _paths(pair, report)
        row["heatmap"], row["submission"] = str(heat.relative_to(report)), str(copy.relative_to(report))
    return row
