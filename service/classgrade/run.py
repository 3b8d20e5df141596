"""A class graded: the TA's input checked, the references rendered, every pair graded, the report written."""

from __future__ import annotations

import contextlib
import hashlib
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from tracer import decode_png

from ..client import ServerError
from ..course.errors import ClassError
from ..images.ppm import viewable
from ..settings import Settings
from . import journal
from .backends import Backend, open_backend
from .checks import outside, scene_keys, writable
from .faults import one_line, run_tasks
from .forms import ReportRow, Stamp
from .isolation import unwritable
from .job import TaskScene
from .programs import check_programs, discover_programs, program_jobs, program_tasks, warn
from .records import ClassRun, Coursework, GradeJob, Marked, Pair
from .report import COLUMNS, alike, summary, write_atomic
from .rows import files, has_image, kept_row, report_row
from .submissions import discover
from .taskfile import TaskSettings, load_tasks
from .writing import write_report


@dataclass
class Outcome:
    """A graded class: every pair's row (as the report has it), what was ignored, the references this run
    rendered (the others were already in the report) and its time."""

    rows: list[ReportRow]
    ignored: list[tuple[str, str]]
    renders: int
    seconds: float
    unwritten: list[str] = field(default_factory=list)  # a line per grade the report could not write whole

    def count(self, status: str) -> int:
        return sum(r["status"] == status for r in self.rows)

    def summary(self) -> str:
        return summary(self.rows, self.renders, self.seconds)

    def alike(self) -> list[str]:
        """A warning per task most of whose students are not passed for one same reason (:func:`.report.alike`)."""
        return alike(self.rows)


@dataclass
class Checked:
    """The class once the TA's input has been checked: the batch, the tasks' settings, the scene file of each
    scene key and each file's text, the service's settings, and when the run started."""

    batch: Coursework
    tasks: dict[str, TaskSettings]
    scene_of_key: dict[str, Path]
    texts: dict[Path, bytes]
    settings: Settings
    started: float


Progress = Callable[[int, int], None]


def grade_class(run: ClassRun, progress: Progress | None = None) -> Outcome:
    """Grade the class; ``progress(done, total)`` is told of the pairs graded as they are.  The TA's scenes
    are trusted: held to the service's limits (``PHONGRAY_*``) only with ``run.limits``.  Raises
    :class:`ClassError` (or :class:`service.render.cluster.ClusterError`) for a fault of the TA's, or for a fault of
    the pool, the cluster or the server that retries did not mend (what was finished is kept)."""
    started = time.perf_counter()
    settings = Settings.from_env()
    outside(run.report, run.submissions, run.scenes, run.student_scenes)
    if run.program is not None:
        check_programs(run)
        batch = discover_programs(run.scenes, run.submissions, run.student_scenes)
    else:
        batch = discover(run.scenes, run.submissions, run.student_scenes, settings.max_image_bytes)
    tasks = load_tasks(run.tasks_file, batch.tasks, run.canvas)
    scene_of_key, texts = scene_keys(batch, settings if run.limits else None)
    made = not run.report.exists()
    writable(run.report)
    try:
        return _run(run, Checked(batch, tasks, scene_of_key, texts, settings, started), progress)
    except Exception:
        if made:  # a run stopped by a fault of the TA's leaves no empty report folder behind
            with contextlib.suppress(OSError):
                run.report.rmdir()
        raise


def _run(run: ClassRun, checked: Checked, progress: Progress | None) -> Outcome:
    """:func:`grade_class` once the TA's input has been checked: render what is missing, grade, report (the
    renders held to the service's limits with ``run.limits``)."""
    batch, report = checked.batch, run.report
    todo = [p for p in batch.pairs if not p.row]  # (a missing or unreadable pair has its row from discover)
    refs = {k: report / "references" / f"{k}.png" for k in checked.scene_of_key}
    needed = {k: checked.scene_of_key[k] for k, path in refs.items() if not _usable(path)}
    total = len(batch.pairs)

    def tick() -> None:
        if progress:
            progress(sum(bool(p.row) for p in batch.pairs), total)

    tick()

    backend = open_backend(run, len(todo) + len(needed), checked.settings if run.limits else None)
    try:
        references = _render_all(backend, needed, refs, checked.texts, report)
        _grade_all(backend, run, checked, todo, references, refs, tick)
    except ServerError as exc:  # the service went away, or stopped taking the key, in the middle of the batch
        backend.close(wait=False)
        raise ClassError(
            f"--server {run.server}: {' '.join(str(exc).split())}; {_kept(report)}: run again to resume"
        ) from None
    except BaseException:
        backend.close(wait=False)
        raise
    backend.close()
    _drop_stale_references(report, refs)
    unmade: list[str] = []
    rows = [_row_of(p, refs, report, checked.tasks, unmade) for p in batch.pairs]
    outcome = Outcome(rows, batch.ignored, len(needed), time.perf_counter() - checked.started)
    outcome.rows, unwritten = write_report(
        report, rows, batch.ignored, batch.students, checked.tasks, outcome.summary()
    )
    outcome.unwritten = unmade + unwritten
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


def _render_all(
    backend: Backend, needed: dict[str, Path], refs: dict[str, Path], texts: dict[Path, bytes], report: Path
) -> dict[str, bytes]:
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

    run_tasks(
        backend,
        {key: (backend.render(), (texts[scene],)) for key, scene in needed.items()},
        keep,
        lambda: _kept(report),
    )
    if failures:
        raise ClassError("; ".join(sorted(failures)))
    return done


