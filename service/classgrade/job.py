"""A student's program graded: built once, run on each task's scene, each image graded as an upload's is.

:func:`grade_program` is one task of class grading (a pool process's or a Dask worker's, all of a student's
tasks together, so that the build is done once): it builds the program in its sandbox (when the TA gave a
build command), runs it on each task scene, each run in a sandbox of its own, and grades each image it
wrote exactly as an uploaded image of that task is graded (:func:`service.classgrade.tasks.local_grade`: the
thresholds, the accepted variants, the diagnosis).  A run that fails (a timeout, memory, a crash, no output,
an output that is a link...) makes a failing grade whose reason says so in words, and the others go on; a
failing image is then diagnosed by experiment too (:mod:`service.programs.experiment`), within the same
limits.  Only a sandbox that cannot start stops the batch (the TA's :class:`ClassError`, in one line).

The student's folder travels with the job as a :class:`~service.programs.pack.Pack` (its bytes, digested):
where the job runs, it is checked and unpacked into a folder of its own, so a Dask worker needs no shared file
system and no path of the grading machine's.  Nothing of a run is left on that machine's disk.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

from tracer.image import encode_png

from ..course.errors import ClassError
from ..diagnosis.records import matched
from ..images.grading import ImageError, declared_size, read_submission
from ..programs.digest import digest as digest  # (what a kept grade stands for: its own module)
from ..programs.experiment import Allowance, Thresholds, experiment
from ..programs.outcome import Reason, RunOutcome, busy
from ..programs.pack import DamagedPack, Pack, unpacked
from ..programs.program import Program
from ..programs.runner import BuildStep, ProgramRun, build_program, run_program
from ..programs.sandbox import SandboxUnavailable
from .copied import flags
from .records import GradeJob, Marked, RunInfo
from .tasks import local_grade


@dataclass(frozen=True)
class TaskScene:
    """One task the program renders: its name, and how its image is graded (the scene's text, its reference,
    the thresholds: class grading's :class:`~service.classgrade.records.GradeJob`, its image the run's)."""

    task: str
    grading: GradeJob

    @property
    def thresholds(self) -> Thresholds:
        job = self.grading
        return Thresholds(job.tolerance, job.max_fraction, job.accepted)


@dataclass(frozen=True)
class ProgramJob:
    """A student's program and the tasks it renders: the student's folder where the job was made, and, for a
    job sent to where that folder may not be (a Dask worker), the folder's :class:`Pack`, which is what runs."""

    folder: Path
    program: Program
    tasks: tuple[TaskScene, ...]
    pack: Pack | None = None


#: the wall-time limits a student's probes may take, per task it has, all its experiments together: an honest
#: program answers each of a task's probes about as fast as the task, far within its limit, while one that
#: fails its task and then waits on every probe would cost (1 + probes) limits a task
PROBE_WALLS = 2

#: how much of the end of a run's output (its standard error) a grade keeps for the TA
OUTPUT_KEPT = 2000


def run_info(outcome: RunOutcome) -> RunInfo:
    """A run's end as a grade keeps it (:class:`~service.classgrade.records.RunInfo`): the end of its output,
    at most :data:`OUTPUT_KEPT` characters, and a run timed out on a busy machine said
    (:func:`~service.programs.outcome.busy`)."""
    return RunInfo(
        str(outcome.reason),
        outcome.stderr_tail[-OUTPUT_KEPT:],
        round(outcome.wall_seconds, 3),
        outcome.warning,
        busy(outcome),
    )


def failed_run(outcome: RunOutcome, what: str = "the run") -> Marked:
    """The grade of a pair whose run (or build) failed: a failing pair, its reason in words."""
    return Marked("fail", reason=f"{what} failed: {outcome.reason}: {outcome.detail}", run=run_info(outcome))


def _grade_image(task: TaskScene, image: bytes) -> Marked:
    return local_grade(replace(task.grading, image=image))


def _runner(folder: Path, program: Program, name: str) -> Callable[[bytes], RunOutcome]:
    """Run the program on a scene's text, written as ``name`` (the task's file name) for it to read."""

    def run(scene: bytes) -> RunOutcome:
        with tempfile.TemporaryDirectory(prefix="phongray-scene-") as place:
            path = Path(place, name)
            path.write_bytes(scene)
            given = ProgramRun(folder, program.run, path, program.limits, program.sandbox, program.runtime)
            return run_program(given)

    return run


