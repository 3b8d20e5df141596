"""The teaching assistant's folders listed: their entries in order, the files no one means (hidden, an archive
tool's), and the students' own scenes."""

from __future__ import annotations

import os
from pathlib import Path

from .errors import ClassError
from .lms import composed

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
    ignored = [(str(scenes / e.name), HIDDEN if hidden(e.name) else "not a task scene (<task>.json)")
               for e in scene_files if not is_scene(e.name)]
    return tasks, ignored


def own_scenes(folder: Path, tasks: dict[str, Path],
                    ignored: list[tuple[str, str]]) -> dict[str, dict[str, Path]]:
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
