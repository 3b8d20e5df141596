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

The TA's scenes are trusted: with ``limits`` (``--limits``) every scene is priced with the service's limits
before anything renders, and a render has its ``render_timeout`` and budget.  A fault of where the work runs
(a pool process killed, the Dask scheduler lost, a server connection reset) is retried :data:`RETRIES` times
with backoff; every reference and every grade is kept as it finishes (``REPORT/resume/<student>/<task>.json``
for a grade), so a run stopped by a fault that persists resumes where it stopped.
"""

from __future__ import annotations

import concurrent.futures as futures
import contextlib
import ctypes
import hashlib
import json
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from dataclasses import astuple, dataclass
from functools import partial
from pathlib import Path
from typing import Any

from . import journal
from .diagnosis import Diagnosis, headline
from .gradebook import matched, score
from .report import COLUMNS, NUMBERS, STATUSES, summary, write_atomic, write_report
from .settings import Settings
from .submissions import SCENE_IGNORED, Batch, ClassError, Pair, discover
from .taskfile import TaskSettings, load_tasks

__all__ = ["COLUMNS", "NUMBERS", "SCENE_IGNORED", "STATUSES", "ClassError", "Outcome", "grade_class", "grade_task",
           "render_task"]

# -- the tasks: bytes in, bytes out, so that they run alike in a local pool and on Dask workers ---------------


def render_task(scene: bytes, limits: Settings | None = None) -> tuple[bytes | None, str]:
    """The reference PNG of a scene's text, or (None, the reason it cannot be rendered).  With the service's
    ``limits`` (``grade-class --limits``), a render still going after their ``render_timeout`` or outgrowing
    their budget (:func:`service.limits.budget`) is stopped; without, the TA's scene is trusted."""
    from schemas import load_scene
    from tracer import ImageTooLarge, OverBudget, RenderCancelled, encode_png, render
    from tracer.budget import UNLIMITED

    from .limits import budget, outgrown

    deadline = None if limits is None else time.monotonic() + limits.render_timeout
    loaded = load_scene(scene)
    try:
        return encode_png(render(loaded, threads=1, budget=UNLIMITED if limits is None else budget(loaded, limits),
                                 cancel=None if deadline is None else lambda: time.monotonic() > deadline)), ""
    except ImageTooLarge as exc:
        return None, str(exc)
    except OverBudget as exc:
        assert limits is not None
        return None, str(outgrown(exc, limits))
    except RenderCancelled:
        assert limits is not None
        return None, (f"the render ran past the limit render_timeout = {limits.render_timeout:g} s "
                      f"(PHONGRAY_RENDER_TIMEOUT)")


def grade_task(reference: bytes, image: bytes, tolerance: float, max_fraction: float,
               scene: bytes | None = None, accepted: dict[str, float] | None = None, diagnose: bool = True
               ) -> dict[str, Any]:
    """The grade of a submission against a reference PNG, with its heat-map PNG under ``"heatmap_png"`` and,
    given the reference's ``scene`` text, a failing one graded again against the task's ``accepted`` variants
    (None: the defaults) and, to ``diagnose``, the likely mistake of one that fails them too; or an invalid row
    whose reason lacks only the file's name."""
    from schemas import load_scene

    from . import grading, pipeline

    try:
        graded = pipeline.grade_png(reference, image, tolerance, max_fraction, heatmap="verdict",
                                    explaining=None if scene is None else pipeline.Explaining(
                                        lambda: load_scene(scene), pipeline.Checks(accepted, diagnose),
                                        pipeline.Run(threads=1)))
    except grading.ImageError as exc:
        return {"status": "invalid", "reason": str(exc)}
    return {**graded.as_dict(), "status": "pass" if graded.grade.passed else "fail", "heatmap_png": graded.heatmap}


