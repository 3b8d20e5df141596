"""What a failing submission most likely got wrong: named mistakes, terms out of scale, and where.

Three kinds of evidence, each from renders of the reference scene:

* **Variants.** The reference rendered with each classic mistake
  (:data:`tracer.variants.VARIANTS`), graded against the submission with the
  same measure as the grade itself.  A variant the submission passes against
  is a likely cause; when none passes, one that comes far closer than the
  reference does is named as the closest, and otherwise nothing fits.
* **Terms.** A non-negative least-squares fit of the submission's linear
  values against the reference's additive passes (background, ambient, each
  light's diffuse and specular, reflection, refraction), on the pixels neither
  image clips: a coefficient far from 1 says a term is too strong or too weak,
  and by how much.
* **Where.** The objects the failing pixels show (the object pass), and the
  lights whose light falls on them.

Everything here is pure: the renders come in through a :class:`Renders`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from tracer.passes import ADDITIVE, LIGHT_TERMS
from tracer.variants import BOUNDS, REFERENCE, VARIANTS, Options, unchanged

from .display import percent
from .grading import Grade, grade

if TYPE_CHECKING:
    from tracer import Renderer
    from tracer.render import Fold

#: a variant that is not passed against is still named when it leaves at most this share of the reference's
#: failing pixels
CLOSEST_SHARE = 0.25
#: how much, on average, a speckled mistake's reach towards its far end changes from a pixel to the next
SPECKLE = 0.2
#: a fitted term is out of scale when its coefficient is further than this from 1
TERM_SLACK = 0.15
#: a term fitted below this is missing, not just too weak
MISSING = 0.05
#: a term too faint to matter: less than this share of the image's light
TERM_FLOOR = 0.02
#: the residual (RMS, of 1) that rounding to 8 bits alone leaves: no term is freed below it
ROUNDING = 1.0 / 255
#: at most this many terms are freed
MAX_TERMS = 3


@dataclass(frozen=True)
class Cause:
    variant: str  # a name of tracer.variants.VARIANTS
    mistake: str  # what the student did, in words
    fraction_off_nearby: float  # the submission against the reference rendered with the mistake
    passes: bool  # the submission passes against that render


@dataclass(frozen=True)
class Term:
    name: str  # "ambient", "diffuse", "specular", ... ; light-specific ones name their light
    light: int | None  # index in scene.lights, or None
    scale: float  # the fitted coefficient: 1 is right


@dataclass(frozen=True)
class Share:
    index: int  # index in scene.objects (or scene.lights)
    kind: str  # the object's or light's type
    share: float  # of the failing pixels


@dataclass
class Diagnosis:
    causes: list[Cause] = field(default_factory=list)  # best first; empty when nothing fits
    closest: bool = False  # the first cause is only the closest, not passed against
    terms: list[Term] = field(default_factory=list)  # the terms out of scale
    objects: list[Share] = field(default_factory=list)
    lights: list[Share] = field(default_factory=list)

    def sentence(self) -> str:
        """One sentence for a person: the likely mistake and the evidence, or that nothing fits."""
        if self.causes:
            c = self.causes[0]
            how = "matches" if not self.closest else "comes closest to"
            return (f"Likely: {c.mistake} — the submission {how} the reference rendered with that mistake "
                    f"({percent(c.fraction_off_nearby)} of pixels off)")
        if self.terms:
            return f"Likely: {term_words(asdict(self.terms[0]))} (about ×{self.terms[0].scale:.2f} of the reference's)"
        return "No known mistake fits: compare the heat-map with the reference"

    def as_dict(self) -> dict[str, Any]:
        return {"sentence": self.sentence(), "closest": self.closest,
                "causes": [asdict(c) for c in self.causes], "terms": [asdict(t) for t in self.terms],
                "objects": [asdict(s) for s in self.objects], "lights": [asdict(s) for s in self.lights]}


@dataclass
class Renders:
    """What a diagnosis needs rendered from the reference scene: each call may come from a cache."""

    variant: Callable[[str], np.ndarray]  # name → (H, W, 3) uint8 pixels of the reference with that mistake
    passes: Callable[[list[str], int | None], dict[str, np.ndarray]]  # names, light → tracer passes
    lights: list[str]  # the scene's light types, in order
    objects: list[str]  # the scene's object types, in order
    bound: Callable[[str], np.ndarray] | None = None  # name of BOUNDS → pixels of the mistake's far end
    cancel: Callable[[], bool] | None = None  # the current diagnosis's: true stops its renders
    #: name, row numbers → those rows of the variant's pixels, rendered alone (a first look, :func:`off_at_least`,
    #: or a band of its whole image, :func:`whole_unless_off`)
    rows: Callable[[str, np.ndarray], np.ndarray] | None = None
    #: name of BOUNDS, row numbers → those rows of the mistake's far end, rendered alone (:func:`outside_at_least`)
    bound_rows: Callable[[str, np.ndarray], np.ndarray] | None = None
    #: pixel numbers, fold → the first hits' ``object`` at those pixels alone; their ``diffuse:K`` and
    #: ``specular:K`` go to the fold, a block at a time (:data:`tracer.render.Fold`)
    at: Callable[[np.ndarray, Fold], np.ndarray] | None = None
    #: name → whether the scene cannot show that mistake (its render is the reference's, bit for bit)
    unchanged: Callable[[str], bool] | None = None
    #: called when a diagnosis is over, in its thread: lets go of what was prepared only for its renders
    done: Callable[[], None] | None = None
    #: sets the cancel of the diagnosis this thread runs (``cancel`` is every thread's): two diagnoses of one
    #: cached scene, in two threads, each stop on their own
    cancel_in_thread: Callable[[Callable[[], bool] | None], None] | None = None
    #: hands the columns of the term fit (``background``, ``ambient``, ``reflection``, ``refraction``,
    #: ``diffuse:K``, ``specular:K``, each ``(pixels, 3)``) to a fold, a block of pixels at a time, in order
    #: (:data:`tracer.render.Fold`): the whole image's passes are never needed at once
    blocks: Callable[[Fold], None] | None = None
    #: the bytes of the arrays these renders hold (what a cache of them counts)
    nbytes: Callable[[], int] | None = None

    def check(self) -> None:
        """Raises :class:`tracer.RenderCancelled` once the current diagnosis's cancel says to stop (its deadline,
        or its client gone): polled between the stages that render nothing (grading, the fit)."""
        cancel = self.cancel if self.polled is None else self.polled()
        if cancel is not None and cancel():
            from tracer import RenderCancelled

            raise RenderCancelled("diagnosis cancelled")

    #: the current thread's cancel (set by ``cancel_in_thread``), else ``cancel``
    polled: Callable[[], Callable[[], bool] | None] | None = None


def term_words(term: dict[str, Any]) -> str:
    """``the diffuse of light 1 term is missing`` for a term (as :meth:`Diagnosis.as_dict` lists it)."""
    what = term["name"] if term["light"] is None else f"{term['name']} of light {term['light']}"
    how = "missing" if term["scale"] < MISSING else "too strong" if term["scale"] > 1 else "too weak"
    return f"the {what} term is {how}"


def headline(found: dict[str, Any] | None) -> str:
    """A diagnosis (as :meth:`Diagnosis.as_dict`) in a few words, for a report's cell: the likely mistake,
    the term out of scale, or that nothing fits; empty for none (a pass)."""
    if not found:
        return ""
    if found["causes"]:
        return found["causes"][0]["mistake"] + (" (closest)" if found["closest"] else "")
    if found["terms"]:
        return f"{term_words(found['terms'][0])} (×{found['terms'][0]['scale']:.2f})"
    sentence: str = found["sentence"]
    return sentence if sentence.startswith("No diagnosis") else "no known mistake fits"


def unavailable(why: str) -> dict[str, Any]:
    """A diagnosis (as :meth:`Diagnosis.as_dict`) that could not be made, and why."""
    return {**Diagnosis().as_dict(), "sentence": f"No diagnosis: {why}"}


def diagnose(reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders) -> Diagnosis:
    """The likely causes of a failing grade ``verdict`` of ``submitted`` against ``reference`` (a passing
    grade gets no diagnosis: an empty one)."""
    try:
        return _diagnosed(reference, submitted, verdict, renders)
    finally:  # (cancelled or not)
        if renders.done is not None:
            renders.done()


def _diagnosed(reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders) -> Diagnosis:
    out = Diagnosis()
    if verdict.passed:
        return out
    pixels = submitted.shape[0] * submitted.shape[1]

    # whether a variant with at least ``off`` pixels off (even nearby) cannot pass, or cannot be named the
    # closest either: decided as the grade and the naming decide them, on the share of the pixels
    def cannot_pass(off: int) -> bool:
        return off / pixels > verdict.max_fraction

    def cannot_come_closest(off: int) -> bool:
        return cannot_pass(off) and off / pixels > CLOSEST_SHARE * verdict.fraction_off_nearby

    scored: list[Cause] = []
    later: list[str] = []  # variants that cannot pass, but may come closest if none passes

    def score(name: str, beyond: Callable[[int], bool]) -> bool:
        """Scores variant ``name``, unless its render shows on the way a count of off pixels ``beyond`` says
        is too many (then False: it cannot pass, or come closest, whichever ``beyond`` decides)."""
        image = whole_unless_off(name, submitted, verdict, renders, beyond)
        if image is None:
            return False
        if np.array_equal(image, reference):  # the mistake changes nothing in this scene: no evidence
            return True
        g = grade(image, submitted, "", verdict.tolerance, verdict.max_fraction)
        scored.append(Cause(name, VARIANTS[name][1], g.fraction_off_nearby, g.passed))
        return True

    def shown(name: str) -> bool:  # a mistake the scene cannot show is no evidence of anything: not rendered
        return renders.unchanged is None or not renders.unchanged(name)

    for name in filter(shown, VARIANTS):
        renders.check()
        if name in BOUNDS and renders.bound is not None:
            continue  # (a speckled mistake is scored against its far end below, not by its own render)
        # a first look at a few rows (exact: a lower bound of the variant's off pixels): a variant that cannot pass
        # is scored only if none passes, and then only if it may come closest
        least = None if name in BOUNDS else off_at_least(name, submitted, verdict, renders, cannot_pass)
        if (least is not None and cannot_pass(least)) or not score(name, cannot_pass):
            later.append(name)
    def score_speckled(name: str, beyond: Callable[[int], bool]) -> bool:
        """Scores speckled mistake ``name``, unless its far end shows on the way a count of pixels outside that
        ``beyond`` says is too many (then False, as :func:`score`)."""
        # the variant's own speckles are one pattern of many: only lying between the reference and the far
        # end, in speckles, is evidence of the mistake
        far = bound_unless_outside(name, reference, submitted, verdict, renders, beyond)
        if far is None:
            return False
        outside = speckled(reference, far, submitted, verdict.tolerance)
        if outside is not None:
            scored.append(Cause(name, VARIANTS[name][1], outside, outside <= verdict.max_fraction))
        return True

    later_bounds: list[str] = []  # speckled mistakes that cannot pass, but may come closest if none passes
    for name in filter(shown, BOUNDS) if renders.bound is not None else ():
        renders.check()
        least = outside_at_least(name, reference, submitted, verdict, renders, cannot_pass)
        if (least is not None and cannot_pass(least)) or not score_speckled(name, cannot_pass):
            later_bounds.append(name)
    if not any(c.passes for c in scored):  # then the closest is named: score what may come closest
        for name in later:
            renders.check()
            least = off_at_least(name, submitted, verdict, renders, cannot_come_closest)  # (every row looked at)
            if least is None or not cannot_come_closest(least):
                score(name, cannot_come_closest)
        for name in later_bounds:
            renders.check()
            least = outside_at_least(name, reference, submitted, verdict, renders, cannot_come_closest)
            if least is None or not cannot_come_closest(least):
                score_speckled(name, cannot_come_closest)
    scored.sort(key=lambda c: (not c.passes, c.fraction_off_nearby, c.variant))
    passing = [c for c in scored if c.passes]
    if passing:
        out.causes = passing
    elif scored and scored[0].fraction_off_nearby <= CLOSEST_SHARE * verdict.fraction_off_nearby:
        out.causes, out.closest = scored[:1], True
    if not passing:  # a mistake that explains the image leaves no term to fit
        renders.check()
        out.terms = fit_terms(submitted, renders)
    renders.check()
    out.objects, out.lights = where(reference, submitted, verdict, renders)
    return out


#: a variant is first rendered on one row in this many (with the rows either side), and rendered whole only if
#: those rows do not already rule it out (:func:`off_at_least`)
SAMPLE_EVERY = 16
#: the first look takes one row in this many of those, and the rest only when it does not settle the variant
FIRST_LOOK = 4


def sampled_rows(height: int, every: int = SAMPLE_EVERY) -> tuple[np.ndarray, np.ndarray]:
    """The middle rows a first look grades (every ``every``-th, none on the image's edge), and every row it
    renders for them: each middle row with the rows above and below."""
    middles = np.arange(every // 2, height - 1, every)
    middles = middles[middles >= 1]
    return middles, (middles[:, None] + np.arange(-1, 2)[None, :]).ravel()


def _looks(height: int) -> list[np.ndarray]:
    """The sampled middle rows (:func:`sampled_rows`) in the goes a first look takes them: one in
    :data:`FIRST_LOOK` first, then the rest (none for an image too short to have middle rows)."""
    middles, _ = sampled_rows(height)
    first = middles[FIRST_LOOK // 2::FIRST_LOOK]
    return [look for look in (first, np.setdiff1d(middles, first)) if len(look)]


def off_at_least(name: str, submitted: np.ndarray, verdict: Grade, renders: Renders,
                 beyond: Callable[[int], bool] | None = None) -> int | None:
    """A lower bound of how many pixels of ``submitted`` are off even nearby against variant ``name``, from a
    look at a few of its rows (None when :class:`Renders` has no rows to give); once ``beyond`` says the count
    is too many, no more rows are looked at.

    Exact, not a sample's estimate: a pixel is off nearby when every variant pixel in its 3×3 neighbourhood
    differs from it by more than the tolerance, so each sampled middle row, rendered with the rows above and
    below, gives its off pixels exactly as the whole grade counts them; their count bounds the whole image's.
    A variant whose bound exceeds what passing allows cannot pass, and one whose bound exceeds the closest's
    share cannot be named closest (:func:`diagnose`).  The rows are looked at in two goes, one in
    :data:`FIRST_LOOK` of them first: a bound from some of the rows is a bound too, and most variants are
    settled by it."""
    if renders.rows is None:
        return None
    h, w, _ = submitted.shape
    looks = _looks(h)
    if not looks:
        return None
    off = 0
    for look in looks:
        rows = (look[:, None] + np.arange(-1, 2)[None, :]).ravel()
        bands = renders.rows(name, rows).reshape(len(look), 3, w, 3)
        off += _off_nearby(bands, submitted[look], verdict.tolerance)
        if beyond is not None and beyond(off):
            break
    return off


#: a variant's whole render comes in this many bands of rows, each band's off pixels counted as it comes
BANDS = 4


def whole_unless_off(name: str, submitted: np.ndarray, verdict: Grade, renders: Renders,
                     beyond: Callable[[int], bool] | None = None) -> np.ndarray | None:
    """Variant ``name``'s whole image, rendered a band of rows at a time; None as soon as ``beyond`` says the
    pixels of ``submitted`` off even nearby in the rows so far are too many.

    Exact, as :func:`off_at_least` is: a row whose neighbours above and below have come too gives its off
    pixels exactly as the whole grade counts them, so the count so far is a lower bound of the whole
    image's; ``beyond`` decides on it as the grade decides on the whole count (the share of the pixels, the
    same division), so once it says too many, the variant cannot pass (or come closest): the rest of it is
    not rendered.  The bands come in the order of :func:`_bands`, so that a mistake confined to one part of the image
    shows early; a variant that may pass is rendered whole, each row once (:class:`Renders` keeps the rows of
    the first looks too)."""
    if renders.rows is None or beyond is None:
        return renders.variant(name)
    h = submitted.shape[0]
    image = np.empty_like(submitted)
    came, counted = np.zeros(h, dtype=bool), np.zeros(h, dtype=bool)
    everywhere = np.arange(h)
    above, below = np.maximum(everywhere - 1, 0), np.minimum(everywhere + 1, h - 1)
    off = 0
    for band in _bands(h):
        image[band] = renders.rows(name, band)
        came[band] = True
        ready = np.flatnonzero(came & came[above] & came[below] & ~counted)
        if len(ready) == 0:
            continue
        counted[ready] = True
        bands = np.stack([image[above[ready]], image[ready], image[below[ready]]], axis=1)
        off += _off_nearby(bands, submitted[ready], verdict.tolerance)
        if beyond(off):
            return None
    return image


def _bands(height: int, bands: int = BANDS) -> list[np.ndarray]:
    """The rows of an image ``height`` tall in ``bands`` bands (none empty), in the order a whole render takes
    them: each next band as far as it can be from those before (0, 4, 2, 6, 1, 5, 3, 7 of eight), so that a
    mistake confined to one part of the image shows early."""
    order = [0]
    while len(order) < bands:
        step = len(order)
        order += [k + bands // (2 * step) for k in order] if bands % (2 * step) == 0 else \
            [k for k in range(bands) if k not in order]
    edges = np.linspace(0, height, bands + 1).round().astype(np.int64)
    return [np.arange(edges[k], edges[k + 1]) for k in order[:bands] if edges[k + 1] > edges[k]]


def bound_unless_outside(name: str, reference: np.ndarray, submitted: np.ndarray, verdict: Grade,
                         renders: Renders, beyond: Callable[[int], bool] | None = None) -> np.ndarray | None:
    """Speckled mistake ``name``'s far end, whole, rendered a band of rows at a time as
    :func:`whole_unless_off` renders a variant; None as soon as ``beyond`` says the pixels of ``submitted``
    outside the reference and the far end in the bands so far are too many.

    Exact, as :func:`outside_at_least` is: whether a pixel lies outside depends on that pixel alone, so the
    count so far is a lower bound of :func:`speckled`'s, decided on as it decides (the share of the pixels):
    once too many, the mistake cannot pass (or come closest), and the rest of its far end is not rendered."""
    assert renders.bound is not None
    if renders.bound_rows is None or beyond is None:
        return renders.bound(name)
    image = np.empty_like(submitted)
    off = 0
    for band in _bands(submitted.shape[0]):
        image[band] = renders.bound_rows(name, band)
        off += _outside(reference[band], image[band], submitted[band], verdict.tolerance)
        if beyond(off):
            return None
    return image


def _outside(reference: np.ndarray, far: np.ndarray, submitted: np.ndarray, tolerance: float) -> int:
    """How many pixels of ``submitted`` lie outside the reference and the far end, each channel within
    ``tolerance`` (as :func:`speckled` counts them)."""
    ref, low, sub = (a.astype(np.int16) for a in (reference, far, submitted))
    return int(np.count_nonzero(np.any((sub < np.minimum(ref, low) - tolerance) |
                                       (sub > np.maximum(ref, low) + tolerance), axis=2)))


def _off_nearby(bands: np.ndarray, middles: np.ndarray, tolerance: float) -> int:
    """How many pixels of the submitted rows ``middles (k, W, 3)`` are off even nearby against the variant's
    ``bands (k, 3, W, 3)`` (each middle row with the rows above and below): every variant pixel in the 3×3
    neighbourhood (the row's ends repeated) differs from it by more than ``tolerance`` in some channel, as
    :func:`service.grading.grade` counts them."""
    k, _, w, _ = bands.shape
    # channel planes, as the grade compares them: (3, k, 3, W + 2) and (3, k, W), differences in uint8
    padded = np.ascontiguousarray(np.moveaxis(np.pad(bands, ((0, 0), (0, 0), (1, 1), (0, 0)), mode="edge"), 3, 0))
    sub = np.ascontiguousarray(np.moveaxis(middles, 2, 0))
    best = np.full((k, w), 255, dtype=np.uint8)
    for dy in range(3):
        for dx in range(3):
            near = padded[:, :, dy, dx:dx + w]
            diff = [np.maximum(near[c], sub[c]) - np.minimum(near[c], sub[c]) for c in range(3)]
            np.minimum(best, np.maximum(np.maximum(diff[0], diff[1]), diff[2]), out=best)
    return int(np.count_nonzero(best > tolerance))


def outside_at_least(name: str, reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders,
                     beyond: Callable[[int], bool] | None = None) -> int | None:
    """For a speckled mistake ``name`` of :data:`tracer.variants.BOUNDS`: a lower bound of how many pixels of
    ``submitted`` lie outside the reference and the mistake's far end (:func:`speckled`'s share, as a count),
    from a look at the sampled middle rows of the far end (None when :class:`Renders` has no rows to give);
    once ``beyond`` says the count is too many, no more rows are looked at.

    Exact, as :func:`off_at_least` is: whether a pixel lies outside depends on that pixel alone, so the
    sampled rows give their outside pixels exactly as :func:`speckled` counts them, and their count bounds
    the whole image's.  A mistake whose bound exceeds what passing allows cannot pass, and one whose bound
    exceeds the closest's share cannot be named closest: its far end is rendered whole only when it can."""
    if renders.bound_rows is None:
        return None
    looks = _looks(submitted.shape[0])
    if not looks:
        return None
    off = 0
    for look in looks:
        off += _outside(reference[look], renders.bound_rows(name, look), submitted[look], verdict.tolerance)
        if beyond is not None and beyond(off):
            break
    return off


