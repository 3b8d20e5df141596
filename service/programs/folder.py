"""The private copy of a student's folder a program runs in, made without trusting anything in it.

The copy holds the student's regular files and folders only: a link is skipped, never followed (it could name
the TA's files, or another student's), and so is a FIFO, a socket or a device, and whatever is deeper or has a
longer path than the copy keeps (:data:`MAX_DEPTH`, :data:`MAX_PATH`).  A folder that holds more
than a limit of bytes, or more than :data:`MAX_ENTRIES` files and folders, is :class:`FolderTooLarge`, so a
student cannot fill the disk of the machine that grades, nor make each run spend its time (outside every
limit of the run) copying and removing a folder of a hundred thousand empty files: the folder is measured,
listing it without reading a file, before anything is copied.  A build's result comes back out of its sandbox
as a tar stream (:func:`unpack`), read with the same rules.
"""

from __future__ import annotations

import errno
import io
import os
import stat
import tarfile
from collections.abc import Iterator
from pathlib import Path, PurePosixPath

from ..course.errors import ClassError
from ..course.folders import Folder
from ..course.untrusted import UntrustedFileError

#: how deep a student's folders are followed, and the longest path (in bytes, below the student's folder) a
#: file or folder may have: deeper and longer ones are left out, as links are (each name may be 255 bytes, so a
#: folder can hold paths longer than the machine's PATH_MAX, 4096, which no file of the copy could then have)
MAX_DEPTH, MAX_PATH = 32, 1024
#: bytes each file or folder counts for besides its content (a tar header's size), so that a folder of a
#: million empty files is over the limit too
ENTRY_BYTES = 512
#: the most files and folders a student's folder (or a build's result) may hold: a program with its vendored
#: packages holds a few thousand (NumPy's are 1,650), and copying ten thousand small files takes well under
#: a second
MAX_ENTRIES = 10_000


class FolderTooLarge(Exception):
    """The student's folder (or what a build left in it) holds more than the limit allows."""


class _Budget:
    def __init__(self, limit: int, entries: int = MAX_ENTRIES):
        self.left, self.entries = limit, entries

    def take(self, size: int) -> None:
        self.left -= size + ENTRY_BYTES
        self.entries -= 1
        if self.left < 0:
            raise FolderTooLarge("the student's folder is larger than the limit")
        if self.entries < 0:
            raise FolderTooLarge(f"the student's folder holds more than {MAX_ENTRIES} files and folders")


def _write_new(path: Path, data: bytes) -> None:
    """A new regular file at ``path`` (never through a link, never over an existing file)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)


def _mode(source: Folder, name: str) -> int:
    """The copy's mode: executable (by its owner only) when the student's file is."""
    try:
        executable = os.stat(name, dir_fd=source.fd, follow_symlinks=False).st_mode & 0o111
    except OSError:
        executable = 0
    return 0o700 if executable else 0o600


def _left_out(source: Folder, name: str) -> bool:
    """A file or folder whose path below the student's folder is longer than :data:`MAX_PATH`."""
    return len(os.fsencode(source.rel + name)) > MAX_PATH


def _copy(source: Folder, target: Path, budget: _Budget, depth: int) -> None:
    try:
        entries = source.entries()
    except OSError:  # (a folder that cannot be listed is copied empty)
        return
    for entry in entries:
        if entry.link or _left_out(source, entry.name):
            continue
        if entry.folder:
            if depth < MAX_DEPTH:
                _copy_folder(source, entry.name, target, budget, depth)
            continue
        try:
            data = source.read(entry.name, max(budget.left, 0))
        except UntrustedFileError as exc:
            if "larger than the limit" in str(exc):
                raise FolderTooLarge("the student's folder is larger than the limit") from None
            continue  # a FIFO, a device, a file that cannot be read: not part of the program
        budget.take(len(data))
        _write_new(target / entry.name, data)
        os.chmod(target / entry.name, _mode(source, entry.name))


def _copy_folder(source: Folder, name: str, target: Path, budget: _Budget, depth: int) -> None:
    """Copy the folder ``name`` of ``source``; one that cannot be opened (or is a link now) is left out."""
    try:
        sub = source.sub(name)
    except OSError:
        return
    with sub:
        budget.take(0)
        (target / name).mkdir(mode=0o700)
        _copy(sub, target / name, budget, depth + 1)


def _listed(source: Folder) -> Iterator[tuple[str, os.stat_result | OSError]]:
    """The entries of ``source`` the copy looks at (their paths within :data:`MAX_PATH`), each with its status
    as it is (a link not followed), or the error its status gave; the listing's own error is raised."""
    with os.scandir(source.fd) as listing:
        for entry in listing:
            if _left_out(source, entry.name):
                continue
            try:
                yield entry.name, entry.stat(follow_symlinks=False)
            except OSError as exc:
                yield entry.name, exc


