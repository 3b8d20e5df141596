"""How each run's memory and processes are held to its limits, and which way is in force on this machine.

Memory is the run's total, all its processes together: a cgroup of the run's own where one can be made
(:mod:`service.programs.cgroup`: root on a cgroup v2 machine, or ``$PHONGRAY_CGROUP``), else the watchdog
(:mod:`service.programs.watchdog`), which also holds each process to its address space (``RLIMIT_AS``).
Processes are the run's own count whoever runs phongray: in the sandbox, ``RLIMIT_NPROC`` set inside its
own user namespace, where the kernel (Linux 5.14 and later) counts that sandbox's processes and threads
only, and its cgroup's ``pids.max`` where it has one; without the sandbox, a user of the run's own (root)
or the watchdog's count.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import Protocol

from .cgroup import CgroupError, Cgroups, find
from .limits import Limits
from .watchdog import Watchdog


class Guard(Protocol):
    """What :func:`service.programs.process.run_command` asks of a run's guard."""

    name: str
    cpu_seconds: float  # the run's CPU time (once stopped)

    @property
    def waited_seconds(self) -> float:
        """How long the run's processes waited, ready, for a CPU (once stopped)."""

    def start(self, pid: int, kill: Callable[[], None], inside: int | None = None) -> None: ...

    def last_look(self) -> None:
        """At the wall-time limit, just before the kill: settle whether the run is over a limit then."""

    def stop(self) -> str | None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class Enforcement:
    """Where runs' groups are made here, or why none can be."""

    cgroups: Cgroups | None
    why_not: str = ""

    def describe(self) -> str:
        """In a line, which way holds a run's memory and processes here."""
        if self.cgroups is not None:
            return f"each run's memory and processes are held by a cgroup of its own (in {self.cgroups.parent})"
        return (
            f"each run's memory is held by the watchdog, all its processes together (no cgroup of its own: "
            f"{self.why_not}); its processes by the kernel's count in its sandbox"
        )


@cache
def enforcement() -> Enforcement:
    """This machine's way, found once per process."""
    try:
        return Enforcement(find(given=os.environ.get("PHONGRAY_CGROUP")))
    except CgroupError as exc:
        return Enforcement(None, str(exc))


def guard(limits: Limits, sandbox: bool) -> tuple[Guard, list[str]]:
    """A new run's guard, and the argv that runs its command under it (:class:`CgroupError` where its group
    cannot be made)."""
    cgroups = enforcement().cgroups
    if cgroups is not None:
        group = cgroups.group(limits.memory_bytes, limits.processes)
        return group, group.prefix
    counts = None if sandbox or os.geteuid() == 0 else limits.processes
    return Watchdog(limits.memory_bytes, counts, most=limits.processes), []
