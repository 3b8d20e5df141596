"""The teaching assistant's folders listed: their entries in order, the files no one means (hidden, an archive
tool's), the students' own scenes, and a folder opened once and read through (:class:`Folder`)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from .errors import ClassError
from .lms import composed
from .untrusted import read_untrusted

#: folders an archive tool leaves beside the students' (never a student)
NOT_STUDENTS = {"__MACOSX"}


def sorted_entries(folder: Path) -> list[os.DirEntry[str]]:
    try:
        with os.scandir(folder) as it:
            return sorted(it, key=lambda e: e.name)
    except OSError as exc:
        raise ClassError(f"{folder}: cannot read: {exc.strerror or exc}") from None


def hidden(name: str) -> bool:
    """A file no one means as a scene or a student: hidden (``.DS_Store``, the ``._spheres.json`` a Mac's archive
    leaves beside each file, an editor's ``.#spheres.json``), or an archive tool's folder (``__MACOSX``)."""
    return name.startswith(".") or name in NOT_STUDENTS


def is_scene(name: str) -> bool:
    return name.endswith(".json") and not hidden(name)


HIDDEN = "a hidden file or an archive tool's (never a scene)"


def task_scenes(scenes: Path) -> tuple[dict[str, Path], list[tuple[str, str]]]:
    """The tasks of a scenes folder, ``<task>.json`` each, and its other files, ignored (and why);
    :class:`ClassError` when there is no task."""
    scene_files = [e for e in sorted_entries(scenes) if e.is_file()]
    tasks = {e.name[:-5]: scenes / e.name for e in scene_files if is_scene(e.name)}
    if not tasks:
        raise ClassError(f"{scenes}: no task scenes (<task>.json)")
    ignored = [
        (str(scenes / e.name), HIDDEN if hidden(e.name) else "not a task scene (<task>.json)")
        for e in scene_files
        if not is_scene(e.name)
    ]
    return tasks, ignored


def own_scenes(folder: Path, tasks: dict[str, Path], ignored: list[tuple[str, str]]) -> dict[str, dict[str, Path]]:
    """``<student>/<task>.json`` of the TA's folder of students' own scenes, by the student's name (composed, as
    the submissions' are); a file for no task stops the run (a hidden one is ``ignored``)."""
    out: dict[str, dict[str, Path]] = {}
    for entry in sorted_entries(folder):
        if hidden(entry.name):
            ignored.append((str(folder / entry.name), HIDDEN))
            continue
        if not entry.is_dir():
            raise ClassError(f"{folder / entry.name}: expected a folder per student (<student>/<task>.json)")
        for file in sorted_entries(folder / entry.name):
            path = folder / entry.name / file.name
            if hidden(file.name):
                ignored.append((str(path), HIDDEN))
                continue
            task = file.name[:-5] if file.name.endswith(".json") else None
            if task not in tasks:
                raise ClassError(f"{path}: names no task (the tasks are {', '.join(sorted(tasks))})")
            out.setdefault(composed(entry.name), {})[task] = path
    return out


def _is_link(entry: os.DirEntry[str]) -> bool:
    try:
        return entry.is_symlink()
    except OSError:
        return False


def _is_folder(entry: os.DirEntry[str]) -> bool:
    """A folder itself, not a link to one (an entry that cannot be looked at is taken as a file: reading it says
    why it cannot be graded)."""
    try:
        return entry.is_dir(follow_symlinks=False)
    except OSError:
        return False


@dataclass(frozen=True)
class Entry:
    name: str
    folder: bool  # a folder itself, not a link to one
    link: bool


class Folder:
    """A folder opened once and held: the TA's submissions folder, or a student's (opened without following a
    link, ``O_NOFOLLOW``, through the folder it is in).  Its entries are listed, its folders opened and its
    files read through it, never by a second lookup of a path, which a student could have swapped for a link
    meanwhile."""

    def __init__(self, fd: int, shown: Path, rel: str = ""):
        self.fd, self.shown, self.rel = fd, shown, rel  # rel: the path below the student's folder ("hw3/")

    @classmethod
    def root(cls, path: Path) -> Folder:
        """The TA's submissions folder (a link to it is the TA's, and followed)."""
        try:
            return cls(os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC), path)
        except OSError as exc:
            raise ClassError(f"{path}: cannot read: {exc.strerror or exc}") from None

    def sub(self, name: str, student: bool = False) -> Folder:
        """A folder in this one (OSError when it cannot be opened, or is a link now); ``student``: a student's
        own folder, the one its files' paths start from."""
        fd = os.open(name, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC, dir_fd=self.fd)
        return Folder(fd, self.shown / name, "" if student else f"{self.rel}{name}/")

    def entries(self) -> list[Entry]:
        """What the folder holds, sorted by name (OSError when it cannot be listed)."""
        with os.scandir(self.fd) as it:
            return sorted((Entry(e.name, _is_folder(e), _is_link(e)) for e in it), key=lambda e: e.name)

    def read(self, name: str, limit: int) -> bytes:
        return read_untrusted(name, limit, dir_fd=self.fd)

    def __enter__(self) -> Folder:
        return self

    def __exit__(self, *exc: object) -> None:
        os.close(self.fd)
