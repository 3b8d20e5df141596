"""Mistakes that come together: which two or three mistakes made a failing image, confirmed by one render.

A student with two bugs fails against the reference rendered with either one.  Rendering every combination of
the mistakes would cost a render per pair; instead the failing image itself says which to try:

* **Image-level mistakes** (the image flipped, mirrored left to right, stored as grey, with red and blue
  swapped, gamma 1/2.2) are tried on the reference's own pixels, with no render: each is a change of the stored
  image (:data:`OUTER`), and every subset of them is compared with the submission at once.  Those found are
  undone on the submission (flips and the channel swap) or applied to what it is compared with (grey, gamma).
* **Render-level mistakes** change the light of the image; what each changes is taken from rows of its render
  that the single-mistake diagnosis already looked at (:attr:`Looks.rows`).  The differences of mistakes
  made together add up, all but exactly (each mistake changes one term of a sum of terms): the submission
  less the reference is fitted with the sum of the differences of one, two or three mistakes, on those rows.
  The new mistakes of :data:`tracer.scene.variants.MORE_VARIANTS` are looked at only where the term fit points to
  them (:func:`.tried.pointed`): the fit says which to try.
* **One render** of the merged options (:func:`merged`) confirms the combination with the grade's own
  measure, or leaves it the closest; one more for each other reading, where the rows cannot tell one of its
  mistakes from another (:func:`readings`: no refraction, or the normal leaving glass not flipped).

When nothing fits, :mod:`.nearest` ranks the explanations by their share of the difference.  Which mistakes are
tried, and what is needed of the scene to try them, is :mod:`.tried`'s.  Pure (:class:`.tried.Looks`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from itertools import combinations, product
from typing import TYPE_CHECKING

import numpy as np

from tracer.scene.variants import VARIANTS

from ..images.grading import grade
from .combination import ALL, Combination, Member, classic_first, compatible, merged
from .records import Term
from .stored import GAMMA, OUTER, SHOWN, STORED, image_level, outer, undone
from .tried import Looks, candidates

if TYPE_CHECKING:
    from ..images.grading import Grade

#: a further render-level mistake is added to a combination when it leaves at most this share of the mean
#: difference the combination without it leaves (each mistake of a combination accounts for a real part)
ADD_AT_MOST = 0.7
#: ... and makes the mean difference at least this much smaller, in 8-bit levels beyond the tolerance: more than
#: the rounding of a float sum, so that a mistake that changes nothing in those rows is never added
ADD_LEVELS = 1e-6
#: at most this many render-level mistakes together
MAX_TOGETHER = 3
#: at most this many readings of one combination are rendered (:func:`readings`)
MAX_READINGS = 4


# -- the differences of mistakes add up ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Rows:
    """The rows a combination is chosen on: the reference's, the submission's (image-level mistakes undone), and
    the image-level mistakes applied to every model of them (grey, gamma)."""

    reference: np.ndarray  # (k, W, 3) uint8
    submitted: np.ndarray  # (k, W, 3) uint8
    outer: tuple[str, ...]  # "grayscale", or none
    deltas: dict[str, np.ndarray]  # mistake → its render's rows less the reference's, float

    tolerance: float = 2.0  # the grade's: a difference within it is no difference
    known: dict[tuple[str, ...], float] = field(default_factory=dict)  # the errors worked out, by sorted names

    def error(self, names: tuple[str, ...]) -> float:
        key = tuple(sorted(names))
        if key not in self.known:
            self.known[key] = self._error(key)
        return self.known[key]

    def alike(self, a: str, b: str) -> bool:
        """Whether the rows cannot tell mistakes ``a`` and ``b`` apart: each changes them, and alike, to the last
        bit (no refraction, and the normal leaving glass not flipped, with shadows: :data:`ALIKE`).  Two such are
        two readings of one change, never two changes: made together, the one leaves the other nothing to do
        (no refracted ray to leave glass by), though their differences added would count it twice."""
        if a == b or a in STORED or b in STORED:
            return False
        da, db = self.deltas[a], self.deltas[b]
        return bool(np.any(da)) and np.array_equal(da, db)

    def fits(self, names: tuple[str, ...]) -> bool:
        """Whether the mistakes can be made together (:func:`compatible`) and the rows tell them all apart."""
        return compatible(names) and not any(self.alike(a, b) for a, b in combinations(names, 2))

    def ranked(self, tried: Iterable[tuple[str, ...]]) -> list[tuple[float, tuple[str, ...]]]:
        """The combinations ``tried`` that fit, by their error, and of equal errors the classic mistakes first
        (:func:`classic_first`): of two readings the rows cannot tell apart, the classic one is tried first."""
        return sorted(((self.error(p), p) for p in tried if self.fits(p)), key=lambda e: (e[0], classic_first(e[1])))

    def _error(self, names: tuple[str, ...]) -> float:
        """How far the submission's rows are from the reference's with the mistakes ``names`` made, their
        differences added: the mean, over the pixels, of the largest channel difference beyond the tolerance
        (levels).  A small highlight missing weighs as its pixels do, rounding not at all."""
        model = self.reference.astype(np.float64) + sum((self.deltas[n] for n in names if n not in STORED), np.zeros(1))
        stored = np.floor(np.clip(model, 0.0, 255.0) + 0.5).astype(np.uint8)
        return _beyond(outer(stored, (*self.outer, *(n for n in names if n in STORED))), self.submitted, self.tolerance)


def _beyond(a: np.ndarray, b: np.ndarray, tolerance: float) -> float:
    """The mean over pixels of ``b`` of the largest channel difference beyond ``tolerance`` from the nearest of
    the pixel of ``a`` and its neighbours left and right (the grade forgives a shift of a pixel; rows come
    alone, so only along them)."""
    wide = np.pad(a.astype(np.int16), ((0, 0), (1, 1), (0, 0)), mode="edge")
    sub, w = b.astype(np.int16), b.shape[1]
    diff = np.abs(wide[:, 0:w] - sub).max(axis=-1)
    for dx in (1, 2):
        np.minimum(diff, np.abs(wide[:, dx : dx + w] - sub).max(axis=-1), out=diff)
    return float(np.mean(np.maximum(diff - tolerance, 0.0)))


#: rows a combination is chosen on: this share of the image's, at least :data:`LEAST_ROWS`
ROW_SHARE = 1 / 16
LEAST_ROWS = 8


def telling_rows(reference: np.ndarray, submitted: np.ndarray, tolerance: float) -> np.ndarray:
    """The rows a combination is chosen on, :data:`ROW_SHARE` of them: in each of as many bands of the image, the
    row where the submission departs most from the reference (by :func:`_beyond`), so that a small highlight
    missing and a shadow far from it are both seen; in order."""
    h = reference.shape[0]
    k = min(h, max(LEAST_ROWS, round(ROW_SHARE * h)))
    diff = np.max(np.abs(reference.astype(np.int16) - submitted.astype(np.int16)), axis=-1)
    weight = np.maximum(diff - tolerance, 0).sum(axis=1)
    edges = np.linspace(0, h, k + 1).round().astype(np.int64)
    return np.array([a + int(np.argmax(weight[a:b])) for a, b in zip(edges[:-1], edges[1:]) if b > a])


def chosen(rows: Rows) -> tuple[str, ...]:
    """The render-level mistakes, at most :data:`MAX_TOGETHER`, whose differences added explain the rows: the
    best one, then the best pair if it leaves at most :data:`ADD_AT_MOST` of what the one leaves, then a third
    likewise; each at least :data:`ADD_LEVELS` better.  A pair is of two mistakes that each help alone, or of the
    best one and any other.  Empty when no mistake helps."""
    names = sorted(rows.deltas)
    best: tuple[str, ...] = ()
    error = rows.error(())

    def better(than: float, names: tuple[str, ...]) -> float | None:
        e = rows.error(names)
        return e if e <= ADD_AT_MOST * than and than - e >= ADD_LEVELS else None

    singles = rows.ranked((n,) for n in names)
    if singles and better(error, singles[0][1]) is not None:
        best, error = singles[0][1], singles[0][0]
    # (a mistake whose difference alone takes the rows further from the submission is no part of it, unless
    # made with the best one: a darker image's mistake, made with gamma's brightening, is no help alone)
    every = names
    names = sorted(n for e, (n,) in singles if e < rows.error(()))
    tried = set(combinations(names, 2))
    if singles:
        first = singles[0][1][0]
        tried |= {(min(first, n), max(first, n)) for n in every if n != first}
    pairs = rows.ranked(tried)
    if pairs and better(error, pairs[0][1]) is not None:
        best, error = pairs[0][1], pairs[0][0]
    while 2 <= len(best) < MAX_TOGETHER:
        more = rows.ranked((*best, n) for n in names if n not in best)
        if not more or better(error, more[0][1]) is None:
            break
        best, error = more[0][1], more[0][0]
    return best


def shares(rows: Rows, names: tuple[str, ...]) -> dict[str, float]:
    """Per mistake of ``names``, the share of the submission's whole mean difference (no mistake made) that
    making it takes away, the others made."""
    base = rows.error(())
    if base <= 0:
        return {n: 0.0 for n in names}
    full = rows.error(names)
    return {n: max(0.0, (rows.error(tuple(m for m in names if m != n)) - full) / base) for n in names}


# -- one render confirms -----------------------------------------------------------------------------------------


def compose(
    reference: np.ndarray,
    submitted: np.ndarray,
    verdict: Grade,
    looks: Looks,
    terms: list[Term],
    numbers: np.ndarray | None = None,
) -> Combination | None:
    """The mistakes made together that explain a failing ``submitted`` (graded ``verdict``), chosen on rows
    ``numbers`` (None: :func:`telling_rows`) and confirmed by one render of them all (none when they are
    image-level mistakes alone: the reference's pixels stored with them); None when no mistake helps, or when
    the one mistake found is a classic one alone (the single-mistake diagnosis has graded it already)."""
    found = image_level(reference, submitted)
    rows = _rows(reference, submitted, looks, candidates(looks, terms), (found, verdict.tolerance, numbers))
    inner = chosen(rows)
    names = (*inner, *found)
    if not names:
        return None
    if len(names) == 1 and names[0] in VARIANTS:  # (an image-level one alone is named as it always was)
        return _partnered(submitted, verdict, looks, (rows, terms), inner[0]) if inner else None
    if all(n in STORED or n in OUTER for n in names) and GAMMA not in names:
        image = outer(reference, names)  # (exact for all but the mirror, which is within a level)
        g = grade(image, submitted, "", verdict.tolerance, verdict.max_fraction, looks.open)
        return _combination(rows, inner, found, g, candidates(looks, terms))
    return _rendered(submitted, verdict, looks, rows, (inner, found, candidates(looks, terms)))


def _rendered(
    submitted: np.ndarray,
    verdict: Grade,
    looks: Looks,
    rows: Rows,
    made: tuple[tuple[str, ...], dict[str, float], dict[str, str]],
) -> Combination:
    """The render-level mistakes ``inner`` (with the image-level ones ``found``), each of their :func:`readings`
    graded against its render: the first the submission passes against, with the others it passes against as
    its readings, unless, of three, the first two pass alone (a third added for a residue of the rows' sum, too
    small for the grade to see, is no mistake the image shows); else, of three, the first two (the third was
    added where its difference did not add to theirs) when the submission passes against them; else one mistake
    swapped, the nearest on the rows, when it passes; else the first, which comes closest."""
    inner, found, tried = made
    graded = []
    for names in readings(rows, inner):
        g = grade(
            looks.render(merged((*names, *found))), submitted, "", verdict.tolerance, verdict.max_fraction, looks.open
        )
        graded.append(_combination(rows, names, found, g, tried))
    passing = [c for c in graded if c.passes]
    if passing and len(inner) == MAX_TOGETHER:  # (a third the image need not show: the two alone, if they pass)
        fewer = _rendered(submitted, verdict, looks, rows, (inner[:-1], found, tried))
        if fewer.passes:
            return fewer
    if passing:
        return replace(passing[0], readings=tuple(passing[1:]))
    if len(inner) == MAX_TOGETHER:  # (a third whose difference did not add: Blinn–Phong uses no R)
        fewer = _rendered(submitted, verdict, looks, rows, (inner[:-1], found, tried))
        return fewer if fewer.passes else graded[0]
    swaps = [(rows.error(p), p) for m in inner for n in rows.deltas if n not in inner and (p := _swap(inner, m, n))]
    best = min(((e, p) for e, p in swaps if rows.fits(p) and p not in [c.names for c in graded]), default=None)
    if best is not None:  # (the runner-up on the rows: one more render, only when nothing passes)
        image = looks.render(merged((*best[1], *found)))
        g = grade(image, submitted, "", verdict.tolerance, verdict.max_fraction, looks.open)
        return _combination(rows, best[1], found, g, tried) if g.passed else graded[0]
    return graded[0]


def _swap(inner: tuple[str, ...], m: str, n: str) -> tuple[str, ...]:
    return () if m in STORED or n in STORED else tuple(n if x == m else x for x in inner)


def readings(rows: Rows, inner: tuple[str, ...]) -> list[tuple[str, ...]]:
    """``inner``, then as many mistakes with some made in place of others the rows cannot tell them from
    (:meth:`Rows.alike`, or made in place of it the rows are as near the submission's: the reflected vector
    with the wrong sign and no specular term, on rows that miss the few pixels a light behind a surface lights),
    classic ones first, at most :data:`MAX_READINGS` in all.  The rows of each mistake are rendered with no other
    made: what they cannot tell apart, made with the others, a render may (with no shadow rays, light reaches the
    inside of a glass ball its refracted rays cannot leave, and lights it)."""
    error = rows.error(inner)

    def twin(m: str, n: str) -> bool:
        if rows.alike(m, n):
            return True
        swapped = _swap(inner, m, n)
        return bool(swapped) and rows.fits(swapped) and rows.error(swapped) <= error

    each = [[m, *sorted((n for n in rows.deltas if n not in inner and twin(m, n)), key=_one_first)] for m in inner]
    return [p for p in product(*each) if len(set(p)) == len(p) and compatible(p)][:MAX_READINGS]


def _one_first(name: str) -> tuple[int, tuple[str, ...]]:
    return classic_first((name,))


def _partnered(
    submitted: np.ndarray, verdict: Grade, looks: Looks, chosen_on: tuple[Rows, list[Term]], first: str
) -> Combination | None:
    """The classic mistake the rows chose alone (not passed against) with its partner nearest on the rows, when
    one render of the two passes: where one saturates the image, the other's difference does not add."""
    rows, terms = chosen_on
    alone = rows.reference + rows.deltas[first]
    kept = alone >= 255.0  # (a channel the first mistake saturates stays saturated: the partner adds nothing there)

    def error(n: str) -> float:
        model = np.where(kept, alone, alone + rows.deltas[n])
        return _beyond(np.floor(np.clip(model, 0.0, 255.0) + 0.5).astype(np.uint8), rows.submitted, rows.tolerance)

    partners = [n for n in rows.deltas if n != first and n not in STORED and rows.fits((first, n))]
    ranked = sorted((min(error(n), rows.error((first, n))), n) for n in partners)
    for n in [n for e, n in ranked[:2] if e < rows.error((first,)) - ADD_LEVELS]:  # (one render each)
        g = grade(looks.render(merged((first, n))), submitted, "", verdict.tolerance, verdict.max_fraction, looks.open)
        if g.passed:
            return _combination(rows, (first, n), {}, g, candidates(looks, terms))
    return None


def _combination(
    rows: Rows, inner: tuple[str, ...], found: dict[str, float], g: Grade, tried: dict[str, str]
) -> Combination:
    """The render-level mistakes ``inner`` and image-level ``found``, graded ``g``, with their shares."""
    inner_shares = shares(rows, inner)
    members = [Member(n, ALL[n][1], inner_shares[n], _why(tried[n], inner_shares[n])) for n in inner]
    members += [Member(n, ALL[n][1], found[n], f"the image is the reference's {SHOWN[n]}") for n in found]
    members.sort(key=lambda m: -m.share)
    return Combination(tuple(members), g.fraction_off_nearby, g.passed)


def stored_only(
    reference: np.ndarray, submitted: np.ndarray, verdict: Grade, open_pixels: np.ndarray | None = None
) -> Combination | None:
    """The image-level mistakes alone, when the submission passes against the reference's pixels stored with
    them: found with no render at all, before any mistake is rendered (None also for the classic flip alone,
    which the single-mistake diagnosis names as it always has)."""
    found = image_level(reference, submitted)
    names = tuple(n for n in OUTER if n in found)
    if not names or names == ("image-flipped",):
        return None
    g = grade(outer(reference, names), submitted, "", verdict.tolerance, verdict.max_fraction, open_pixels)
    if not g.passed:
        return None
    members = [Member(n, ALL[n][1], found[n], f"the image is the reference's {SHOWN[n]}") for n in names]
    return Combination(tuple(sorted(members, key=lambda m: -m.share)), g.fraction_off_nearby, True)


def _rows(
    reference: np.ndarray,
    submitted: np.ndarray,
    looks: Looks,
    tried: dict[str, str],
    how: tuple[dict[str, float], float, np.ndarray | None],
) -> Rows:
    """The :class:`Rows` of a submission with the image-level mistakes ``found`` (undone on it, or, grey,
    applied to the models), the render-level mistakes ``tried`` each rendered on the rows (gamma applied)."""
    found, tolerance, numbers = how
    grey = ("grayscale",) if "grayscale" in found else ()
    sub = undone(submitted, tuple(found))
    if numbers is None:
        numbers = telling_rows(outer(reference, grey), sub, tolerance)
    ref_rows = reference[numbers].astype(np.float64)
    deltas = {
        n: np.zeros(1) if n in STORED else looks.rows(n, numbers).astype(np.float64) - ref_rows
        for n in tried
        if n not in found
    }
    return Rows(reference[numbers], sub[numbers], grey, deltas, tolerance)


def _why(pointer: str, share: float) -> str:
    accounts = f"the mistake accounts for {round(100 * share)} % of the difference"
    return f"{pointer} out of scale; {accounts}" if pointer.startswith("the fit") else accounts
