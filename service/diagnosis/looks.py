"""A variant ruled out from a few of its rows: exact lower bounds of its pixels off, from first looks and bands
of its render, and the measure a speckled mistake is scored with."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..images.grading import Grade
from ..images.nearby import rows_distance
from .renders import Renders

#: how much, on average, a speckled mistake's reach towards its far end changes from a pixel to the next, in an
#: image of one sample per pixel (:func:`speckle_threshold` for more)
SPECKLE = 0.2


def speckle_threshold(samples: int) -> float:
    """:data:`SPECKLE` for pixels that are each the mean of ``samples`` × ``samples`` sub-samples.

    Each sub-sample of a speckled mistake reaches its far end or not, pixel by pixel as by chance: the mean of n²
    of them varies from one pixel to the next as 1/n does (16 sub-samples of 08_antialiased: 0.136 on average,
    against 0.5 at one), so the threshold falls as 1/n.  It never falls below half of :data:`SPECKLE`: a smooth
    departure's changes from a pixel to the next come from edges and rounding, which averaging sub-samples does not
    shrink (on 08_antialiased: no specular term 0.030, the Blinn–Phong half vector 0.064, the image 0.7× as bright
    0.023)."""
    return SPECKLE * max(1.0 / max(samples, 1), 0.5)


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


def _looks(height: int, first: np.ndarray | None = None) -> list[np.ndarray]:
    """The sampled middle rows (:func:`sampled_rows`) in the goes a first look takes them: one in
    :data:`FIRST_LOOK` first (or ``first``, when given), then the rest (none for an image too short to have
    middle rows)."""
    middles, _ = sampled_rows(height)
    if first is None or len(first) == 0:
        first = middles[FIRST_LOOK // 2 :: FIRST_LOOK]
    return [look for look in (first, np.setdiff1d(middles, first)) if len(look)]


def off_rows(
    reference: np.ndarray, submitted: np.ndarray, tolerance: float, open_pixels: np.ndarray | None = None
) -> np.ndarray:
    """Per row of ``submitted``, how many of its pixels are off even nearby against ``reference`` (as
    :func:`_off_nearby` counts them); 0 on the image's first and last rows, which no look takes as a middle."""
    h = submitted.shape[0]
    counts = np.zeros(h, dtype=np.int64)
    if h >= 3:
        middles = np.arange(1, h - 1)
        shut = None if open_pixels is None else open_pixels[middles]
        counts[1:-1] = _off_per_row(_threes(reference, middles), _threes(submitted, middles), tolerance, shut)
    return counts


def _threes(image: np.ndarray, middles: np.ndarray) -> np.ndarray:
    """Each row ``middles`` of an (H, W, 3) image with the rows above and below (the edges repeated): (k, 3, W, 3)."""
    h = image.shape[0]
    return image[np.clip(middles[:, None] + np.arange(-1, 2)[None, :], 0, h - 1)]


def telling_middles(counts: np.ndarray, enough: float) -> np.ndarray:
    """The middle rows a first look takes when the submission's off rows against the reference are known
    (``counts``, :func:`off_rows`): those with the most off pixels, most first, until they hold more than
    ``enough`` of them, at most as many as :func:`sampled_rows` has.

    A cost, never an answer: any distinct middle rows give an exact lower bound (:func:`off_at_least`).  A
    variant that agrees with the reference on these rows is off there as often as the reference is, more than
    ``enough``: it is ruled out by this one look; only a variant that changes these very rows is looked at
    further."""
    ranked = np.argsort(-counts, kind="stable")
    ranked = ranked[counts[ranked] > 0][: len(sampled_rows(len(counts))[0])]
    held = np.cumsum(counts[ranked])
    take = int(np.searchsorted(held, enough, side="right")) + 1
    return np.sort(ranked[:take])