def _local_grade(scene: bytes, reference: bytes, image: bytes, tolerance: float, max_fraction: float,
                 accepted: dict[str, float] | None = None, diagnose: bool = True) -> dict[str, Any]:
    """:func:`grade_task` with the scene's text first, as the service's grade task takes it (the reference is
    already rendered: the scene is for the accepted variants and, unless not to ``diagnose``, the diagnosis of
    a failing pair)."""
    return grade_task(reference, image, tolerance, max_fraction, scene, accepted, diagnose)


def _server_render(server: str, api_key: str | None, scene: bytes, limits: Settings | None = None
                   ) -> tuple[bytes | None, str]:
    """:func:`render_task` by a running service (which has its own ``render_timeout``); a refusal of the scene
    (its limits, its time) is the reason."""
    from .client import ServerError, post_json

    try:
        return _patient(post_json, server, "/render", scene, api_key=api_key), ""
    except ServerError as exc:
        if _too_slow(exc):
            return None, f"the server stopped it: {exc.detail}"
        if exc.ta_side or exc.status == 503:
            raise
        return None, f"the server refuses it: {exc.detail}"


def _server_grade(server: str, api_key: str | None, scene: bytes, reference: bytes, image: bytes,
                  tolerance: float, max_fraction: float, accepted: dict[str, float] | None = None,
                  diagnose: bool = True) -> dict[str, Any]:
    """:func:`grade_task` by a running service (which renders the same reference, from its cache, and accepts
    its own default variants: a task's ``accepted`` is for local grading)."""

    from .client import ServerError, post_form

    fields = {"scene": scene, "tolerance": repr(tolerance), "max_fraction": repr(max_fraction),
              "diagnose": "true" if diagnose else "false"}
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


#: a fault of the pool, the cluster or the server (a lost connection) is retried this many times ...
RETRIES = 4
#: ... after this many seconds, doubled at each retry (0.5 + 1 + 2 + 4 s: a restarting server worker is back)
BACKOFF = 0.5
#: seconds to reach a lost Dask scheduler again, at each retry
RECONNECT_TIMEOUT = 10.0
#: the longest a request waits out a busy service's 503s (Retry-After), in seconds
BUSY_WAIT = 600.0


def _too_slow(exc: Exception) -> bool:
    """The service's 503 for a render past its ``render_timeout`` (the scene's, not to be waited out)."""
    return getattr(exc, "status", 0) == 503 and "render_timeout" in str(getattr(exc, "detail", ""))


def _patient(func: Callable[..., bytes], server: str, *args: Any, **kw: Any) -> bytes:
    """A request to the service that waits out its 503s (their Retry-After, for at most :data:`BUSY_WAIT`
    seconds) and retries a lost connection (a worker restarting: reset, refused, closed) :data:`RETRIES` times
    with backoff.  Every request of class grading is a pure function of its body, so sending it again is safe."""
    from .client import ServerError

    deadline = time.monotonic() + BUSY_WAIT
    lost = 0
    while True:
        try:
            return func(server, *args, **kw)
        except ServerError as exc:
            if exc.status == 503 and not _too_slow(exc) and time.monotonic() < deadline:
                time.sleep(exc.retry_after if exc.retry_after is not None else 1.0)
            elif exc.lost and lost < RETRIES:
                time.sleep(BACKOFF * 2**lost)
                lost += 1
            else:
                if exc.lost:
                    exc.args = (f"{exc} (after {lost} retries)",)
                raise


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


