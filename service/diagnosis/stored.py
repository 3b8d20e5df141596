"""The mistakes of the stored image: a change of the 8-bit pixels alone (flipped, mirrored left to right, grey,
red and blue swapped, gamma), tried on the reference's own pixels with no render (:func:`image_level`), undone
on a submission (:func:`undone`) or applied to what it is compared with (:func:`outer`)."""

from __future__ import annotations

import numpy as np

from tracer.scene.variants import Options

#: the mistakes of the stored image tried on the reference's pixels, in the order a tracer makes them (the rows,
#: then the channels): each a change of the 8-bit image alone, tried with no render
OUTER = ("image-flipped", "camera-left-handed", "grayscale", "channels-swapped")
#: gamma is a change of the stored values too, but one a brighter light also makes: it is chosen with the
#: render-level mistakes (its difference is not added: it is applied to the sum of the others')
GAMMA = "gamma"
#: the mistakes of the stored values alone, applied to a model of the rows rather than added to it: gamma, and
#: the grey and channel swap that a large difference of another mistake hides from :func:`image_level`
STORED = (GAMMA, "grayscale", "channels-swapped")
#: an image-level mistake is kept when leaving it out makes the mean difference at least this much larger
#: (× the difference with it): a transform that changes little (a left-right mirror of a symmetric scene) is no
#: evidence
KEEP_OUTER = 1.25
#: at most this many rows are compared to find the image-level mistakes
SAMPLED_ROWS = 128
#: a flip the mean difference hides (a brighter light or gamma changes every pixel more than the flip moves
#: them) is kept on the evidence of the edges when the submission's edges overlap the flipped reference's at
#: least this many times as much as the reference's own (an image not flipped overlaps its own edges more)
FLIP_EDGES = 1.3
#: ... and when that overlap is at least this: a camera mistake (a horizontal fov) moves every outline, and the
#: few the flipped reference then shares by chance are no evidence (at 64 pixels across, upright images of the
#: student mistakes share at most 0.22 of theirs with the flipped reference; flipped ones, where the mean
#: difference hides the flip, 0.39 and more)
FLIP_OVERLAP = 0.3
#: an edge: a pixel whose grey level differs from its right or lower neighbour's by more than this, in levels
EDGE_LEVELS = 12
#: gamma 1/2.2 of an 8-bit value, as a table
_GAMMA = np.floor(255.0 * (np.arange(256) / 255.0) ** (1 / 2.2) + 0.5).astype(np.uint8)


def outer(image: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """``image`` (..., H, W, 3) uint8 stored with the image-level mistakes ``names``.  Gamma is applied to the
    8-bit values (an image from linear colour is within a few levels of it, more in the darkest shades: enough
    to tell, not to confirm, which one render does)."""
    out = _GAMMA[image] if GAMMA in names else image
    if "image-flipped" in names:
        out = out[..., ::-1, :, :]
    if "camera-left-handed" in names:
        out = out[..., :, ::-1, :]
    return Options(grayscale="grayscale" in names, channels_swapped="channels-swapped" in names).stored(out)


def undone(submitted: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """The submission with the invertible image-level mistakes of ``names`` undone (flips, the channel swap): what
    the reference's rows are compared with.  Grey and gamma cannot be undone: they are applied to the other side."""
    out = submitted
    if "channels-swapped" in names and "grayscale" not in names:
        out = out[..., ::-1]
    if "camera-left-handed" in names:
        out = out[:, ::-1]
    if "image-flipped" in names:
        out = out[::-1]
    return out


def mean_difference(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean(np.abs(a.astype(np.int16) - b.astype(np.int16))))


def image_level(reference: np.ndarray, submitted: np.ndarray) -> dict[str, float]:
    """The image-level mistakes the submission shows, from the reference's pixels alone, each with the share of
    the mean difference it takes away: the subset of :data:`OUTER` whose stored reference is nearest the
    submission (mean difference), less each member whose leaving out makes that less than :data:`KEEP_OUTER`
    times larger (no evidence of it).  Compared on at most :data:`SAMPLED_ROWS` rows evenly apart (all of a
    smaller image's): these mistakes change every row alike, and what they find is confirmed by a grade of the
    whole image (:func:`.compose.stored_only`, or the one render of a combination)."""
    subsets = [tuple(n for k, n in enumerate(OUTER) if mask >> k & 1) for mask in range(1 << len(OUTER))]
    h = reference.shape[0]
    rows = np.arange(0, h, max(1, -(-h // SAMPLED_ROWS)))  # (the rows of the submission compared)

    def stored(names: tuple[str, ...]) -> np.ndarray:  # those rows of the reference stored with ``names``
        source = reference[h - 1 - rows] if "image-flipped" in names else reference[rows]
        return outer(source, tuple(n for n in names if n != "image-flipped"))

    errors = {s: mean_difference(stored(s), submitted[rows]) for s in subsets}
    best = min(subsets, key=lambda s: (errors[s], len(s)))
    base = errors[()]
    kept = {}
    for n in best:
        without = errors[tuple(m for m in best if m != n)]
        if without > KEEP_OUTER * errors[best]:
            kept[n] = min(1.0, (without - errors[best]) / base) if base > 0 else 0.0
    if "image-flipped" not in kept and flipped_edges(reference, submitted):
        flipped = errors[("image-flipped",)]
        kept = {"image-flipped": max(0.0, (base - flipped) / base) if base > 0 else 0.0, **kept}
    return kept


def edges(image: np.ndarray) -> np.ndarray:
    """(H − 1, W − 1) bool: where the grey level of ``image`` changes by more than :data:`EDGE_LEVELS` to the
    right or below: the outlines of what it shows, which a change of brightness (a light too bright, gamma,
    an ambient term of another colour) leaves where they are."""
    grey = image.astype(np.int16).sum(axis=2)
    across = np.abs(np.diff(grey, axis=1))[:-1, :]
    down = np.abs(np.diff(grey, axis=0))[:, :-1]
    return np.maximum(across, down) > 3 * EDGE_LEVELS


def flipped_edges(reference: np.ndarray, submitted: np.ndarray) -> bool:
    """Whether the submission's outlines are the flipped reference's rather than its own: their overlap
    (shared edge pixels over edge pixels of either) with the flipped reference's is at least :data:`FLIP_OVERLAP`
    and :data:`FLIP_EDGES` times that with the reference's.  A scene alike upside down overlaps both alike: no
    evidence."""
    mine, theirs = edges(submitted), edges(reference)
    upside = edges(reference[::-1])

    def overlap(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.count_nonzero(a & b)) / max(1, int(np.count_nonzero(a | b)))

    flipped = overlap(mine, upside)
    return flipped >= FLIP_OVERLAP and flipped > FLIP_EDGES * max(overlap(mine, theirs), 1e-9)


#: how an image-level mistake shows, for its evidence
SHOWN = {
    "gamma": "brightened as gamma 1/2.2 brightens it",
    "image-flipped": "upside down",
    "camera-left-handed": "mirrored left to right",
    "grayscale": "in grey",
    "channels-swapped": "with red and blue swapped",
}
