"""Students' programs, run in a sandbox: build once, then render each scene.

:func:`run_program` runs a :class:`ProgramRun` and returns a :class:`RunOutcome`; :func:`build_program` runs a
:class:`BuildStep` first.  What a program can see and the limits it runs within: :mod:`.sandbox`, :mod:`.limits`.
"""

from .limits import Limits
from .outcome import Reason, RunOutcome
from .runner import BuildStep, Built, ProgramRun, build_program, check_sandbox, command_argv, run_program
from .sandbox import SandboxUnavailable

__all__ = [
    "BuildStep",
    "Built",
    "Limits",
    "ProgramRun",
    "Reason",
    "RunOutcome",
    "SandboxUnavailable",
    "build_program",
    "check_sandbox",
    "command_argv",
    "run_program",
]