def grade_run(task: TaskScene, run: Callable[[bytes], RunOutcome], allowance: Allowance | None = None) -> Marked:
    """One task: the run, its image graded (with ``image``, the bytes graded, which :func:`grade_program` keeps
    as the PNG of their pixels, and how the run went: :func:`run_info`), and a failing image diagnosed by
    experiment (``experiment``: its sentences, the likeliest first, joined by "; "; a run that failed is not
    asked more).  An image that cannot be read as a PNG is an invalid pair, as an uploaded one is."""
    outcome = run(task.grading.scene)
    if not outcome.ok or outcome.image is None:
        return failed_run(outcome)
    result = replace(_grade_image(task, outcome.image), image=outcome.image, run=run_info(outcome))
    if task.grading.diagnose and result.status == "fail":
        found = None if result.graded is None else result.graded.diagnosis
        # (the task's likeliest exact match, kept out)
        known = tuple(matched(None if found is None else found.as_dict())[:1])
        said = experiment(task.grading.scene, outcome.image, run, task.thresholds, known, allowance).sentences
        result = replace(result, experiment="; ".join(said) or None)
    return result


@contextmanager
def _source(job: ProgramJob) -> Iterator[Path | None]:
    """The student's folder where the job runs: its own, or its pack unpacked (removed afterwards); None
    for a pack of a folder over the limit."""
    if job.pack is None:
        yield job.folder
    elif job.pack.too_large is not None:
        yield None
    else:
        with unpacked(job.pack, job.program.limits.folder_bytes) as folder:
            yield folder


@contextmanager
def _built(job: ProgramJob, folder: Path) -> Iterator[tuple[Path | None, RunOutcome | None]]:
    """The folder the runs use: the student's, or what its build left (removed afterwards); the build's
    outcome when it failed."""
    if job.program.build is None:
        yield folder, None
        return
    with tempfile.TemporaryDirectory(prefix="phongray-built-") as into:
        program = job.program
        step = BuildStep(folder, program.build or "", program.limits, program.sandbox, program.runtime)
        built = build_program(step, Path(into))
        yield built.folder, None if built.folder is not None else built.outcome


def _graded(job: ProgramJob, folder: Path | None) -> dict[str, Marked]:
    what = "the build" if job.program.build is not None else "the run"
    if folder is None:
        assert job.pack is not None and job.pack.too_large is not None
        too_large = RunOutcome(Reason.FOLDER_TOO_LARGE, job.pack.too_large)
        return {task.task: failed_run(too_large, what) for task in job.tasks}
    with _built(job, folder) as (runs_in, failed):
        if runs_in is None:
            assert failed is not None
            return {task.task: failed_run(failed, "the build") for task in job.tasks}
        runs = {task.task: _runner(runs_in, job.program, f"{task.task}.json") for task in job.tasks}
        allowance = Allowance(PROBE_WALLS * len(job.tasks) * job.program.limits.wall_seconds)
        return {task.task: grade_run(task, runs[task.task], allowance) for task in job.tasks}


def _kept_image(image: bytes, reference: bytes) -> bytes | None:
    """What a grade keeps of a program's image (the report's copy): the PNG of its pixels as they were graded,
    never the program's own bytes, which can carry megabytes of chunks no decoder shows; None where it cannot
    be read (an invalid pair keeps no copy)."""
    try:
        return encode_png(read_submission(image, declared_size(reference)))
    except (ImageError, ValueError):
        return None


def _with_kept_image(result: Marked, reference: bytes) -> Marked:
    return result if result.image is None else replace(result, image=_kept_image(result.image, reference))


def grade_program(job: ProgramJob) -> dict[str, Marked]:
    """Every task's grade of one student's program, by task name (see the module's docstring), flagged for the
    TA when the program holds phongray's code or its images are the references (:mod:`.copied`).
    :class:`ClassError` (the TA's, in one line, naming the student whose run found it) when a sandbox cannot
    start: the machine's set-up, never the student's."""
    try:
        with _source(job) as folder:
            results = _graded(job, folder)
            if folder is not None:
                references = {task.task: task.grading.reference for task in job.tasks}
                flag = flags(folder, results, references, job.program.limits)
                if flag is not None:
                    results = {t: replace(r, flag=flag[0], flag_reason=flag[1]) for t, r in results.items()}
            return {  # (once flagged: the flag is on the very bytes the program wrote)
                task.task: _with_kept_image(results[task.task], task.grading.reference) for task in job.tasks
            }
    except (SandboxUnavailable, DamagedPack) as exc:
        raise ClassError(f"{job.folder.name}'s program: {exc}") from None