def _measure(source: Folder, budget: _Budget, depth: int) -> None:
    """Count what :func:`_copy` would copy, its regular files' sizes as listed (no file is read), stopping
    with :class:`FolderTooLarge` at the first entry over the budget."""
    try:
        for name, info in _listed(source):
            if isinstance(info, OSError):
                continue
            if stat.S_ISREG(info.st_mode):
                budget.take(info.st_size)
            elif stat.S_ISDIR(info.st_mode) and depth < MAX_DEPTH:
                budget.take(0)
                try:
                    sub = source.sub(name)
                except OSError:
                    continue
                with sub:
                    _measure(sub, budget, depth + 1)
    except OSError:  # (a folder that cannot be listed is copied empty)
        return


def unreadable(student: Path) -> str | None:
    """The first of a student's files and folders that this user may not read, as its path below the student's
    folder (``""``: the folder itself), among what :func:`copy_folder` would copy, walked as :func:`_measure`
    walks it (regular files and folders, no link, within :data:`MAX_DEPTH`, :data:`MAX_PATH` and
    :data:`MAX_ENTRIES`); None when it may read them all.  Only a refusal counts (``EACCES``, ``EPERM``): what
    vanished meanwhile the copy does not find either."""
    if not os.access(student, os.R_OK | os.X_OK):
        return ""
    try:
        root = Folder.root(student)
    except ClassError:
        return None
    with root:
        return _unreadable(root, [MAX_ENTRIES], 0)


def _refused(exc: OSError) -> bool:
    return exc.errno in (errno.EACCES, errno.EPERM)


def _unreadable(source: Folder, left: list[int], depth: int) -> str | None:
    """:func:`unreadable` below ``source``, ``left[0]`` the entries it may still look at."""
    try:
        for name, info in _listed(source):
            if isinstance(info, OSError):
                if _refused(info):
                    return source.rel + name
                continue
            folder = stat.S_ISDIR(info.st_mode)
            if not (stat.S_ISREG(info.st_mode) or (folder and depth < MAX_DEPTH)):
                continue
            left[0] -= 1
            if left[0] < 0:
                return None
            if not os.access(name, os.R_OK | os.X_OK if folder else os.R_OK, dir_fd=source.fd, follow_symlinks=False):
                return source.rel + name + ("/" if folder else "")
            found = _unreadable_in(source, name, left, depth) if folder else None
            if found is not None:
                return found
    except OSError as exc:
        return source.rel if _refused(exc) else None
    return None


def _unreadable_in(source: Folder, name: str, left: list[int], depth: int) -> str | None:
    try:
        sub = source.sub(name)
    except OSError as exc:
        return f"{source.rel}{name}/" if _refused(exc) else None
    with sub:
        return _unreadable(sub, left, depth + 1)


def copy_folder(student: Path, target: Path, limit: int) -> None:
    """Copy the student's folder into the empty folder ``target``: regular files and folders only, at most
    ``limit`` bytes of files and :data:`MAX_ENTRIES` entries (:class:`FolderTooLarge` beyond, found before
    anything is copied).  Files keep their executable bit, as a program built by the student needs it."""
    with Folder.root(student) as root:
        _measure(root, _Budget(limit), 0)
        _copy(root, target, _Budget(limit), 0)


def _safe_name(name: str) -> PurePosixPath | None:
    """A name of a build's tar stream as a path in the folder; None for one that leaves it, is deeper than
    :data:`MAX_DEPTH` or longer than :data:`MAX_PATH` (left out, as the copy of a student's folder leaves them)."""
    path = PurePosixPath(name)
    parts = [p for p in path.parts if p not in ("", ".")]
    if path.is_absolute() or ".." in parts or not parts or len(parts) > MAX_DEPTH + 1:
        return None
    kept = PurePosixPath(*parts)
    return kept if len(os.fsencode(str(kept))) <= MAX_PATH else None


def unpack(stream: bytes, target: Path, limit: int) -> None:
    """Unpack a build's result, a tar stream made in its sandbox, into the empty folder ``target``: folders
    and regular files only (links, devices and names leaving the folder are skipped), at most ``limit``
    bytes of files."""
    budget = _Budget(limit)
    with tarfile.open(fileobj=io.BytesIO(stream), mode="r:") as tar:
        for member in tar:
            name = _safe_name(member.name)
            if name is None or not (member.isdir() or member.isreg()):
                continue
            budget.take(member.size if member.isreg() else 0)
            try:
                _unpack_member(tar, member, target / name)
            except OSError:  # (a name that is both a file and a folder in the stream: the first one stays)
                continue


def _unpack_member(tar: tarfile.TarFile, member: tarfile.TarInfo, path: Path) -> None:
    os.makedirs(path.parent, mode=0o700, exist_ok=True)  # (only folders and regular files are made in target)
    if member.isdir():
        os.makedirs(path, mode=0o700, exist_ok=True)
        return
    extracted = tar.extractfile(member)
    if extracted is not None:
        _write_new(path, extracted.read())
        os.chmod(path, 0o700 if member.mode & 0o111 else 0o600)


def chown_tree(root: Path, uid: int) -> None:
    """Give ``root`` and everything in it to ``uid`` (the sandbox's user), when this process may."""
    if os.geteuid() != 0:
        return
    os.chown(root, uid, uid, follow_symlinks=False)
    for path in root.rglob("*"):
        os.chown(path, uid, uid, follow_symlinks=False)