def speckled(reference: np.ndarray, bound: np.ndarray, submitted: np.ndarray, tolerance: float) -> float | None:
    """For a mistake that varies from point to point: the share of pixels that do not lie between the
    reference and the mistake's far end ``bound`` (within the tolerance, every channel), when the submission
    departs from the reference towards it in speckles; None when it does not.

    Speckles: where the submission departs, how far it goes towards the bound (0 at the reference, 1 at the
    bound) changes from one pixel to the next by at least :data:`SPECKLE` on average.  A smooth departure
    (a light missing, a term too weak) changes slowly, and is not this mistake."""
    ref, low, sub = (a.astype(np.int16) for a in (reference, bound, submitted))
    outside = np.any((sub < np.minimum(ref, low) - tolerance) | (sub > np.maximum(ref, low) + tolerance), axis=2)
    gap = (low - ref).astype(np.float64)
    channel = np.argmax(np.abs(gap), axis=2)[..., None]
    span = np.take_along_axis(gap, channel, axis=2)[..., 0]
    moved = np.take_along_axis((sub - ref).astype(np.float64), channel, axis=2)[..., 0]
    can = np.abs(span) > tolerance
    departs = can & (np.abs(moved) > tolerance)
    if departs.sum() < 16:
        return None
    share = np.where(can, moved / np.where(can, span, 1.0), 0.0)
    pairs = can[:, 1:] & can[:, :-1]
    if not pairs.any() or float(np.abs(np.diff(share, axis=1))[pairs].mean()) < SPECKLE:
        return None
    return float(outside.mean())