def _resumed(pair: Pair, report: Path, stamp: Stamp) -> ReportRow | None:
    """The row of a grade an earlier run finished for the same reference, the same bytes and the same
    thresholds (with its heat-map and copy in place), or None (:mod:`service.classgrade.journal` checks the rest)."""
    row = journal.kept(journal.path(report, pair.student, pair.task), stamp)
    if row is not None and has_image(row) and not all(p.exists() for p in files(pair, report)):
        return None
    return row


def _grade_all(
    backend: Backend,
    run: ClassRun,
    checked: Checked,
    todo: list[Pair],
    references: dict[str, bytes],
    refs: dict[str, Path],
    tick: Callable[[], None],
) -> None:
    """Grade every pair on the backend (its bytes were read when the class was found); every file is written
    here, never by the tasks.  A grade an earlier run finished is taken as it was kept."""
    if run.program is not None:
        _grade_programs(backend, run, checked, todo, refs, tick)
        return
    pending: dict[int, tuple[Callable[..., Any], tuple[Any, ...]]] = {}
    about: dict[int, tuple[Pair, bytes, Stamp]] = {}
    grade = backend.grade()
    for n, pair in enumerate(todo):
        assert pair.key is not None and pair.data is not None
        job = _job(run, checked, pair, references.get(pair.key, b""))
        stamp = journal.stamp(pair.key, hashlib.sha256(job.image).hexdigest(), job.tolerance, job.max_fraction)
        if not run.diagnose:  # a grade without its likely mistake is not one a diagnosing run may take
            stamp["diagnosis"] = False
        if job.accepted is not None:
            stamp["accepted"] = job.accepted
        row = _resumed(pair, run.report, stamp)
        if row is not None:
            pair.row = row
            continue
        if pair.key not in references:
            references[pair.key] = refs[pair.key].read_bytes()
        pending[n] = (grade, (replace(job, reference=references[pair.key]),))
        about[n] = (pair, job.image, stamp)
    tick()

    def keep(n: int, result: Marked) -> None:
        pair, image, stamp = about[n]
        _graded(pair, result, image, run.report, stamp)
        tick()

    run_tasks(backend, pending, keep, lambda: _kept(run.report))


def _grade_programs(
    backend: Backend, run: ClassRun, checked: Checked, todo: list[Pair], refs: dict[str, Path], tick: Callable[[], None]
) -> None:
    """Grade every student's program on the backend, one task per student (:mod:`.programs`); each pair's
    grade is kept as an image's is."""

    def task_of(pair: Pair) -> TaskScene:
        return TaskScene(pair.task, _job(run, checked, pair, refs[pair.key or ""].read_bytes()))

    jobs = program_jobs(run, todo, task_of, lambda pair, stamp: _resumed(pair, run.report, stamp))
    tick()

    def keep(student: str, results: dict[str, Marked]) -> None:
        for pair, stamp in jobs[student][1]:
            result = results[pair.task]
            warn(pair, result)
            _graded(pair, result, result.image or b"", run.report, stamp)
        tick()

    for tasks in program_tasks(jobs):
        run_tasks(backend, tasks, keep, lambda: _kept(run.report))


def _job(run: ClassRun, checked: Checked, pair: Pair, reference: bytes) -> GradeJob:
    """What the backend grades for a pair: its task's thresholds where the tasks file gives them, else the
    run's (a program's pair has no image yet: its run makes it)."""
    own = checked.tasks[pair.task]
    accepted = None if own.accepted is None else {str(name): amount for name, amount in own.accepted.items()}
    return GradeJob(
        checked.texts[pair.scene],
        reference,
        pair.data or b"",
        run.tolerance if own.tolerance is None else own.tolerance,
        run.max_fraction if own.max_fraction is None else own.max_fraction,
        accepted,
        run.diagnose,
    )


def _graded(pair: Pair, marked: Marked, image: bytes, report: Path, stamp: Stamp) -> None:
    """Keep a backend's grade of a pair: write its heat-map and the copy of the submission (the very bytes
    graded), then its row (:func:`~.rows.kept_row`), for the report and for a run that resumes (a PPM's copy
    is the PNG of its pixels)."""
    pair.row = kept_row(marked, pair.image)
    if has_image(pair.row) and marked.graded is not None and marked.graded.heatmap is not None:
        heat, copy = files(pair, report)
        write_atomic(heat, marked.graded.heatmap)
        write_atomic(copy, viewable(image))  # (a PPM's copy: the PNG of its pixels, which a browser shows)
    journal.keep(journal.path(report, pair.student, pair.task), stamp, pair.row)


def _row_of(
    pair: Pair, refs: dict[str, Path], report: Path, tasks: dict[str, TaskSettings], faults: list[str]
) -> ReportRow:
    """A pair's row (:func:`~.rows.report_row`); one that cannot be made is the pair's :func:`unwritable` row
    (and a line in ``faults``), never the class's lost report."""
    try:
        return report_row(pair, refs.get(pair.key or ""), report, tasks[pair.task]).row()
    except Exception as exc:
        faults.append(f"{pair.student}/{pair.task}: its row: {one_line(exc)}")
        known = {**pair.row, "student": pair.student, "task": pair.task, "lms_id": pair.lms_id, "lms": pair.lms}
        known.update(file=pair.file, scene="own" if pair.own else "shared", points=tasks[pair.task].points)
        return unwritable(known, COLUMNS, "its row", exc)