def _scene_keys(batch: Batch, settings: Settings | None) -> tuple[dict[str, Path], dict[Path, bytes]]:
    """Validate every scene of the TA's once (the tasks' and the students' own), and price it with the service's
    limits ``settings`` when given (``--limits``): key → scene file, and each file's text.  An invalid scene, or
    one the service would refuse up front, stops the run before anything renders, every problem named by file
    (and line)."""
    from schemas import SceneError

    from .limits import LimitError, check_body, check_scene
    from .pipeline import load_scene
    from .scenekey import scene_key

    keys: dict[Path, str] = {}
    texts: dict[Path, bytes] = {}
    problems: list[str] = []
    for pair in batch.pairs:
        if pair.scene in keys:
            pair.key = keys[pair.scene]
            continue
        keys[pair.scene] = ""
        try:
            text = texts[pair.scene] = pair.scene.read_bytes()
            if settings is not None:
                check_body(text, settings)
            scene = load_scene(str(pair.scene), text)
            if settings is not None:
                check_scene(scene, settings)
            pair.key = keys[pair.scene] = scene_key(scene)
        except SceneError as exc:
            problems.extend(exc.lines)  # type: ignore[attr-defined]
        except LimitError as exc:
            problems.append(f"{pair.scene}: {exc} (the service's limit, asked for by --limits)")
        except OSError as exc:
            problems.append(f"{pair.scene}: cannot read: {exc.strerror or exc}")
    if problems:
        raise ClassError("; ".join(problems))
    return {key: scene for scene, key in keys.items()}, texts


#: the folders a report writes into
REPORT_FOLDERS = ("references", "submissions", "heatmaps", "gradescope", journal.RESUME)


def _outside(report: Path, submissions: Path, scenes: Path, student_scenes: Path | None) -> None:
    """The report folder is not inside the submissions folder (its files would be a student's next run), nor
    the submissions folder inside a folder the report writes (its copies would be); nor is it the scenes folder
    (its report.json would be a task) or inside the students' scenes (a student of them)."""
    inside, outer = report.resolve(), submissions.resolve()
    if inside == outer or inside.is_relative_to(outer):
        raise ClassError(f"{report}: the report folder is inside the submissions folder {submissions} (it would "
                         f"be graded as a student's); write it elsewhere")
    if inside == scenes.resolve():
        raise ClassError(f"{report}: the report folder is the scenes folder (its report.json would be read as a "
                         f"task); write it elsewhere")
    if student_scenes is not None and inside.is_relative_to(student_scenes.resolve()):
        raise ClassError(f"{report}: the report folder is inside the --student-scenes folder {student_scenes} "
                         f"(it would be read as a student's scenes); write it elsewhere")
    for name in REPORT_FOLDERS:
        if outer.is_relative_to(inside / name):
            raise ClassError(f"{report}: the report writes its {name}/ folder where the submissions folder "
                             f"{submissions} is (its files would be graded as the students'); write it elsewhere")


def _writable(report: Path) -> None:
    """The report folder can be made and written to (else the run stops before any grading)."""
    try:
        report.mkdir(parents=True, exist_ok=True)
        write_atomic(report / ".phongray-write-check", b"")
        (report / ".phongray-write-check").unlink()
    except OSError as exc:
        raise ClassError(f"{report}: cannot write the report there: {exc.strerror or exc}") from None


def _die_with_parent(parent: int, prctl: bool) -> None:
    """Initializer of a pool process: it ends when grade-class does, however grade-class ends (SIGKILL, the
    OOM killer), never left running.  On Linux the kernel kills it (PR_SET_PDEATHSIG; only when the pool was
    made by the main thread, as the signal comes when the creating thread ends); everywhere, a watchdog thread
    sees the parent gone."""
    if prctl and sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL, 0, 0, 0)  # 1: PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent died before the signal was asked for
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.25)
        os._exit(1)

    threading.Thread(target=watch, name="phongray-parent-watch", daemon=True).start()


