"""A speckled mistake made with another: shadow acne and a second mistake in one image.

Shadow acne is never one of a combination fitted by :mod:`.compose` (its speckles are the student's own pattern,
no render has them).  It is scored against its far end instead (:func:`.looks.speckled`): an image with acne lies,
pixel by pixel, between the reference and the reference with every shadow ray blocked, departing in speckles.
With a second mistake ``X`` made too, the image lies between the reference rendered with ``X`` and that render's
far end (``X`` made, every shadow ray blocked): the same test, with ``X``'s render in place of the reference.

Which ``X`` to try is chosen on the rows where the submission is most off (:func:`.compose.telling_rows`), with
no new render: each mistake's rows (kept from the first round) against an envelope of acne's own far end moved
as ``X`` moves the reference (``X``'s rows plus the far end's difference; flipped or brightened as ``X`` stores
the image).  The :data:`TRIED` best are confirmed on the whole image by one render each of their far end, and
the first whose image passes the speckled test (at most the grade's share of pixels outside, in speckles) is
named with acne: "shadow acne and the Blinn–Phong highlight", each with its deduction.
"""

from __future__ import annotations

from dataclasses import fields, replace

import numpy as np

from tracer.scene.variants import BOUNDS, REFERENCE, VARIANTS, Options

from ..images.grading import Grade
from .combination import ALL, Combination, Member, merged
from .compose import _beyond, telling_rows
from .looks import speckled
from .renders import Renders
from .stored import GAMMA, outer

#: what the search is asked: the speckled mistake, the reference, the submission, its verdict, the renders
_Args = tuple[str, np.ndarray, np.ndarray, Grade, Renders]
#: second mistakes whose change acne may speckle all over (the pixels a spot's cone reaches): where the plain test
#: (:func:`shows`) fails, their far end is rendered and the test made between the far ends (:func:`shows_speckled`)
SPECKLED_OVER = (
    "spot-radians",
    "spot-ramp-angle",
    "area-not-divided",
    "no-attenuation",
    "spot-cone-ignored",
    "attenuation-not-squared",
)
#: at most this many second mistakes are confirmed by a render of their far end
TRIED = 2
#: mistakes never tried with acne: no shadows hides it (no shadow ray, no acne: the image is no shadows'), the
#: other speckled ones are not made twice, and an offset too large is rendered on its own ladder
NEVER = ("no-shadows", "offset-too-large", *BOUNDS)


def speckled_with(reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders) -> Combination | None:
    """Shadow acne (each speckled mistake of :data:`tracer.scene.variants.BOUNDS`) made with one other classic mistake,
    when the submission passes the speckled test against that mistake's render and its far end; None when the
    scene cannot show acne or no second mistake makes it pass."""
    for name in BOUNDS:
        if renders.unchanged(name):
            continue
        ranked = _ranked(name, reference, submitted, verdict.tolerance, renders)
        for other in ranked[:TRIED]:
            renders.check()
            found = _confirmed(name, other, reference, submitted, verdict, renders)
            if found is not None:
                return _with_twins(found, other, ranked, (name, reference, submitted, verdict, renders))
    return None


def _with_twins(found: Combination, other: str, ranked: list[str], args: _Args) -> Combination:
    """``found`` with a reading for each other mistake of the :data:`TRIED` ranked first with which the submission
    passes the test too (one render of its far end each): no specular term, and the reflected vector with the
    wrong sign, differ only where a light lies behind a surface, and acne's speckles cover that; made with acne,
    the image cannot tell them apart, so both are said, the one leaving fewer pixels off first."""
    name, reference, submitted, verdict, renders = args
    readings = []
    for n in ranked[ranked.index(other) + 1 : TRIED]:  # (those ranked before it were tried: none passed)
        renders.check()
        twin = _confirmed(name, n, reference, submitted, verdict, renders)
        if twin is not None:
            readings.append(twin)
    if not readings:
        return found
    first, *rest = sorted([found, *readings], key=lambda c: c.fraction_off_nearby)  # (the nearer reading first)
    return replace(first, readings=tuple(rest))