#: a fit whose matrix (the used values × the terms) takes at most this is solved on the matrix itself; a larger
#: one on a factor of its Gram matrix, summed a block of pixels at a time (:class:`_Fit`)
FIT_MATRIX_BYTES = 32 << 20
#: ... and at most this many terms (each try of a term sums all the others over every row)
FIT_MATRIX_TERMS = 64
#: pixels per block when the fit's columns are taken from passes held whole
FIT_BLOCK_PIXELS = 1 << 14
BASE_TERMS = ("background", "ambient", "reflection", "refraction")


def fit_terms(submitted: np.ndarray, renders: Renders) -> list[Term]:
    """The additive terms out of scale, most out of scale first, by forward selection of least squares fits.

    The submission's linear values ≈ Σ coefficient · pass over the reference's additive passes (background,
    ambient, each light's diffuse and specular, reflection, refraction), on the pixels neither image clips.
    Terms that look alike on those pixels (ambient light and a directional light on a flat floor) cannot be
    told apart by one fit of every coefficient, so the coefficients start at 1 and are freed one at a time:
    each round frees the term whose non-negative fit (with the terms freed before it) leaves the smallest
    residual, and stops when that does not at least halve the residual or the residual is down to rounding.

    The passes come a block of pixels at a time (:attr:`Renders.blocks`), and the fit holds the used values
    while they take at most :data:`FIT_MATRIX_BYTES` (then it solves on them, as one matrix); past that, it
    keeps only the Gram matrix MᵀM of M = [terms | submission], summed block by block, and solves on a factor
    F of it (FᵀF = MᵀM): ‖M z‖ = ‖F z‖ for every z, so every fit and residual is the same least squares
    problem on (terms + 1) rows instead of the used values (the same answer up to rounding), and memory does
    not grow with the pixels."""
    columns = [(name, None) for name in BASE_TERMS] + [
        (term, k) for k, kind in enumerate(renders.lights) if kind != "ambient" for term in ("diffuse", "specular")]
    fit = _Fit([name if k is None else f"{name}:{k}" for name, k in columns],
               submitted.reshape(-1, 3).astype(np.float64) / 255.0, renders.check)
    if renders.blocks is not None:
        renders.blocks(fit.fold)
    else:  # (renders without blocks: the whole passes, as one block)
        base = renders.passes(list(BASE_TERMS), None)
        whole = {name: base[name].reshape(-1, 3) for name in BASE_TERMS}
        for k, kind in enumerate(renders.lights):
            if kind != "ambient":
                own = renders.passes(["diffuse", "specular"], k)
                whole |= {f"{t}:{k}": own[t].reshape(-1, 3) for t in ("diffuse", "specular")}
        fit.fold(0, whole)
    free, coef = fit.solve()
    terms = [Term(columns[i][0], columns[i][1], float(c)) for i, c in zip(free, coef)
             if abs(c - 1.0) > TERM_SLACK]
    return sorted(terms, key=lambda t: -abs(t.scale - 1.0))