class _Backend:
    """Where the tasks run, checked before any is sent: an executor, the render task and the grade task.  After
    a fault of the executor itself (a pool process killed, the Dask scheduler lost) :meth:`reset` makes a new
    one; a server's faults are retried per request (:func:`_patient`)."""

    def __init__(self, server: str | None, cluster: str | None, jobs: int | None, work: int, api_key: str | None,
                 cluster_wait: float, limits: Settings | None):
        self.cluster, self.cluster_wait = cluster, cluster_wait
        self.client: Any = None
        self.workers = max(1, min(jobs or os.cpu_count() or 1, work))
        self.executor: futures.Executor | None = None
        #: what a fault of the executor raises (for a result, or for a submission)
        self.faults: tuple[type[BaseException], ...] = ()
        self.render: Callable[..., Any] = partial(render_task, limits=limits)
        self.grade: Callable[..., Any] = _local_grade
        self.diagnose = True  # whether a failing pair's likely mistake is named (see no_diagnosis)
        if server:
            from .client import ServerError, check

            try:
                check(server, api_key)
            except ServerError as exc:
                raise ClassError(f"--server {server}: {exc}") from None
            self.name = f"--server {server}"
            self.executor = futures.ThreadPoolExecutor(max_workers=jobs or 4)
            self.render = partial(_server_render, server, api_key)
            self.grade = partial(_server_grade, server, api_key)
        elif cluster:
            self.name = f"--cluster {cluster}"
            self.faults = (futures.CancelledError, OSError, TimeoutError)
            self._connect()
        elif work:
            self.name = "the pool of processes"
            self.faults = (BrokenProcessPool,)
            self._pool()

    def no_diagnosis(self) -> None:
        """Grade without naming failing pairs' likely mistakes (--no-diagnosis)."""
        self.grade, self.diagnose = partial(self.grade, diagnose=False), False

    def _pool(self) -> None:
        context = multiprocessing.get_context("spawn")  # no fork of a process that may hold threads
        self.executor = futures.ProcessPoolExecutor(
            max_workers=self.workers, mp_context=context, initializer=_die_with_parent,
            initargs=(os.getpid(), threading.current_thread() is threading.main_thread()))

    def _connect(self, timeout: float = 10.0) -> None:
        """A client of the scheduler (a new one when the old has lost it) with a worker, and its executor."""
        from .cluster import client, connect_timeout, wait_for_workers

        assert self.cluster is not None
        started = time.monotonic()
        if self.client is None or getattr(self.client, "status", "running") != "running":
            self._close_client()
            self.client = client(self.cluster, connect_timeout(timeout, self.cluster_wait))
        wait_for_workers(self.client, self.cluster, self.cluster_wait, time.monotonic() - started)
        self.executor = self.client.get_executor(retries=2)

    def _close_client(self) -> None:
        old, self.client = self.client, None
        if old is not None:
            with contextlib.suppress(Exception):
                old.close(timeout=5)

    def reset(self) -> None:
        """A new executor after a fault of the old one (:class:`ClusterError` if the cluster cannot be had)."""
        if self.executor is not None:
            with contextlib.suppress(Exception):
                self.executor.shutdown(wait=False, cancel_futures=True)
        if self.cluster:
            self._connect(RECONNECT_TIMEOUT)
        else:
            self._pool()

    def close(self, wait: bool = True) -> None:
        """Done with: ``wait`` for what still runs (not after an error or an interruption: a pool process then
        ends with its task, or with grade-class)."""
        if self.executor is not None:
            with contextlib.suppress(Exception):
                self.executor.shutdown(wait=wait, cancel_futures=True)
        self._close_client()


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    if isinstance(exc, BrokenProcessPool):
        return "a pool process died (killed, or out of memory)"
    if isinstance(exc, futures.CancelledError):
        return f"the work was cancelled ({text or 'the scheduler was lost'})"
    from .cluster import ClusterError

    if isinstance(exc, ClusterError) and text:
        return text
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _run_tasks(backend: _Backend, tasks: dict[Any, tuple[Callable[..., Any], tuple[Any, ...]]],
               done: Callable[[Any, Any], None], kept: Callable[[], str]) -> None:
    """Run every task on the backend; ``done(key, result)`` keeps each result as it comes (so that no finished
    work is lost, whatever happens next).  A fault of the executor (``backend.faults``) is retried
    :data:`RETRIES` times with backoff on a new one, with only the unfinished tasks; then the run stops with
    :class:`ClassError` (one line, saying what ``kept()`` kept).  Any other error stops it once every task
    already running has finished and been kept."""
    from .cluster import ClusterError

    pending = dict(tasks)
    attempt = 0
    while pending:
        fault: BaseException | None = None
        fatal: BaseException | None = None
        submitted: dict[Any, Any] = {}
        assert backend.executor is not None
        try:
            for key, (func, args) in pending.items():
                submitted[backend.executor.submit(func, *args)] = key
        except backend.faults as exc:
            fault = exc
        for fut in futures.as_completed(submitted):
            key = submitted[fut]
            try:
                result = fut.result()
            except backend.faults as exc:
                fault = fault or exc
                continue
            except futures.CancelledError:  # cancelled below, after an error
                continue
            except Exception as exc:
                if fatal is None:
                    fatal = exc
                    for other in submitted:
                        other.cancel()
                continue
            done(key, result)
            del pending[key]
        if fatal is not None:
            raise fatal
        while pending and fault is not None:
            if attempt >= RETRIES:
                raise ClassError(f"{backend.name}: {_one_line(fault)} (tried {RETRIES + 1} times); stopped with "
                                 f"{len(pending)} tasks unfinished; {kept()}: run again to resume")
            time.sleep(BACKOFF * 2**attempt)
            attempt += 1
            try:
                backend.reset()
                fault = None
            except Exception as exc:
                if not isinstance(exc, (ClusterError, *backend.faults)):
                    raise
                fault = exc


