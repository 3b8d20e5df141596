"""How the TA runs every student's program (:class:`Program`), checked when it is made: a command that cannot be
run is the TA's mistake, found before any student is run."""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from .limits import Limits
from .runner import BuildStep, ProgramRun, command_argv
from .runtime import check_names
from .sandbox import SYSTEM, search_path


@dataclass(frozen=True)
class Program:
    """How the TA runs every student's program: the command template (``{scene}``, ``{output}``), the build
    command run once first (None: none), the limits, the sandbox (off only on purpose), and the runtime the
    programs are given (:mod:`service.programs.runtime`: a folder shown read-only, Debian packages)."""

    run: str
    build: str | None = None
    limits: Limits = field(default_factory=Limits)
    sandbox: bool = True
    runtime: str | None = None
    packages: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        """ValueError for a command that cannot be run (the TA's mistake, found before any student is run):
        one that cannot be split, a run that names no ``{scene}`` or no ``{output}``, or a command whose program is
        a name (not a path into the student's folder) that no folder of the sandbox's ``PATH`` holds."""
        ProgramRun(Path("."), self.run, Path("scene.json"))
        if "{scene}" not in self.run:
            raise ValueError(
                f"command {self.run!r}: it names no {{scene}}, the task scene's file the program renders "
                f"(python3 render.py {{scene}} {{output}})"
            )
        if self.build is not None:
            BuildStep(Path("."), self.build)
        check_names(self.runtime, self.packages)
        for command in (self.run, self.build):
            if command is not None:
                _installed(command, search_path(self.runtime))
                _shown(command, self.runtime if self.sandbox else "/")


def _shown(command: str, runtime: str | None) -> None:
    """The command's program, when an absolute path (``/usr/local/bin/node``), is an executable file that the
    programs see: in the sandbox's system folders or the runtime (``runtime`` ``/`` without a sandbox: every
    path), so that a path missing here is not every student's crash."""
    first = command_argv(command)[0]
    if not first.startswith("/") or "{" in first:
        return
    seen = ("/usr", *SYSTEM, *([runtime] if runtime else []))
    real = os.path.realpath(first)  # (a link under /usr to what the sandbox does not show runs nothing either)
    inside = all(any(p == top or p.startswith(top.rstrip("/") + "/") for top in seen) for p in (first, real))
    if not (os.path.isfile(first) and os.access(first, os.X_OK)) or not inside:
        raise ValueError(
            f"command {command!r}: no program {first} that a student's program can run (the sandbox shows "
            f"{', '.join(seen)}); install it there, or name it by its name"
        )


def _installed(command: str, path: str) -> None:
    """The command's program, when a bare name (``python3``, ``make``), is in the sandbox's ``PATH``: the
    system's ``/usr`` (and the runtime) is what a sandboxed program sees, so a name missing here is missing
    for every student."""
    first = command_argv(command)[0]
    if "/" not in first and "{" not in first and shutil.which(first, path=path) is None:
        raise ValueError(
            f"command {command!r}: no program {first!r} in {path} (what a student's program finds in "
            f"its sandbox); install it, or name it by its path"
        )
