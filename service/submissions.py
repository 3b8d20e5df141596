"""A class's folders as a teaching assistant has them, and the students' files as untrusted input.

``SCENES/<task>.json`` are the tasks and ``STUDENT_SCENES/<student>/<task>.json`` (optional) a student's own
scene for a task: both folders are the TA's.  ``SUBMISSIONS/<student>/`` is each student's folder, as a
learning-management system downloads it: the image of a task is ``<task>.png`` there or one folder deeper
(``frank/hw3/spheres.png``), its extension and name matched regardless of case.  A submitted file that is no
PNG (``spheres.jpg``) is graded, and so reported as the format it is.  Nothing in a student's folder is ever
a setting: a scene found there is ignored, with the reason.  Links are never followed, and every byte read
from a student's folder is read by :func:`read_untrusted`.
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


class ClassError(Exception):
    """Input of the teaching assistant's that the batch cannot use: the run stops before any grading."""


class UntrustedFileError(ValueError):
    """A student's file that cannot be read as a submission (a link, not a regular file, too large)."""


#: extensions of images other than PNG: such a file named after a task is that task's (wrong) submission
OTHER_IMAGES = {"jpg", "jpeg", "gif", "bmp", "tif", "tiff", "webp", "heic", "heif", "avif"}
#: folders an archive tool leaves beside the students' (never a student)
NOT_STUDENTS = {"__MACOSX"}
SCENE_IGNORED = ("a scene among the submissions is not used (a student's own scene comes from the TA's "
                 "--student-scenes folder)")


def file_kind(mode: int) -> str:
    """What a file that is not a regular one is, in words (from its ``st_mode``)."""
    return ("a symbolic link; links in submissions are not followed" if stat.S_ISLNK(mode)
            else "a folder, not a file" if stat.S_ISDIR(mode)
            else "a FIFO, not a regular file" if stat.S_ISFIFO(mode)
            else "a device, not a regular file" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
            else "not a regular file")


