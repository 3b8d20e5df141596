"""A Gradescope submission laid out as a student's folder of a class, for the autograder to grade it as
grade-class grades one (:mod:`.autograder`).

Students upload their images as they have them: at the top of the upload or one folder down (``hw3/`` of a
zip, which Gradescope unpacks), in any case, with a resubmission's or a second download's suffix
(``cornell-1.png``, ``Cornell (1).png``).  Of several files for a task, the one nearest the top is graded, and
of those the latest copy (the highest number; the name itself is the first), a PNG or PPM before another
format.  A file named nearly as a task (``whitted.png`` for ``whitted_aa``) is laid out as it is, so that the
grade of the task says "did you mean".

Each file graded is copied into the student's folder under its task's name (its extension kept: a JPEG is
graded as the JPEG it is), and every message a student reads names it as the student named it
(``hw3/Cornell (1).jpg: image is a JPEG; PNG or PPM required``), never by the temporary folder it was graded
in (:func:`as_uploaded`).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..course.folders import hidden
from ..course.lms import TaskNames
from ..course.untrusted import UntrustedFileError, read_untrusted
from .forms import Results
from .submissions import GRADED, OTHER_IMAGES

#: the largest submitted file read (as the service's max_image_bytes)
MAX_BYTES = 16 * 1024 * 1024
#: what learning-management systems and browsers add to a file's name: "Spheres (1)", "spheres-2"
SUFFIX = re.compile(r"^(?P<task>.+?)(?: ?\((?P<copy>\d+)\)|-(?P<again>\d+))?$")


@dataclass(frozen=True)
class Found:
    """A submitted file taken as a task's: its path in the submission, and how late a copy it is."""

    name: str  # as the student named it, below the submission (hw3/Cornell.png)
    copy: int  # 0 for the name itself, N for "(N)" or "-N"

    @property
    def depth(self) -> int:
        return self.name.count("/")


def _extension(name: str) -> str:
    base = name.rsplit("/", 1)[-1]
    return base.rsplit(".", 1)[1].lower() if "." in base else ""


def task_files(names: list[str], tasks: list[str]) -> tuple[dict[str, Found], list[tuple[str, str]]]:
    """Which submitted file is each task's, and the files left out with the reason.  A file is a task's when
    its name without its extension is the task's in any case, or is with a copy's suffix (``Spheres (1).png``,
    ``spheres-1.png``); of several, the one nearest the top, then the latest copy (the highest number; the
    name itself is the first), a PNG or PPM before another format."""
    folded = {t.casefold(): t for t in tasks}
    found: dict[str, list[Found]] = {}
    left: list[tuple[str, str]] = []
    for name in names:
        base = name.rsplit("/", 1)[-1]
        stem = base.rsplit(".", 1)[0] if "." in base else base
        task, copy = folded.get(stem.casefold()), 0
        match = SUFFIX.match(stem)
        if task is None and match:
            task = folded.get(match["task"].casefold())
            copy = int(match["copy"] or match["again"] or 0)
        if task is None:
            left.append((name, f"names no task (the tasks are {', '.join(sorted(tasks))})"))
        else:
            found.setdefault(task, []).append(Found(name, copy))
    chosen: dict[str, Found] = {}
    for task, files in found.items():
        files.sort(key=lambda f: (f.depth, -f.copy, _extension(f.name) not in GRADED, f.name))
        chosen[task] = files[0]
        left += [(f.name, f"another file for {task} is graded: {files[0].name}") for f in files[1:]]
    return chosen, left


def uploaded_names(submission: Path) -> list[str]:
    """The regular files of an upload, at its top and one folder down (``hw3/cornell.png``), as paths below it;
    a link is never followed, and an archive tool's folders (``__MACOSX``, hidden ones) are no student's."""
    names: list[str] = []
    try:
        with os.scandir(submission) as top:
            entries = sorted(top, key=lambda e: e.name)
    except OSError:
        return names
    for entry in entries:
        if entry.is_file(follow_symlinks=False):
            names.append(entry.name)
        elif entry.is_dir(follow_symlinks=False) and not hidden(entry.name):
            try:
                with os.scandir(entry.path) as below:
                    inner = sorted(e.name for e in below if e.is_file(follow_symlinks=False))
            except OSError:
                continue
            names += [f"{entry.name}/{name}" for name in inner]
    return names


@dataclass
class LaidOut:
    """What laying an upload out did: lines for the autograder's log, and each file laid out (its path in the
    student's folder) with the name the student gave it."""

    lines: list[str] = field(default_factory=list)
    shown: dict[Path, str] = field(default_factory=dict)


def lay_out(submission: Path, student: Path, tasks: list[str]) -> LaidOut:
    """Copy each task's file of the upload ``submission`` into ``student`` (the folder grade-class grades), and
    each file named nearly as a task that has none, as it is (its grade then says "did you mean")."""
    chosen, left = task_files(uploaded_names(submission), tasks)
    out = LaidOut()
    names = TaskNames(tasks)
    for name, why in left:
        base = name.rsplit("/", 1)[-1]
        near = names.near(base) if _extension(name) in (*GRADED, *OTHER_IMAGES) else None
        if near is not None and near not in chosen and why.startswith("names no task"):
            _copy(submission, name, student / name, out)
            why = f"names no task (did you mean {near}?)"
        out.lines.append(f"not graded: {name}: {why}")
    for task, found in chosen.items():
        ext = _extension(found.name) or "png"
        folder = found.name.rpartition("/")[0]
        if _copy(submission, found.name, student / folder / f"{task}.{ext}", out) and found.name != f"{task}.{ext}":
            out.lines.append(f"graded as {task}: {found.name}")
    return out


def _copy(submission: Path, name: str, target: Path, out: LaidOut) -> bool:
    """Copy one uploaded file (read as untrusted, at most :data:`MAX_BYTES`); False, with a line, if it cannot
    be read."""
    try:
        data = read_untrusted(submission / name, MAX_BYTES)
    except UntrustedFileError as exc:
        out.lines.append(f"not graded: {name}: {exc}")
        return False
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_bytes(data)
    out.shown[target] = name
    return True


def as_uploaded(results: Results, student: Path, shown: dict[Path, str]) -> Results:
    """A student's results with every file named as the student named it: a laid-out file by its uploaded name,
    anything else in the student's folder by its path below it; never the temporary folder's path."""
    names = sorted(((str(path), name) for path, name in shown.items()), key=lambda p: -len(p[0]))
    names.append((f"{student}{os.sep}", ""))

    def plain(text: str) -> str:
        for path, name in names:
            text = text.replace(path, name)
        return text

    tests = [{**t, "output": plain(t["output"])} if isinstance(t.get("output"), str) else t for t in results["tests"]]
    out = {**results, "tests": tests}
    if isinstance(out.get("output"), str):
        out["output"] = plain(out["output"])
    return out
