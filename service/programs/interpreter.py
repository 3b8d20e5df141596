"""Whether the interpreter the TA's run command names starts within a run's memory, checked before any student
is run.

A run's memory holds each of its processes to its address space where the watchdog guards it
(``RLIMIT_AS``, :mod:`service.programs.guard`), and some interpreters reserve far more address space than they
touch: Node's V8 reserves its code range as it starts, and under ``--memory 512M`` dies with "Failed to reserve
virtual memory" before running a line.  Every student's program would then end as ``memory``: the TA's
mistake, told once, before any student is run, with the least memory of a few in which it starts; as is an
interpreter that crashes doing nothing (Python under 4 MiB) or cannot start its threads within ``--processes``.
"""

from __future__ import annotations

import shlex
import tempfile
from dataclasses import replace
from pathlib import Path

from .limits import GIB, Limits
from .outcome import Reason
from .program import Program
from .runner import ProgramRun, command_argv, run_program

#: interpreters a run command names, by name, and arguments that start them and do nothing
IDLE: dict[str, str] = {
    "node": "-e 0",
    "nodejs": "-e 0",
    "python3": "-c pass",
    "python": "-c pass",
    "java": "-version",
    "ruby": "-e 0",
    "perl": "-e 0",
}
#: how long an interpreter is given to start and do nothing
WALL_SECONDS = 30.0
#: how an idle interpreter ends that started: it writes no image
STARTED = (Reason.OK, Reason.NO_OUTPUT)
#: the largest memory a failing interpreter is tried with, doubling from the run's
MOST = 16 * GIB


def fails_to_start(program: Program) -> str | None:
    """One line when the run command's interpreter (one of :data:`IDLE`) cannot start and do nothing within the
    run's limits, or None: a command whose program is the student's own, or another, is not looked at.  Where
    more memory lets it start, the line says how much (doubling the run's, up to :data:`MOST`)."""
    first = command_argv(program.run)[0]
    name = Path(first).name
    if name not in IDLE:
        return None
    given = program.limits.memory_bytes
    idle = f"{shlex.quote(first)} {IDLE[name]} {{output}}"  # (the interpreter as the command names it)
    failed = _failure(program, idle, given)
    if failed is None:
        return None
    sizes = [given << k for k in range(1, 8) if given << k <= MOST]
    least = next((size for size in sizes if _failure(program, idle, size) is None), None)
    if least is None:
        limits = f"--memory {_size(given)}, --processes {program.limits.processes}"
        return f"{name} fails as it starts within a run's limits ({limits}), before any student's code ({failed})"
    return (
        f"--memory {_size(given)}: {name} fails as it starts, before any student's code ({failed}); "
        f"it starts with --memory {_size(least)}"
    )


def _failure(program: Program, idle: str, memory: int) -> str | None:
    """How the interpreter ended, when it did not start and do nothing within the run's limits with ``memory``
    (its reason, and the first line it printed); else None."""
    limits: Limits = replace(program.limits, memory_bytes=memory, wall_seconds=WALL_SECONDS)
    with tempfile.TemporaryDirectory(prefix="phongray-interpreter-") as empty:
        scene = Path(empty, "scene.json")
        scene.write_text("{}")
        outcome = run_program(ProgramRun(Path(empty), idle, scene, limits, program.sandbox, program.runtime))
    if outcome.reason in STARTED:
        return None
    lines = [line.strip(" #") for line in outcome.stderr_tail.splitlines() if line.strip(" #")]
    return f"{outcome.reason}: {lines[0] if lines else outcome.detail}"


def _size(size: int) -> str:
    """A size as ``--memory`` takes it: ``768M``, ``2G``."""
    return f"{size // GIB}G" if size % GIB == 0 else f"{size >> 20}M"
