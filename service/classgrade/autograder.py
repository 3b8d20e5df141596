"""A Gradescope autograder: the bundle (``phongray autograder``) and what runs in Gradescope's container.

The bundle is a zip with ``setup.sh`` and ``run_autograder`` at its root, as Gradescope's autograder
specification asks, beside phongray's own source tree (``phongray/``) and the course (``course/``: the task
scenes, the students' own scenes, the tasks file, and each scene's reference, rendered when the bundle is
built).  Gradescope unpacks it into ``/autograder/source`` and runs ``setup.sh`` once, then ``run_autograder``
for each submission, with the student's files in ``/autograder/submission``; the results go to
``/autograder/results/results.json``.

A submission is graded as a class of one student by :func:`service.classgrade.grade_class`, so its
``results.json`` is the one a class report gives that student; the upload is laid out as that student's
folder by :mod:`.uploads` (images one folder down found, near misses named, files named as the student
named them).  ``PHONGRAY_AUTOGRADER_ROOT`` moves
``/autograder`` elsewhere (a test, a dry run).
"""

from __future__ import annotations

import importlib.metadata
import io
import json
import os
import shutil
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import service
from schemas import SceneError
from tracer import ImageTooLarge, Renderer, encode_png, render
from tracer.scene.shown import unchanged

from ..course.errors import ClassError
from ..course.untrusted import read_own
from ..diagnosis.accepting import accepted_ladders, file_name
from ..programs.program import Program
from ..render.scenekey import scene_key
from ..work.pipeline import load_scene
from .bundled import PROGRAM_FILE, lay_out_program, load_program, program_files
from .feedback import printed
from .forms import Results
from .programs import bundle_checked
from .records import ClassRun
from .run import grade_class
from .submissions import discover
from .taskfile import TaskSettings, load_tasks
from .uploads import LaidOut, as_uploaded, lay_out

#: where Gradescope lays the autograder out, unless PHONGRAY_AUTOGRADER_ROOT says otherwise
ROOT = "/autograder"
#: the bundle's folders
SOURCE, COURSE = "phongray", "course"
#: phongray's packages, copied into the bundle's source tree
PACKAGES = ("schemas", "tracer", "service", "bench")
#: a file's timestamp in the zip: the same bundle, byte for byte, from the same course
STAMP = (2024, 1, 1, 0, 0, 0)
#: the variable that names the bundle's accepted variants rendered beforehand (service.diagnosis.accepting.STORED)
STORED = "PHONGRAY_ACCEPTED_RENDERS"


@dataclass(frozen=True)
class Bundled:
    """What went into a bundle."""

    tasks: list[str]
    references: int  # scenes rendered
    size: int  # bytes of the zip


# -- the bundle ------------------------------------------------------------------------------------------------


def build(
    scenes: Path,
    out: Path,
    tasks_file: Path | None = None,
    student_scenes: Path | None = None,
    program: Program | None = None,
    requirements: Path | None = None,
) -> Bundled:
    """Write the autograder zip ``out`` for the task scenes in ``scenes`` (with a ``program``, for students'
    programs: :mod:`.bundled`, and the ``requirements`` of their runtime); :class:`ClassError` for a fault of
    the TA's (an invalid scene or tasks file, a scene that does not render), before anything is written."""
    if program is not None:
        bundle_checked(program)
    with tempfile.TemporaryDirectory() as empty:  # (the TA's folders checked as a class of one empty folder)
        (Path(empty) / "nobody").mkdir()
        batch = discover(scenes, Path(empty), student_scenes)
    files: dict[str, bytes] = {}
    for task, path in batch.tasks.items():
        files[f"{COURSE}/scenes/{task}.json"] = _read(path)
    for student in sorted(_own_scenes(student_scenes)):
        for path in sorted((student_scenes / student).iterdir()):  # type: ignore[operator]
            files[f"{COURSE}/student-scenes/{student}/{path.name}"] = _read(path)
    if tasks_file is not None:
        files[f"{COURSE}/tasks.json"] = _read(tasks_file)
    files.update({f"{COURSE}/{name}": data for name, data in program_files(program, requirements, _read).items()})
    scenes_of = {
        name: text
        for name, text in files.items()
        if name.endswith(".json") and not name.endswith(("/tasks.json", f"/{PROGRAM_FILE}"))
    }
    references = _references(scenes_of)
    files.update({f"{COURSE}/references/{key}.png": png for key, png in references.items()})
    files.update(_variants(scenes_of, load_tasks(tasks_file, batch.tasks)))
    files.update(_source_tree())
    data = _zip(files)
    try:
        out.write_bytes(data)
    except OSError as exc:
        raise ClassError(f"{out}: cannot write: {exc.strerror or exc}") from None
    return Bundled(sorted(batch.tasks), len(references), len(data))