def grade_class(scenes: Path, submissions: Path, report: Path, tolerance: float = 2.0, max_fraction: float = 0.001,
                jobs: int | None = None, server: str | None = None, cluster: str | None = None,
                progress: Callable[[int, int], None] | None = None, api_key: str | None = None,
                student_scenes: Path | None = None, tasks_file: Path | None = None,
                cluster_wait: float = 30.0, limits: bool = False, diagnose: bool = True
                ) -> Outcome:
    """Grade the class; ``server`` (a URL) or ``cluster`` (a Dask scheduler address) send the work away.  The
    TA's scenes are trusted: held to the service's limits (``PHONGRAY_*``) only with ``limits``.
    Raises :class:`ClassError` (or :class:`service.cluster.ClusterError`) for a fault of the TA's, or for a
    fault of the pool, the cluster or the server that retries did not mend (what was finished is kept)."""
    started = time.perf_counter()
    settings = Settings.from_env()
    _outside(report, submissions, scenes, student_scenes)
    batch = discover(scenes, submissions, student_scenes, settings.max_image_bytes)
    tasks = load_tasks(tasks_file, batch.tasks)
    scene_of_key, texts = _scene_keys(batch, settings if limits else None)
    made = not report.exists()
    _writable(report)
    try:
        return _run(batch, tasks, scene_of_key, texts, report, tolerance, max_fraction, jobs, server, cluster,
                    progress, api_key, cluster_wait, started, settings, limits, diagnose)
    except Exception:
        if made:  # a run stopped by a fault of the TA's leaves no empty report folder behind
            with contextlib.suppress(OSError):
                report.rmdir()
        raise


