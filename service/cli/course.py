"""``phongray grade-class`` and ``phongray autograder``: a course's tasks, graded for every student or bundled
for Gradescope; exit 0 when done, 2 when the TA's input or set-up is unusable."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from service.cli.common import CliError, thresholds
from service.cli.display import ProgressBar, printable
from service.cli.options import Commands, command, limits, no_diagnosis, positive_int
from service.cli.options import remote as remote_options
from service.cli.options import thresholds as threshold_options
from service.cli.programs import add_arguments as program_options
from service.images.figures import counted

if TYPE_CHECKING:
    from service.programs.program import Program


def cmd_grade_class(args: argparse.Namespace) -> int:
    """Exit 0 when the batch ran (whatever the verdicts), 2 when the TA's input or set-up is unusable."""
    from service.classgrade import ClassRun, grade_class
    from service.course.errors import ClassError
    from service.render.cluster import ClusterError

    thresholds(args)
    if args.server and args.cluster:
        raise CliError("--server and --cluster: choose one")
    program = students_program(args)
    bar = ProgressBar(unit="pairs")
    bar.enabled = bar.enabled and not args.quiet
    try:
        run = ClassRun(
            Path(args.scenes),
            Path(args.submissions),
            Path(args.output),
            args.tolerance,
            args.max_fraction,
            jobs=args.jobs,
            server=args.server,
            cluster=args.cluster,
            api_key=args.api_key,
            student_scenes=Path(args.student_scenes) if args.student_scenes else None,
            tasks_file=Path(args.tasks) if args.tasks else None,
            cluster_wait=args.cluster_wait,
            diagnose=not args.no_diagnosis,
            limits=args.limits,
            program=program,
            canvas=args.canvas_assignment,
        )
        outcome = grade_class(run, progress=bar)
    except (ClassError, ClusterError) as exc:  # (names in it are printed with their control characters escaped)
        raise CliError(printable(str(exc))) from None
    except OSError as exc:
        raise CliError(printable(f"{exc.filename or args.output}: {exc.strerror or exc}")) from None
    finally:
        bar.close()
    for name, why in outcome.ignored:
        print(printable(f"ignored: {name}: {why}"), file=sys.stderr)
    for line in outcome.alike():  # (the TA's to look at: a task scene of the wrong size, a task misnamed)
        print(printable(f"warning: {line}"), file=sys.stderr)
    for line in outcome.unwritten:  # (each such grade's row says so, with its verdict and score)
        print(printable(f"not written whole: {line}"), file=sys.stderr)
    if not args.quiet:
        print(printable(f"{outcome.summary()}; report in {Path(args.output) / 'index.html'}"))
        if program is not None and not args.cluster:  # (a worker holds its runs as its own machine allows)
            from service.programs.guard import enforcement

            print(f"students' programs ran here: {enforcement().describe()}")
    return 0


def students_program(args: argparse.Namespace) -> Program | None:
    """The students' program of ``--run`` and its options (None: images); a TA's mistake in them is one line."""
    from service.cli.programs import program

    try:
        return program(args)
    except ValueError as exc:
        raise CliError(printable(str(exc))) from None


def cmd_autograder(args: argparse.Namespace) -> int:
    """Exit 0 when the bundle is written, 2 when the TA's input is unusable (nothing is written then)."""
    from service.classgrade.autograder import build
    from service.course.errors import ClassError

    if not args.output.endswith(".zip"):
        raise CliError(f"{args.output}: Gradescope takes the autograder as a zip; name the output *.zip")
    program = students_program(args)
    try:
        built = build(
            Path(args.scenes),
            Path(args.output),
            Path(args.tasks) if args.tasks else None,
            Path(args.student_scenes) if args.student_scenes else None,
            program,
            Path(args.runtime_requirements) if args.runtime_requirements else None,
        )
    except ClassError as exc:
        raise CliError(printable(str(exc))) from None
    print(
        printable(
            f"{args.output}: {counted(len(built.tasks), 'task')} ({', '.join(built.tasks)}), "
            f"{counted(built.references, 'reference')} rendered, {built.size / 1e6:.1f} MB; upload it as "
            "the assignment's autograder"
        )
    )
    return 0


