"""Which render-level mistakes a composition (:mod:`.compose`) tries, and what it needs of the scene to try them:
every classic mistake the scene can show, and the new ones (:data:`tracer.scene.variants.MORE_VARIANTS`) the term
fit points to."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tracer.scene.variants import BOUNDS, MORE_VARIANTS, VARIANTS, Options

from .records import Term
from .stored import OUTER, STORED


@dataclass(frozen=True)
class Looks:
    """What a composition needs of the scene: rows of a mistake's render, one whole render of merged options,
    and which mistakes the scene can show at all."""

    rows: Callable[[str, np.ndarray], np.ndarray]  # a name of ALL, row numbers → those rows, (k, W, 3) uint8
    render: Callable[[Options], np.ndarray]  # options → the whole image (H, W, 3) uint8
    shown: Callable[[str], bool]  # name → whether the scene can show the mistake (else it renders the reference)
    lights: tuple[str, ...]  # the scene's light types, in order
    open: np.ndarray | None = None  # (H, W) bool: the pixels not counted against a submission (Renders.open)


#: the term fit's slack: a coefficient further than this from 1 is out of scale
SLACK = 0.15


def pointed(terms: list[Term], lights: tuple[str, ...]) -> dict[str, str]:
    """The new render-level mistakes (:data:`tracer.scene.variants.MORE_VARIANTS`) the fitted terms point to, each with
    the term that points to it, in words: a spot's term too strong (its exponent ignored), a light's term out of
    scale (its colour ignored), a light's term too weak (clamped per term; reflections blended, which darken
    the local colour of a mirror), the refractions out of scale (the normal leaving glass)."""
    out: dict[str, str] = {}
    for t in terms:
        what = f"{t.name}:{t.light}" if t.light is not None else t.name
        kind = lights[t.light] if t.light is not None and 0 <= t.light < len(lights) else None
        if kind == "spot" and t.scale > 1 + SLACK:
            out.setdefault("spot-exponent-ignored", what)
        if kind is not None:
            out.setdefault("light-colour-ignored", what)
        if t.scale < 1 - SLACK and t.name in ("diffuse", "specular", "ambient"):
            out.setdefault("clamped-per-term", what)
            out.setdefault("reflection-blended", what)
        if t.name == "reflection":
            out.setdefault("reflection-blended", what)
        if t.name == "refraction":
            out.setdefault("exit-normal-not-flipped", what)
    return out


def candidates(looks: Looks, terms: list[Term]) -> dict[str, str]:
    """The render-level mistakes to try, each with why: every classic one the scene can show (the single-mistake
    diagnosis has looked at them already), the new ones the fit points to (:func:`pointed`), or every new one
    the scene can show when the fit has no term out of scale (the difference is in no term's scale: the fit
    cannot point), and the scene's samples ignored when it asks for more than one (aliasing is no term's).  A
    speckled mistake (shadow acne) is never one of a combination: its own speckles are not the student's."""
    out = {name: "" for name in VARIANTS if name not in OUTER and name not in BOUNDS and looks.shown(name)}
    out |= {name: "" for name in STORED}
    new = pointed(terms, looks.lights) if terms else {name: "" for name in MORE_VARIANTS if name not in OUTER}
    out |= {name: f"the fit's {what}" if what else "" for name, what in new.items() if looks.shown(name)}
    if looks.shown("samples-ignored"):
        out["samples-ignored"] = "the scene's samples per pixel"
    return out
