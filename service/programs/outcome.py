"""How a run of a student's program ended, in a word a report can show: :class:`Reason`, :class:`RunOutcome`.

A run that the parent stopped is a timeout; one that ended by a signal or an exit status other than 0 is
named by the limit it ran into when that is known from the signal (``SIGXCPU``: CPU time; ``SIGXFSZ``: a file
too large) or, as a program that handles the failure itself exits with an error instead, from the usual
messages at the end of its standard error (Python's ``MemoryError``, C++'s ``std::bad_alloc``, ``File too
large``, ...): those words are the program's, so a program can make its crash read as another reason, but
never turn a failure into a success.  A run that succeeded is then judged by its output file.
"""

from __future__ import annotations

import os
import signal
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from tracer.image import decode_png

from .limits import Limits
from .process import Finished
from .scripts import split_times


class Reason(StrEnum):
    OK = "ok"
    TIMEOUT = "timeout"
    CPU_TIME = "cpu-time"
    MEMORY = "memory"
    OUTPUT_TOO_LARGE = "output-too-large"
    CRASHED = "crashed"
    NO_OUTPUT = "no-output"
    OUTPUT_NOT_REGULAR = "output-not-a-regular-file"
    FOLDER_TOO_LARGE = "folder-too-large"
    PROCESSES = "processes"


#: how a run's end is told to a student: the scene it ran on is hidden from them, and a program chooses its
#: exit status, its signal and how it fails (a crash, memory, no output...), so it could spell out in them what
#: it read of the scene; a student is told only whether it ran out of time or failed otherwise (the TA's report
#: keeps every reason and detail).  A folder over its limit is the student's own files, told as it is.
TOLD = {"timeout": "timed out", "cpu-time": "timed out", "folder-too-large": "did not start: the folder is too large"}


def told(reason: Reason) -> str:
    """A run's end as a student is told it: ``timed out``, ``crashed``, or the folder too large."""
    return TOLD.get(str(reason), "crashed")


#: the end of standard error's words for running out of memory, and for writing a file past the limit, in any
#: case (Python's, C++'s, the C library's, Node's ``EFBIG: file too large`` and ``Array buffer allocation failed``)
MEMORY_WORDS = (
    "memoryerror",
    "std::bad_alloc",
    "cannot allocate memory",
    "out of memory",
    "enomem",
    "allocation failed",
    "failed to reserve virtual memory",
)
FILE_SIZE_WORDS = ("file too large", "no space left on device", "efbig")


@dataclass(frozen=True)
class RunOutcome:
    """The end of one run: why (``reason``, and ``detail`` in words), the image it wrote (its bytes, read as an
    untrusted file, or None), the end of its standard error, the time it took, and the warning to show with
    it (a run without a sandbox)."""

    reason: Reason
    detail: str
    image: bytes | None = None
    stderr_tail: str = ""
    wall_seconds: float = 0.0
    cpu_seconds: float = 0.0
    warning: str | None = None
    waited_seconds: float = 0.0  # how long it waited, ready, for a CPU (:func:`busy`)

    @property
    def ok(self) -> bool:
        return self.reason is Reason.OK

    def pixels(self) -> np.ndarray:
        """The image's pixels, decoded as an uploaded image's are (:func:`tracer.image.decode_png`)."""
        if self.image is None:
            raise ValueError(f"the run wrote no image ({self.detail})")
        return decode_png(self.image)


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def _signal(finished: Finished) -> int | None:
    """The signal that ended the program: the wait status's (the sandbox killed), or the shell's ``128 + n``
    for its command's (a status above 128 that a program chose itself reads as a signal too)."""
    code = finished.exit_code
    if code is None:
        return os.WTERMSIG(finished.status)
    return code - 128 if code > 128 else None


def size(count: int) -> str:
    """A number of bytes in words: ``2 GiB``, ``512 MiB``, ``1000 bytes``."""
    for unit, name in ((1 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB")):
        if count % unit == 0:
            return f"{count // unit} {name}"
    return f"{count} bytes"


def _guarded(finished: Finished, limits: Limits) -> tuple[Reason, str] | None:
    """The limit the run's guard ended it for (:mod:`service.programs.guard`), in words."""
    if finished.exceeded == "memory":
        by = finished.held_by or "its guard"
        limit = size(limits.memory_bytes)
        return Reason.MEMORY, f"ran out of memory (limit {limit}, its processes together, held by {by}; killed)"
    if finished.exceeded == "processes":
        return Reason.PROCESSES, f"ran more than {limits.processes} processes and threads at once; killed"
    return None


#: a run killed at its wall time that waited, ready, for a CPU longer than it ran and for at least this part of
#: its wall time was on a busy machine: it was not given the CPU it asked for
BUSY = 0.5


def busy(outcome: RunOutcome) -> str | None:
    """For a run killed at its wall time that waited, ready, for a CPU longer than it ran and for most of that
    time, a line for the TA naming the busy machine (the run's CPU time and its wait: its guard's measure);
    else None.  Kept out of the run's reason, which stays the same however busy the machine."""
    if outcome.reason is not Reason.TIMEOUT:
        return None
    cpu, waited = outcome.cpu_seconds, outcome.waited_seconds
    if waited <= cpu or waited < BUSY * outcome.wall_seconds:
        return None
    return (
        f"timed out having run {cpu:.1f} s and waited {waited:.1f} s for a CPU: the grading machine was busy "
        f"(grade it again with fewer --jobs, or a longer --run-timeout)"
    )


def failure(finished: Finished, limits: Limits) -> tuple[Reason, str] | None:
    """Why the run failed, before its output is looked at; None when it exited with status 0."""
    guarded = _guarded(finished, limits)
    if guarded is not None:
        return guarded
    if finished.timed_out:
        return Reason.TIMEOUT, f"still running at the wall-time limit of {limits.wall_seconds:g} s; killed"
    sig = _signal(finished)
    code = finished.exit_code
    if sig is None and code == 0:
        return None
    tail, cpu = split_times(finished.stderr_tail, finished.cpu_seconds)
    if sig == signal.SIGXCPU or (sig == signal.SIGKILL and cpu >= limits.cpu_seconds):
        return Reason.CPU_TIME, f"used the CPU-time limit of {limits.cpu_seconds} s; killed"
    words = tail.lower()
    if sig == signal.SIGXFSZ or any(word in words for word in FILE_SIZE_WORDS):
        return Reason.OUTPUT_TOO_LARGE, f"wrote more than the output limit of {limits.output_bytes} bytes"
    ended = f"killed by {_signal_name(sig)}" if sig is not None else f"exit {code}"
    if any(word in words for word in MEMORY_WORDS):
        return Reason.MEMORY, f"ran out of memory (limit {size(limits.memory_bytes)}; {ended})"
    return Reason.CRASHED, f"crashed ({ended})"
