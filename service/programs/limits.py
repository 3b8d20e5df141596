"""The limits a student's program runs within, and how each is put on it.

CPU time and file size are resource limits (``setrlimit``) that the sandbox and every process in it inherit;
memory and processes are the run's, all its processes together (:mod:`service.programs.guard` says how they
are held); wall time is the parent's (:mod:`service.programs.process` kills the whole sandbox); the output
size is also the size of the tmpfs folders a program can write to (:mod:`service.programs.sandbox`).
"""

from __future__ import annotations

from dataclasses import dataclass

GIB = 1 << 30
MB = 1000 * 1000
#: the files each process of a run may hold open (``RLIMIT_NOFILE``, soft and hard): what each open file can
#: hold in the kernel is counted to its memory (:mod:`service.programs.usage`), and this bounds the count's cost
#: and the sockets a process can have in flight, held by no process (the kernel allows a user as many as this)
OPEN_FILES = 256


@dataclass(frozen=True)
class Limits:
    """What one run (or one build) of a student's program may use; the defaults are a course's.

    ``memory_bytes`` is the memory of the run's processes together, ``processes`` its processes and threads at
    once (:mod:`service.programs.guard`), ``cpu_seconds`` each process's CPU time (``RLIMIT_CPU``),
    ``wall_seconds`` the whole run from start to end, ``output_bytes`` any one file written (``RLIMIT_FSIZE``) and
    the image read back; ``folder_bytes`` the private copy of the student's folder (and of a build's result);
    ``stderr_bytes`` how much of the end of the program's output is kept to show."""

    memory_bytes: int = 2 * GIB
    processes: int = 64
    wall_seconds: float = 60.0
    cpu_seconds: int = 60
    output_bytes: int = 100 * MB
    folder_bytes: int = 100 * MB
    stderr_bytes: int = 4096

    def __post_init__(self) -> None:
        for name in (
            "memory_bytes",
            "processes",
            "wall_seconds",
            "cpu_seconds",
            "output_bytes",
            "folder_bytes",
            "stderr_bytes",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, not {getattr(self, name)!r}")

    def prlimit_argv(
        self, address_space: bool = True, processes: bool = False, file_bytes: int | None = None
    ) -> list[str]:
        """``prlimit`` (util-linux) setting these limits, soft and hard, on the command that follows it: the CPU
        time, file size (``file_bytes`` in place of the output limit: a build's result), :data:`OPEN_FILES` and
        no core file; with ``address_space``, each process's address space at most the memory limit; with
        ``processes``, ``RLIMIT_NPROC`` (which counts the processes of a user, in a user namespace).  The CPU
        limit's hard value is one second above the soft one, so a program first gets ``SIGXCPU`` (which
        :mod:`service.programs.outcome` names) and is killed a second later if it ignores it."""
        return [
            "prlimit",
            *([f"--as={self.memory_bytes}"] if address_space else []),
            *([f"--nproc={self.processes}"] if processes else []),
            f"--cpu={self.cpu_seconds}:{self.cpu_seconds + 1}",
            f"--fsize={file_bytes or self.output_bytes}",
            f"--nofile={OPEN_FILES}",
            "--core=0",
            "--",
        ]

    @property
    def workdir_bytes(self) -> int:
        """The size of the tmpfs that is the program's working folder: the copy of its folder and room for
        what it writes there, at most :attr:`output_bytes` more."""
        return self.folder_bytes + self.output_bytes