class _Fit:
    """The term fit of :func:`fit_terms`, fed a block of pixels at a time (:meth:`fold`), then :meth:`solve`."""

    def __init__(self, names: list[str], submitted: np.ndarray, check: Callable[[], None]):
        self.names, self.sub, self.check = names, submitted, check
        self.rows: list[np.ndarray] = []  # the used values of each block, (m_i, n): while they are small
        self.values: list[np.ndarray] = []  # the submission's there, (m_i,)
        self.held = 0
        self.gram: np.ndarray | None = None  # once they are not: MᵀM of M = [terms | submission], (n + 1, n + 1)
        self.energy = np.zeros(len(names))
        self.used = 0

    def fold(self, first: int, part: dict[str, np.ndarray]) -> None:
        self.check()
        cols = [part[name] for name in self.names]
        total = sum(cols)  # (in the order the whole image's sum takes: the same values)
        sub = self.sub[first:first + len(cols[0])]
        use = (total < 1.0 - 1e-3) & (sub > 0) & (sub < 1)  # neither image clips there: the values are linear
        count = int(use.sum())
        if count == 0:
            return
        a = np.stack([c[use] for c in cols], axis=1)
        b = sub[use]
        self.used += count
        if self.gram is None:
            self.rows.append(a)
            self.values.append(b)
            self.held += a.nbytes + b.nbytes
            if self.held <= FIT_MATRIX_BYTES and len(self.names) <= FIT_MATRIX_TERMS:
                return
            a, b = np.concatenate(self.rows), np.concatenate(self.values)
            self.rows, self.values, self.gram = [], [], np.zeros((len(self.names) + 1,) * 2)
        self.energy += a.sum(axis=0)
        m = np.column_stack([a, b])
        self.gram += m.T @ m

    def solve(self) -> tuple[list[int], np.ndarray]:
        """The terms freed and their coefficients."""
        if self.used < 16:
            return [], np.zeros(0)
        if self.gram is None:  # the used values themselves: one matrix
            a, b = np.concatenate(self.rows), np.concatenate(self.values)
            energy = np.array([np.ascontiguousarray(a[:, i]).sum() for i in range(a.shape[1])])
            return _forward(a, b, energy, None, self.check)
        # a factor F of the Gram matrix (FᵀF = MᵀM, from its eigenvectors: it may be singular, a term zero
        # everywhere), whose rows stand for the used values: ‖M z‖ = ‖F z‖ for every z
        self.check()
        values, vectors = np.linalg.eigh(self.gram)
        f = np.sqrt(np.maximum(values, 0.0))[:, None] * vectors.T
        return _forward(f[:, :-1], f[:, -1], self.energy, self.used, self.check)