def _own_scenes(student_scenes: Path | None) -> list[str]:
    return [] if student_scenes is None else [p.name for p in student_scenes.iterdir() if p.is_dir()]


def _read(path: Path) -> bytes:
    try:
        return read_own(path)
    except OSError as exc:
        raise ClassError(f"{path}: cannot read: {exc.strerror or exc}") from None


def _references(scenes: dict[str, bytes]) -> dict[str, bytes]:
    """Each distinct scene's reference PNG by canonical scene key; the TA's invalid scene or one that cannot be
    rendered stops the build, every problem named."""
    out: dict[str, bytes] = {}
    problems: list[str] = []
    for name, text in scenes.items():
        try:
            scene = load_scene(name, text)
            key = scene_key(scene)
            if key not in out:
                out[key] = encode_png(render(scene))
        except SceneError as exc:
            problems.extend(exc.lines)  # type: ignore[attr-defined]
        except ImageTooLarge as exc:
            problems.append(f"{name}: {exc}")
    if problems:
        raise ClassError("; ".join(problems))
    return out


def _variants(scenes: dict[str, bytes], tasks: dict[str, TaskSettings]) -> dict[str, bytes]:
    """The whole renders of each scene's accepted variants (its task's, or the defaults), rendered now so that
    a submission that fails the reference is graded against them without rendering them again in Gradescope's
    container: ``course/variants/<scene key>/<file name>`` (:data:`service.diagnosis.accepting.STORED`)."""
    out: dict[str, bytes] = {}
    for name, text in scenes.items():
        scene = load_scene(name, text)
        given = tasks[name.rsplit("/", 1)[1][:-5]].accepted
        if unchanged("offset-too-large", scene):
            continue
        accepted = None if given is None else {str(k): v for k, v in given.items()}
        for rungs in accepted_ladders(scene, accepted):
            for rung in rungs:
                path = f"{COURSE}/variants/{scene_key(scene)}/{file_name(rung.options)}"
                if path not in out:
                    out[path] = encode_png(Renderer(scene, rung.options).pixels())
    return out


