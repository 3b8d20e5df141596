"""The optional tasks file of a class: per task, its points, its own grading thresholds and its deductions.

```json
{"spheres": {"points": 10, "tolerance": 3, "deductions": {"no-shadows": 4}}, "mirror": {"points": 5},
 "glass": {"accepted": {"normal-offset": 0.002}}}
```

A deduction names a mistake by its id (:data:`tracer.scene.variants.VARIANTS` and ``MORE_VARIANTS``): an image whose
one fault is that mistake scores the task's points less the deduction (:mod:`service.classgrade.gradebook`).

``show`` is what a student reads of the task in Gradescope's output (:func:`~.feedback.test_output`):
``images`` (the default) and ``diagnosis`` the verdict, its reason, the likely mistake and the partial credit,
``verdict`` the verdict and its reason, ``verdict-only`` passed or failed: for a hidden scene (a program's
task), the TA's choice of how much of it the feedback gives away.

``phongray_code`` is what a program's pair scores when its folder holds phongray's own code
(:mod:`service.classgrade.copied`): ``review`` (the default) keeps its grade and flags it in the TA's report,
``zero`` scores it nothing and tells the student why.

``canvas`` is the Canvas assignment a task's score goes to in the Canvas gradebook (:mod:`.lmsbook`), as
Canvas's gradebook names its column, ``Homework 3 (12345)``; ``late_penalty`` the late policy, the fraction of
the task's points a submission the LMS marked late loses (0, the default: none; Canvas's own late policy is a
percentage of the points, too).  The key ``"*"`` gives every task's settings, which a task's own replace:
``{"*": {"canvas": "Homework 3 (12345)", "late_penalty": 0.1}, "mirror": {"points": 5}}`` sends every task
to one assignment (its column holds the total) with a tenth of the points off for late work.

A task the file does not name is worth 1 point and graded with the command's thresholds.  The file is the
teaching assistant's: a mistake in it stops the run (:class:`~service.course.errors.ClassError`).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, field_validator
from pydantic_core import PydanticCustomError

from schemas import SceneError, parse_json
from schemas.errors import problems_from_validation, suggestion
from schemas.locate import as_lines
from tracer.scene.variants import MORE_VARIANTS, VARIANTS

from ..course.errors import ClassError
from ..course.lms import did_you_mean
from ..course.untrusted import read_own

#: a number of the TA's: a JSON number, finite (a string "5", true or 1e400 is a mistake, not 5, 1 or infinity)
Number = Annotated[float, Field(strict=True, allow_inf_nan=False)]
#: a Canvas assignment as Canvas's gradebook names its column, its title and id: ``Homework 3 (12345)``
CANVAS_ASSIGNMENT = re.compile(r"^(.*\S)\s\((\d+)\)$")
#: what a Canvas assignment must be given as
CANVAS_WORDS = (
    "give the assignment as Canvas's gradebook names its column, its title and id: 'Homework 3 (12345)' (the id "
    "is the number in the assignment's address, .../assignments/12345)"
)
#: the most points a task (or a deduction) may be worth: a class's total of them stays a finite number in every
#: report (1e308 twice overflowed to infinity, which no JSON holds)
MOST_POINTS = 1e6
#: the key of tasks.json whose settings are every task's, unless the task's own say otherwise
EVERY = "*"


class TaskSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    points: Annotated[Number, Field(ge=0, le=MOST_POINTS)] = 1.0
    tolerance: Annotated[Number, Field(ge=0, le=255)] | None = None  # None: the command's --tolerance
    max_fraction: Annotated[Number, Field(ge=0, le=1)] | None = None  # None: the command's --max-fraction
    visibility: Literal["visible", "hidden", "after_due_date", "after_published"] = "visible"  # Gradescope's
    #: what a student reads of the task (Gradescope's output): a hidden scene's TA may show less
    show: Literal["images", "diagnosis", "verdict", "verdict-only"] = "images"
    deductions: dict[str, Annotated[Number, Field(ge=0, le=MOST_POINTS)]] = Field(default_factory=dict)  # id → points
    #: what a pair of a program holding phongray's own code scores (service.classgrade.copied): its grade, flagged
    #: for the TA (review), or nothing (zero)
    phongray_code: Literal["review", "zero"] = "review"
    #: the accepted variants of honest tracers, name → largest amount × the visible size (None: the defaults,
    #: tracer.scene.variants.ACCEPTED_DEFAULT; {}: the reference alone)
    accepted: dict[Literal["normal-offset", "t-min"], Annotated[Number, Field(ge=0, le=0.1)]] | None = None
    #: the Canvas assignment the task's score goes to, as Canvas's gradebook names its column (None: the task's name)
    canvas: str | None = None
    #: the late policy: the fraction of the task's points a late submission loses (0: none)
    late_penalty: Annotated[Number, Field(ge=0, le=1)] = 0.0

    @field_validator("points", mode="before")
    @classmethod
    def _points_given(cls, value: object) -> object:
        if value is None:  # (unlike the thresholds', a null here is no default: the key left out is)
            raise PydanticCustomError("points_null", "must be a number (leave the key out for the default, 1 point)")
        return value

    @field_validator("canvas")
    @classmethod
    def _canvas_column(cls, value: str | None) -> str | None:
        if value is not None and not CANVAS_ASSIGNMENT.match(value):
            raise PydanticCustomError("canvas_assignment", CANVAS_WORDS)
        return value


_FILE = TypeAdapter(dict[str, TaskSettings])


def _suggested(problems: list[tuple[str, str]]) -> list[tuple[str, str]]:
    """An unknown key of a task's settings with the closest setting's name (``tolerence`` → ``tolerance``)."""
    return [
        (
            where,
            what + suggestion(where.rsplit(".", 1)[-1], TaskSettings.model_fields) if what == "unknown key" else what,
        )
        for where, what in problems
    ]


def load_tasks(path: Path | None, tasks: dict[str, Path], canvas: str | None = None) -> dict[str, TaskSettings]:
    """Every task's settings: from the file at ``path`` where it names the task, over its ``"*"`` (every task's),
    over the defaults; ``canvas`` (``--canvas-assignment``) in place of the ``"*"``'s Canvas assignment."""
    given: dict[str, TaskSettings] = {}
    text = b""
    if canvas is not None:
        _canvas_option(canvas)
    if path is not None:
        try:
            text = read_own(path)
        except OSError as exc:
            raise ClassError(f"{path}: cannot read: {exc.strerror or exc}") from None
        try:
            given = _FILE.validate_python(parse_json(text, shared=False))
        except SceneError as exc:
            raise ClassError("; ".join(as_lines(str(path), exc.problems, text))) from None
        except ValidationError as exc:
            problems = _suggested(problems_from_validation(exc))
            raise ClassError("; ".join(as_lines(str(path), problems, text))) from None
        unknown = sorted(set(given) - set(tasks) - {EVERY})
        if unknown:
            named = ", ".join(name + suggestion(name, tasks) for name in unknown)
            raise ClassError(f"{path}: no task {named} (the tasks are {', '.join(sorted(tasks))})")
        if EVERY in given and EVERY in tasks:
            raise ClassError(f"{path}: {EVERY!r} is every task's settings, and also a task's name: rename its scene")
        _known_mistakes(path, given, text)
    every = given.get(EVERY, TaskSettings())
    if canvas is not None:
        every = TaskSettings.model_validate({**_given(every), "canvas": canvas})
    merged = {task: _over(every, given.get(task)) for task in tasks}
    if path is not None:
        _within_points(path, given, merged, text)
    return merged


