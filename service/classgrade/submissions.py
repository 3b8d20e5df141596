"""A class's folders as a teaching assistant has them, and the students' files as untrusted input.

``SCENES/<task>.json`` are the tasks and ``STUDENT_SCENES/<student>/<task>.json`` (optional) a student's own
scene for a task: both folders are the TA's.  ``SUBMISSIONS`` holds the students' files as a
learning-management system downloads them (:mod:`service.course.lms`): a folder per student (Moodle's
``<name>_<id>_assignsubmission_file_`` too) where the image of a task is ``<task>.png`` or one folder deeper
(``frank/hw3/spheres.png``), or Canvas's flat ``<login>_<id>_<id>_<task>.png``; a name is matched regardless of
case and of a resubmission's suffix.  A submitted file that is no PNG (``spheres.jpg``) is graded, and so
reported as the format it is.  Nothing in a student's folder is ever a setting: a scene found there is
ignored, with the reason.  Links are never followed; each student's folder is opened once and held
(:class:`Folder`) while its files are found and read, so that nothing is looked up again by a path a student
could swap for a link while the references render; every byte read from a student's folder is read by
:func:`read_untrusted`, when the class is found.
"""

from __future__ import annotations

import re
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path

from ..course.errors import ClassError
from ..course.folders import NOT_STUDENTS, Entry, Folder, own_scenes, task_scenes
from ..course.lms import LAYOUTS, Owner, TaskNames, file_owner, folder_owner, student_names
from ..course.untrusted import UntrustedFileError
from .forms import ReportRow
from .records import Coursework, Pair

#: the extensions of the image formats graded (service.images.grading: PNG, and the PPM students' tracers print)
GRADED = ("png", "ppm")
#: extensions of images other than those graded: such a file named after a task is that task's (wrong) submission
OTHER_IMAGES = {"jpg", "jpeg", "gif", "bmp", "tif", "tiff", "webp", "heic", "heif", "avif"}
#: the most bytes read of a submission when no limit is given (the service's max_image_bytes)
DEFAULT_LIMIT = 16 << 20
SCENE_IGNORED = (
    "a scene among the submissions is not used (a student's own scene comes from the TA's --student-scenes folder)"
)


def discover(
    scenes: Path, submissions: Path, student_scenes: Path | None = None, limit: int = DEFAULT_LIMIT
) -> Coursework:
    """Every (student, task) pair of the class, each submission read (at most ``limit`` bytes) through the
    folders it was found in, held open meanwhile; :class:`ClassError` for a folder of the TA's that is
    unusable, a submissions folder in which no student is found (or whose one folder holds the class), or a
    student's own scenes under another name than the student's."""
    tasks, ignored = task_scenes(scenes)
    own = own_scenes(student_scenes, tasks, ignored) if student_scenes is not None else {}
    with Folder.root(submissions) as root:
        sources = _sources(root, ignored)
        if not sources:
            raise ClassError(f"{submissions}: no student found; expected {LAYOUTS}")
        names = TaskNames(tasks)
        _not_one_level_up(root, sources, names)
        found = {student: _student(root, source, names, limit, ignored) for student, source in sources.items()}
    if student_scenes is not None:
        _scenes_name_students(student_scenes, own, sources)
    pairs = []
    students = sorted({*found, *own})
    for student in students:
        mine = found.get(student, {})
        source = sources.get(student, Source())
        for task, shared in tasks.items():
            scene = own.get(student, {}).get(task)
            pair = Pair(student, task, None, scene or shared, scene is not None, lms_id=source.id, lms=source.lms)
            mine.get(task, Submitted(row={"status": "missing", "reason": f"no {task}.png"})).fill(pair)
            pairs.append(pair)
    return Coursework(tasks, students, pairs, ignored)


@dataclass
class Source:
    """Where one student's files are: their folders in the submissions folder (a Moodle student may have two),
    and their files lying in it (Canvas's), each with the name the student gave it."""

    folders: list[str] = field(default_factory=list)
    files: list[tuple[Entry, Owner]] = field(default_factory=list)  # (the file, whose it is and what it is)
    id: str = ""  # the LMS's id of the student, if the names gave one
    lms: str = ""  # the LMS whose naming gave it ("canvas", "moodle")


