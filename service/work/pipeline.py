"""The grading pipeline, written once for the command line, the HTTP service and class grading.

scene text → a validated scene (or every problem as ``FILE:LINE: path: message``); submitted bytes → pixels of
the scene's size (or why not); reference PNG and pixels → the grade, its reason and its heat-map.  Whatever does
the rendering (here, a cluster, a service), these steps and their words are the same.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

import numpy as np
from pydantic import ValidationError

from schemas import Image, Scene, SceneError, parse_json, validate_scene
from schemas.errors import problems_from_validation
from schemas.locate import Located, as_lines, format_located
from tracer import RenderCancelled, decode_png, open_pixels
from tracer.sizes import ImageTooLarge, check_size

from ..diagnosis import CACHE, Cached, Diagnosis, Renders, accepting, diagnose, renders_of
from ..diagnosis.accepting import Failing
from ..diagnosis.behind import behind_mistake, renders_behind
from ..diagnosis.nuisance import behind_offset
from ..images import grading
from ..images.heatmap import Kind, heatmap_png
from ..render.scenekey import scene_key

#: values of a scene's ``image`` given beside it (``--width``, ``?samples=2``), by name; None keeps the scene's
Overrides = Mapping[str, int | None]


class BadInput(ValueError):
    """Input that cannot be used, as the one line to show (files named, problems joined by ``; ``)."""


def scene_lines(name: str, errors: Sequence[Located]) -> list[str]:
    """``NAME:LINE: path: message`` per located problem (``{"path", "message", "line"}``, as /validate gives)."""
    return format_located(name, errors)


def with_overrides(scene: Scene, overrides: Overrides | None) -> Scene:
    """The scene with values of its ``image`` replaced (``--width``, ``?samples=2``; None keeps the scene's).
    Overrides apply to a valid scene: they neither complete nor mend one, so that a scene is accepted exactly
    when its JSON Schema says so.  Raises :class:`SceneError` for an override out of range."""
    given = {k: v for k, v in (overrides or {}).items() if v is not None}
    if not given:
        return scene
    try:
        image = Image.model_validate({**scene.image.model_dump(), **given})
    except ValidationError as exc:
        raise SceneError([(f"image.{path}", message) for path, message in problems_from_validation(exc)]) from None
    return scene.model_copy(update={"image": image})


def load_scene(name: str, text: bytes, overrides: Overrides | None = None, shared: bool = False) -> Scene:
    """The validated scene of a file's text, ``overrides`` applied to its ``image``; :class:`SceneError`
    (with ``.lines``) names every problem by file and line."""
    try:
        return with_overrides(validate_scene(parse_json(text, shared=shared)), overrides)
    except SceneError as exc:
        exc.lines = as_lines(name, exc.problems, text)  # type: ignore[attr-defined]
        raise


def renderable_scene(name: str, text: bytes) -> Scene:
    """:func:`load_scene`, and a scene beyond what phongray renders (:func:`tracer.sizes.check_size`: too many
    pixels, rays or light samples) refused as its file's problem, a :class:`SceneError` whose ``.lines`` are
    render's own words: valid as the format goes, but no task scene."""
    scene = load_scene(name, text)
    try:
        check_size(scene)
    except ImageTooLarge as exc:
        error = SceneError([("", str(exc))])
        error.lines = [f"{name}: {exc}"]  # type: ignore[attr-defined]
        raise error from None
    return scene


def scene_or_bad_input(name: str, text: bytes, overrides: Overrides | None = None) -> Scene:
    """:func:`load_scene`, its problems as one :class:`BadInput` line."""
    try:
        return load_scene(name, text, overrides)
    except SceneError as exc:
        raise BadInput("; ".join(exc.lines)) from None  # type: ignore[attr-defined]


@dataclass(frozen=True)
class Graded:
    grade: grading.Grade
    heatmap: bytes | None  # PNG, when one was asked for
    diagnosis: Diagnosis | None = None  # of a failing grade, when one was asked for
    #: the accepted variant it passed as ("a ray offset of 0.003 along the normal"), None: the reference
    accepted: str | None = None

    def as_dict(self) -> dict[str, Any]:
        """The grade's numbers, its ``reason`` (why it failed; empty when it passed), its ``diagnosis``
        (what the student most likely got wrong; null when it passed or none was asked for) and the accepted
        variant it passed as (``accepted``; null when it passed against the reference or failed)."""
        return {
            **self.grade.as_dict(),
            "reason": self.grade.reason,
            "diagnosis": None if self.diagnosis is None else self.diagnosis.as_dict(),
            "accepted": self.accepted,
        }


@dataclass(frozen=True)
class Checks:
    """What a failing grade is checked for: the accepted variants (name → largest amount; None: the
    defaults, ``{}``: none), and then, when it fails them too, the diagnosis (``diagnose``)."""

    accepted: dict[str, float] | None = None
    diagnose: bool = True


@dataclass(frozen=True)
class Checking:
    """How the checks of a failing grade run: on how many threads (None: every core), what stops them (true:
    :class:`tracer.RenderCancelled`), and the cache of diagnosis renders (None: this process's,
    :data:`service.diagnosis.CACHE`)."""

    threads: int | None = None
    cancel: Callable[[], bool] | None = None
    cache: Cached | None = None


@dataclass(frozen=True)
class Explaining:
    """What a failing grade is explained with: the reference's scene (``scene()``, called only when a grade
    fails), what it is checked for, and how the checks run."""

    scene: Callable[[], Scene]
    checks: Checks = Checks()
    run: Checking = Checking()


def explain(
    scene: Scene,
    graded: Graded,
    reference: np.ndarray,
    submitted: np.ndarray,
    checks: Checks = Checks(),
    run: Checking = Checking(),
) -> Graded:
    """``graded`` passed against an accepted variant (:mod:`service.diagnosis.accepting`), or else with the
    diagnosis of a failing grade (:mod:`service.diagnosis`): the reference scene rendered with each classic
    mistake and its passes, cached by canonical scene (in ``run.cache``), compared with the submission.  A
    passing grade comes back as it is; a failing one is first graded without the pixels the format leaves open,
    where the scene has any (:func:`without_open`)."""
    if graded.grade.passed:
        return graded
    opened = left_open(scene, run)
    if opened is not None:
        graded = _without(graded, reference, submitted, opened)
        if graded.grade.passed:
            return graded
    failing = Failing(reference, submitted, graded.grade, opened)  # (the open pixels are not counted by any check)
    held = CACHE if run.cache is None else run.cache
    make = partial(renders_of, scene, run.threads, open_pixels=opened)
    renders = held.get(scene_key(scene), make, scene.image.width * scene.image.height)
    renders.cancel_in_thread(run.cancel)  # (the cached renders may be another grade's at the same time)
    try:  # (the rungs of the offsets' ladders kept with the diagnosis's renders: one budget, each rendered once)
        found_variant = accepting.accept(scene, failing, checks.accepted, run.threads, run.cancel, renders)
    finally:
        renders.done()
        held.trim()
    if found_variant is not None:
        return Graded(found_variant.grade, graded.heatmap, None, found_variant.words)
    if not checks.diagnose:
        return graded
    found = _diagnosed(failing, renders, held, run)
    if not any(c.passes for c in found.causes) and found.unavailable is None:
        found = _behind_offset(scene, failing, checks, run, found) or found
    if not any(c.passes for c in found.causes) and found.unavailable is None:
        found = _behind_mistake(scene, failing, (renders, held), run, found) or found
    return Graded(graded.grade, graded.heatmap, found)


def _diagnosed(failing: Failing, renders: Renders, held: Cached, run: Checking) -> Diagnosis:
    """The diagnosis of a failing pair with the scene's renders (held in the run's cache, ``held``)."""
    renders.cancel_in_thread(run.cancel)  # (the cached renders may be another diagnosis's at the same time)
    try:
        return diagnose(failing.reference, failing.submitted, failing.failed, renders)
    finally:
        held.trim()  # (what it rendered counted, cancelled or not)


def _behind_offset(scene: Scene, failing: Failing, checks: Checks, run: Checking, found: Diagnosis) -> Diagnosis | None:
    """``found`` with a mistake the submission matches at the honest offset it shows besides it (fitted as a
    nuisance, :mod:`service.diagnosis.nuisance`); None when there is none."""
    return behind_offset(scene, failing, found, checks.accepted, (run.threads, run.cancel))


def _behind_mistake(
    scene: Scene, failing: Failing, kept: tuple[Renders, Cached], run: Checking, found: Diagnosis
) -> Diagnosis | None:
    """``found`` with the mistakes the submission matches behind another it names (:mod:`service.diagnosis.behind`);
    None when there are none, or when the time runs out on the way (``found`` is a whole diagnosis already: it is
    not lost to a further look's).  The renders on that mistake's base are held with the scene's (``kept``: the
    scene's renders and their cache)."""
    renders, held = kept
    made = renders_behind(scene, scene_key(scene), (run.threads, run.cancel), held, failing.open_pixels)
    renders.cancel_in_thread(run.cancel)
    try:
        return behind_mistake(failing, found, renders, made)
    except RenderCancelled:
        return None
    finally:
        renders.done()
        held.trim()


def left_open(scene: Scene, run: Checking) -> np.ndarray | None:
    """The pixels of ``scene`` the format leaves open, ``(H, W)`` bool: which of two overlapping coplanar surfaces
    shows (:func:`tracer.open_pixels`, a render made only for a scene that has such surfaces); None where none is."""
    opened = open_pixels(scene, run.threads, run.cancel)
    return None if opened is None or not opened.any() else opened


def without_open(scene: Scene, graded: Graded, reference: np.ndarray, submitted: np.ndarray, run: Checking) -> Graded:
    """``graded`` graded again without the pixels of ``scene`` the format leaves open (:func:`left_open`)."""
    opened = left_open(scene, run)
    return graded if opened is None else _without(graded, reference, submitted, opened)


def _without(graded: Graded, reference: np.ndarray, submitted: np.ndarray, opened: np.ndarray) -> Graded:
    """``graded`` graded again with the pixels ``opened`` not counted."""
    g = graded.grade
    return replace(
        graded, grade=grading.grade(reference, submitted, g.reference_sha256, g.tolerance, g.max_fraction, opened)
    )


def read_image(data: bytes, size: tuple[int, int]) -> np.ndarray:
    """A submission's pixels, of ``size = (width, height)``; :class:`grading.ImageError` says why not."""
    return grading.read_submission(data, size)


def compare(
    reference_png: bytes,
    submitted: np.ndarray,
    tolerance: float,
    max_fraction: float,
    heatmap: Kind | None = None,
    legend: bool = False,
    reference: np.ndarray | None = None,
) -> Graded:
    """Grade ``submitted`` pixels against a reference PNG (decoded here unless its ``reference`` pixels are
    given); with ``heatmap``, the heat-map of that kind too."""
    pixels = decode_png(reference_png) if reference is None else reference
    result = grading.grade(pixels, submitted, hashlib.sha256(reference_png).hexdigest(), tolerance, max_fraction)
    heat = heatmap_png(pixels, submitted, tolerance, heatmap, legend) if heatmap else None
    return Graded(result, heat)


def grade_png(
    reference_png: bytes,
    image: bytes,
    tolerance: float,
    max_fraction: float,
    heatmap: Kind | None = None,
    legend: bool = False,
    explaining: Explaining | None = None,
) -> Graded:
    """A submitted image's grade against a reference PNG; when it fails and ``explaining`` is given, graded
    against the accepted variants and diagnosed as it says (:func:`explain`); :class:`grading.ImageError` when
    it cannot be graded."""
    pixels = decode_png(reference_png)
    submitted = read_image(image, (pixels.shape[1], pixels.shape[0]))
    graded = compare(reference_png, submitted, tolerance, max_fraction, heatmap, legend, reference=pixels)
    if explaining is None or graded.grade.passed:
        return graded
    return explain(explaining.scene(), graded, pixels, submitted, explaining.checks, explaining.run)


#: the largest reference ``phongray compare`` decodes (the service's default max_pixels)
MAX_COMPARED_PIXELS = 4096 * 4096


def read_reference(data: bytes) -> np.ndarray:
    """The pixels of a reference PNG given as a file (``phongray compare``): opaque, at most
    :data:`MAX_COMPARED_PIXELS`; :class:`grading.ImageError` says why not."""
    return read_image(data, grading.declared_size(data, MAX_COMPARED_PIXELS))
