"""How learning-management systems lay out a class's submissions: whose a folder or a file is, and which task
a file's name is for.

* **Folders per student**: ``SUBMISSIONS/<student>/<task>.png`` (or one folder deeper).
* **Moodle** downloads a folder per submission, ``Ada Adams_123456_assignsubmission_file_/<task>.png``
  (the student is "Ada Adams"), or, not in folders, ``Ada Adams_123456_assignsubmission_file_<task>.png``.
* **Canvas** downloads one flat folder of ``<login>[_LATE]_<user id>_<submission id>_<task>.png``
  (``adamsada_LATE_12345_67890_spheres-1.png`` is adamsada's spheres, handed in late).

A file's name is forgiven its case (``Spheres.PNG``) and the suffixes a resubmission or a browser's second
download adds (``spheres-1.png``, ``Spheres (1).png``).  Two students of one name (two ids) are told apart by
their ids: ``Ada Adams (123456)``.  A student's name is taken in Unicode's composed form (NFC): an archive
unpacked on a Mac spells ``José`` decomposed, the TA's ``--student-scenes`` folder perhaps not.
"""

from __future__ import annotations

import difflib
import re
import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass

#: Moodle's folder of one submission: the student's full name, their id, the submission plugin (the name is all
#: before the last ``_<id>_assignsubmission_``: a name a student gave themselves may hold one of its own)
MOODLE_FOLDER = re.compile(r"^(?P<name>[^.].*)_(?P<id>\d+)_assignsubmission_[a-z]+_?$")
#: Moodle's file of one submission when it is downloaded without folders
MOODLE_FILE = re.compile(r"^(?P<name>[^.].*?)_(?P<id>\d+)_assignsubmission_file_(?P<file>.+)$")
#: Canvas's file of one submission: login, LATE when late, user id, submission id, the file's own name
CANVAS_FILE = re.compile(r"^(?P<name>[^_.][^_]*?)(?P<late>_late)?_(?P<id>\d+)_\d+_(?P<file>.+)$", re.IGNORECASE)
#: what a resubmission or a second download appends to a file's name: ``-1`` (Canvas), `` (1)`` (browsers)
RESUBMITTED = re.compile(r"^(?P<base>.+?)(?:-\d+| \(\d+\))$")
#: the layouts a submissions folder may have, in words, for a folder in which no student is found
LAYOUTS = (
    "a folder per student (<student>/<task>.png), Moodle's folders "
    "(<name>_<id>_assignsubmission_file_/<task>.png) or Canvas's flat folder (<login>_<id>_<id>_<task>.png)"
)
#: how close a file's name must be to a task's to be suggested (difflib's ratio)
NEAR = 0.75


@dataclass(frozen=True)
class Owner:
    """Whose an entry of the submissions folder is, by an LMS's naming."""

    name: str  # the student's name as the LMS gives it
    id: str  # the LMS's id of the student ("" for a plain folder)
    file: str = ""  # for a flat file, the name the student gave it (spheres-1.png)
    lms: str = ""  # the LMS whose naming it is: "canvas", "moodle" ("" for a plain folder)
    late: bool = False  # the LMS marked the file late (Canvas's _LATE_)


def composed(name: str) -> str:
    """A name in Unicode's composed form (NFC), as two spellings of ``José`` are one student's; kept as it is
    when composing would lengthen it (a few letters, ``\u0958``, decompose under NFC: 255 bytes of them would
    be no file name of the report's)."""
    nfc = unicodedata.normalize("NFC", name)
    return nfc if len(nfc.encode(errors="surrogateescape")) <= len(name.encode(errors="surrogateescape")) else name


def folder_owner(name: str) -> Owner:
    """The student a folder of the submissions folder is of: Moodle's name and id, else the folder's name."""
    moodle = MOODLE_FOLDER.match(name)
    return Owner(composed(moodle["name"]), moodle["id"], lms="moodle") if moodle else Owner(composed(name), "")


def file_owner(name: str) -> Owner | None:
    """The student a file lying in the submissions folder itself is of (Moodle's or Canvas's naming), or None;
    a Canvas file marked ``_LATE_`` (or ``_late_``) is late."""
    if moodle := MOODLE_FILE.match(name):
        return Owner(composed(moodle["name"]), moodle["id"], moodle["file"], "moodle")
    if canvas := CANVAS_FILE.match(name):
        return Owner(composed(canvas["name"]), canvas["id"], canvas["file"], "canvas", canvas["late"] is not None)
    return None


def student_names(owners: Iterable[Owner]) -> dict[Owner, str]:
    """Each owner's student name: the name, or, for a name that two ids share, the name and the id; a name
    that is still another id's (a student who called themselves ``Bo Li (17)``) gets its own id too, so that
    no two ids are ever one student.  Names are compared regardless of case, as a Mac's or Windows's file
    system compares the report's folders of them (``Ada Adams`` and ``ada adams`` would share one)."""
    owners = list(owners)
    names = {owner: owner.name for owner in owners}
    for _ in range(len(owners) + 1):
        taken: dict[str, set[str]] = {}
        for owner, name in names.items():
            if owner.id:
                taken.setdefault(name.casefold(), set()).add(owner.id)
        clash = {o for o, name in names.items() if o.id and len(taken[name.casefold()]) > 1 and name == o.name}
        if not clash:
            break
        names.update({o: f"{o.name} ({o.id})" for o in clash})
    return names


@dataclass(frozen=True)
class Named:
    """The task a file's name is for, as :meth:`TaskNames.match` finds it."""

    task: str | None  # None: no task
    ext: str  # the extension, lower case ("" for none)
    exact: bool  # named as the task is spelt (not only regardless of case)


class TaskNames:
    """The tasks' names, to tell which task a file's name is for, and which task a near miss meant."""

    def __init__(self, tasks: Iterable[str]):
        self.tasks = set(tasks)
        self.spelt = {composed(task): task for task in sorted(self.tasks, reverse=True)}  # (composed, as names are)
        self.folded: dict[str, str] = {}
        for task in sorted(self.tasks):
            self.folded.setdefault(composed(task).lower(), task)

    def _task(self, stem: str) -> tuple[str | None, bool]:
        if stem in self.tasks:
            return stem, True
        stem = composed(stem)
        if stem in self.spelt:
            return self.spelt[stem], True
        return self.folded.get(stem.lower()), False

    def match(self, name: str) -> Named:
        """The task of a file's name: its stem exactly, else regardless of case, else without a resubmission's
        suffix (``spheres-1``, ``Spheres (1)``), and another (a download's copy resubmitted: ``spheres (1)-1``);
        and its extension, lower case."""
        stem, dot, ext = name.rpartition(".")
        if not dot or not stem:
            return Named(None, "", False)
        task, exact = self._task(stem)
        while task is None and (again := RESUBMITTED.match(stem)):  # one suffix at a time: spheres (1)-1
            stem = again["base"]
            task, exact = self._task(stem)
        return Named(task, ext.lower(), exact)

    def near(self, name: str) -> str | None:
        """The task a file's name that matches none nearly is (``sphere.png`` → spheres), or None."""
        stem = name.rpartition(".")[0] or name
        while again := RESUBMITTED.match(stem):
            stem = again["base"]
        stem = composed(stem).lower()
        close = difflib.get_close_matches(stem, list(self.folded), n=1, cutoff=NEAR)
        return self.folded[close[0]] if close else None


def did_you_mean(word: str, known: Iterable[str]) -> str:
    """`` (did you mean 'no-shadows'?)`` for a near miss of a known word, else nothing."""
    close = difflib.get_close_matches(word, list(known), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""