def _over(every: TaskSettings, own: TaskSettings | None) -> TaskSettings:
    """A task's settings: its own where it gives them, else every task's (``"*"``)."""
    if own is None:
        return every
    return TaskSettings.model_validate({**_given(every), **_given(own)})


def _given(settings: TaskSettings) -> dict[str, object]:
    """The settings a file (or an option) gave, not the defaults."""
    return settings.model_dump(include=settings.model_fields_set)


def _canvas_option(canvas: str) -> None:
    """``--canvas-assignment`` names an assignment as Canvas's gradebook names its column (else exit 2)."""
    if not CANVAS_ASSIGNMENT.match(canvas):
        raise ClassError(f"--canvas-assignment {canvas!r}: {CANVAS_WORDS}")


def _known_mistakes(path: Path, given: dict[str, TaskSettings], text: bytes) -> None:
    """Every deduction names a mistake the diagnosis knows (else the run stops, naming the place; a misspelt id
    with the nearest one)."""
    known = {**VARIANTS, **MORE_VARIANTS}
    problems = [
        (
            f"{task}.deductions.{mistake}",
            f"no such mistake{did_you_mean(mistake, known)} (the ids are in docs/grading.md)",
        )
        for task, settings in sorted(given.items())
        for mistake in settings.deductions
        if mistake not in known
    ]
    if problems:
        raise ClassError("; ".join(as_lines(str(path), problems, text)))


def _within_points(path: Path, given: dict[str, TaskSettings], merged: dict[str, TaskSettings], text: bytes) -> None:
    """Every deduction takes at most its task's points (else the run stops, naming the place: the task's own
    deductions, or the ``"*"``'s that it takes)."""
    problems = []
    for task, settings in sorted(merged.items()):
        own = given.get(task)
        where = task if own is not None and "deductions" in own.model_fields_set else EVERY
        for mistake, less in settings.deductions.items():
            if less > settings.points:
                whose = "the task's points" if where == task else f"the points of task {task}"
                default = "" if "points" in settings.model_fields_set else " (points not given: the default)"
                problems.append((f"{where}.deductions.{mistake}", f"must be ≤ {whose}, {settings.points:g}{default}"))
    if problems:
        raise ClassError("; ".join(as_lines(str(path), problems, text)))