def _sources(root: Folder, ignored: list[tuple[str, str]]) -> dict[str, Source]:
    """Each student's :class:`Source`, by the student's name; what is no student's is ``ignored``."""
    try:
        entries = root.entries()
    except OSError as exc:
        raise ClassError(f"{root.shown}: cannot read: {exc.strerror or exc}") from None
    owners: dict[Owner, Source] = {}
    for entry in entries:
        shown = str(root.shown / entry.name)
        if entry.folder and (entry.name.startswith(".") or entry.name in NOT_STUDENTS):
            ignored.append((shown, "not a student's folder"))
        elif entry.folder:
            owners.setdefault(folder_owner(entry.name), Source()).folders.append(entry.name)
        elif (owner := file_owner(entry.name)) is not None:  # a link too: reading it says it is one
            owners.setdefault(Owner(owner.name, owner.id, lms=owner.lms), Source()).files.append((entry, owner))
        else:  # (a link to a folder is not a student's: it is never listed, let alone read)
            ignored.append((shown, "a symbolic link (not followed)" if entry.link else "not in a student's folder"))
    out: dict[str, Source] = {}
    for owner, name in student_names(owners).items():
        merged = out.setdefault(name, Source())
        merged.folders += owners[owner].folders
        merged.files += owners[owner].files
        merged.id = merged.id or owner.id
        merged.lms = merged.lms or owner.lms
    return out


def _not_one_level_up(root: Folder, sources: dict[str, Source], names: TaskNames) -> None:
    """A submissions folder whose one folder holds a class (an export unpacked into a folder of its own, and that
    folder's parent given): :class:`ClassError`, not a class of one student with every image "2 files; keep
    one" or missing.  The folder holds a class when two of its entries are two students' by an LMS's naming, or
    two of its folders each hold an image for one task (a student's part1/spheres.png and part2/lights.png
    are one student's)."""
    if len(sources) != 1:
        return
    (source,) = sources.values()
    if source.files or len(source.folders) != 1 or source.id:  # (a folder named by an LMS is a student's)
        return
    (name,) = source.folders
    try:
        with root.sub(name) as folder:
            entries = folder.entries()
            lms = {
                (o.name, o.id)
                for e in entries
                if (o := folder_owner(e.name) if e.folder else file_owner(e.name)) is not None and o.id
            }
            held: dict[str, int] = {}  # task → how many of the folders hold its image
            for entry in (e for e in entries if e.folder and len(lms) < 2 and max(held.values(), default=0) < 2):
                with folder.sub(entry.name) as below:
                    for task in {
                        n.task
                        for n in map(names.match, (e.name for e in below.entries()))
                        if n.task is not None and n.ext in GRADED
                    }:
                        held[task] = held.get(task, 0) + 1
    except OSError:  # (a folder that cannot be read: the student's row says so)
        return
    if len(lms) >= 2 or max(held.values(), default=0) >= 2:
        kind = "an LMS's export" if len(lms) >= 2 else "a folder per student"
        raise ClassError(
            f"{root.shown}: its one folder, {name}, holds the submissions of several students "
            f"({kind}): give {root.shown / name} as the submissions folder"
        )


@dataclass
class Submitted:
    """What a student's files give one task: the file graded and its bytes, or the row that says why not."""

    image: Path | None = None
    file: str | None = None
    data: bytes | None = None
    row: ReportRow = field(default_factory=dict)
    late: bool = False  # the LMS marked the file late

    def fill(self, pair: Pair) -> None:
        pair.image, pair.file, pair.data, pair.row = self.image, self.file, self.data, dict(self.row)
        pair.late = self.late


@dataclass(frozen=True)
class Candidate:
    """A file that may be a task's submission, in the folder it was found in (held open)."""

    rank: tuple[int, bool]  # (depth, not a PNG or PPM): the lowest is graded
    folder: Folder
    name: str
    late: bool = False  # the LMS marked it late (Canvas's _LATE_)

    @property
    def shown(self) -> Path:
        return self.folder.shown / self.name

    def read(self, limit: int) -> Submitted:
        rel = self.folder.rel + self.name
        try:
            return Submitted(self.shown, rel, self.folder.read(self.name, limit), late=self.late)
        except UntrustedFileError as exc:
            reason = f"{self.shown}: {exc}"
            return Submitted(self.shown, rel, row={"status": "invalid", "reason": reason}, late=self.late)


#: the most files a reason names (a student's folder may hold thousands: the report stays readable)
LISTED = 5


def _listed(files: list[str]) -> str:
    """``a, b, c`` or, past :data:`LISTED`, ``a, b, c, d, e and 995 more``."""
    more = len(files) - LISTED
    return ", ".join(files[:LISTED]) + (f" and {more} more" if more > 0 else "")


def _invalid(reason: str) -> Submitted:
    return Submitted(row={"status": "invalid", "reason": reason})


