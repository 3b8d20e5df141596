"""The records of class grading: the run's options, a pair of a student and a task, the job a backend grades,
what a backend returns for it, the pairs found in the class's folders, and a pair's grade as the report writes
it."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal

from ..programs.program import Program
from ..work.pipeline import Graded
from .forms import ReportRow


@dataclass(frozen=True)
class ClassRun:
    """What ``grade-class`` is asked to do: the TA's folders, the thresholds, and where the work runs.  A
    ``server`` (a URL) or a ``cluster`` (a Dask scheduler's address) sends the work away, else a pool of
    ``jobs`` processes grades here; with ``limits`` the TA's scenes are held to the service's limits.  With a
    ``program``, each student's folder holds a program to run on the task scenes (:mod:`.programs`)."""

    scenes: Path
    submissions: Path
    report: Path
    tolerance: float = 2.0
    max_fraction: float = 0.001
    jobs: int | None = None
    server: str | None = None
    cluster: str | None = None
    api_key: str | None = None
    student_scenes: Path | None = None
    tasks_file: Path | None = None
    cluster_wait: float = 30.0
    limits: bool = False
    diagnose: bool = True
    program: Program | None = None  # the students' programs to run (--run); None: they handed in images
    canvas: str | None = None  # the Canvas assignment of every task tasks.json gives none (--canvas-assignment)


@dataclass
class Pair:
    """A student and a task: what the student submitted for it, the scene it is graded against, and (once
    graded, or when nothing can be) its row of results."""

    student: str
    task: str
    image: Path | None  # the submitted file, as the report names it; None: missing
    scene: Path  # the student's own scene (the TA's), or the task's
    own: bool
    key: str | None = None  # the canonical scene hash
    file: str | None = None  # the submitted file, relative to the student's folder (spheres.png, hw3/Spheres.PNG)
    row: ReportRow = field(default_factory=dict)
    data: bytes | None = None  # the submitted bytes, read once, when the class was found
    lms_id: str = ""  # the student's id in the learning-management system's export (Canvas's, Moodle's), if any
    lms: str = ""  # which LMS's export it is ("canvas", "moodle"; "" for a folder per student)
    late: bool = False  # the file graded was handed in late (Canvas marks it _LATE_)


@dataclass(frozen=True)
class GradeJob:
    """What a backend grades for one pair, bytes only (so that it crosses to a pool process, a Dask worker or a
    service alike): the scene's text, its reference PNG, the submitted image, the thresholds, the task's
    accepted variants (None: the defaults) and whether a failing image's likely mistake is named.

    The submission is an image; another kind (a student's program, to be run before it is graded) would be
    another field here, made into the image by the backend's task before the same grading."""

    scene: bytes
    reference: bytes
    image: bytes
    tolerance: float
    max_fraction: float
    accepted: dict[str, float] | None = None
    diagnose: bool = True


@dataclass(frozen=True)
class RunInfo:
    """A program's run as its grade keeps it: ``run`` (its reason's word: ``ok``, ``timeout``, ...),
    ``run_output`` (the end of its output: the TA's to read, never shown to a student, as it may hold what the
    program read of a hidden scene), ``run_seconds``, ``run_warning`` (a run without a sandbox) and ``run_busy``
    (a run timed out on a busy machine), both said to the TA, never kept in the report."""

    run: str
    run_output: str
    run_seconds: float
    run_warning: str | None = None
    run_busy: str | None = None


#: what became of a graded pair
Status = Literal["pass", "fail", "invalid"]


@dataclass(frozen=True)
class Marked:
    """A pair's grade as every backend returns it (a pool process, a Dask worker, a running service), the one
    form between the grading and the report (:func:`service.classgrade.rows.kept_row`): picklable, no dicts.

    ``graded`` is the image's grade (with its heat-map, diagnosis and accepted variant); None when the image
    is ``invalid`` (``reason`` says why, lacking the file's name) or a program's run (or build) failed
    (``reason`` says how).  A program's pair has its ``run``, the ``image`` it wrote (the PNG of its pixels
    once kept), what ``experiment`` found of a failing one, and a ``flag`` for the TA."""

    status: Status
    graded: Graded | None = None
    reason: str = ""
    run: RunInfo | None = None
    image: bytes | None = None
    experiment: str | None = None
    flag: str | None = None
    flag_reason: str | None = None

    @classmethod
    def of(cls, graded: Graded) -> Marked:
        """A graded image's: it passed or failed."""
        return cls("pass" if graded.grade.passed else "fail", graded)

    @classmethod
    def invalid(cls, reason: str) -> Marked:
        return cls("invalid", reason=reason)


@dataclass
class Coursework:
    """The class as found in its folders: the tasks' scenes, the students, every pair, and what was ignored."""

    tasks: dict[str, Path]
    students: list[str]
    pairs: list[Pair]
    ignored: list[tuple[str, str]]  # (file, why it is not graded)


@dataclass
class Row:
    """A pair's grade as the report writes it: who and what, the verdict and why, the likely mistakes, the
    points, the thresholds, the comparison's numbers and the files beside the report.  Its fields are the
    report's columns in their order (:data:`~service.classgrade.report.COLUMNS`); :meth:`row` is the dict
    report.json, report.csv and the HTML are written from."""

    student: str
    lms_id: str
    lms: str  # the LMS whose export the student is of ("canvas", "moodle", "")
    task: str
    status: str
    reason: str
    likely: str | None
    mistakes: list[str]
    scene: str
    file: str | None
    passed: bool | None
    points: float
    score: float
    deducted: str | None
    late: bool  # the LMS marked the file graded late (Canvas's _LATE_)
    late_deducted: float | None  # the points the late policy took (None: on time)
    tolerance: float | None
    max_fraction: float | None
    mean_abs_error: float | None
    rmse: float | None
    psnr: float | None
    max_error: float | None
    fraction_off: float | None
    fraction_off_nearby: float | None
    width: int | None
    height: int | None
    reference_sha256: str | None
    reference: str | None
    submission: str | None
    heatmap: str | None
    experiment: str | None = None  # a program's: what its answers to the probes show (.programs)
    run: str | None = None  # a program's: how its run ended, in a word (ok, timeout, memory, ...)
    run_seconds: float | None = None
    run_output: str | None = None  # the end of the run's output: the TA's, never shown to a student
    flag: str | None = None  # a program's: phongray-code or identical (service.classgrade.copied), for the TA
    flag_reason: str | None = None

    def row(self) -> ReportRow:
        """The grade as the report's row: its columns, in order."""
        return asdict(self)
