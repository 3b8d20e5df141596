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
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import ClassError

if TYPE_CHECKING:
    from ..programs.program import Program

#: the program's commands and limits, in the bundle's course folder
PROGRAM_FILE = "program.json"


def program_json(program: Program) -> bytes:
    """The TA's program options as the bundle keeps them."""
    return (
        json.dumps(
            {"run": program.run, "build": program.build, "sandbox": program.sandbox, "limits": asdict(program.limits)},
            indent=1,
        )
        + "\n"
    ).encode()


def load_program(course: Path) -> Program | None:
    """The bundle's program options (None: an image assignment); :class:`ClassError` for a file that is not
    one this phongray writes."""
    from ..programs import Limits
    from ..programs.program import Program

    path = course / PROGRAM_FILE
    if not path.exists():
        return None
    try:
        given = json.loads(path.read_text())
        return Program(given["run"], given["build"], Limits(**given["limits"]), given["sandbox"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ClassError(f"{path}: not a program file of this phongray's ({exc})") from None


def lay_out_program(submission: Path, student: Path, program: Program) -> list[str]:
    """Copy the uploaded folder into ``student`` as its program (regular files and folders only, as a run's
    copy is); lines that say what stopped the copy."""
    from ..programs.folder import FolderTooLarge, copy_folder

    try:
        copy_folder(submission, student, program.limits.folder_bytes)
    except FolderTooLarge as exc:
        return [f"not graded whole: {exc} ({program.limits.folder_bytes} bytes)"]
    return []
