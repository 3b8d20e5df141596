"""The records of class grading: a pair of a student and a task, and the batch of them found in the class's
folders."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


@dataclass
class Pair:
    student: str
    task: str
    image: Path | None  # the submitted file, as the report names it; None: missing
    scene: Path  # the student's own scene (the TA's), or the task's
    own: bool
    key: str | None = None  # the canonical scene hash
    file: str | None = None  # the submitted file, relative to the student's folder (spheres.png, hw3/Spheres.PNG)
    row: dict[str, Any] = field(default_factory=dict)
    data: bytes | None = None  # the submitted bytes, read once, when the class was found
    lms_id: str = ""  # the student's id in the learning-management system's export (Canvas's, Moodle's), if any


@dataclass
class Batch:
    tasks: dict[str, Path]
    students: list[str]
    pairs: list[Pair]
    ignored: list[tuple[str, str]]  # (file, why it is not graded)
