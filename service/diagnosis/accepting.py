"""Accepted variants: the ways an honest student's tracer may differ from the reference and still pass.

A grade that fails against the reference is taken again against the
reference rendered as honest tracers render it (:data:`tracer.scene.variants.
ACCEPTED_DEFAULT`): shadow and secondary rays started off the surface along
its normal, up to 5·10⁻³ of the scene's visible size, or by a t_min up to
10⁻² of it.  Each is rendered at a ladder of round amounts in the scene's units
(:mod:`.offsets`): the image passes as the first two neighbouring rungs (the
first from the reference), smallest first, whose range holds it and explains
its failure, and the verdict names the rung of them it comes closer to, the
amount that decided it: "PASS, as rendered with a ray offset of 0.003 along
the normal".  A passing
image costs nothing more: these renders are made only for an image that
fails the reference, and kept for the last few scenes, so a class's failing
pairs of one task share them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from schemas import Scene
from tracer import Renderer
from tracer.scene.shown import unchanged
from tracer.scene.variants import ACCEPTED_DEFAULT, Options

from ..images.grading import GROSS_ALLOWED, Grade, grade, range_counts
from ..images.nearby import rows_distance
from ..render.scenekey import scene_key
from .kept import KEPT, KEPT_PIXELS, KEPT_RENDERS, STORED, _Kept, file_name, stored  # noqa: F401 (re-exported)
from .looks import off_rows, sampled_rows, telling_middles
from .offsets import Rung, ladder, narrowed, rung, visible_size
from .renders import Renders
from .settled import FIRST_ROWS, unsettled, windows

#: an accepted variant explains a failing image when the image leaves at most this share of its pixels off
#: the reference off the variant too (an honest tracer's matches its variant all but exactly; a mistake that
#: merely looks alike at the threshold, an offset far too large in a scene that barely shows it, does not)
EXPLAINED = 0.5


@dataclass(frozen=True)
class Acceptance:
    """A failing image that passes against an accepted variant: which (in words), that grade, and the rung that
    decided it."""

    words: str  # "a ray offset of 0.001 along the normal"
    grade: Grade
    rung: Rung


@dataclass(frozen=True)
class Failing:
    """A submission that failed the reference: both images (``(H, W, 3) uint8``), the grade, and the pixels the
    format leaves open (not counted; None: none)."""

    reference: np.ndarray
    submitted: np.ndarray
    failed: Grade
    open_pixels: np.ndarray | None = None


def accepted_ladders(scene: Scene, accepted: dict[str, float] | None, key: str | None = None) -> list[list[Rung]]:
    """Per accepted variant (``accepted``: name → largest amount × the visible size; None: the defaults), its
    ladder of rungs, ascending (:func:`service.diagnosis.offsets.ladder`)."""
    size = visible_size(scene, key)
    given = ACCEPTED_DEFAULT if accepted is None else accepted
    return [rungs for kind in sorted(given) if (rungs := ladder(kind, given[kind] * size, size))]


def brackets(rungs: list[Rung]) -> list[tuple[Rung | None, Rung]]:
    """The neighbouring rungs of a ladder, ascending, the first from the reference (None) to the lowest rung."""
    return list(zip([None, *rungs[:-1]], rungs))


def accept(
    scene: Scene,
    pair: Failing,
    accepted: dict[str, float] | None = None,
    threads: int | None = None,
    cancel: Callable[[], bool] | None = None,
    renders: Renders | None = None,
) -> Acceptance | None:
    """The first accepted variant and bracket of its ladder (``accepted``: name → largest amount × the visible
    size; None: the defaults), smallest first, whose range (the renders of its two rungs, or of the reference and
    the lowest rung) the submitted pixels pass against (:func:`envelope_counts`, with the failed grade's
    thresholds), and which explains the failure (at most :data:`EXPLAINED` of the pixels off the reference are
    off the range); None when none does.  Its words name the rung of the range the image comes closer to (the
    higher, from the reference): the amount that decided it.

    A ladder is first looked at on the rows where the submission is most off, its rungs alone: when no range of
    them nor any narrower range between two can hold the image there (:mod:`.settled`, the same verdict as the
    whole ladder), it is given up, unnarrowed; a mistake costs a few rows of each rung.  With ``renders`` (the
    scene's renders for diagnosis, :class:`.renders.Renders`) its rungs are kept with them: the diagnosis's
    ladder of offsets too large starts where this one ends, and renders that rung no more.

    A scene with no light but ambient and no mirror or glass renders every offset as the reference (no shadow or
    secondary ray is cast): it renders none of them."""
    if unchanged("offset-too-large", scene):
        return None
    key = scene_key(scene)
    counts = off_rows(pair.reference, pair.submitted, pair.failed.tolerance, pair.open_pixels)
    look = Look(key, threads, cancel, telling_middles(counts, np.inf), renders)
    allowed = min(pair.failed.max_fraction, EXPLAINED * pair.failed.fraction_off_nearby) * pair.submitted[..., 0].size
    first = replace(look, middles=telling_middles(counts, FIRST_ROWS * allowed))
    for rungs in accepted_ladders(scene, accepted, key):
        left = _unsettled(scene, pair, rungs, first, allowed, 1)  # (then on more rows, from the pair left open)
        if left is None or _unsettled(scene, pair, rungs, look, allowed, left) is None:
            continue  # (no range of its rungs, nor any narrower one, can hold the image: the same None, sooner)
        found = _found(scene, pair, rungs, look, allowed)
        if found is not None:
            return _quoted(scene, pair, rungs, look, found)
    return None


def _unsettled(scene: Scene, pair: Failing, rungs: list[Rung], look: Look, allowed: float, start: int) -> int | None:
    """None when, on the rows ``look`` takes, no range of two neighbouring rungs of the ladder (the first from the
    reference) nor any narrower range between two of them can leave at most ``allowed`` pixels off
    (:func:`.settled.unsettled`, from pair ``start`` on, those before it settled on some of these rows): then
    :func:`_found` finds nothing, and is not asked; else the first pair that leaves it open.  Counted where the
    submission is off against the reference (a lower bound, :func:`.settled.windows`): the rungs are rendered near
    there alone."""
    middles, rows = look.looked(pair.submitted.shape[0])
    if not len(middles) or all(look.has(r.options) for r in rungs):
        return start  # (whole renders at hand, kept or rendered beforehand, are what decides: no rows rendered)
    w = pair.submitted.shape[1]
    submitted = pair.submitted[rows].reshape(len(middles), 3, w, 3)
    reference = pair.reference[rows].reshape(len(middles), 3, w, 3)
    shut = rows_distance(reference, reference, submitted) <= pair.failed.tolerance
    if pair.open_pixels is not None:
        shut |= pair.open_pixels[middles]
    wanted = windows(~shut, middles, pair.submitted.shape[0])

    def bands(k: int) -> np.ndarray:
        image = reference if k == 0 else look.near(scene, rungs[k - 1].options, rows, wanted)
        return image.reshape(len(middles), 3, w, 3)

    return unsettled(bands, len(rungs) + 1, submitted, pair.failed.tolerance, shut, lambda off: off > allowed, start)


def _found(scene: Scene, pair: Failing, rungs: list[Rung], look: Look, allowed: float) -> Acceptance | None:
    """The image accepted as a range of one ladder's amounts: two neighbouring rungs, smallest first, else a
    narrower range (:func:`_narrowed`); None when none holds it."""
    for k, (low, high) in enumerate(brackets(rungs)):
        after = rungs[k + 1] if k + 1 < len(rungs) else None
        parts = [r for r in (low, high) if r is not None]
        found = _bracket(scene, pair, parts, look, (allowed, low is None), after)
        if found is not None:
            return found
    return _narrowed(scene, pair, rungs, look, allowed)


def _quoted(scene: Scene, pair: Failing, rungs: list[Rung], look: Look, found: Acceptance) -> Acceptance:
    """``found``, said as the rung of its ladder whose render the image comes closest to, when that is not the one
    it was found as (an image within the range of two small amounts, where larger ones change little, made with a
    larger one): every rung looked at on a few rows first, and the nearest rendered whole."""

    def alone(r: Rung) -> tuple[int, int]:
        return sampled_off(scene, [r], pair, look, reference=False)

    best = min(rungs, key=alone)
    if alone(best) >= alone(found.rung):
        return found
    pixels, failed = pair.submitted[..., 0].size, pair.failed
    own = [
        grade(
            look.whole(scene, r.options, pixels),
            pair.submitted,
            failed.reference_sha256,
            failed.tolerance,
            failed.max_fraction,
            pair.open_pixels,
        ).fraction_off_nearby
        for r in (found.rung, best)
    ]
    return replace(found, words=best.words, rung=best) if own[1] < own[0] else found


def _narrowed(scene: Scene, pair: Failing, rungs: list[Rung], look: Look, allowed: float) -> Acceptance | None:
    """The image accepted as a narrower range of amounts, when no range of two rungs holds it: the range of two
    rungs that leaves the fewest of its pixels off on a few rows, halved there (:func:`.offsets.narrowed`), and
    rendered whole only if its rows may pass."""
    size, kind = visible_size(scene, look.key), rungs[0].kind

    def parts(amounts: tuple[float, ...]) -> list[Rung]:
        return [rung(kind, a, size) for a in amounts if a > 0]

    def off(amounts: tuple[float, ...]) -> tuple[int, int]:
        return sampled_off(scene, parts(amounts), pair, look, amounts[0] == 0)

    def alone(amount: float) -> tuple[int, int]:
        return off((amount,)) if amount > 0 else sampled_off(scene, [], pair, look)

    amounts = [0.0, *(r.amount for r in rungs)]
    chosen = tuple(narrowed(alone, *min(zip(amounts, amounts[1:]), key=off)))
    if off(chosen)[0] > allowed:
        return None  # (its rows alone cannot pass)
    return _bracket(scene, pair, parts(chosen), look, (allowed, chosen[0] == 0))


def _bracket(
    scene: Scene, pair: Failing, rungs: list[Rung], look: Look, how: tuple[float, bool], after: Rung | None = None
) -> Acceptance | None:
    """The image accepted as the range of ``rungs`` (and the reference, when ``how`` says so: (the pixels off
    allowed, whether from the reference)), or None: first from a few rows, then whole.  Its words are those of
    the rung it comes closest to, of these or the next one up (``after``, looked at unless the image is one of
    these exactly): a student's 0.001 lies within the range of the reference and 0.0005 where the two differ
    little, and is said as 0.001 all the same."""
    failed, pixels = pair.failed, pair.submitted[..., 0].size
    allowed, from_reference = how
    kept = all(look.has(r.options) for r in rungs)
    if not kept and first_look(scene, rungs, pair, look, from_reference) > allowed:
        return None  # (its rows alone leave too many pixels off: it cannot pass, whole)
    images = [look.whole(scene, r.options, pixels) for r in rungs]
    ranged = [pair.reference, *images] if from_reference else images
    counts = envelope_counts(ranged, pair.submitted, failed.tolerance, pair.open_pixels)
    if counts.off_nearby > allowed or counts.grossly_off > GROSS_ALLOWED:
        return None
    own = [
        grade(image, pair.submitted, failed.reference_sha256, failed.tolerance, failed.max_fraction, pair.open_pixels)
        for image in images
    ]
    nearer = min(range(len(rungs)), key=lambda k: (own[k].fraction_off_nearby, -k))
    if after is not None and own[nearer].fraction_off_nearby > 0:
        image = look.whole(scene, after.options, pixels)
        graded = grade(
            image, pair.submitted, failed.reference_sha256, failed.tolerance, failed.max_fraction, pair.open_pixels
        )
        if graded.fraction_off_nearby < own[nearer].fraction_off_nearby:
            rungs, own, nearer = [*rungs, after], [*own, graded], len(rungs)
    passed = replace(own[nearer], passed=True, fraction_off_nearby=counts.off_nearby / pixels)
    return Acceptance(rungs[nearer].words, replace(passed, grossly_off=counts.grossly_off), rungs[nearer])


@dataclass(frozen=True)
class Look:
    """How a first look renders: the scene's key (its rows are kept under it), its threads and what cancels it,
    the middle rows it looks at (None: :func:`service.diagnosis.looks.sampled_rows`), and the scene's renders
    for diagnosis (:class:`.renders.Renders`, in the cache of them and its budget) where they are at hand
    (else what it renders is kept in :data:`KEPT_RENDERS`): a rung an offset too large's ladder shares is
    rendered once for both."""

    key: str
    threads: int | None
    cancel: Callable[[], bool] | None
    middles: np.ndarray | None = None
    renders: Renders | None = None

    def rows(self, scene: Scene, options: Options, rows: np.ndarray) -> np.ndarray:
        """Rows ``rows`` of the scene rendered with ``options``, each kept for the next failing image (with the
        scene's renders for diagnosis, kept there; rows an earlier look without them kept are taken as they are)."""
        if self.renders is not None:
            kept = KEPT_RENDERS.kept_rows((self.key, options), rows)
            return self.renders.with_rows(options, rows) if kept is None else kept
        return KEPT_RENDERS.rows_of((self.key, options), rows, partial(_render_rows, scene, options, how=self))

    def near(self, scene: Scene, options: Options, rows: np.ndarray, wanted: np.ndarray) -> np.ndarray:
        """Rows ``rows`` of the scene rendered with ``options``, right where ``wanted`` (``(H, W)`` bool) is True:
        with the scene's renders for diagnosis, those pixels alone (:meth:`.renders.Renders.with_pixels`); else,
        or where an earlier look kept the rows, the whole rows (:meth:`rows`)."""
        if self.renders is None or KEPT_RENDERS.kept_rows((self.key, options), rows) is not None:
            return self.rows(scene, options, rows)
        return self.renders.with_pixels(options, wanted)[rows]

    def whole(self, scene: Scene, options: Options, pixels: int) -> np.ndarray:
        """The whole image with ``options``: from the folder of those rendered beforehand (:data:`STORED`), else
        rendered once and kept."""
        key = (self.key, options)
        if self.renders is None or stored(key) is not None:
            return KEPT_RENDERS.get(key, partial(_render, scene, options, self.threads, self.cancel), pixels)
        return self.renders.with_options(options)

    def has(self, options: Options) -> bool:
        """Whether the whole image with ``options`` is at hand, without a render."""
        key = (self.key, options)
        return KEPT_RENDERS.has(key) or (self.renders is not None and self.renders.holds(options))

    def looked(self, height: int) -> tuple[np.ndarray, np.ndarray]:
        """The middle rows a look takes in an image ``height`` tall, and every row it renders for them (each
        middle row with the rows either side)."""
        if self.middles is None or not len(self.middles):
            return sampled_rows(height)
        return self.middles, (self.middles[:, None] + np.arange(-1, 2)[None, :]).ravel()


def first_look(scene: Scene, rungs: list[Rung], pair: Failing, how: Look, reference: bool = True) -> int:
    """A lower bound of :func:`envelope_counts`'s pixels off for the range of ``rungs`` (and the reference, with
    ``reference``), from their renders of a few rows alone (:meth:`Look.looked`: the rows where the submission is
    most off against the reference, as many as every 16th row would be, each with the rows either side).

    Exact, not an estimate: a pixel's count depends on its 3×3 neighbourhood alone (both ways), so each sampled
    middle row, rendered with the rows above and below, gives its off pixels exactly as the whole count does,
    and their count bounds the whole image's (0 for an image too short to have middle rows)."""
    return sampled_off(scene, rungs, pair, how, reference)[0]


def sampled_off(scene: Scene, rungs: list[Rung], pair: Failing, how: Look, reference: bool = True) -> tuple[int, int]:
    """:func:`first_look`'s count, and the sum of the sampled pixels' nearby distances (which tells two ranges
    that leave as many pixels off apart)."""
    middles, rows = how.looked(pair.submitted.shape[0])
    if not len(middles):
        return 0, 0
    w = pair.submitted.shape[1]
    images = ([pair.reference[rows]] if reference else []) + [how.rows(scene, r.options, rows) for r in rungs]
    low = np.min(images, axis=0).reshape(len(middles), 3, w, 3)
    high = np.max(images, axis=0).reshape(len(middles), 3, w, 3)
    near = rows_distance(low, high, pair.submitted[rows].reshape(len(middles), 3, w, 3))
    if pair.open_pixels is not None:
        near = np.where(pair.open_pixels[middles], 0, near)
    return int(np.count_nonzero(near > pair.failed.tolerance)), int(near.sum(dtype=np.int64))


#: the pixels off even nearby, and grossly off, against the range of renders
#: (:func:`service.images.grading.range_counts`)
envelope_counts = range_counts


def envelope_off(renders: list[np.ndarray], submitted: np.ndarray, tolerance: float) -> int:
    """The pixels of ``submitted`` off even nearby the range of ``renders`` (:func:`envelope_counts`)."""
    return envelope_counts(renders, submitted, tolerance).off_nearby


def _render(scene: Scene, options: Options, threads: int | None, cancel: Callable[[], bool] | None) -> np.ndarray:
    return Renderer(scene, options).pixels(threads=threads, cancel=cancel)


def _render_rows(scene: Scene, options: Options, rows: np.ndarray, *, how: Look) -> np.ndarray:
    return Renderer(scene, options).pixels_of_rows(rows, how.threads, cancel=how.cancel)
