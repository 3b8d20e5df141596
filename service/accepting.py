"""Accepted variants: the ways an honest student's tracer may differ from the reference and still pass.

A grade that fails against the reference is taken again against the
reference rendered as honest tracers render it (:data:`tracer.variants.
ACCEPTED_DEFAULT`: shadow and secondary rays started up to 10⁻³ of the
scene's size off the surface, along its normal or by a t_min), smallest
amount first; the first that passes is the verdict, "PASS, as rendered with a
0.001 ray offset".  A passing image costs nothing more: these renders are made
only for an image that fails the reference, and kept for the last few scenes,
so a class's failing pairs of one task share them.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from schemas import Scene
from tracer import Renderer
from tracer.variants import ACCEPTED_DEFAULT, Options, accepted_options, unchanged

from .grading import Grade, grade

#: an accepted variant explains a failing image when the image leaves at most this share of its pixels off
#: the reference off the variant too (an honest tracer's matches its variant all but exactly; a mistake that
#: merely looks alike at the threshold, an offset far too large in a scene that barely shows it, does not)
EXPLAINED = 0.5
#: renders of accepted variants kept (by scene and variant), each of at most this many pixels
KEPT = 8
KEPT_PIXELS = 640 * 480


@dataclass(frozen=True)
class Acceptance:
    """A failing image that passes against an accepted variant: which (in words), and that grade."""

    words: str  # "a 0.001 ray offset"
    grade: Grade


class _Kept:
    """The last :data:`KEPT` accepted variants rendered, by canonical scene key and options."""

    def __init__(self) -> None:
        self.held: dict[tuple[str, object], np.ndarray] = {}
        self.lock = threading.Lock()

    def get(self, key: tuple[str, object], make: Callable[[], np.ndarray], pixels: int) -> np.ndarray:
        with self.lock:
            if key in self.held:
                return self.held[key]
        image = make()
        if pixels <= KEPT_PIXELS:
            with self.lock:
                self.held[key] = image
                while len(self.held) > KEPT:
                    self.held.pop(next(iter(self.held)))
        return image


KEPT_RENDERS = _Kept()


def accept(scene: Scene, submitted: np.ndarray, failed: Grade, accepted: dict[str, float] | None = None,
           threads: int | None = None, cancel: Callable[[], bool] | None = None) -> Acceptance | None:
    """The first accepted variant (``accepted``: name → largest amount; None: the defaults) against which the
    ``submitted`` pixels pass, graded with ``failed``'s thresholds, and which explains the failure (at most
    :data:`EXPLAINED` of the pixels off the reference are off the variant); None when none does.

    A scene with no light but ambient and no mirror or glass renders every offset as the reference (no shadow or
    secondary ray is cast): it renders none of them."""
    from .scenekey import scene_key

    if unchanged("offset-too-large", scene):
        return None
    key = scene_key(scene)
    pixels = scene.image.width * scene.image.height
    for words, options in accepted_options(ACCEPTED_DEFAULT if accepted is None else accepted):
        variant = KEPT_RENDERS.get((key, options), partial(_render, scene, options, threads, cancel), pixels)
        again = grade(variant, submitted, failed.reference_sha256, failed.tolerance, failed.max_fraction)
        if again.passed and again.fraction_off_nearby <= EXPLAINED * failed.fraction_off_nearby:
            return Acceptance(words, again)
    return None


def _render(scene: Scene, options: Options, threads: int | None, cancel: Callable[[], bool] | None
            ) -> np.ndarray:
    return Renderer(scene, options).pixels(threads=threads, cancel=cancel)