def add(sub: Commands) -> None:
    p = command(
        sub,
        "grade-class",
        "grade every student's images of every task; write a report",
        description="SCENES/<task>.json are the tasks, SUBMISSIONS/<student>/<task>.png (or .ppm) the images "
        "(any case of the name, a resubmission's -1 or (1), or one folder deeper; Moodle's "
        "<name>_<id>_assignsubmission_file_ folders and Canvas's flat <login>_<id>_<id>_<task>.png "
        "too). A student's own scene comes from the TA's --student-scenes "
        "DIR/<student>/<task>.json, never from the submissions. Writes report.json, report.csv, "
        "gradebook.csv (and Canvas's and Moodle's import files for their exports' students), "
        "index.html, gradescope/<student>/results.json, references and heat-maps into REPORT. Exit 0 "
        "when the batch ran, 2 when the TA's input or set-up is unusable (nothing is graded then).",
    )
    p.add_argument("scenes", metavar="SCENES_DIR", help="a <task>.json per task")
    p.add_argument("submissions", metavar="SUBMISSIONS_DIR", help="the students' images, as an LMS downloads them")
    p.add_argument("-o", "--output", metavar="REPORT_DIR", required=True, help="where the report goes")
    p.add_argument(
        "--student-scenes", metavar="DIR", help="the TA's folder of students' own scenes, <student>/<task>.json"
    )
    p.add_argument(
        "--tasks",
        metavar="TASKS.json",
        help="per task its points, thresholds and deductions by "
        'mistake id: {"spheres": {"points": 10, "tolerance": 3, '
        '"deductions": {"no-shadows": 4}}}',
    )
    p.add_argument(
        "--canvas-assignment",
        metavar="'TITLE (ID)'",
        help="the Canvas assignment every task's score goes to in canvas-gradebook.csv, as Canvas's gradebook "
        "names its column: 'Homework 3 (12345)' (tasks.json's \"*\": {\"canvas\": ...}; a task's own wins)",
    )
    threshold_options(p)
    p.add_argument("--jobs", type=positive_int, help="processes (default: all cores; with --server, 4 requests)")
    no_diagnosis(
        p,
        "skip naming the likely mistake of each failing image (it renders the scene once per "
        "classic mistake): a faster run, with an empty 'likely' column",
    )
    p.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="print nothing but errors and ignored files (no progress bar, no summary line)",
    )
    limits(p)
    remote_options(p, cluster=True)
    program_options(p)
    p.set_defaults(func=cmd_grade_class)


def add_autograder(sub: Commands) -> None:
    p = command(
        sub,
        "autograder",
        "write a Gradescope autograder (setup.sh, run_autograder) for a course's scenes",
        description="SCENES/<task>.json are the tasks. Writes a zip to upload to Gradescope as a "
        "programming assignment's autograder: it installs phongray (setup.sh) and grades the "
        "PNG images a student uploads, one per task, with a test per task (run_autograder). "
        "The references are rendered now. Exit 0 when written, 2 when the TA's input is "
        "unusable.",
    )
    p.add_argument("scenes", metavar="SCENES_DIR", help="a <task>.json per task")
    p.add_argument("-o", "--output", metavar="AUTOGRADER.zip", required=True, help="the zip to write")
    p.add_argument("--tasks", metavar="TASKS.json", help="per task its points, thresholds and accepted variants")
    p.add_argument(
        "--student-scenes",
        metavar="DIR",
        help="students' own scenes, <student>/<task>.json, "
        "<student> being their Gradescope email, its part "
        "before the @, student id or name",
    )
    program_options(p)
    p.add_argument(
        "--runtime-requirements",
        metavar="FILE",
        help="with --run: a pip requirements file (numpy, pillow); setup.sh builds a Python environment of "
        "it for the programs, with the image's python3",
    )
    p.set_defaults(func=cmd_autograder)