def _forward(a: np.ndarray, b: np.ndarray, energy: np.ndarray, used: int | None,
             check: Callable[[], None]) -> tuple[list[int], np.ndarray]:
    """Forward selection over the columns of ``a`` against ``b``: the used values themselves (``used`` None), or
    the rows of their triangular factor, which give the same sums of squares, over ``used`` values."""
    keep = [i for i, e in enumerate(energy) if e > TERM_FLOOR * energy.sum()]
    n = a.shape[1]
    every = None if used is None else a.sum(axis=1)  # (R's rows are few: the others' sum from the whole's)

    def rms(r: np.ndarray) -> float:
        return float(np.sqrt(np.mean(r ** 2))) if used is None else float(np.sqrt(np.sum(r ** 2) / used))

    def fitted(free: list[int]) -> tuple[float, np.ndarray]:
        if every is None:
            rest = b - a[:, [i for i in range(n) if i not in free]].sum(axis=1)
        else:
            rest = b - (every - a[:, free].sum(axis=1))
        coef = nnls(a[:, free], rest)
        return rms(a[:, free] @ coef - rest), coef

    free: list[int] = []
    coef = np.zeros(0)
    residual = rms(a.sum(axis=1) - b)
    while residual > ROUNDING and len(free) < MAX_TERMS:
        tries = []
        for i in keep:
            if i not in free:
                check()
                tries.append((fitted(free + [i]), i))
        if not tries:
            break
        (best, best_coef), i = min(tries, key=lambda t: t[0][0])
        if best > 0.5 * residual:
            break
        free, coef, residual = free + [i], best_coef, best
    return free, coef


