"""A cgroup (v2) of its own for each run, where the grading machine lets phongray make one: the kernel then
holds the run's processes together to its memory limit and its process limit.

The runs' groups are made in one parent group: ``$PHONGRAY_CGROUP`` (a group the grading user may write,
delegated to it, with phongray running in another group of that delegated subtree), or, for root,
``/sys/fs/cgroup/phongray`` (made when missing, with the memory and pids controllers enabled for it).  Each
run gets ``<parent>/run-<pid>-<random>`` with ``memory.max`` (no swap) and ``pids.max``; its command moves
itself in before it starts the sandbox, so that every process of the run is counted from the first.  Past
its memory the kernel kills the whole group (``memory.oom.group``) and the run ends as ``memory``; past its
processes a ``fork`` fails, as under ``RLIMIT_NPROC``.  The group counts what the run's tmpfs folders hold
too.  Where the machine offers the cpu controller, each run's group has one share of the CPU (the default
``cpu.weight``), and says how long its processes waited for one (``cpu.pressure``).  It is removed when the
run ends (a group left by a grader that died is removed by the next).

Where no such group can be made (a cgroup v1 machine, a container whose cgroup holds its processes, a user
with no delegated subtree) :func:`find` says why, and :mod:`service.programs.watchdog` holds the limits.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

MOUNT = Path("/sys/fs/cgroup")
#: the controllers a run's group needs, and the one it has where the machine offers it (its CPU: each run's group
#: has the same weight, so each run gets one share of the CPU however many processes or sessions it makes)
CONTROLLERS, OPTIONAL = ("memory", "pids"), ("cpu",)
#: processes outside the sandbox the group also holds (bubblewrap's own)
OUTER = 2
#: how long a run's group is given to empty once the run has ended, before it is left for the next grader
REMOVE_SECONDS = 2.0
#: the command that moves itself into the group (``$0``) and then runs the rest
MOVE_IN = 'echo $$ > "$0/cgroup.procs" && exec "$@"'


class CgroupError(Exception):
    """No run's group can be made here; its message says why."""


def _write(path: Path, text: str) -> None:
    try:
        path.write_text(text)
    except OSError as exc:
        raise CgroupError(f"cannot write {text.strip()!r} to {path} ({exc.strerror or exc})") from None


def _enable(group: Path) -> None:
    """The memory and pids controllers enabled for the children of ``group``, and the cpu controller where it
    offers it (once there, nothing written)."""
    offered = set((group / "cgroup.controllers").read_text().split())
    if not set(CONTROLLERS) <= offered:
        raise CgroupError(f"{group} does not offer the memory and pids controllers")
    wanted = [*CONTROLLERS, *(c for c in OPTIONAL if c in offered)]
    if not set(wanted) <= set((group / "cgroup.subtree_control").read_text().split()):
        _write(group / "cgroup.subtree_control", " ".join(f"+{c}" for c in wanted))


def _pairs(path: Path) -> dict[str, str]:
    """A cgroup file of ``name value`` lines (``memory.events``, ``cpu.stat``); empty where it cannot be read."""
    try:
        return dict(line.split()[:2] for line in path.read_text().splitlines() if len(line.split()) >= 2)
    except OSError:
        return {}