def off_at_least(
    name: str | tuple[str, ...],
    submitted: np.ndarray,
    verdict: Grade,
    renders: Renders,
    beyond: Callable[[int], bool] | None = None,
    first: np.ndarray | None = None,
) -> int | None:
    """A lower bound of how many pixels of ``submitted`` are off even nearby against variant ``name``, from a
    look at a few of its rows (None for an image too short to have middle rows); once ``beyond`` says the count
    is too many, no more rows are looked at.

    Exact, not a sample's estimate: a pixel is off nearby when every variant pixel in its 3×3 neighbourhood
    differs from it by more than the tolerance, so each sampled middle row, rendered with the rows above and
    below, gives its off pixels exactly as the whole grade counts them; their count bounds the whole image's.
    A variant whose bound exceeds what passing allows cannot pass, and one whose bound exceeds the closest's
    share cannot be named closest (:func:`diagnose`).  The rows are looked at in two goes, one in
    :data:`FIRST_LOOK` of them first: a bound from some of the rows is a bound too, and most variants are
    settled by it.  ``first``, when given (:func:`telling_middles`), is the first look instead, and the rest
    of the sampled rows the second.  With several names, the bound is against the range of their renders
    (:func:`service.images.grading.range_counts`)."""
    h, w, _ = submitted.shape
    looks = _looks(h, first)
    if not looks:
        return None
    names = (name,) if isinstance(name, str) else name
    off = 0
    for look in looks:
        rows = (look[:, None] + np.arange(-1, 2)[None, :]).ravel()
        bands = [renders.rows(n, rows).reshape(len(look), 3, w, 3) for n in names]
        low = bands[0] if len(bands) == 1 else np.min(bands, axis=0)
        high = low if len(bands) == 1 else np.max(bands, axis=0)
        near = rows_distance(low, high, _threes(submitted, look))
        if renders.open is not None:
            near = np.where(renders.open[look], 0, near)
        off += int(np.count_nonzero(near > verdict.tolerance))
        if beyond is not None and beyond(off):
            break
    return off


#: a variant's whole render comes in this many bands of rows, each band's off pixels counted as it comes
BANDS = 4


