"""A class of students' programs (``grade-class --run``): a folder per student, one job per student.

``SUBMISSIONS/<student>/`` holds a student's program (:func:`discover_programs`).  Each student with a task
left to grade is one task of the backend, :func:`service.classgrade.job.grade_program`: the program built once,
then run on each of its task scenes, each run in a sandbox of its own, each image graded as an uploaded one;
in a pool here or on a Dask worker alike, the student's folder sent with the task as bytes
(:mod:`service.programs.pack`), so that a worker needs no shared file system.  What it returns is kept pair by
pair as an image's grade is (:func:`~service.classgrade.run.keep_grade`: the heat-map, the copy of the image,
the journal), so the report, resuming and Gradescope's results are those of images.  A kept grade stands for
the program's files and commands (:func:`service.programs.digest.digest`): a student who changed nothing is not
run again.

The TA's mistakes stop the batch before any student is run (:func:`check_programs`): a command that cannot
run, bubblewrap missing or unable to start (unless ``--no-sandbox``), a runtime that is not installed, does
not start in the sandbox or would show programs what they may not see, an interpreter that runs out of memory
as it starts (:mod:`service.programs.interpreter`), ``--server`` (which grades images).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..course.errors import ClassError
from ..course.folders import hidden, own_scenes, sorted_entries, task_scenes
from ..programs import SandboxUnavailable, check_sandbox
from ..programs.digest import digest
from ..programs.folder import unreadable
from ..programs.interpreter import fails_to_start
from ..programs.pack import pack_folder
from ..programs.program import Program
from ..programs.runtime import check_runtime, runtime_starts
from . import journal
from .forms import ReportRow, Stamp
from .job import ProgramJob, TaskScene, grade_program
from .records import ClassRun, Coursework, Marked, Pair


def check_programs(run: ClassRun) -> None:
    """:class:`ClassError`, in one line, for a run of programs that cannot be made (the TA's to mend)."""
    if run.server:
        raise ClassError(
            f"--server {run.server}: a service grades images; run students' programs here or on a "
            f"Dask cluster (--cluster)"
        )
    program = run.program
    assert program is not None
    private = {
        "the task scenes": run.scenes,
        "the students' folders": run.submissions,
        "the report": run.report,
        "the students' own scenes": run.student_scenes,
    }
    problem = check_runtime(program.runtime, program.packages, private)
    if problem is not None:
        raise ClassError(problem)
    try:
        if program.sandbox:
            check_sandbox()
        problem = None if program.runtime is None else runtime_starts(program.runtime, program.sandbox)
        problem = problem or fails_to_start(program)
    except SandboxUnavailable as exc:
        raise ClassError(str(exc)) from None
    if problem is not None:
        raise ClassError(problem)


def bundle_checked(program: Program) -> None:
    """:class:`ClassError` for a bundle's run command whose interpreter cannot start within the run's limits
    (:mod:`service.programs.interpreter`), found as the bundle is made rather than as every student's zero on
    Gradescope; not looked at where no sandbox can start here (the image's batch looks again, before its one
    student)."""
    try:
        if program.sandbox:
            check_sandbox()
        problem = fails_to_start(program)
    except SandboxUnavailable:
        return
    if problem is not None:
        raise ClassError(problem)


def discover_programs(scenes: Path, submissions: Path, student_scenes: Path | None = None) -> Coursework:
    """Every (student, task) pair of a class of programs: a student is a folder of ``submissions`` (not a link,
    not a hidden one), its pairs left to grade; anything else there is ignored.  A student with an own scene
    (``--student-scenes``) but no folder has each pair missing."""
    tasks, ignored = task_scenes(scenes)
    own = own_scenes(student_scenes, tasks, ignored) if student_scenes is not None else {}
    students = []
    for entry in sorted_entries(submissions):
        shown = str(submissions / entry.name)
        if hidden(entry.name) or not entry.is_dir(follow_symlinks=False):
            ignored.append((shown, "not a student's program folder (a folder per student)"))
        else:
            students.append(entry.name)
    if not students:
        raise ClassError(f"{submissions}: no student found; expected a folder per student holding the program")
    for student in students:
        _all_readable(submissions, submissions / student)
    pairs = []
    for student in sorted({*students, *own}):
        for task, shared in tasks.items():
            scene = own.get(student, {}).get(task)
            pair = Pair(student, task, submissions / student, scene or shared, scene is not None)
            if student not in students:
                pair.row = {"status": "missing", "reason": f"no folder {student}/ holding a program"}
            pairs.append(pair)
    return Coursework(tasks, sorted({*students, *own}), pairs, ignored)


def _all_readable(submissions: Path, folder: Path) -> None:
    """:class:`ClassError` naming the first of a student's files or folders this user may not read
    (:func:`~service.programs.folder.unreadable`): the copy a program runs in would leave it out, and the student
    would be charged with the crash (a folder unpacked by another user, as root)."""
    found = unreadable(folder)
    if found is not None:
        raise ClassError(
            f"{folder / found if found else folder}: this user cannot read it, so a student's program would run "
            f"without it; make the students' files readable (chmod -R u+rwX {submissions}, as their owner) and "
            f"run again"
        )


Stamped = tuple[Pair, Stamp]


def program_jobs(
    run: ClassRun,
    todo: list[Pair],
    task_of: Callable[[Pair], TaskScene],
    resumed: Callable[[Pair, Stamp], ReportRow | None],
) -> dict[str, tuple[ProgramJob, list[Stamped]]]:
    """Per student with a task left to grade, the job and its pairs with their stamps; a pair an earlier run
    kept for the same program, scene and thresholds is taken as it was (``resumed``)."""
    assert run.program is not None
    jobs: dict[str, tuple[ProgramJob, list[Stamped]]] = {}
    for student in sorted({p.student for p in todo}):
        folder = run.submissions / student
        code = digest(folder, run.program)
        tasks, stamped = [], []
        for pair in (p for p in todo if p.student == student):
            assert pair.key is not None
            task = task_of(pair)
            job = task.grading
            stamp = {**journal.stamp(pair.key, code, job.tolerance, job.max_fraction), "program": True}
            if not job.diagnose:
                stamp["diagnosis"] = False
            if job.accepted is not None:
                stamp["accepted"] = job.accepted
            row = resumed(pair, stamp)
            if row is not None:
                pair.row = row
                continue
            tasks.append(task)
            stamped.append((pair, stamp))
        if tasks:
            jobs[student] = (ProgramJob(folder, run.program, tuple(tasks)), stamped)
    return jobs


def warn(pair: Pair, result: Marked) -> None:
    """A run without a sandbox says so, every time; so does a run timed out on a busy machine."""
    for said in () if result.run is None else (result.run.run_warning, result.run.run_busy):
        if said:
            print(f"{pair.student}/{pair.task}: {said}", file=sys.stderr)


#: bytes of students' folders (their packs) sent to the backend at once: a batch of students is sent when the
#: one before has been graded, so that a class of large folders is never all in memory
PACKS_AT_ONCE = 512 << 20


def program_tasks(
    jobs: dict[str, tuple[ProgramJob, list[Stamped]]],
) -> Iterator[dict[str, tuple[Callable[..., Any], tuple[Any, ...]]]]:
    """The backend's tasks, one :func:`grade_program` per student, its folder sent with it as bytes (its
    :class:`~service.programs.pack.Pack`, made here), in batches of at most :data:`PACKS_AT_ONCE` bytes."""
    batch: dict[str, tuple[Callable[..., Any], tuple[Any, ...]]] = {}
    size = 0
    for student, (job, _) in jobs.items():
        pack = pack_folder(job.folder, job.program.limits.folder_bytes)
        if batch and size + len(pack.data) > PACKS_AT_ONCE:
            yield batch
            batch, size = {}, 0
        batch[student] = (grade_program, (replace(job, pack=pack),))
        size += len(pack.data)
    if batch:
        yield batch
