"""Accepted variants: the ways an honest student's tracer may differ from the reference and still pass.

A grade that fails against the reference is taken again against the
reference rendered as honest tracers render it (:data:`tracer.variants.
ACCEPTED_DEFAULT`: shadow and secondary rays started up to 10⁻³ of the
scene's size off the surface, along its normal or by a t_min), each at its
largest amount and halves of it: an image within the range of those renders
and the reference passes, "PASS, as rendered with a 1e-3 ray offset".  A
passing image costs nothing more: these renders are made only for an image
that fails the reference, and kept for the last few scenes, so a class's
failing pairs of one task share them.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np

from schemas import Scene
from tracer import Renderer, decode_png
from tracer.variants import ACCEPTED_DEFAULT, Options, accepted_options, unchanged

from ..grading import BAND, Grade, grade
from .looks import sampled_rows

#: an accepted variant explains a failing image when the image leaves at most this share of its pixels off
#: the reference off the variant too (an honest tracer's matches its variant all but exactly; a mistake that
#: merely looks alike at the threshold, an offset far too large in a scene that barely shows it, does not)
EXPLAINED = 0.5
#: renders of accepted variants kept (by scene and variant, whole or a first look's rows), each of at most this
#: many pixels
KEPT = 40
KEPT_PIXELS = 640 * 480


@dataclass(frozen=True)
class Acceptance:
    """A failing image that passes against an accepted variant: which (in words), and that grade."""

    words: str  # "a 0.001 ray offset"
    grade: Grade


class _Kept:
    """The last :data:`KEPT` accepted variants rendered, by canonical scene key and options."""

    def __init__(self) -> None:
        self.held: dict[tuple[object, ...], np.ndarray] = {}
        self.lock = threading.Lock()

    def has(self, key: tuple[object, ...]) -> bool:
        with self.lock:
            return key in self.held or stored(key) is not None

    def get(self, key: tuple[object, ...], make: Callable[[], np.ndarray], pixels: int) -> np.ndarray:
        with self.lock:
            if key in self.held:
                return self.held[key]
        path = stored(key)
        image = make() if path is None else decode_png(path.read_bytes())
        if pixels <= KEPT_PIXELS:
            with self.lock:
                self.held[key] = image
                while len(self.held) > KEPT:
                    self.held.pop(next(iter(self.held)))
        return image


KEPT_RENDERS = _Kept()

#: a folder of accepted variants rendered beforehand (an autograder bundle's), ``<scene key>/<file_name>``
STORED = "PHONGRAY_ACCEPTED_RENDERS"


def file_name(options: Options) -> str:
    """The name of a whole render of an accepted variant in a folder of them: ``normal-0.001.png``."""
    return f"{options.offset_along}-{options.offset!r}.png"


def stored(key: tuple[object, ...]) -> Path | None:
    """The file of a whole render ``key`` = (scene key, options) in the folder :data:`STORED` names, if there is
    one (never a first look's rows)."""
    folder = os.environ.get(STORED)
    if not folder or len(key) != 2 or not isinstance(key[1], Options):
        return None
    path = Path(folder) / str(key[0]) / file_name(key[1])
    return path if path.is_file() else None


@dataclass(frozen=True)
class Failing:
    """A submission that failed the reference: both images (``(H, W, 3) uint8``) and the grade."""

    reference: np.ndarray
    submitted: np.ndarray
    failed: Grade


def accept(
    scene: Scene,
    pair: Failing,
    accepted: dict[str, float] | None = None,
    threads: int | None = None,
    cancel: Callable[[], bool] | None = None,
) -> Acceptance | None:
    """The first accepted variant (``accepted``: name → largest amount; None: the defaults) whose range of
    amounts, from the reference to its largest, the submitted pixels pass against (:func:`envelope_off`, with
    the failed grade's thresholds), and which explains the failure (at most :data:`EXPLAINED` of the pixels off
    the reference are off the range); None when none does.  Its words are those of the amount it comes
    closest to.

    A scene with no light but ambient and no mirror or glass renders every offset as the reference (no shadow or
    secondary ray is cast): it renders none of them."""
    from ..scenekey import scene_key

    if unchanged("offset-too-large", scene):
        return None
    key = scene_key(scene)
    pixels = scene.image.width * scene.image.height
    submitted, failed = pair.submitted, pair.failed
    allowed = min(failed.max_fraction, EXPLAINED * failed.fraction_off_nearby) * pixels
    for rungs in accepted_options(ACCEPTED_DEFAULT if accepted is None else accepted):
        kept = all(KEPT_RENDERS.has((key, options)) for _, options in rungs)
        if not kept and first_look(scene, rungs, pair, Look(key, threads, cancel)) > allowed:
            continue  # (its rows alone leave too many pixels off: it cannot pass, whole)
        images = [
            KEPT_RENDERS.get((key, options), partial(_render, scene, options, threads, cancel), pixels)
            for _, options in rungs
        ]
        off = envelope_off([pair.reference, *images], submitted, failed.tolerance)
        if off > allowed:
            continue
        grades = [
            grade(image, submitted, failed.reference_sha256, failed.tolerance, failed.max_fraction) for image in images
        ]
        best = min(range(len(rungs)), key=lambda k: grades[k].fraction_off_nearby)
        return Acceptance(rungs[best][0], replace(grades[best], passed=True, fraction_off_nearby=off / pixels))
    return None


@dataclass(frozen=True)
class Look:
    """How a first look renders: the scene's key (its rows are kept under it), its threads and what cancels it."""

    key: str
    threads: int | None
    cancel: Callable[[], bool] | None

    def rows(self, scene: Scene, options: Options, rows: np.ndarray) -> np.ndarray:
        """Rows ``rows`` of the scene rendered with ``options``, kept for the next failing image."""
        return KEPT_RENDERS.get(
            (self.key, options, "rows"),
            partial(_render_rows, scene, options, rows, self),
            scene.image.width * len(rows),
        )


def first_look(scene: Scene, rungs: list[tuple[str, Options]], pair: Failing, how: Look) -> int:
    """A lower bound of :func:`envelope_off` for the range of ``rungs`` and the reference, from their renders of
    a few rows alone (:func:`service.diagnosis.looks.sampled_rows`: every 16th row with the rows either side).

    Exact, not an estimate: a pixel's count depends on its 3×3 neighbourhood alone, so each sampled middle row,
    rendered with the rows above and below, gives its off pixels exactly as the whole count does, and their
    count bounds the whole image's (0 for an image too short to have middle rows)."""
    middles, rows = sampled_rows(pair.submitted.shape[0])
    if not len(middles):
        return 0
    images = [pair.reference[rows]] + [how.rows(scene, options, rows) for _, options in rungs]
    return sum(
        _middle_off([image[3 * k : 3 * k + 3] for image in images], pair.submitted[m], pair.failed.tolerance)
        for k, m in enumerate(middles)
    )


def _middle_off(triplets: list[np.ndarray], row: np.ndarray, tolerance: float) -> int:
    """The pixels of one submitted ``row`` (W, 3) off even nearby the range of renders of it and the rows either
    side (each (3, W, 3))."""
    low = np.min(triplets, axis=0).astype(np.int16)
    high = np.max(triplets, axis=0).astype(np.int16)
    lo = np.pad(low, ((0, 0), (1, 1), (0, 0)), mode="edge") - tolerance
    hi = np.pad(high, ((0, 0), (1, 1), (0, 0)), mode="edge") + tolerance
    sub, w = row.astype(np.int16), row.shape[0]
    near = np.zeros(w, dtype=bool)
    for dy in range(3):
        for dx in range(3):
            near |= np.all((sub >= lo[dy, dx : dx + w]) & (sub <= hi[dy, dx : dx + w]), axis=1)
    return int(np.count_nonzero(~near))


def envelope_off(renders: list[np.ndarray], submitted: np.ndarray, tolerance: float) -> int:
    """The pixels of ``submitted`` off even nearby the range of ``renders`` (each ``(H, W, 3) uint8``): those
    with a channel outside [lowest − tolerance, highest + tolerance] of the renders at every pixel of their 3×3
    neighbourhood (edges repeat).  With one render this is the grade's own count of pixels off even nearby; with
    renders of one variant at several amounts it forgives any amount between them, as far as a pixel's value
    moves between theirs (an offset shifts a glass ball's rim a little with each amount).  Rows are compared
    :data:`BAND` at a time."""
    h = submitted.shape[0]
    low, high = np.min(renders, axis=0).astype(np.int16), np.max(renders, axis=0).astype(np.int16)
    off = 0
    for top in range(0, h, BAND):
        bottom = min(top + BAND, h)
        rows = np.clip(np.arange(top - 1, bottom + 1), 0, h - 1)
        lo = np.pad(low[rows], ((0, 0), (1, 1), (0, 0)), mode="edge") - tolerance
        hi = np.pad(high[rows], ((0, 0), (1, 1), (0, 0)), mode="edge") + tolerance
        sub = submitted[top:bottom].astype(np.int16)
        n, w = bottom - top, submitted.shape[1]
        near = np.zeros((n, w), dtype=bool)
        for dy in range(3):
            for dx in range(3):
                window = (slice(dy, dy + n), slice(dx, dx + w))
                near |= np.all((sub >= lo[window]) & (sub <= hi[window]), axis=2)
        off += int(np.count_nonzero(~near))
    return off


def _render(scene: Scene, options: Options, threads: int | None, cancel: Callable[[], bool] | None) -> np.ndarray:
    return Renderer(scene, options).pixels(threads=threads, cancel=cancel)


def _render_rows(scene: Scene, options: Options, rows: np.ndarray, how: Look) -> np.ndarray:
    return Renderer(scene, options).pixels_of_rows(rows, how.threads, cancel=how.cancel)
