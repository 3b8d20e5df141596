"""A student's file read as untrusted input: a regular file, never through a link, a FIFO or a device, and never
more bytes than the limit."""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path


class UntrustedFileError(ValueError):
    """A student's file that cannot be read as a submission (a link, not a regular file, too large)."""


def file_kind(mode: int) -> str:
    """What a file that is not a regular one is, in words (from its ``st_mode``)."""
    return (
        "a symbolic link; links in submissions are not followed"
        if stat.S_ISLNK(mode)
        else "a folder, not a file"
        if stat.S_ISDIR(mode)
        else "a FIFO, not a regular file"
        if stat.S_ISFIFO(mode)
        else "a device, not a regular file"
        if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
        else "not a regular file"
    )


def read_own(path: Path | str) -> bytes:
    """A TA's own file (a task scene, the tasks file), read whole: a regular file, links followed.  A FIFO, a
    socket or a device (``/dev/zero``), which would wait for a writer that never comes or never end, is refused
    with an OSError saying what it is: it is opened without blocking and looked at once open."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    with os.fdopen(fd, "rb") as f:
        mode = os.fstat(f.fileno()).st_mode
        if not stat.S_ISREG(mode):
            raise OSError(0, file_kind(mode))
        return f.read()


def read_untrusted(path: Path | str, limit: int, dir_fd: int | None = None) -> bytes:
    """The bytes of a file in a student's folder: a regular file, not through a link, at most ``limit`` bytes
    (``path`` a name in the folder open as ``dir_fd``, when given).  :class:`UntrustedFileError` says why not.
    The file is looked at before it is opened (a FIFO or a device is never opened), opened without following a
    link and without blocking, and checked again once open (the same file, still regular); no more than
    ``limit + 1`` bytes are ever read."""
    try:
        before = os.stat(path, dir_fd=dir_fd, follow_symlinks=False)
    except OSError as exc:
        raise UntrustedFileError(f"cannot read: {exc.strerror or exc}") from None
    if not stat.S_ISREG(before.st_mode):
        raise UntrustedFileError(file_kind(before.st_mode))
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, dir_fd=dir_fd)
    except OSError as exc:
        if exc.errno == errno.ELOOP:  # (a link put in its place since it was looked at)
            raise UntrustedFileError(file_kind(stat.S_IFLNK)) from None
        raise UntrustedFileError(f"cannot read: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "rb") as f:
            now = os.fstat(f.fileno())
            if not stat.S_ISREG(now.st_mode) or (now.st_dev, now.st_ino) != (before.st_dev, before.st_ino):
                raise UntrustedFileError(
                    f"{file_kind(now.st_mode)} (it changed while it was read)"
                    if not stat.S_ISREG(now.st_mode)
                    else "changed while it was read"
                )
            data = f.read(limit + 1)
    except OSError as exc:  # EIO, EISDIR, ...: the student's file, not the batch's fault
        raise UntrustedFileError(f"cannot read: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise UntrustedFileError(f"larger than the limit max_image_bytes = {limit} bytes")
    return data