def _run(batch: Batch, tasks: dict[str, TaskSettings], scene_of_key: dict[str, Path], texts: dict[Path, bytes],
         report: Path, tolerance: float, max_fraction: float, jobs: int | None, server: str | None,
         cluster: str | None, progress: Callable[[int, int], None] | None, api_key: str | None,
         cluster_wait: float, started: float, settings: Settings, limits: bool, diagnose: bool = True
         ) -> Outcome:
    """:func:`grade_class` once the TA's input has been checked: render what is missing, grade, report (the
    renders held to the service's limits ``settings`` with ``limits``)."""
    todo = [p for p in batch.pairs if not p.row]  # (a missing or unreadable pair has its row from discover)
    refs = {k: report / "references" / f"{k}.png" for k in scene_of_key}
    needed = {k: scene_of_key[k] for k, path in refs.items() if not _usable(path)}
    total = len(batch.pairs)

    def tick() -> None:
        if progress:
            progress(sum(bool(p.row) for p in batch.pairs), total)

    tick()
    from .client import ServerError

    backend = _Backend(server, cluster, jobs, len(todo) + len(needed), api_key, cluster_wait,
                       settings if limits else None)
    if not diagnose:
        backend.no_diagnosis()
    try:
        references = _render_all(backend, needed, refs, texts, report)
        _grade_all(backend, todo, references, refs, report, tasks, tolerance, max_fraction, tick, texts)
    except ServerError as exc:  # the service went away, or stopped taking the key, in the middle of the batch
        backend.close(wait=False)
        raise ClassError(f"--server {server}: {' '.join(str(exc).split())}; {_kept(report)}: run again to "
                         f"resume") from None
    except BaseException:
        backend.close(wait=False)
        raise
    backend.close()
    _drop_stale_references(report, refs)
    rows = [_row(p, refs, report, tasks) for p in batch.pairs]
    outcome = Outcome(rows, batch.ignored, len(needed), time.perf_counter() - started)
    write_report(report, rows, batch.ignored, batch.students, tasks, outcome.summary())
    return outcome


def _drop_stale_references(report: Path, refs: dict[str, Path]) -> None:
    """An earlier run's references of scenes that are no longer the batch's (a scene changed, a task gone)
    are removed: the report's references folder holds this batch's and no other."""
    current = set(refs.values())
    with contextlib.suppress(OSError):
        for old in (report / "references").glob("*.png"):
            if old not in current:
                old.unlink()


def _usable(reference: Path) -> bool:
    """A reference an earlier run kept that decodes (one cut short, or a Git LFS pointer where a course's bundle
    was copied from, is rendered again rather than failing every pair of its scene)."""
    from tracer import decode_png

    try:
        decode_png(reference.read_bytes())
    except Exception:  # (Pillow raises many kinds for a broken file; a missing one is OSError)
        return False
    return True


def _kept(report: Path) -> str:
    """What a stopped run leaves for the next: its references and grades, counted."""
    def count(folder: str) -> int:
        with contextlib.suppress(OSError):
            return sum(1 for _ in (report / folder).rglob("*.json" if folder == journal.RESUME else "*.png"))
        return 0

    return f"{count('references')} references and {count(journal.RESUME)} grades are kept in {report}"


def _render_all(backend: _Backend, needed: dict[str, Path], refs: dict[str, Path], texts: dict[Path, bytes],
                report: Path) -> dict[str, bytes]:
    """Every reference the batch lacks, rendered and kept as each comes; one that cannot be rendered stops the
    run (once the others are kept)."""
    done: dict[str, bytes] = {}
    failures = []

    def keep(key: str, result: tuple[bytes | None, str]) -> None:
        png, failure = result
        if png is None:
            failures.append(f"{needed[key]}: {failure}")
        else:
            write_atomic(refs[key], png)
            done[key] = png

    _run_tasks(backend, {key: (backend.render, (texts[scene],)) for key, scene in needed.items()}, keep,
               lambda: _kept(report))
    if failures:
        raise ClassError("; ".join(sorted(failures)))
    return done


def _resumed(pair: Pair, report: Path, stamp: dict[str, Any]) -> dict[str, Any] | None:
    """The row of a grade an earlier run finished for the same reference, the same bytes and the same
    thresholds (with its heat-map and copy in place), or None (:mod:`service.journal` checks the rest)."""
    row = journal.kept(journal.path(report, pair.student, pair.task), stamp)
    if row is not None and row["status"] in ("pass", "fail") and not all(p.exists() for p in _paths(pair, report)):
        return None
    return row