def whole_unless_off(
    name: str,
    submitted: np.ndarray,
    verdict: Grade,
    renders: Renders,
    beyond: Callable[[int], bool] | None = None,
    counts: np.ndarray | None = None,
) -> np.ndarray | None:
    """Variant ``name``'s whole image, rendered a band of rows at a time; None as soon as ``beyond`` says the
    pixels of ``submitted`` off even nearby in the rows so far are too many.

    Exact, as :func:`off_at_least` is: a row whose neighbours above and below have come too gives its off
    pixels exactly as the whole grade counts them, so the count so far is a lower bound of the whole
    image's; ``beyond`` decides on it as the grade decides on the whole count (the share of the pixels, the
    same division), so once it says too many, the variant cannot pass (or come closest): the rest of it is
    not rendered.  The bands come in the order of :func:`_bands`, so that a mistake confined to one part of the image
    shows early; a variant that may pass is rendered whole, each row once (:class:`Renders` keeps the rows of
    the first looks too); with ``counts`` (:func:`off_rows`), the bands with the most pixels off against the
    reference come first, where a variant that cannot pass shows it soonest."""
    if beyond is None:
        return renders.variant(name)
    h = submitted.shape[0]
    image = np.empty_like(submitted)
    came, counted = np.zeros(h, dtype=bool), np.zeros(h, dtype=bool)
    everywhere = np.arange(h)
    above, below = np.maximum(everywhere - 1, 0), np.minimum(everywhere + 1, h - 1)
    off = 0
    for band in _ranked(_bands(h), counts):
        image[band] = renders.rows(name, band)
        came[band] = True
        ready = np.flatnonzero(came & came[above] & came[below] & ~counted)
        if len(ready) == 0:
            continue
        counted[ready] = True
        bands = np.stack([image[above[ready]], image[ready], image[below[ready]]], axis=1)
        shut = None if renders.open is None else renders.open[ready]
        off += _off_nearby(bands, _threes(submitted, ready), verdict.tolerance, shut)
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
        order += (
            [k + bands // (2 * step) for k in order]
            if bands % (2 * step) == 0
            else [k for k in range(bands) if k not in order]
        )
    edges = np.linspace(0, height, bands + 1).round().astype(np.int64)
    return [np.arange(edges[k], edges[k + 1]) for k in order[:bands] if edges[k + 1] > edges[k]]


def _ranked(bands: list[np.ndarray], counts: np.ndarray | None) -> list[np.ndarray]:
    """``bands`` with the most pixels off against the reference (``counts``, per row) first, in their own order
    among equals; as they are without ``counts``.  Only the order changes: every band still comes, each once,
    so a whole image is the same image, and the count so far is a lower bound however they come."""
    if counts is None:
        return bands
    return [bands[k] for k in sorted(range(len(bands)), key=lambda k: -int(counts[bands[k]].sum()))]


def bound_unless_outside(
    name: str,
    reference: np.ndarray,
    submitted: np.ndarray,
    verdict: Grade,
    renders: Renders,
    beyond: Callable[[int], bool] | None = None,
    counts: np.ndarray | None = None,
) -> np.ndarray | None:
    """Speckled mistake ``name``'s far end, whole, rendered a band of rows at a time as
    :func:`whole_unless_off` renders a variant; None as soon as ``beyond`` says the pixels of ``submitted``
    outside the reference and the far end in the bands so far are too many.

    Exact, as :func:`outside_at_least` is: whether a pixel lies outside depends on that pixel alone, so the
    count so far is a lower bound of :func:`speckled`'s, decided on as it decides (the share of the pixels):
    once too many, the mistake cannot pass (or come closest), and the rest of its far end is not rendered.
    ``counts``: the bands in the order :func:`whole_unless_off` takes them."""
    if beyond is None:
        return renders.bound(name)
    image = np.empty_like(submitted)
    off = 0
    for band in _ranked(_bands(submitted.shape[0]), counts):
        image[band] = renders.bound_rows(name, band)
        off += _outside(reference[band], image[band], submitted[band], verdict.tolerance)
        if beyond(off):
            return None
    return image


def _outside(reference: np.ndarray, far: np.ndarray, submitted: np.ndarray, tolerance: float) -> int:
    """How many pixels of ``submitted`` lie outside the reference and the far end, each channel within
    ``tolerance`` (as :func:`speckled` counts them)."""
    ref, low, sub = (a.astype(np.int16) for a in (reference, far, submitted))
    return int(
        np.count_nonzero(
            np.any((sub < np.minimum(ref, low) - tolerance) | (sub > np.maximum(ref, low) + tolerance), axis=2)
        )
    )


def _off_nearby(bands: np.ndarray, submitted: np.ndarray, tolerance: float, shut: np.ndarray | None = None) -> int:
    """How many pixels of the submitted middle rows are off even nearby against the variant's ``bands``
    (:func:`_off_per_row`, summed)."""
    return int(_off_per_row(bands, submitted, tolerance, shut).sum())


def _off_per_row(
    bands: np.ndarray, submitted: np.ndarray, tolerance: float, shut: np.ndarray | None = None
) -> np.ndarray:
    """How many pixels of each middle row are off even nearby, per row, as :func:`service.images.grading.grade` counts
    them (both ways, :mod:`service.images.nearby`): ``bands`` the variant's and ``submitted`` the submission's
    ``(k, 3, W, 3)`` rows, each middle row with the rows above and below (the image's edges repeated); the
    pixels ``shut`` (``(k, W)``, True: not counted) are not counted."""
    near = rows_distance(bands, bands, submitted)
    if shut is not None:
        near = np.where(shut, 0, near)
    return np.count_nonzero(near > tolerance, axis=1)


def outside_at_least(
    name: str,
    reference: np.ndarray,
    submitted: np.ndarray,
    verdict: Grade,
    renders: Renders,
    beyond: Callable[[int], bool] | None = None,
    first: np.ndarray | None = None,
) -> int | None:
    """For a speckled mistake ``name`` of :data:`tracer.scene.variants.BOUNDS`: a lower bound of how many pixels of
    ``submitted`` lie outside the reference and the mistake's far end (:func:`speckled`'s share, as a count),
    from a look at the sampled middle rows of the far end (None for an image too short to have middle rows);
    once ``beyond`` says the count is too many, no more rows are looked at.

    Exact, as :func:`off_at_least` is: whether a pixel lies outside depends on that pixel alone, so the
    sampled rows give their outside pixels exactly as :func:`speckled` counts them, and their count bounds
    the whole image's.  A mistake whose bound exceeds what passing allows cannot pass, and one whose bound
    exceeds the closest's share cannot be named closest: its far end is rendered whole only when it can.
    ``first``: the first look's rows, as :func:`off_at_least` takes them."""
    looks = _looks(submitted.shape[0], first)
    if not looks:
        return None
    off = 0
    for look in looks:
        off += _outside(reference[look], renders.bound_rows(name, look), submitted[look], verdict.tolerance)
        if beyond is not None and beyond(off):
            break
    return off


#: at least this share of the departures must go beyond every pixel of the reference around them for them to be
#: speckles: a shadow's speckle darkens a lit pixel past its lit neighbours (80–94 % of acne's departures on the
#: examples at 64 px, 25 % on the Cornell homework's), while a pixel that mixes two surfaces otherwise (a
#: student's anti-aliasing averaged in gamma space: 2 % of its departures) stays between them
BEYOND_SHARE = 0.1


def _beyond_neighbours(reference: np.ndarray, submitted: np.ndarray, tolerance: float) -> np.ndarray:
    """``(H, W)`` bool: where the submission lies, in some channel, more than ``tolerance`` beyond every pixel
    of the reference's 3×3 neighbourhood (below the least or above the most)."""
    wide = np.pad(reference.astype(np.int16), ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = reference.shape[:2]
    around = np.stack([wide[dy : dy + h, dx : dx + w] for dy in range(3) for dx in range(3)])
    sub = submitted.astype(np.int16)
    return np.any((sub < around.min(axis=0) - tolerance) | (sub > around.max(axis=0) + tolerance), axis=2)


def speckled(
    reference: np.ndarray, bound: np.ndarray, submitted: np.ndarray, tolerance: float, samples: int = 1
) -> float | None:
    """For a mistake that varies from point to point: the share of pixels that do not lie between the
    reference and the mistake's far end ``bound`` (within the tolerance, every channel), when the submission
    departs from the reference towards it in speckles; None when it does not.

    Speckles: where the submission departs, how far it goes towards the bound (0 at the reference, 1 at the
    bound) changes from one pixel to the next by at least :data:`SPECKLE` on average, over the pairs of
    neighbouring pixels one of which departs (sparse speckles on a large lit surface are speckles as much as
    dense ones: the pairs where neither departs say nothing of how it departs); with ``samples`` × ``samples``
    sub-samples a pixel, at least :func:`speckle_threshold` of them.  A smooth departure (a light
    missing, a term too weak) changes slowly inside the region it darkens, and is not this mistake."""
    ref, low, sub = (a.astype(np.int16) for a in (reference, bound, submitted))
    outside = np.any((sub < np.minimum(ref, low) - tolerance) | (sub > np.maximum(ref, low) + tolerance), axis=2)
    gap = (low - ref).astype(np.float64)
    channel = np.argmax(np.abs(gap), axis=2)[..., None]
    span = np.take_along_axis(gap, channel, axis=2)[..., 0]
    moved = np.take_along_axis((sub - ref).astype(np.float64), channel, axis=2)[..., 0]
    can = np.abs(span) > tolerance
    departs = can & (np.abs(moved) > tolerance)
    beyond = np.count_nonzero(departs & _beyond_neighbours(reference, submitted, tolerance))
    if departs.sum() < 16 or beyond < BEYOND_SHARE * departs.sum():
        return None  # (too few, or between the reference's own neighbours: pixels that mix surfaces otherwise)
    share = np.where(can, moved / np.where(can, span, 1.0), 0.0)
    pairs = can[:, 1:] & can[:, :-1] & (departs[:, 1:] | departs[:, :-1])
    if not pairs.any() or float(np.abs(np.diff(share, axis=1))[pairs].mean()) < speckle_threshold(samples):
        return None
    return float(outside.mean())
