"""The teaching assistant's input checked before anyone is graded: the scenes, and the report folder."""

from __future__ import annotations

import re
from pathlib import Path

from schemas import SceneError

from ..admission.limits import LimitError, check_body, check_scene
from ..course.errors import ClassError
from ..course.untrusted import read_own
from ..render.scenekey import scene_key
from ..settings import Settings
from ..work.pipeline import load_scene
from . import journal
from .records import Coursework
from .report import write_atomic

#: the name a tasks file usually has, and what to do with one found among the task scenes
TASKS_FILE = "tasks.json"
MOVE = "keep it beside the scenes folder and give it with --tasks"


def scene_keys(batch: Coursework, settings: Settings | None) -> tuple[dict[str, Path], dict[Path, bytes]]:
    """Validate every scene of the TA's once (the tasks' and the students' own), and price it with the service's
    limits ``settings`` when given (``--limits``): key → scene file, and each file's text.  An invalid scene, or
    one the service would refuse up front, stops the run before anything renders, every problem named by file
    (and line)."""
    keys: dict[Path, str] = {}
    texts: dict[Path, bytes] = {}
    problems: list[str] = []
    for pair in batch.pairs:
        if pair.scene in keys:
            pair.key = keys[pair.scene]
            continue
        keys[pair.scene] = ""
        try:
            text = texts[pair.scene] = read_own(pair.scene)
            if settings is not None:
                check_body(text, settings)
            scene = load_scene(str(pair.scene), text)
            if settings is not None:
                check_scene(scene, settings)
            pair.key = keys[pair.scene] = scene_key(scene)
        except SceneError as exc:
            if pair.scene.name == TASKS_FILE:  # (the TA's tasks file, put among the scenes: said first)
                problems.append(f"{pair.scene}: {TASKS_FILE} among the task scenes is read as a task scene; {MOVE}")
            problems.extend(exc.lines)  # type: ignore[attr-defined]
        except LimitError as exc:
            problems.append(f"{pair.scene}: {exc} (the service's limit, asked for by --limits)")
        except OSError as exc:
            problems.append(f"{pair.scene}: cannot read: {exc.strerror or exc}")
    if problems:
        raise ClassError("; ".join(problems))
    return {key: scene for scene, key in keys.items()}, texts


#: the folders a report writes into
REPORT_FOLDERS = ("references", "submissions", "heatmaps", "gradescope", journal.RESUME)


def outside(report: Path, submissions: Path, scenes: Path, student_scenes: Path | None) -> None:
    """The report folder is not inside the submissions folder (its files would be a student's next run), nor
    the submissions folder inside a folder the report writes (its copies would be); nor is it the scenes folder
    (its report.json would be a task) or inside the students' scenes (a student of them)."""
    inside, outer = report.resolve(), submissions.resolve()
    if inside == outer or inside.is_relative_to(outer):
        raise ClassError(
            f"{report}: the report folder is inside the submissions folder {submissions} (it would "
            f"be graded as a student's); write it elsewhere"
        )
    if inside == scenes.resolve():
        raise ClassError(
            f"{report}: the report folder is the scenes folder (its report.json would be read as a "
            f"task); write it elsewhere"
        )
    if student_scenes is not None and inside.is_relative_to(student_scenes.resolve()):
        raise ClassError(
            f"{report}: the report folder is inside the --student-scenes folder {student_scenes} "
            f"(it would be read as a student's scenes); write it elsewhere"
        )
    for name in REPORT_FOLDERS:
        if outer.is_relative_to(inside / name):
            raise ClassError(
                f"{report}: the report writes its {name}/ folder where the submissions folder "
                f"{submissions} is (its files would be graded as the students'); write it elsewhere"
            )


#: what a folder an earlier run wrote its report to holds (a run stopped before its report still kept its grades)
REPORT_MARKS = ("report.json", "resume")
#: a reference's file name: its scene's key (a SHA-256 in hex) and .png
REFERENCE_NAME = re.compile(r"[0-9a-f]{64}\.png")


def _references_only(report: Path, held: list[str]) -> bool:
    """Whether the folder holds (``held``) only references phongray rendered (``references/<scene key>.png``),
    as the autograder's bundle brings them."""
    if held != ["references"]:
        return False
    try:
        return all(REFERENCE_NAME.fullmatch(p.name) for p in (report / "references").iterdir())
    except OSError:
        return False


def writable(report: Path) -> None:
    """The report folder can be made and written to (else the run stops before any grading), and is new, empty
    or an earlier report: a folder of the TA's own files is not one to write into, since the report replaces
    what its own folders (references/, gradescope/) held."""
    try:
        held = [p.name for p in report.iterdir() if not p.name.startswith(".")] if report.is_dir() else []
    except OSError:
        held = []  # (said below, as it fails to be written)
    if held and not any((report / mark).exists() for mark in REPORT_MARKS) and not _references_only(report, held):
        raise ClassError(
            f"{report}: the folder holds files of its own ({', '.join(sorted(held)[:3])}"
            f"{', ...' if len(held) > 3 else ''}) and no phongray report; write the report to a new folder"
        )
    try:
        report.mkdir(parents=True, exist_ok=True)
        write_atomic(report / ".phongray-write-check", b"")
        (report / ".phongray-write-check").unlink()
    except OSError as exc:
        raise ClassError(f"{report}: cannot write the report there: {exc.strerror or exc}") from None