def _grade_all(backend: _Backend, todo: list[Pair], references: dict[str, bytes], refs: dict[str, Path],
               report: Path, tasks: dict[str, TaskSettings], tolerance: float, max_fraction: float,
               tick: Callable[[], None], texts: dict[Path, bytes]) -> None:
    """Grade every pair on the backend (its bytes were read when the class was found); every file is written
    here, never by the tasks.  A grade an earlier run finished is taken as it was kept."""
    pending: dict[int, tuple[Callable[..., Any], tuple[Any, ...]]] = {}
    about: dict[int, tuple[Pair, bytes, dict[str, Any]]] = {}
    for n, pair in enumerate(todo):
        assert pair.key is not None and pair.data is not None
        image = pair.data
        own = tasks[pair.task]
        thresholds = (tolerance if own.tolerance is None else own.tolerance,
                      max_fraction if own.max_fraction is None else own.max_fraction)
        stamp = journal.stamp(pair.key, hashlib.sha256(image).hexdigest(), *thresholds)
        if not backend.diagnose:  # a grade without its likely mistake is not one a diagnosing run may take
            stamp["diagnosis"] = False
        if own.accepted is not None:
            stamp["accepted"] = own.accepted
        row = _resumed(pair, report, stamp)
        if row is not None:
            pair.row = row
            continue
        if pair.key not in references:
            references[pair.key] = refs[pair.key].read_bytes()
        accepted = () if own.accepted is None else (own.accepted,)  # (the defaults: the call as it was)
        pending[n] = (backend.grade, (texts[pair.scene], references[pair.key], image, *thresholds, *accepted))
        about[n] = (pair, image, stamp)
    tick()

    def keep(n: int, result: dict[str, Any]) -> None:
        pair, image, stamp = about[n]
        _graded(pair, result, image, report, stamp)
        tick()

    _run_tasks(backend, pending, keep, lambda: _kept(report))


def _graded(pair: Pair, result: dict[str, Any], image: bytes, report: Path, stamp: dict[str, Any]) -> None:
    """Keep a grade task's row; write its heat-map and the copy of the submission (the very bytes graded), then
    the grade itself, for a run that resumes."""
    if result["status"] == "invalid":
        pair.row = {"status": "invalid", "reason": f"{pair.image}: {result['reason']}"}
    else:
        result = dict(result)  # a cluster gives identical tasks (the same image graded twice) one shared result
        diagnosis = result.pop("diagnosis", None)
        result["likely"] = headline(Diagnosis.from_dict(diagnosis) if diagnosis else None)
        result["mistakes"] = matched(diagnosis)
        accepted = result.pop("accepted", None)
        if accepted:  # passed as an honest tracer's variant: the reason says which
            result["reason"] = f"as rendered with {accepted}"
        heat, copy = _paths(pair, report)
        write_atomic(heat, result.pop("heatmap_png"))
        write_atomic(copy, image)
        pair.row = result
    journal.keep(journal.path(report, pair.student, pair.task), stamp, pair.row)


def _paths(pair: Pair, report: Path) -> tuple[Path, Path]:
    return (report / "heatmaps" / pair.student / f"{pair.task}.png",
            report / "submissions" / pair.student / f"{pair.task}.png")


def _row(pair: Pair, refs: dict[str, Path], report: Path, tasks: dict[str, TaskSettings]) -> dict[str, Any]:
    row: dict[str, Any] = {c: None for c in COLUMNS}
    row.update({k: v for k, v in pair.row.items() if k in row})
    row.update(student=pair.student, task=pair.task, scene="own" if pair.own else "shared")
    row["reason"] = row["reason"] or ""
    row["points"] = tasks[pair.task].points
    row["mistakes"] = row["mistakes"] or []
    row["score"], row["deducted"] = astuple(score(row, tasks[pair.task]))
    row["file"], row["lms_id"] = pair.file, pair.lms_id
    ref = refs.get(pair.key or "")
    if ref is not None and ref.exists():
        row["reference"] = str(ref.relative_to(report))
    if row["status"] in ("pass", "fail"):
        heat, copy = _paths(pair, report)
        row["heatmap"], row["submission"] = str(heat.relative_to(report)), str(copy.relative_to(report))
    return row
