"""A student's folder as bytes (:class:`Pack`), so that the program can be graded wherever the work runs (a
pool process here, or a Dask worker that shares no file system with the grading machine).

The pack is made where the submissions are: the folder is copied as a run's copy is
(:func:`service.programs.folder.copy_folder`: regular files and folders only, a link never followed, within
the folder limit) and that copy written as a tar stream, its names sorted and its times, owners and modes
set to fixed values (a file is executable or not), so that the same folder always makes the same bytes.
Its SHA-256 travels with it: where the program is graded, :func:`unpacked` checks the bytes against it
before unpacking them (with :func:`service.programs.folder.unpack`'s rules and limit) into a folder of its
own, removed afterwards.  A folder over the limit makes a pack that says so and holds nothing.
"""

from __future__ import annotations

import hashlib
import io
import os
import tarfile
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from .folder import FolderTooLarge, copy_folder, unpack


@dataclass(frozen=True)
class Pack:
    """A student's folder as a tar stream and its SHA-256; or, for a folder over the limit, why not."""

    data: bytes
    sha256: str
    too_large: str | None = None


def _add(tar: tarfile.TarFile, root: Path, path: Path) -> None:
    info = tar.gettarinfo(str(path), arcname=path.relative_to(root).as_posix())
    info.mtime, info.uid, info.gid, info.uname, info.gname = 0, 0, 0, "", ""
    info.mode = 0o700 if info.isdir() or info.mode & 0o100 else 0o600
    if info.isreg():
        with open(path, "rb") as f:
            tar.addfile(info, f)
    else:
        tar.addfile(info)


def _stream(root: Path) -> bytes:
    """The tar stream of ``root``'s copy (trusted: phongray made it), in a fixed order, with fixed headers."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w", format=tarfile.PAX_FORMAT) as tar:
        for folder, dirs, files in os.walk(root):
            dirs.sort()
            for name in [*dirs, *sorted(files)]:
                _add(tar, root, Path(folder, name))
    return buffer.getvalue()


def pack_folder(folder: Path, limit: int) -> Pack:
    """The student's ``folder`` as a :class:`Pack`, at most ``limit`` bytes of files (see the module)."""
    with tempfile.TemporaryDirectory(prefix="phongray-pack-") as place:
        try:
            copy_folder(folder, Path(place), limit)
        except FolderTooLarge as exc:
            return Pack(b"", "", str(exc))
        data = _stream(Path(place))
    return Pack(data, hashlib.sha256(data).hexdigest())


class DamagedPack(Exception):
    """A pack whose bytes are not those it was made with (damaged on its way)."""


@contextmanager
def unpacked(pack: Pack, limit: int) -> Iterator[Path]:
    """The pack unpacked into a folder of its own (removed afterwards), at most ``limit`` bytes of files;
    :class:`DamagedPack` when its bytes do not have its digest."""
    if hashlib.sha256(pack.data).hexdigest() != pack.sha256:
        raise DamagedPack("the student's folder arrived damaged: its digest is not the one it was sent with")
    with tempfile.TemporaryDirectory(prefix="phongray-student-") as place:
        unpack(pack.data, Path(place), limit)
        yield Path(place)