class RunGroup:
    """One run's group (a guard of :mod:`service.programs.process`): :attr:`prefix` runs a command in it;
    :meth:`stop` says whether the kernel killed the run for its memory; :meth:`close` removes it."""

    name = "its cgroup"

    def __init__(self, path: Path, memory_bytes: int, processes: int):
        self.path = path
        self.cpu_seconds = self.waited_seconds = 0.0
        path.mkdir()
        try:
            _write(path / "memory.max", str(memory_bytes))
            with contextlib.suppress(CgroupError, FileNotFoundError):  # (no swap accounting: no swap to limit)
                _write(path / "memory.swap.max", "0")
            _write(path / "memory.oom.group", "1")
            _write(path / "pids.max", str(processes + OUTER))
        except BaseException:
            self.close()
            raise
        self.prefix = ["/bin/sh", "-c", MOVE_IN, str(path)]

    def start(self, pid: int, kill: Callable[[], None], inside: int | None = None) -> None:
        """Nothing to do: the kernel holds the limits."""

    def last_look(self) -> None:
        """Nothing to do: the kernel has killed a run over its memory at once."""

    def stop(self) -> str | None:
        events = _pairs(self.path / "memory.events")
        self.cpu_seconds = int(_pairs(self.path / "cpu.stat").get("usage_usec", 0)) / 1e6
        with contextlib.suppress(OSError, ValueError, IndexError):  # (cpu.pressure: where the kernel keeps it)
            some = (self.path / "cpu.pressure").read_text().splitlines()[0]
            self.waited_seconds = int(some.rpartition("total=")[2]) / 1e6
        return "memory" if int(events.get("oom_kill", 0)) + int(events.get("oom_group_kill", 0)) else None

    def close(self) -> None:
        """Kill what is left in the group (nothing, once the sandbox has gone) and remove it."""
        with contextlib.suppress(OSError):
            (self.path / "cgroup.kill").write_text("1")
        deadline = time.monotonic() + REMOVE_SECONDS
        while True:
            try:
                self.path.rmdir()
                return
            except FileNotFoundError:
                return
            except OSError:
                if time.monotonic() > deadline:
                    return  # (left, empty, for the next grader to remove)
                time.sleep(0.02)


class Cgroups:
    """The parent group the runs' groups are made in."""

    def __init__(self, parent: Path):
        self.parent = parent

    def group(self, memory_bytes: int, processes: int) -> RunGroup:
        """A new run's group; :class:`CgroupError` where it cannot be made."""
        path = self.parent / f"run-{os.getpid()}-{secrets.token_hex(4)}"
        try:
            return RunGroup(path, memory_bytes, processes)
        except OSError as exc:
            raise CgroupError(f"cannot make {path} ({exc.strerror or exc})") from None

    def sweep(self) -> None:
        """Remove the groups of graders that have ended (left behind when one died)."""
        for group in self.parent.glob("run-*-*"):
            pid = group.name.split("-")[1]
            if pid.isdigit() and not Path(f"/proc/{pid}").exists():
                with contextlib.suppress(OSError):
                    group.rmdir()

    def check(self) -> None:
        """A group made, a process moved into it and the group removed: :class:`CgroupError` where not."""
        run = self.group(1 << 30, 8)
        try:
            moved = subprocess.run([*run.prefix, "true"], capture_output=True, text=True, check=False)
            if moved.returncode != 0:
                raise CgroupError(f"cannot move a process into {run.path}: {moved.stderr.strip()}")
        finally:
            run.close()


def find(mount: Path = MOUNT, given: str | None = None, root: bool | None = None) -> Cgroups:
    """Where the runs' groups are made here (see the module's docstring): ``given`` is ``$PHONGRAY_CGROUP``;
    :class:`CgroupError`, saying why, where they cannot be made."""
    root = os.geteuid() == 0 if root is None else root
    if given:
        parent = Path(given)
        if not (parent / "cgroup.controllers").is_file():
            raise CgroupError(f"PHONGRAY_CGROUP={given} is not a cgroup v2 group")
    elif not root:
        raise CgroupError("the grading user is not root and PHONGRAY_CGROUP names no group delegated to it")
    elif not (mount / "cgroup.controllers").is_file():
        raise CgroupError(f"{mount} is not a cgroup v2 hierarchy (this machine uses cgroup v1)")
    else:
        parent = mount / "phongray"
        try:
            _enable(mount)
            parent.mkdir(exist_ok=True)
        except OSError as exc:
            raise CgroupError(f"cannot make {parent} ({exc.strerror or exc})") from None
    try:
        _enable(parent)
    except OSError as exc:
        raise CgroupError(f"cannot read {parent} ({exc.strerror or exc})") from None
    cgroups = Cgroups(parent)
    cgroups.sweep()
    cgroups.check()
    return cgroups
