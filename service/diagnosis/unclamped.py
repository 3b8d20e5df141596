"""Colours not clamped behind another mistake: the dark dots a wrap leaves, found where the other mistake's render
saturates.

A student who stores colours without clamping them wraps a value above 1 around in 8 bits: a highlight's
brightest pixels come out dark (1.2 × white stores as 51).  Made alone, the mistake is a variant like any other.
Made with another mistake, its dots fall where *that* mistake's image saturates (no shadow rays light pixels a
shadow kept below 1), so its difference measured against the reference does not add to the other's, and the
other mistake alone is named, as the closest or as a match with a few pixels off (the dots, too few to fail it
by their count, or near a dark neighbour).

So where the diagnosis names one mistake and the submission is still off against its render, and every pixel
off lies within a pixel of one that render saturates and the submission darkens by at least :data:`DARKER`
levels (the wrap's signature: an honest tracer is never that much darker where the image is white), the two
mistakes are rendered together once; the pair is named when the submission passes against it with fewer pixels
off than against the mistake alone.
"""

from __future__ import annotations

import numpy as np

from ..images.grading import Grade, grade, nearby_difference
from .combination import ALL, Combination, Member, compatible, merged
from .renders import Renders

NAME = "colours-not-clamped"
#: a wrapped pixel is at least this many levels darker than white in the channel that wrapped (a value up to 1.5
#: stores at most 127): an honest tracer's highlight differs by a few levels
DARKER = 64


def behind(first: str, submitted: np.ndarray, verdict: Grade, renders: Renders) -> Combination | None:
    """Mistake ``first`` made with colours not clamped, where the submission shows the wrap's signature against
    ``first``'s render and passes against the two made together (one render); None where not."""
    if first == NAME or first not in ALL or not compatible((first, NAME)) or renders.unchanged(NAME):
        return None
    image = renders.variant(first)
    if not _wrap_signature(image, submitted, verdict.tolerance, renders.open):
        return None
    both = renders.render(merged((first, NAME)))
    alone = grade(image, submitted, "", verdict.tolerance, verdict.max_fraction, renders.open)
    g = grade(both, submitted, "", verdict.tolerance, verdict.max_fraction, renders.open)
    if not g.passed or g.fraction_off_nearby >= alone.fraction_off_nearby:
        return None
    evidence = "its dark dots lie where the other mistake's image is white"
    members = (
        Member(first, ALL[first][1], 1.0, "the rest of the image matches it"),
        Member(NAME, ALL[NAME][1], 0.0, evidence),
    )
    return Combination(members, g.fraction_off_nearby, True)


def _wrap_signature(image: np.ndarray, submitted: np.ndarray, tolerance: float, shut: np.ndarray | None) -> bool:
    """Whether some pixels of ``submitted`` are off even nearby against ``image``, and each lies within a pixel of
    one ``image`` saturates in a channel ``submitted`` stores at least :data:`DARKER` levels lower."""
    near = nearby_difference(image, submitted, 0, image.shape[0])
    off = near > tolerance
    if shut is not None:
        off &= ~shut
    if not off.any():
        return False
    wrapped = ((image == 255) & (submitted.astype(np.int16) <= 255 - DARKER)).any(axis=2)
    padded = np.pad(wrapped, 1)
    h, w = wrapped.shape
    around = np.zeros_like(wrapped)
    for dy in range(3):
        for dx in range(3):
            around |= padded[dy : dy + h, dx : dx + w]
    return bool(np.all(around[off]))
