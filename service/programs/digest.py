"""What a kept grade of a student's program stands for (:func:`digest`): a class graded again takes a kept grade
only when the program is the same, and run the same way.

The digest is a SHA-256 of records, each of fixed shape, so that two different folders never make the same
bytes to hash (every name and every content is preceded by its length): how the program is built, run and
limited, the runtime it is given (its folder and its Debian packages, by name), then each folder and regular
file of the student's folder that a run's copy would hold (:mod:`service.programs.folder`: read through
the folder's descriptors, never following a link, no deeper than :data:`~.folder.MAX_DEPTH`, no path longer
than :data:`~.folder.MAX_PATH`), in order of name, a file with whether it is executable (a program handed in
without its executable bit and given it later is another program) and its bytes.  No more than the folder
limit's bytes or :data:`~.folder.MAX_ENTRIES` entries are read: a larger folder is not run.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import stat
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..course.folders import Folder
from .folder import MAX_DEPTH, MAX_ENTRIES, MAX_PATH

if TYPE_CHECKING:
    from .program import Program

#: bytes read from a file at a time
CHUNK = 1 << 20


def _record(sha: Any, kind: bytes, *parts: bytes) -> None:
    """One record: its kind, then each part preceded by its length."""
    sha.update(kind)
    for part in parts:
        sha.update(len(part).to_bytes(8, "big") + part)


class _Digesting:
    """The budget of one digest: bytes and entries left."""

    def __init__(self, sha: Any, limit: int):
        self.sha, self.left, self.entries = sha, limit, MAX_ENTRIES

    def folder(self, source: Folder, depth: int) -> None:
        try:
            entries = source.entries()
        except OSError:
            return
        for entry in entries:
            name = source.rel + entry.name
            if entry.link or len(os.fsencode(name)) > MAX_PATH or self.left < 0 or self.entries < 0:
                continue
            self.entries -= 1
            if entry.folder and depth < MAX_DEPTH:
                with contextlib.suppress(OSError), source.sub(entry.name) as sub:
                    _record(self.sha, b"D", os.fsencode(name))
                    self.folder(sub, depth + 1)
            elif not entry.folder:
                with contextlib.suppress(OSError):
                    self.file(source, entry.name, os.fsencode(name))

    def file(self, source: Folder, name: str, shown: bytes) -> None:
        """A regular file's record (a FIFO's, a device's or a link's none): its name, whether it is
        executable, and its bytes' own SHA-256 with their length."""
        fd = os.open(name, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, dir_fd=source.fd)
        with os.fdopen(fd, "rb") as f:
            mode = os.fstat(fd).st_mode
            if not stat.S_ISREG(mode):
                return
            content, size = hashlib.sha256(), 0
            while self.left >= 0 and (chunk := f.read(CHUNK)):
                content.update(chunk)
                size += len(chunk)
                self.left -= len(chunk)
        executable = b"x" if mode & 0o111 else b"-"
        _record(self.sha, b"F", shown, executable, str(size).encode(), content.digest())


def digest(folder: Path, program: Program) -> str:
    """What a kept grade of the program in ``folder`` stands for (see the module's docstring)."""
    sha = hashlib.sha256()
    how = (program.run, program.build, program.limits, program.sandbox)
    packages = [p.encode() for p in program.packages]
    _record(sha, b"P", repr(how).encode(), os.fsencode(program.runtime or ""), str(len(packages)).encode(), *packages)
    with contextlib.suppress(OSError):
        opened = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        with Folder(opened, folder) as root:
            _Digesting(sha, program.limits.folder_bytes).folder(root, 0)
    return sha.hexdigest()