def _source_tree() -> dict[str, bytes]:
    """phongray's packages as they are installed here, with a ``pyproject.toml`` from its metadata: what
    ``setup.sh`` installs with pip."""
    home = Path(service.__file__).resolve().parent.parent
    files: dict[str, bytes] = {}
    for package in PACKAGES:
        for path in sorted((home / package).rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts and path.suffix != ".pyc":
                files[f"{SOURCE}/{path.relative_to(home).as_posix()}"] = path.read_bytes()
    files[f"{SOURCE}/phongray.py"] = (home / "phongray.py").read_bytes()
    files[f"{SOURCE}/pyproject.toml"] = _pyproject().encode()
    for name in ("setup.sh", "run_autograder"):
        files[name] = _script(name)
    return files


def _pyproject() -> str:
    meta = importlib.metadata.metadata("phongray")
    needs = [r for r in importlib.metadata.requires("phongray") or [] if "extra ==" not in r]
    return "\n".join(
        [
            "[build-system]",
            'requires = ["setuptools>=64"]',
            'build-backend = "setuptools.build_meta"',
            "",
            "[project]",
            'name = "phongray"',
            f'version = "{meta["Version"]}"',
            'requires-python = ">=3.11"',
            f"dependencies = {json.dumps(needs)}",
            "",
            "[project.scripts]",
            'phongray = "service.cli:main"',
            "",
            "[tool.setuptools]",
            'py-modules = ["phongray"]',
            "",
            "[tool.setuptools.packages.find]",
            f"include = {json.dumps([p + '*' for p in PACKAGES])}",
            "",
            "[tool.setuptools.package-data]",
            'service = ["static/*"]',
            '"service.classgrade" = ["gradescope/*"]',
            "",
        ]
    )


def _script(name: str) -> bytes:
    return (Path(__file__).parent / "gradescope" / name).read_bytes()


def _zip(files: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(files):
            info = zipfile.ZipInfo(name, STAMP)
            executable = name in ("setup.sh", "run_autograder")
            info.external_attr = (0o100755 if executable else 0o100644) << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, files[name])
    return buffer.getvalue()


# -- in Gradescope's container ---------------------------------------------------------------------------------


def submitter(root: Path) -> list[str]:
    """The names a submission's students go by (``submission_metadata.json``: each user's email, the email's
    part before the @, student id and name), to find their own scenes by; none when it cannot be read."""
    try:
        meta = json.loads((root / "submission_metadata.json").read_text())
        users = meta.get("users") or []
    except (OSError, ValueError, AttributeError):
        return []
    names: list[str] = []
    for user in users if isinstance(users, list) else []:
        if isinstance(user, dict):
            email = str(user.get("email") or "")
            names += [email, email.split("@")[0], str(user.get("sid") or ""), str(user.get("name") or "")]
    return [n for n in names if n]


def run(root: Path) -> int:
    """Grade ``root/submission`` against ``root/source/course`` and write ``root/results/results.json``; 0
    when it was graded, 2 when the bundle is unusable (the results then say so, with no score)."""
    results = root / "results" / "results.json"
    try:
        outcome = _grade(root)
    except ClassError as exc:
        _write(results, {"score": 0.0, "output": f"The autograder could not grade this submission: {exc}", "tests": []})
        print(f"phongray autograder: {exc}", file=sys.stderr)
        return 2
    _write(results, outcome)
    for test in outcome["tests"]:
        print(printed(test))  # (Gradescope shows what run_autograder prints to the instructors only)
    print(f"total: {outcome['score']:g}; results in {results}")
    return 0


def _grade(root: Path) -> Results:
    """The submission graded as a class of one: its results.json, as grade-class writes it."""
    course = root / "source" / COURSE
    scenes = course / "scenes"
    if not scenes.is_dir():
        raise ClassError(f"{course}: no scenes; is this a phongray autograder bundle?")
    tasks = sorted(p.name[:-5] for p in scenes.iterdir() if p.name.endswith(".json"))
    program = load_program(course)
    if program is not None:  # the program runs as a user of its own: /autograder (hidden scenes, references,
        os.chmod(root, 0o700)  # results) is closed to it even where no sandbox hides it (a bundle's --no-sandbox)
    with tempfile.TemporaryDirectory() as work:
        place = Path(work)
        who = _own_folder(course / "student-scenes", submitter(root))
        student = place / "submissions" / (who or "submission")
        student.mkdir(parents=True)
        laid = (
            lay_out(root / "submission", student, tasks)
            if program is None
            else LaidOut(lay_out_program(root / "submission", student, program))
        )
        for line in laid.lines:
            print(line)
        own = None
        if who is not None:
            own = place / "student-scenes"
            shutil.copytree(course / "student-scenes" / who, own / who)
        report = place / "report"
        if (course / "references").is_dir():
            shutil.copytree(course / "references", report / "references")
        tasks_file = course / "tasks.json"
        os.environ[STORED] = str(course / "variants")  # (the pool's processes inherit it)
        grade_class(
            ClassRun(
                scenes,
                place / "submissions",
                report,
                jobs=1,
                student_scenes=own,
                tasks_file=tasks_file if tasks_file.exists() else None,
                program=program,
            )
        )
        results = json.loads((report / "gradescope" / student.name / "results.json").read_text())
        return as_uploaded(results, student, laid.shown)


def _own_folder(folder: Path, names: list[str]) -> str | None:
    """The folder of the TA's students' own scenes that one of ``names`` names (in any case), if any."""
    if not folder.is_dir():
        return None
    folded = {n.casefold() for n in names}
    return next((p.name for p in sorted(folder.iterdir()) if p.name.casefold() in folded), None)


def _write(path: Path, results: Results) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=1, ensure_ascii=False) + "\n")


def main() -> int:
    """``python -m service.classgrade.autograder``: what ``run_autograder`` runs."""
    return run(Path(os.environ.get("PHONGRAY_AUTOGRADER_ROOT") or ROOT))


if __name__ == "__main__":
    sys.exit(main())