def read_untrusted(path: Path, limit: int) -> bytes:
    """The bytes of a file in a student's folder: a regular file, not through a link, at most ``limit`` bytes.
    :class:`UntrustedFileError` says why not.  The file is looked at before it is opened (a FIFO or a device is
    never opened), opened without following a link and without blocking, and checked again once open (the same
    file, still regular); no more than ``limit + 1`` bytes are ever read."""
    try:
        before = os.lstat(path)
    except OSError as exc:
        raise UntrustedFileError(f"cannot read: {exc.strerror or exc}") from None
    if not stat.S_ISREG(before.st_mode):
        raise UntrustedFileError(file_kind(before.st_mode))
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        if os.path.islink(path):
            raise UntrustedFileError(file_kind(stat.S_IFLNK)) from None
        raise UntrustedFileError(f"cannot read: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "rb") as f:
            now = os.fstat(f.fileno())
            if not stat.S_ISREG(now.st_mode) or (now.st_dev, now.st_ino) != (before.st_dev, before.st_ino):
                raise UntrustedFileError(f"{file_kind(now.st_mode)} (it changed while it was read)"
                                         if not stat.S_ISREG(now.st_mode) else "changed while it was read")
            data = f.read(limit + 1)
    except OSError as exc:  # EIO, EISDIR, ...: the student's file, not the batch's fault
        raise UntrustedFileError(f"cannot read: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise UntrustedFileError(f"larger than the limit max_image_bytes = {limit} bytes")
    return data


@dataclass
class Pair:
    student: str
    task: str
    image: Path | None  # None: missing
    scene: Path  # the student's own scene (the TA's), or the task's
    own: bool
    key: str | None = None  # the canonical scene hash
    file: str | None = None  # the submitted file, relative to the student's folder (spheres.png, hw3/Spheres.PNG)
    row: dict[str, Any] = field(default_factory=dict)


@dataclass
class Batch:
    tasks: dict[str, Path]
    students: list[str]
    pairs: list[Pair]
    ignored: list[tuple[str, str]]  # (file, why it is not graded)


def _entries(folder: Path) -> list[os.DirEntry[str]]:
    try:
        with os.scandir(folder) as it:
            return sorted(it, key=lambda e: e.name)
    except OSError as exc:
        raise ClassError(f"{folder}: cannot read: {exc.strerror or exc}") from None


def _is_link(entry: os.DirEntry[str]) -> bool:
    try:
        return entry.is_symlink()
    except OSError:
        return False


def _task_of(name: str, tasks: dict[str, Path], folded: dict[str, str]) -> tuple[str | None, str]:
    """The task a file's name is for (its stem exactly, else regardless of case) and its extension, lower case."""
    stem, dot, ext = name.rpartition(".")
    if not dot or not stem:
        return None, ""
    return (stem if stem in tasks else folded.get(stem.lower())), ext.lower()


def _listing(folder: Path) -> tuple[list[os.DirEntry[str]], str]:
    """A student's folder's entries, or (none, why they cannot be listed): the student's fault, not the batch's."""
    try:
        with os.scandir(folder) as it:
            return sorted(it, key=lambda e: e.name), ""
    except OSError as exc:
        return [], f"cannot read the folder: {exc.strerror or exc}"


def _is_folder(entry: os.DirEntry[str]) -> bool:
    """A folder itself, not a link to one (an entry that cannot be looked at is taken as a file: reading it says
    why it cannot be graded)."""
    try:
        return entry.is_dir(follow_symlinks=False)
    except OSError:
        return False


def _student(folder: Path, shown: Path, tasks: dict[str, Path], folded: dict[str, str],
             ignored: list[tuple[str, str]]) -> tuple[dict[str, Path | str], list[str]]:
    """Per task, the submitted file (a path) or why the student's files for it cannot be graded (a reason); and
    the student's folders that cannot be read (``hw3: cannot read the folder: Permission denied``)."""
    top, why = _listing(folder)
    if why:
        return {task: f"{shown}: {why}" for task in tasks}, []
    unreadable: list[str] = []
    candidates: dict[str, list[tuple[tuple[int, int, int], Path, Path]]] = {}
    levels: list[tuple[int, Path, Path, list[os.DirEntry[str]]]] = [(0, folder, shown, top)]
    for e in top:
        if _is_folder(e):
            below, why = _listing(folder / e.name)
            if why:
                unreadable.append(f"{shown / e.name}: {why}")
                ignored.append((str(shown / e.name), why))
            levels.append((1, folder / e.name, shown / e.name, below))
    for depth, base, where, entries in levels:
        for entry in entries:
            path, rel = base / entry.name, where / entry.name
            task, ext = _task_of(entry.name, tasks, folded)
            if _is_folder(entry) and not (task is not None and (ext == "png" or ext in OTHER_IMAGES)):
                if depth:  # (a folder named as a task's image is a candidate: reading it says it is a folder)
                    ignored.append((str(rel), "a folder two levels down (phongray looks one folder deep)"))
                continue
            if task is None:
                ignored.append((str(rel), "matches no task"))
            elif ext == "json":
                ignored.append((str(rel), SCENE_IGNORED))
            elif ext == "png" or ext in OTHER_IMAGES:
                rank = (depth, ext != "png", entry.name.rpartition(".")[0] != task)
                candidates.setdefault(task, []).append((rank, path, rel))
            else:
                ignored.append((str(rel), f"matches task {task}, but is no image"))
    found: dict[str, Path | str] = {}
    for task, options in candidates.items():
        options.sort(key=lambda o: o[0])
        best = [o for o in options if o[0] == options[0][0]]
        if len(best) > 1:
            found[task] = f"{len(best)} files for {task}: {', '.join(str(o[2]) for o in best)}; keep one"
            continue
        found[task] = options[0][1]
        for _, _, rel in options[1:]:
            ignored.append((str(rel), f"another file for {task} is graded: {options[0][2]}"))
    return found, unreadable


def discover(scenes: Path, submissions: Path, student_scenes: Path | None = None) -> Batch:
    """Every (student, task) pair of the class; :class:`ClassError` for a folder of the TA's that is unusable."""
    scene_files = [e for e in _entries(scenes) if e.is_file()]
    tasks = {e.name[:-5]: scenes / e.name for e in scene_files if e.name.endswith(".json")}
    if not tasks:
        raise ClassError(f"{scenes}: no task scenes (<task>.json)")
    folded: dict[str, str] = {}
    for task in tasks:
        folded.setdefault(task.lower(), task)
    ignored = [(str(scenes / e.name), "not a task scene (<task>.json)") for e in scene_files
               if not e.name.endswith(".json")]
    own = _student_scenes(student_scenes, tasks) if student_scenes is not None else {}
    folders: dict[str, Path] = {}
    for entry in _entries(submissions):
        folder = _is_folder(entry)
        if folder and not entry.name.startswith(".") and entry.name not in NOT_STUDENTS:
            folders[entry.name] = submissions / entry.name
        else:  # (a link to a folder is not a student's: it is never listed, let alone read)
            why = ("not a student's folder" if folder else "a symbolic link (not followed)"
                   if _is_link(entry) else "not in a student's folder")
            ignored.append((str(submissions / entry.name), why))
    pairs = []
    students = sorted({*folders, *own})
    for student in students:
        found, unreadable = (_student(folders[student], folders[student], tasks, folded, ignored)
                             if student in folders else ({}, []))
        for task, shared in tasks.items():
            scene = own.get(student, {}).get(task)
            what = found.get(task)
            pair = Pair(student, task, what if isinstance(what, Path) else None, scene or shared, scene is not None)
            if isinstance(what, Path):
                pair.file = what.relative_to(folders[student]).as_posix()
            if isinstance(what, str):
                pair.row = {"status": "invalid", "reason": what}
            elif what is None and unreadable:  # not found, but perhaps in a folder that cannot be read
                pair.row = {"status": "invalid", "reason": f"no {task}.png found; {'; '.join(unreadable)}"}
            pairs.append(pair)
    return Batch(tasks, students, pairs, ignored)


def _student_scenes(folder: Path, tasks: dict[str, Path]) -> dict[str, dict[str, Path]]:
    """``<student>/<task>.json`` of the TA's folder of students' own scenes; a file for no task stops the run."""
    out: dict[str, dict[str, Path]] = {}
    for entry in _entries(folder):
        if not entry.is_dir():
            raise ClassError(f"{folder / entry.name}: expected a folder per student (<student>/<task>.json)")
        for file in _entries(folder / entry.name):
            path = folder / entry.name / file.name
            task = file.name[:-5] if file.name.endswith(".json") else None
            if task not in tasks:
                raise ClassError(f"{path}: names no task (the tasks are {', '.join(sorted(tasks))})")
            out.setdefault(entry.name, {})[task] = path
    return out
