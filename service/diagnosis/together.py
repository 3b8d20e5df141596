"""The diagnosis's last steps: when no single classic mistake passes, the mistakes made together
(:mod:`.compose`), and when nothing fits, the nearest explanations, ranked by how much of the difference each
accounts for: a failing image's diagnosis never ends with no cause at all.

The renders come from the diagnosis's own (:class:`.renders.Renders`): rows of a classic mistake's render are
those its first looks rendered (kept), rows of a new one are rendered and kept the same way.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .combination import ALL, Combination
from .compose import compose, telling_rows
from .nearest import Explanation, nearest
from .records import Cause, Term
from .renders import Renders
from .stored import OUTER
from .too_large import NAME as TOO_LARGE
from .tried import Looks, candidates
from .with_offset import with_offset
from .words import Names, term_sentence

if TYPE_CHECKING:
    from ..images.grading import Grade

#: a combination not passed against is still named the closest when it leaves at most this share of the
#: reference's failing pixels (as a single mistake is, :data:`.causes.CLOSEST_SHARE`)
CLOSEST_SHARE = 0.25
#: at most this many nearest explanations are listed
NEAREST = 5


def looks_of(renders: Renders) -> Looks:
    """The :class:`Looks` of a diagnosis's renders."""
    unchanged = renders.unchanged
    return Looks(renders.rows, renders.render, lambda name: not unchanged(name), tuple(renders.lights), renders.open)


def fitted(terms: list[Term]) -> list[Term]:
    return [Term(t.name, t.light, t.scale) for t in terms]


def combined(
    reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders, terms: list[Term]
) -> Combination | None:
    """The mistakes made together the submission matches or comes nearest (:func:`.compose.compose`); None
    when no mistake helps, or the one found is a classic one alone.  Where none is passed against and the scene
    can show an offset too large, the offset made with another mistake at its own amount
    (:func:`.with_offset.with_offset`) when the submission passes against that."""
    renders.check()
    looks = looks_of(renders)
    found = compose(reference, submitted, verdict, looks, fitted(terms))
    if (found is None or not found.passes) and looks.shown(TOO_LARGE):
        tried = [*candidates(looks, fitted(terms)), *filter(looks.shown, OUTER)]
        return with_offset(reference, submitted, verdict, renders, tried) or found
    return found


def beside_closest(
    reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders, terms: list[Term], closest: str
) -> Combination | None:
    """The mistakes made together the submission passes against, chosen (:func:`.compose.compose`) on the rows
    where it departs most from the render of the mistake it comes ``closest`` to, not from the reference: a second
    mistake that shows on few pixels (a highlight missing beside shadows missing) lies on none of the rows the
    first one's difference fills, and its own difference is seen on these.  None when none passes."""
    renders.check()
    numbers = telling_rows(renders.variant(closest), submitted, verdict.tolerance)
    found = compose(reference, submitted, verdict, looks_of(renders), fitted(terms), numbers)
    return found if found is not None and found.passes else None


def together_causes(combination: Combination) -> list[Cause]:
    """The causes of a combination, one per mistake, each with the combination's grade and its evidence; then
    those of each other reading of the same image (:attr:`.combination.Combination.readings`) likewise: a cause's
    mistake and its ``together`` say which reading it is of."""
    names = combination.names
    mine = [
        Cause(
            m.variant,
            m.mistake,
            combination.fraction_off_nearby,
            combination.passes,
            [n for n in names if n != m.variant],
            m.share,
            m.evidence,
        )
        for m in combination.members
    ]
    return mine + [c for other in combination.readings for c in together_causes(other)]


def closer(
    combination: Combination | None, causes: list[Cause], closest: bool, verdict: Grade
) -> tuple[list[Cause], bool]:
    """The causes named when nothing passes: the combination when it comes closer than the closest single
    mistake (and far closer than the reference, as :data:`CLOSEST_SHARE` says), else the causes as they are."""
    if combination is None:
        return causes, closest
    best = causes[0].fraction_off_nearby if causes else np.inf
    near = combination.fraction_off_nearby <= CLOSEST_SHARE * verdict.fraction_off_nearby
    if combination.passes or (near and combination.fraction_off_nearby < best):
        return together_causes(combination), not combination.passes
    return causes, closest


def explanation_words(e: Explanation, names: Names) -> str:
    """What a nearest explanation says the difference is: "the specular of light 'key', which is missing", "what
    no shadow rays changes"."""
    if e.term is not None:
        return term_sentence(e.term.name, e.term.light, e.term.scale, names, ", which ")
    return f"what {ALL[e.variant or ''][1]} changes"


def nearest_causes(
    reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders, terms: list[Term]
) -> list[Cause]:
    """The nearest explanations as causes, none passed against, most of the difference first: a mistake by its
    id, a term as ``term:NAME`` or ``term:NAME:LIGHT``, each with its share of the difference and its words."""
    shared = [(f, t.share) for f, t in zip(fitted(terms), terms) if t.share]
    renders.check()
    ranked = nearest(reference, submitted, looks_of(renders), shared, verdict.tolerance)
    names = renders.names
    out = []
    for e in ranked[:NEAREST]:
        if e.term is not None:
            variant = "term:" + (e.term.name if e.term.light is None else f"{e.term.name}:{e.term.light}")
        else:
            variant = e.variant or ""
        out.append(
            Cause(
                variant,
                explanation_words(e, names),
                verdict.fraction_off_nearby,
                False,
                [],
                e.share,
                f"accounts for about {round(100 * e.share)} % of the difference",
            )
        )
    return out
