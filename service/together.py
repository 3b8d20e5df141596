"""The diagnosis's last step (issue 47): when no single classic mistake fits, the mistakes made together
(:mod:`service.compose`), and when nothing fits, the nearest explanations, ranked: a failing image's diagnosis
never ends with no cause at all.

The renders come from the diagnosis's own (:class:`service.diagnosis.Renders`): rows of a classic mistake's
render are those its first looks rendered (kept), rows of a new one are rendered here, once per diagnosis.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

import numpy as np

from tracer import Renderer
from tracer.variants import VARIANTS, Options, unchanged

from .compose import ALL, Combination, Explanation, Fitted, Looks, compose, nearest
from .words import Names, how_bright, nearest_sentence, term_name

#: a combination not passed against is still named the closest when it leaves at most this share of the
#: reference's failing pixels (the single mistakes' rule, :data:`service.diagnosis.CLOSEST_SHARE`)
CLOSEST_SHARE = 0.25
#: at most this many nearest explanations are listed
NEAREST = 5


def looks_of(scene: Any, renders: Any, threads: int | None = None) -> Looks:
    """A :class:`Looks` of a scene from its diagnosis renders: a classic mistake's rows as the diagnosis keeps
    them, a new one's rendered (and kept for this diagnosis), a combination rendered whole."""
    made: dict[str, np.ndarray] = {}

    def rows(name: str, numbers: np.ndarray) -> np.ndarray:
        if name in VARIANTS and renders.rows is not None:
            return np.asarray(renders.rows(name, numbers))
        key = f"{name}:{numbers.tobytes().hex()}"
        if key not in made:
            made[key] = Renderer(scene, ALL[name][0]).pixels_of_rows(numbers, threads)
        return made[key]

    def render(options: Options) -> np.ndarray:
        return Renderer(scene, options).pixels(threads=threads)

    return Looks(rows, render, lambda name: not unchanged(name, scene), tuple(light.type for light in scene.lights))


def _cause(cls: type, **values: Any) -> Any:
    """A cause record of ``cls`` from those of ``values`` it has."""
    have = {f.name for f in fields(cls)}
    return cls(**{k: v for k, v in values.items() if k in have})


def together_causes(combination: Combination, cause: type) -> list[Any]:
    """The causes of a combination, one per mistake, each with the combination's grade and its evidence."""
    names = combination.names
    return [_cause(cause, variant=m.variant, mistake=m.mistake, fraction_off_nearby=combination.fraction_off_nearby,
                   passes=combination.passes, together=[n for n in names if n != m.variant], share=m.share,
                   evidence=m.evidence) for m in combination.members]


def explanation_words(e: Explanation, names: Names) -> str:
    """What a nearest explanation says the difference is: "the specular of light 'key' (missing)", "what no
    shadow rays changes"."""
    if e.term is not None:
        return f"{term_name(e.term.name, e.term.light, names)} ({how_bright(e.term.scale)})"
    return f"what {ALL[e.variant or ''][1]} changes"


def nearest_causes(ranked: list[Explanation], names: Names, fraction: float, cause: type) -> list[Any]:
    """The nearest explanations as causes, none passed against: a mistake by its id, a term as ``term:NAME``
    (``term:specular:1``), each with its share of the difference and its words."""
    out = []
    for e in ranked[:NEAREST]:
        if e.term is not None:
            key = e.term.name if e.term.light is None else f"{e.term.name}:{e.term.light}"
            variant = f"term:{key}"
        else:
            variant = e.variant or ""
        out.append(_cause(cause, variant=variant, mistake=explanation_words(e, names), fraction_off_nearby=fraction,
                          passes=False, share=e.share, evidence="accounts for about "
                          f"{round(100 * e.share)} % of the difference"))
    return out


def completed(found: Any, reference: np.ndarray, submitted: np.ndarray, verdict: Any, looks: Looks,
              context: tuple[Names, list[tuple[Fitted, float]]]) -> Any:
    """``found`` (a diagnosis with no cause passed against) with the mistakes made together that the submission
    matches, or comes closest to, and otherwise the nearest explanations: never no cause.  ``context``: the
    scene's words and the fitted terms out of scale, each with its share of the difference."""
    names, terms = context
    kind = _cause_type(found)
    combination = compose(reference, submitted, verdict, looks, [t for t, _ in terms])
    if combination is not None:
        best = found.causes[0].fraction_off_nearby if found.causes else np.inf
        if combination.passes or (combination.fraction_off_nearby <= CLOSEST_SHARE * verdict.fraction_off_nearby
                                  and combination.fraction_off_nearby < best):
            found.causes, found.closest = together_causes(combination, kind), not combination.passes
            return found
    if not found.causes:
        ranked = nearest(reference, submitted, looks, terms, verdict.tolerance)
        found.causes = nearest_causes(ranked, names, verdict.fraction_off_nearby, kind)
    return found


def _cause_type(found: Any) -> type:
    from . import diagnosis

    return diagnosis.Cause if not found.causes else type(found.causes[0])


def sentence_of_nearest(found: Any) -> str | None:
    """The sentence of a diagnosis whose causes are nearest explanations (none passed against, none the closest):
    "No known mistake fits exactly: most of the difference is …"; None for any other."""
    if not found.causes or found.closest or any(c.passes for c in found.causes):
        return None
    first = found.causes[0]
    share = getattr(first, "share", None)
    return nearest_sentence(first.mistake, share) if share is not None else None
