"""The command line's options for students' programs (``grade-class`` and ``autograder`` take the same):
``--run``, ``--build``, the limits and ``--no-sandbox``, made into a :class:`~service.classgrade.job.Program`.
Nothing of :mod:`service.programs` is imported until a program is made (a render's start-up does not pay for
it); an option not given takes :class:`~service.programs.limits.Limits`'s default.

A size is a number of bytes with an optional unit: ``K``, ``M``, ``G`` (and ``KiB``, ``MiB``, ``GiB``) are
powers of 1024, ``KB``, ``MB``, ``GB`` powers of 1000: ``--memory 2G`` is the default 2 GiB,
``--output-size 100MB`` the default 100 MB.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from service.cli.options import MOST_WAIT

if TYPE_CHECKING:
    from service.programs.program import Program

UNITS = {
    "": 1,
    "K": 1 << 10,
    "KIB": 1 << 10,
    "M": 1 << 20,
    "MIB": 1 << 20,
    "G": 1 << 30,
    "GIB": 1 << 30,
    "KB": 1000,
    "MB": 1000**2,
    "GB": 1000**3,
}
_SIZE = re.compile(r"\s*(\d+(?:\.\d+)?)\s*([A-Za-z]*)\s*")
#: the largest size an option takes (a pebibyte): beyond, no limit means anything, and prlimit cannot read it
MOST_BYTES = 1 << 50
#: the most processes a run may be given (Linux's largest pid_max)
MOST_PROCESSES = 1 << 22


def size(text: str) -> int:
    """A size in bytes (``2G``, ``512MiB``, ``100MB``, ``4096``); argparse's error for anything else."""
    found = _SIZE.fullmatch(text)
    unit = found.group(2).upper() if found else ""
    if found is None or unit not in UNITS or float(found.group(1)) * UNITS[unit] < 1:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a size: a number of bytes with an optional unit, "
            f"K, M, G (powers of 1024) or KB, MB, GB (of 1000), such as 2G"
        )
    value = int(float(found.group(1)) * UNITS[unit])
    if value > MOST_BYTES:
        raise argparse.ArgumentTypeError(f"{text!r}: at most 1024T (a pebibyte)")
    return value


def _positive(kind: Callable[[str], float], most: float) -> Callable[[str], float]:
    """argparse's type: a number of ``kind`` (int, float) above 0 and at most ``most``."""

    def parse(text: str) -> float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f"{text!r}: must be > 0")
        if not value <= most:
            raise argparse.ArgumentTypeError(f"{text!r}: must be at most {most:.15g}")
        return value

    return parse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of students' programs, as a group of ``parser``'s."""
    group = parser.add_argument_group(
        "students' programs",
        "with --run, SUBMISSIONS/<student>/ holds each student's program, run in a sandbox "
        "(bubblewrap) on every task scene; its image is then graded as an uploaded one",
    )
    group.add_argument(
        "--run",
        metavar="TEMPLATE",
        help="the program's command line, with {scene} and {output} (python3 render.py {scene} "
        "{output}, ./raytracer {scene} {output}), or {stdout} for a program that prints its image",
    )
    group.add_argument("--build", metavar="CMD", help="a command run once per student first, in the sandbox (make)")
    group.add_argument(
        "--run-timeout",
        type=_positive(float, MOST_WAIT),
        metavar="S",
        help="wall time of a run, and of a build (default: 60); the CPU time of each process is "
        "held to the same number of seconds",
    )
    group.add_argument(
        "--memory", type=size, metavar="SIZE", help="memory of the run's processes together (default: 2G)"
    )
    group.add_argument(
        "--processes",
        type=_positive(int, MOST_PROCESSES),
        metavar="N",
        help="processes and threads of a run at once (default: 64)",
    )
    group.add_argument(
        "--output-size", type=size, metavar="SIZE", help="any one file a program writes, and its image (default: 100MB)"
    )
    group.add_argument(
        "--no-sandbox",
        action="store_true",
        help="run the programs without bubblewrap (only the limits apply; every run says so)",
    )
    group.add_argument(
        "--runtime",
        metavar="DIR",
        help="a folder the programs are given, read-only at the same path, its bin/ first on their PATH (a "
        "virtual environment made with /usr/bin/python3 holding NumPy and Pillow)",
    )
    group.add_argument(
        "--runtime-packages",
        type=_names,
        metavar="PKG,...",
        help="Debian packages the programs need (python3-numpy,python3-pil): checked here, installed by the "
        "autograder's setup.sh",
    )


def _names(text: str) -> tuple[str, ...]:
    return tuple(name.strip() for name in text.split(",") if name.strip())


PROGRAM_OPTIONS = (
    "build",
    "no_sandbox",
    "run_timeout",
    "memory",
    "processes",
    "output_size",
    "runtime",
    "runtime_packages",
    "runtime_requirements",
)


def program(args: argparse.Namespace) -> Program | None:
    """The options' program (None without ``--run``); ValueError, in words, for a TA's mistake: a command
    that cannot run, or a program option without ``--run``."""
    if args.run is None:
        named = [f"--{name.replace('_', '-')}" for name in PROGRAM_OPTIONS if getattr(args, name, None)]
        if named:
            raise ValueError(f"{', '.join(named)}: only with --run (the students' program's command line)")
        return None
    from service.programs.limits import Limits
    from service.programs.program import Program

    given: dict[str, Any] = {"memory_bytes": args.memory, "processes": args.processes, "output_bytes": args.output_size}
    if args.run_timeout is not None:
        given.update(wall_seconds=args.run_timeout, cpu_seconds=max(1, int(args.run_timeout)))
    limits = Limits(**{name: value for name, value in given.items() if value is not None})
    runtime = args.runtime
    bundled = hasattr(args, "runtime_requirements")  # (the autograder's options: it builds its own runtime)
    if bundled and args.runtime_requirements:
        from service.programs.runtime import BUNDLED

        if runtime is not None:
            raise ValueError("--runtime and --runtime-requirements: choose one")
        runtime = BUNDLED
    elif bundled and runtime is not None:
        raise ValueError(
            f"--runtime {runtime}: a folder of this machine does not reach Gradescope; name a requirements "
            f"file (--runtime-requirements) or Debian packages (--runtime-packages)"
        )
    packages = args.runtime_packages or ()
    return Program(args.run, args.build, limits, not args.no_sandbox, runtime, packages)
