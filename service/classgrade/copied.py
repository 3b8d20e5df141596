"""phongray in a student's program: its own code in the folder, or images identical to its references, flagged
for the TA (:func:`flags`).

A student can hand in phongray itself: its code (``tracer/``, ``schemas/``, ``service/``), with NumPy, pydantic
and embreex beside it, fits the folder limit and renders every hidden scene as the reference does.  The sandbox
hides every phongray installed on the machine (:mod:`service.programs.hidden`), not one a student brings.  So the
student's folder is read for phongray's code: the distinct lines of phongray's own source (:func:`fingerprint`:
stripped, at least :data:`LENGTH` characters, imports left out) that its files hold.  A folder that holds
:data:`LINES` of them or more is flagged ``phongray-code``, with the count and the file that holds most: a
vendored phongray holds thousands, a tracer written from the scene format none, and NumPy, pydantic, Pillow or
Python's own library fewer than ten (the lines they share with phongray are the commonplace ones).

A program whose image is the reference's PNG byte for byte on every task is flagged ``identical``, for the TA to
look at: only for review, as it is no proof (a tracer written from the scene format that keeps the equations
exactly, writing its PNG with zlib's defaults as phongray does, makes the same bytes on simple scenes; the
test's own student tracer does).  ``tasks.json``'s ``phongray_code`` says what a task's flagged pair scores:
``review`` (the default: its score stands, the TA's report shows the flag) or ``zero``.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import os
import stat
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..programs.folder import MAX_ENTRIES

if TYPE_CHECKING:
    from .records import Marked

#: a line of phongray's source counts when it is at least this long (stripped): shorter ones are commonplace
LENGTH = 40
#: a folder holding this many distinct lines of phongray's source is flagged
LINES = 100
#: a file read for lines: at most this many bytes, and not a binary one (a NUL in its first 8 KiB)
FILE_BYTES = 4 << 20


@functools.cache
def fingerprint() -> frozenset[bytes]:
    """The distinct lines of phongray's own Python source (this installation's), as :func:`_lines` makes them."""
    roots = [Path(importlib.import_module(name).__file__ or ".").parent for name in ("tracer", "schemas", "service")]
    files = [p for root in roots for p in root.rglob("*.py")]
    found: set[bytes] = set()
    for path in files:
        with contextlib.suppress(OSError):
            found.update(_lines(path.read_bytes()))
    return frozenset(found)


def _lines(data: bytes) -> set[bytes]:
    stripped = (line.strip() for line in data.splitlines())
    return {s for s in stripped if len(s) >= LENGTH and not s.startswith((b"import ", b"from "))}


def _read(path: Path) -> bytes:
    """A regular file's first :data:`FILE_BYTES` (not through a link), or nothing for a binary one."""
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return b""
        data = f.read(FILE_BYTES)
    return b"" if b"\0" in data[:8192] else data


def phongray_code(folder: Path, budget: int, entries: int) -> tuple[int, str]:
    """How many distinct lines of phongray's source the student's folder holds, and the file (its path in the
    folder) that holds most; at most ``budget`` bytes and ``entries`` files and folders are looked at (a
    larger folder is not run)."""
    known = fingerprint()
    held: set[bytes] = set()
    best, most = "", 0
    for root, dirs, files in os.walk(folder, followlinks=False):
        dirs.sort()
        entries -= len(dirs) + len(files)
        if entries < 0:
            break
        for name in sorted(files):
            path = Path(root, name)
            try:
                data = _read(path)
            except OSError:
                continue
            budget -= len(data)
            found = _lines(data) & known
            held |= found
            if len(found) > most:
                best, most = str(path.relative_to(folder)), len(found)
            if budget < 0:
                return len(held), best
    return len(held), best


def flags(
    folder: Path, results: dict[str, Marked], references: dict[str, bytes], limits: Any
) -> tuple[str, str] | None:
    """The flag of every task's result of a student's program (``flag``, ``flag_reason``: the TA's) when its
    folder holds phongray's code, or when every task's image is its reference (``references``, by task) byte
    for byte; else None."""
    count, where = phongray_code(folder, limits.folder_bytes, MAX_ENTRIES)
    if count >= LINES:
        return "phongray-code", f"the program holds {count} lines of phongray's own code (most in {where})"
    if results and all(r.image is not None and r.image == references[t] for t, r in results.items()):
        return "identical", "every image is the reference, byte for byte (for review: an exact tracer can make it)"
    return None