def _ranked(name: str, reference: np.ndarray, submitted: np.ndarray, tolerance: float, renders: Renders) -> list[str]:
    """The second mistakes worth a render, fewest of the telling rows' pixels outside their envelope first (of as
    many, the one whose render is nearest the submission): only those that leave no more outside than acne alone
    does."""
    h = reference.shape[0]
    numbers = telling_rows(reference, submitted, tolerance)
    ref = reference[numbers].astype(np.float64)
    sub = submitted[numbers].astype(np.int16)
    far = renders.bound_rows(name, numbers)

    def outside(low: np.ndarray, high: np.ndarray) -> int:
        out = (sub < low - tolerance) | (sub > high + tolerance)
        return int(np.count_nonzero(np.any(out, axis=2)))

    def envelope(*images: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        stack = np.stack([np.clip(i, 0, 255).astype(np.int16) for i in images])
        return stack.min(axis=0), stack.max(axis=0)

    alone = outside(*envelope(ref, far))
    counts = []
    for other in VARIANTS:
        if other in NEVER or renders.unchanged(other):
            continue
        rows = renders.rows(other, numbers)
        if other == "image-flipped":
            moved = renders.bound_rows(name, h - 1 - numbers)
        elif other == GAMMA:
            moved = outer(far, (GAMMA,))
        else:
            moved = rows.astype(np.float64) + far - ref
        counts.append((outside(*envelope(rows, far, moved)), _beyond(rows, sub, tolerance), other))
    return [other for count, _, other in sorted(counts) if count <= alone]


def _confirmed(
    name: str, other: str, reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders
) -> Combination | None:
    """``name`` and ``other`` made together, when the submission lies between ``other``'s render and its far end
    in speckles, with at most the grade's share of its pixels outside; else None."""
    image = renders.variant(other)
    plain = shows(reference, image, submitted, verdict.tolerance)
    if not plain and other not in SPECKLED_OVER:
        return None
    far = renders.render(_far(name, other))
    if not plain and not shows_speckled((reference, renders.bound(name)), (image, far), submitted, verdict.tolerance):
        return None
    share = speckled(image, far, submitted, verdict.tolerance, renders.samples)
    if share is None or share > verdict.max_fraction:
        return None
    base = _beyond(reference, submitted, verdict.tolerance)
    left = _beyond(image, submitted, verdict.tolerance) / base if base > 0 else 0.0
    members = (
        Member(
            other,
            ALL[other][1],
            max(0.0, 1.0 - left),
            "the image lies between this mistake's render and its far end with every shadow ray blocked",
        ),
        Member(name, ALL[name][1], min(1.0, left), "the rest of the difference is speckles towards that far end"),
    )
    return Combination(tuple(sorted(members, key=lambda m: -m.share)), share, True)


def shows(reference: np.ndarray, image: np.ndarray, submitted: np.ndarray, tolerance: float) -> bool:
    """Whether the submission shows the second mistake where acne cannot explain it: of the pixels where its
    render ``image`` departs from the reference (beyond ``tolerance``), more match the render than match the
    reference, each within the tolerance.  Acne alone leaves a pixel as the reference has it or darkens it
    towards its far end: it never draws another mistake's change, unspeckled, across the pixels it spares."""
    ref, own, sub = (a.astype(np.int16) for a in (reference, image, submitted))
    differs = np.abs(own - ref).max(axis=2) > tolerance
    like_own = differs & (np.abs(sub - own).max(axis=2) <= tolerance)
    like_ref = differs & (np.abs(sub - ref).max(axis=2) <= tolerance)
    return int(np.count_nonzero(like_own)) > int(np.count_nonzero(like_ref))


def shows_speckled(
    ref: tuple[np.ndarray, np.ndarray], own: tuple[np.ndarray, np.ndarray], submitted: np.ndarray, tolerance: float
) -> bool:
    """:func:`shows` where acne speckles the very pixels the second mistake changes (a spot's cone widened across
    a wall acne covers): of the pixels where the mistake's render departs from the reference, more lie between that
    render and its far end (``own``) and not between the reference and acne's far end (``ref``) than the other
    way round.  Acne alone leaves every pixel within ``ref``'s range; only the mistake puts pixels outside it."""
    sub = submitted.astype(np.int16)

    def within(pair: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        low, high = (np.minimum(*pair).astype(np.int16), np.maximum(*pair).astype(np.int16))
        return np.all((sub >= low - tolerance) & (sub <= high + tolerance), axis=2)

    differs = np.abs(own[0].astype(np.int16) - ref[0].astype(np.int16)).max(axis=2) > tolerance
    in_own, in_ref = within(own), within(ref)
    return int(np.count_nonzero(differs & in_own & ~in_ref)) > int(np.count_nonzero(differs & in_ref & ~in_own))


def _far(name: str, other: str) -> Options:
    """The far end of speckled mistake ``name`` with ``other`` made too: every field either changes, the far
    end's (acne everywhere) over the mistake's own."""
    bound = BOUNDS[name]
    update = {f.name: getattr(bound, f.name) for f in fields(Options)}
    update = {k: v for k, v in update.items() if v != getattr(REFERENCE, k)}
    return replace(merged((other,)), **update)
