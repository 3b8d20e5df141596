"""The autograder of a program assignment (``phongray autograder --run``): the students' program's commands
and limits in the bundle, and an uploaded program laid out to be graded as a class of one.

The bundle holds ``course/program.json`` (:func:`program_json`), written from the TA's options; in
Gradescope's container, ``run_autograder`` reads it back (:func:`load_program`) and grades the upload, the
folder ``/autograder/submission``, as that student's program: built once, run on each hidden task scene in
the sandbox as a user of its own (unprivileged: run_autograder runs as root, each run as a random user id
that owns nothing of the machine), each image graded as an uploaded one.  The scenes are in
``/autograder/source``, which no run can see.  ``setup.sh`` installs bubblewrap for such a bundle.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

from ..course.errors import ClassError
from ..programs import Limits
from ..programs.folder import FolderTooLarge, copy_folder
from ..programs.program import Program

#: the program's commands and limits, in the bundle's course folder
PROGRAM_FILE = "program.json"
#: the pip requirements of the programs' runtime (``--runtime-requirements``), which setup.sh builds
REQUIREMENTS_FILE = "runtime-requirements.txt"


def program_json(program: Program) -> bytes:
    """The TA's program options as the bundle keeps them."""
    return (
        json.dumps(
            {
                "run": program.run,
                "build": program.build,
                "sandbox": program.sandbox,
                "limits": asdict(program.limits),
                "runtime": program.runtime,
                "packages": list(program.packages),
            },
            indent=1,
        )
        + "\n"
    ).encode()


def program_files(
    program: Program | None, requirements: Path | None, read: Callable[[Path], bytes]
) -> dict[str, bytes]:
    """The course folder's files of a program assignment: its program file, and the requirements of its
    programs' runtime (which setup.sh builds), read with ``read``."""
    files = {} if program is None else {PROGRAM_FILE: program_json(program)}
    if requirements is not None:
        files[REQUIREMENTS_FILE] = read(requirements)
    return files


def load_program(course: Path) -> Program | None:
    """The bundle's program options (None: an image assignment); :class:`ClassError` for a file that is not
    one this phongray writes."""
    path = course / PROGRAM_FILE
    if not path.exists():
        return None
    try:
        given = json.loads(path.read_text())
        limits, packages = Limits(**given["limits"]), tuple(given.get("packages", ()))
        return Program(given["run"], given["build"], limits, given["sandbox"], given.get("runtime"), packages)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ClassError(f"{path}: not a program file of this phongray's ({exc})") from None


def lay_out_program(submission: Path, student: Path, program: Program) -> list[str]:
    """Copy the uploaded folder into ``student`` as its program (regular files and folders only, as a run's
    copy is); lines that say what stopped the copy."""
    try:
        copy_folder(submission, student, program.limits.folder_bytes)
    except FolderTooLarge as exc:
        return [f"not graded whole: {exc} ({program.limits.folder_bytes} bytes)"]
    return []