def nnls(a: np.ndarray, b: np.ndarray, rounds: int = 200) -> np.ndarray:
    """min ‖a x − b‖ over x ≥ 0, by the Lawson–Hanson active-set method. ``a (m, n)``, ``b (m,)``."""
    m, n = a.shape
    x = np.zeros(n)
    free = np.zeros(n, dtype=bool)
    for _ in range(rounds):
        w = a.T @ (b - a @ x)
        if free.all() or np.max(np.where(free, -np.inf, w)) <= 1e-12:
            break
        free[int(np.argmax(np.where(free, -np.inf, w)))] = True
        for _ in range(rounds):
            z = np.zeros(n)
            z[free] = np.linalg.lstsq(a[:, free], b, rcond=None)[0]
            if np.all(z[free] > 0):
                x = z
                break
            bad = free & (z <= 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                alpha = np.min(np.where(bad, x / (x - z), np.inf))
            x = x + alpha * (z - x)
            free &= x > 1e-12
    return x


def where(reference: np.ndarray, submitted: np.ndarray, verdict: Grade,
          renders: Renders) -> tuple[list[Share], list[Share]]:
    """The objects the failing pixels show and the lights that fall on them, each with its share.  The lights'
    terms at the failing pixels come a block at a time and are counted as they come, never held for all the
    lights at once."""
    diff = np.max(np.abs(reference.astype(np.int16) - submitted.astype(np.int16)), axis=2) > verdict.tolerance
    count = int(diff.sum())
    if count == 0:
        return [], []
    lit_by = np.zeros(len(renders.lights), dtype=np.int64)  # failing pixels each light falls on
    shining = [k for k, kind in enumerate(renders.lights) if kind != "ambient"]

    def fold(first: int, part: dict[str, np.ndarray]) -> None:
        renders.check()
        for k in shining:
            lit_by[k] += int(np.count_nonzero((part[f"diffuse:{k}"] + part[f"specular:{k}"]).max(axis=1) > 1.0 / 255))

    if renders.at is not None:  # the passes of the failing pixels alone
        found = renders.at(np.flatnonzero(diff), fold)
    else:
        found = renders.passes(["object"], None)["object"][diff]
        there: dict[str, np.ndarray] = {}
        for k in shining:
            own = renders.passes(["diffuse", "specular"], k)
            there |= {f"diffuse:{k}": own["diffuse"][diff], f"specular:{k}": own["specular"][diff]}
        fold(0, there)
    objects = [Share(int(k), renders.objects[int(k)] if k >= 0 else "background", float(np.mean(found == k)))
               for k in np.unique(found)]
    lights = [Share(k, renders.lights[k], int(lit_by[k]) / len(found)) for k in shining if lit_by[k]]
    return (sorted(objects, key=lambda s: -s.share), sorted(lights, key=lambda s: -s.share))


#: the variants made from the reference's own linear colour, with no render of their own
DERIVED = ("gamma", "image-flipped")
#: the whole image's passes (every light's terms included) are kept for the scene's later diagnoses when they
#: take at most this; a larger scene's fit and lights are rendered again for each, folded as they come
WHOLE_PASSES_BYTES = 64 << 20


def renders_of(scene: Any, threads: int | None = None) -> Renders:
    """:class:`Renders` of a validated scene, rendered here when first asked for; its ``cancel()`` true stops a
    render with :class:`tracer.RenderCancelled`.

    One render gives every pass, every light's terms and the image's linear colour
    (:meth:`tracer.Renderer.diagnosis_passes`); from that colour come, exactly as their own renders would make
    them, the gamma variant (each pixel's colour to the power 1/2.2, then stored) and the flipped image, and
    the reference itself stands for every variant the scene cannot show (:func:`tracer.variants.unchanged`).
    Only the other variants are rendered, each once.

    That render is made only when something needs the whole image's passes (a fit of the terms, a variant
    made from the colour).  Until then the passes of the failing pixels come alone (``at``), at most the
    image's worth of them in all, and the gamma and flipped variants are rendered, first a few rows of
    them, like any other: the same pixels either way."""
    from tracer import Renderer
    from tracer.image import quantize

    variants: dict[str, np.ndarray] = {}
    bounds: dict[str, np.ndarray] = {}
    made: dict[str, dict[str, np.ndarray]] = {}
    last = threading.local()  # per thread, the last scene prepared and its options
    asked = threading.local()  # per thread, the cancel of the diagnosis it runs (these renders may be shared)

    def polled() -> Callable[[], bool] | None:
        mine: Callable[[], bool] | None = getattr(asked, "cancel", None)
        return mine if mine is not None else out.cancel

    def cancel_in_thread(cancel: Callable[[], bool] | None) -> None:
        asked.cancel = cancel

    def done() -> None:
        last.__dict__.clear()
        asked.__dict__.clear()

    def prepared(options: Options) -> Renderer:
        # a variant's first look, its second and its whole render come one after another: one preparation of
        # the scene (its world, its Embree scene) serves them all.  One per thread, and only the last: threads
        # share no renderer; and none is held once a diagnosis is over, cancelled or not (``done``)
        if getattr(last, "options", None) != options:
            last.__dict__.clear()  # (the last one let go of before the next is built)
            last.renderer = Renderer(scene, options)
            last.options = options
        renderer: Renderer = last.renderer
        return renderer

    height, width, total = scene.image.height, scene.image.width, scene.image.width * scene.image.height
    shining = sum(light.type != "ambient" for light in scene.lights)
    #: whether the whole image's passes, every light's terms included, are small enough to keep (then one render
    #: serves every later fit of the scene); else each fit renders them again, folded as they come
    whole = total * 3 * 8 * (len(ADDITIVE) + 2 + 2 * shining) <= WHOLE_PASSES_BYTES

    def passes() -> dict[str, np.ndarray]:  # the whole image's passes, held (a scene small enough, or no blocks)
        if "all" not in made:
            out.check()
            made["all"] = prepared(REFERENCE).diagnosis_passes(threads=threads, cancel=polled())
        return made["all"]

    def images() -> dict[str, np.ndarray]:
        """The reference's pixels from its linear colour, and its gamma variant: from the passes held, or from a
        render folded as it comes (all it keeps are these)."""
        if "images" not in made:
            if whole or "all" in made:
                colour = passes()["colour"]
                made["images"] = {"reference": quantize(colour),
                                  "gamma": quantize(np.clip(colour, 0.0, None) ** (1.0 / 2.2))}
            else:
                folded(None)
        return made["images"]

    def folded(fold: Fold | None) -> None:
        """A render of the whole image's passes, each chunk to ``fold`` and to the reference's images."""
        out.check()
        mine = "images" not in made
        reference, gamma = (np.empty((total, 3), dtype=np.uint8) for _ in range(2))

        def each(first: int, part: dict[str, np.ndarray]) -> None:
            if mine:  # as Renderer.pixels stores each chunk's colour (and a gamma variant's)
                reference[first:first + len(part["colour"])] = quantize(part["colour"])
                gamma[first:first + len(part["colour"])] = quantize(np.clip(part["colour"], 0.0, None) ** (1.0 / 2.2))
            if fold is not None:
                fold(first, part)

        prepared(REFERENCE).diagnosis_passes(threads=threads, cancel=polled(), fold=each)
        if mine:
            made["images"] = {"reference": reference.reshape(height, width, 3),
                              "gamma": gamma.reshape(height, width, 3)}

    def blocks(fold: Fold) -> None:
        if not whole:
            folded(fold)
            return
        every = passes()
        for first in range(0, total, FIT_BLOCK_PIXELS):
            fold(first, {name: plane.reshape(total, -1)[first:first + FIT_BLOCK_PIXELS]
                         for name, plane in every.items() if name not in ("object", "colour")})

    def made_whole() -> bool:  # the reference's images are at hand, without a render
        return "images" in made or "all" in made

    def variant(name: str) -> np.ndarray:
        if name not in variants:
            if name == "gamma" and made_whole():  # as Renderer.pixels stores a gamma variant's chunk colour
                variants[name] = images()["gamma"]
                kept.pop(name, None)
            elif name == "image-flipped" and made_whole():  # the reference's rows, bottom to top
                variants[name] = images()["reference"][::-1]
                kept.pop(name, None)
            elif unchanged(name, scene):
                variants[name] = images()["reference"]
            elif name in kept:  # the rows not yet rendered
                rows(name, np.arange(height))
            else:
                variants[name] = prepared(VARIANTS[name][0]).pixels(threads=threads, cancel=polled())
        return variants[name]

    #: per variant (and per far end), its rows rendered so far, until it is whole
    kept: dict[str, dict[int, np.ndarray]] = {}
    guard = threading.Lock()

    def kept_rows(key: str, name: str, options: Options, whole: dict[str, np.ndarray],
                  numbers: np.ndarray) -> np.ndarray:
        # a render's rows are kept as they come (first looks, bands), under ``key``, and are not rendered again:
        # once every row has come, they are its whole image, ``whole[name]``
        with guard:
            if name in whole:
                return whole[name][numbers]
            have = dict(kept.get(key, {}))
        todo = np.array(sorted(set(numbers.tolist()) - set(have)), dtype=np.int64)
        if len(todo):
            fresh = prepared(options).pixels_of_rows(todo, threads=threads, cancel=polled())
            with guard:
                if name in whole:  # (made whole meanwhile, in another thread)
                    return whole[name][numbers]
                mine = kept.setdefault(key, {})
                mine.update(zip(todo.tolist(), fresh))
                have = dict(mine)
                if len(mine) == height:
                    whole[name] = np.stack([mine[r] for r in range(height)])
                    kept.pop(key)
        return np.stack([have[r] for r in numbers.tolist()])

    def rows(name: str, numbers: np.ndarray) -> np.ndarray:
        if name in variants or (name in DERIVED and made_whole()) or unchanged(name, scene):
            return variant(name)[numbers]
        return kept_rows(name, name, VARIANTS[name][0], variants, numbers)

    def bound(name: str) -> np.ndarray:
        if name not in bounds:
            if unchanged(name, scene):
                bounds[name] = images()["reference"]
            elif "bound:" + name in kept:  # the rows not yet rendered
                bound_rows(name, np.arange(height))
            else:
                bounds[name] = prepared(BOUNDS[name]).pixels(threads=threads, cancel=polled())
        return bounds[name]

    def bound_rows(name: str, numbers: np.ndarray) -> np.ndarray:
        if name in bounds or unchanged(name, scene):
            return bound(name)[numbers]
        return kept_rows("bound:" + name, name, BOUNDS[name], bounds, numbers)

    spent = [0]  # pixels whose passes were rendered alone so far

    def at(pixels: np.ndarray, fold: Fold) -> np.ndarray:
        # pixels alone while they add up to at most the image (a scene diagnosed once renders only its failing
        # pixels); past that, the whole image once, and kept, when it is small enough to keep
        if "all" in made or (whole and spent[0] + len(pixels) > total):
            rows, cols = np.divmod(pixels, width)
            there = {name: plane[rows, cols] for name, plane in passes().items() if name != "colour"}
            fold(0, there)
            return there["object"]
        spent[0] += len(pixels)
        found = np.empty(len(pixels), dtype=np.int64)

        def each(first: int, part: dict[str, np.ndarray]) -> None:
            found[first:first + len(part["object"])] = part["object"]
            fold(first, part)

        prepared(REFERENCE).diagnosis_passes(threads=threads, cancel=polled(), pixels=pixels, first_hits=True,
                                             fold=each)
        return found

    def of(names: list[str], light: int | None) -> dict[str, np.ndarray]:
        every = passes()
        return {name: every[name if light is None or name not in LIGHT_TERMS else f"{name}:{light}"]
                for name in names}

    def nbytes() -> int:
        return held_bytes([*list(variants.values()), *list(bounds.values()),
                           *(r for rows in list(kept.values()) for r in list(rows.values())),
                           *(a for planes in list(made.values()) for a in list(planes.values()))])

    out = Renders(variant, of, [light.type for light in scene.lights], [obj.type for obj in scene.objects], bound,
                  rows=rows, bound_rows=bound_rows, at=at, unchanged=lambda name: unchanged(name, scene),
                  done=done, cancel_in_thread=cancel_in_thread, blocks=blocks, nbytes=nbytes, polled=polled)
    return out


#: the most renders a diagnosis may need: the variants the scene can show (gamma and the flipped image too, when
#: the pass render is not there to make them from), a speckled mistake's far end in place of the mistake itself,
#: the failing pixels' first hits, and one render for every pass.  Most diagnoses need far fewer: a first look at
#: a few rows of a variant (:func:`off_at_least`) or a band of it (:func:`whole_unless_off`) may spare the rest
def renders_needed(scene: Any) -> int:
    shown = [name for name in [*(v for v in VARIANTS if v not in BOUNDS), *BOUNDS] if not unchanged(name, scene)]
    return len(shown) + 2


def held_bytes(arrays: list[np.ndarray]) -> int:
    """The bytes of the memory ``arrays`` hold, each buffer once (a view counts as its base)."""
    roots: dict[int, int] = {}
    for a in arrays:
        while isinstance(a.base, np.ndarray):
            a = a.base
        roots[id(a)] = a.nbytes
    return sum(roots.values())


#: the largest image whose diagnosis renders are kept for the next pair of the same scene
CACHED_PIXELS = 640 * 480


class Cached:
    """The :class:`Renders` of the last few scenes diagnosed, by canonical scene key: a class's failing pairs
    of one task (or a student's resubmissions) share one set of variant renders.  With ``room``, the arrays
    they hold are counted (:attr:`Renders.nbytes`) and held to ``room()`` bytes, the oldest scenes let go
    first (:meth:`trim`): the service counts them in one budget with its cache of answers."""

    def __init__(self, scenes: int = 4, room: Callable[[], int] | None = None):
        self.scenes = scenes
        self.room = room
        self.held: dict[str, Renders] = {}
        self.made = 0  # Renders built (a miss each)
        self._lock = threading.Lock()

    def get(self, key: str, make: Callable[[], Renders], pixels: int = 0) -> Renders:
        """The renders of scene ``key``, made by ``make()`` unless held; a scene of more than
        :data:`CACHED_PIXELS` pixels is not held (its variants would crowd out everything else)."""
        with self._lock:
            if key in self.held:
                self.held[key] = self.held.pop(key)  # most recently used last
                return self.held[key]
            self.made += 1
        renders = make()
        if pixels > CACHED_PIXELS:
            return renders
        with self._lock:
            self.held[key] = renders
            while len(self.held) > self.scenes:
                self.held.pop(next(iter(self.held)))
        return renders

    @property
    def size(self) -> int:
        """The bytes the scenes held hold."""
        with self._lock:
            held = list(self.held.values())
        return sum(r.nbytes() for r in held if r.nbytes is not None)

    def trim(self) -> None:
        """Let go of the oldest scenes until what is held fits in ``room()`` (after a diagnosis, whose renders
        have grown)."""
        if self.room is None:
            return
        while True:
            with self._lock:
                sizes = [(key, r.nbytes() if r.nbytes is not None else 0) for key, r in self.held.items()]
                if not sizes or sum(size for _, size in sizes) <= max(self.room(), 0):
                    return
                self.held.pop(sizes[0][0], None)

    def __len__(self) -> int:
        return len(self.held)


#: this process's renders for diagnosis (the CLI, each class worker; each service worker has its own, counted)
CACHE = Cached()