class _Walk:
    """One student's files, found in their folders (held open while they are read) and among the flat files."""

    def __init__(self, root: Folder, names: TaskNames, ignored: list[tuple[str, str]], stack: ExitStack):
        self.root, self.names, self.ignored, self.stack = root, names, ignored, stack
        self.candidates: dict[str, list[Candidate]] = {}
        self.near: dict[str, list[str]] = {}  # task → files whose names nearly are the task's
        self.unreadable: list[str] = []  # folders that cannot be listed, with why

    def folder(self, parent: Folder, name: str, depth: int) -> tuple[Folder, list[Entry]] | None:
        try:
            folder = self.stack.enter_context(parent.sub(name, student=depth == 0))
            return folder, folder.entries()
        except OSError as exc:
            why = f"cannot read the folder: {exc.strerror or exc}"
            self.unreadable.append(f"{parent.shown / name}: {why}")
            if depth:
                self.ignored.append((str(parent.shown / name), why))
            return None

    def look(self, folder: Folder, entry: Entry, depth: int, given: Owner | None = None) -> None:
        """Take one entry (``given``: whose a flat file is, by an LMS's naming): a candidate for a task, or ignored
        with the reason."""
        name = given.file if given else entry.name
        named, shown = self.names.match(name), str(folder.shown / entry.name)
        image = named.ext in GRADED or named.ext in OTHER_IMAGES
        if entry.folder and not (named.task is not None and image):
            if depth:  # (a folder named as a task's image is a candidate: reading it says it is a folder)
                self.ignored.append((shown, "a folder two levels down (phongray looks one folder deep)"))
            return
        if named.task is None:
            near = self.names.near(name) if image else None
            self.ignored.append((shown, "matches no task" + (f" (did you mean {near}?)" if near else "")))
            if near is not None:
                self.near.setdefault(near, []).append(folder.rel + entry.name)
        elif named.ext == "json":
            self.ignored.append((shown, SCENE_IGNORED))
        elif image:
            rank = (depth, named.ext not in GRADED)  # (spelt in another case is no less the student's own)
            late = given is not None and given.late
            self.candidates.setdefault(named.task, []).append(Candidate(rank, folder, entry.name, late))
        else:
            self.ignored.append((shown, f"matches task {named.task}, but is no image"))

    def chosen(self, tasks: list[str], limit: int) -> dict[str, Submitted]:
        """Per task, the file graded (read now, through its folder) or the row that says why none is."""
        found: dict[str, Submitted] = {}
        for task, options in self.candidates.items():
            options.sort(key=lambda o: o.rank)
            best = [o for o in options if o.rank == options[0].rank]
            if len(best) > 1:
                found[task] = _invalid(
                    f"{len(best)} files for {task}: {_listed([str(o.shown) for o in best])}; keep one"
                )
                continue
            found[task] = options[0].read(limit)
            for other in options[1:]:
                self.ignored.append((str(other.shown), f"another file for {task} is graded: {options[0].shown}"))
        for task in tasks:
            if task not in found and self.unreadable:  # not found, but perhaps in a folder that cannot be read
                found[task] = _invalid(f"no {task}.png found; {'; '.join(self.unreadable)}")
            elif task not in found and task in self.near:
                found[task] = Submitted(
                    row={
                        "status": "missing",
                        "reason": f"no {task}.png (found {_listed(self.near[task])}: did you mean {task}.png?)",
                    }
                )
        return found


def _student(
    root: Folder, source: Source, names: TaskNames, limit: int, ignored: list[tuple[str, str]]
) -> dict[str, Submitted]:
    """Per task, the student's submission, read, or the row that says why there is none to grade."""
    with ExitStack() as stack:
        walk = _Walk(root, names, ignored, stack)
        places = [(0, root, [entry for entry, _ in source.files])] if source.files else []
        given = {entry.name: owner for entry, owner in source.files}
        for name in source.folders:
            listed = walk.folder(root, name, 0)
            if listed is None:
                continue
            folder, entries = listed
            places.append((0, folder, entries))
            for entry in entries:  # one folder deeper (hw3/)
                below = walk.folder(folder, entry.name, 1) if entry.folder else None
                if below is not None:
                    places.append((1, *below))
        if not places:  # none of the student's folders can be read
            return {task: _invalid("; ".join(walk.unreadable)) for task in names.tasks}
        for depth, folder, entries in places:
            for entry in entries:
                walk.look(folder, entry, depth, given.get(entry.name) if folder is root else None)
        return walk.chosen(sorted(names.tasks), limit)


def _scenes_name_students(folder: Path, own: dict[str, dict[str, Path]], sources: dict[str, Source]) -> None:
    """A student's own scenes are under the student's name as the report gives it; a folder named otherwise for
    a student of the submissions (another case, Moodle's folder name, a name without the id that tells two
    students apart, or with an id that is not needed) stops the run: that student would be graded against the
    task's scene, and a student of that name who sent nothing listed beside them.  (A student with no
    submission at all is no mistake.)"""

    def key(name: str) -> str:
        return re.sub(r" \(\d+\)$", "", folder_owner(name).name).casefold()

    keys: dict[str, set[str]] = {}
    for student in sources:
        keys.setdefault(key(student), set()).add(student)
    for name in sorted(own):
        meant = sorted(keys.get(key(name), set()))
        if name not in sources and meant:
            raise ClassError(
                f"{folder / name}: no student {name} among the submissions (did you mean "
                f"{' or '.join(meant)}? a student's own scenes go in a folder of the name the "
                f"report gives them)"
            )
