"""The shell lines that run a student's command in its sandbox, and the CPU time they report back.

In the sandbox a shell fills the working folder with the copy of the student's folder, runs the command (its
own child: a program killed by a signal ends the shell with ``128 + n``, as bubblewrap reports it), and then
writes to standard error, after a marker line, the CPU time of the command and of every process it waited for
(the shell's ``times``).  The parent cannot measure that itself: bubblewrap's first process does not reap
the sandbox's first process, so none of the program's CPU time reaches the parent's ``wait4``.  The line is
written through the program's standard error, so a program can forge it: the CPU time shown is then wrong,
but the CPU-time *limit* is the kernel's (``RLIMIT_CPU``) and not affected.  A program killed at the
wall-time limit reports no time (its CPU time is then the part the parent saw, :func:`split_times`).
"""

from __future__ import annotations

import re

from .process import Finished
from .sandbox import OUTPUT, SUBMISSION, SandboxUnavailable
from .unavailable import explain

MARK = "--- phongray: CPU time of the program ---"
_REPORT = f'{{ echo; echo "{MARK}"; times; }} >&2'
#: fill the working folder (sandboxed runs only); the copy is bounded by the folder limit (checked before it),
#: not by the limit on a file written: a student's file larger than the output limit (a library, a mesh) is
#: copied, and only then is the limit on a file lowered to ``$blocks`` (512-byte blocks, soft and hard: no
#: process of the student's can raise it again)
FILL = f"cp -R {SUBMISSION}/. . || exit 125; "
LOWER = "ulimit -f {blocks} || exit 125; "
#: a run: the command (its standard output joined to its standard error), then its CPU time
RUN = f'"$@" >&2; s=$?; {_REPORT}; exit $s'
#: a run whose program prints its image: its standard output written to the output file (``$1``), within the
#: same limits as a file it writes itself (RLIMIT_FSIZE), then its CPU time
RUN_PRINTED = f'o=$1; shift; "$@" >"$o"; s=$?; {_REPORT}; exit $s'
#: a build: the command with its output on standard error, its CPU time, then (built) every other process of the
#: sandbox killed (``kill -1`` spares the shell and the sandbox's first process, bubblewrap's) and the folder
#: written as a tar stream to the output file, which no process of the student's can then write
_KEEP = f"{{ kill -9 -1 2>/dev/null; tar -cf {OUTPUT} . || s=125; }}"
BUILD = f'"$@" >&2; s=$?; {_REPORT}; [ $s -ne 0 ] || {_KEEP}; exit $s'
#: a build without a sandbox, in the run's folder on the machine (copied from there)
BUILD_IN_PLACE = f'"$@" >&2; s=$?; {_REPORT}; exit $s'
_TIME = re.compile(r"(\d+)m([\d.]+)s")


def script(body: str, sandboxed: bool, file_bytes: int | None = None) -> str:
    """The shell's script: (sandboxed) the folder's copy, then (``file_bytes``) the limit on a file lowered to
    that many bytes (rounded up to a block: what is read back is checked to the byte), then ``body``."""
    lower = "" if file_bytes is None else LOWER.format(blocks=-(-file_bytes // 512))
    return (FILL + lower if sandboxed else "") + body


def not_started(finished: Finished) -> None:
    """:class:`SandboxUnavailable` when the sandbox never started the student's command, as bubblewrap itself
    says (:class:`~service.programs.process.Finished`'s ``started``: its status, which no program can write),
    with the last line bubblewrap (or a command before it) wrote: no program of the student's ran, so that
    line is theirs.  A run the parent killed (at its wall time, or its guard's limit) is not asked."""
    if finished.started is not False or finished.timed_out or finished.exceeded or finished.stdout_overflow:
        return
    lines = finished.stderr_tail.decode("utf-8", "replace").strip().splitlines()
    said = lines[-1] if lines else f"bubblewrap ended with status {finished.exit_code} and said nothing"
    raise SandboxUnavailable(f"the sandbox cannot start here: {explain(said)}")


def split_times(stderr: bytes, seen: float) -> tuple[str, float]:
    """Standard error without the report of CPU time, and that time (user and system, of the command and its
    children); ``seen`` (what the parent measured) when there is no report, or it says less."""
    text = stderr.decode("utf-8", "replace")
    head, mark, report = text.rpartition(f"\n{MARK}\n")
    if not mark:
        return text, seen
    lines = report.splitlines()
    found = _TIME.findall(lines[1]) if len(lines) > 1 else []
    cpu = sum(int(m) * 60 + float(s) for m, s in found)
    return head, max(cpu, seen)
