"""When nothing fits: every mistake tried and every term out of scale, ranked by the share of the submission's
difference from the reference each accounts for (on the rows :mod:`.compose` chooses mistakes on).  Pure."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .compose import _rows
from .records import Term
from .stored import image_level
from .tried import Looks, candidates

#: a nearest explanation that accounts for less of the difference than this accounts for nothing a person sees
NOTHING = 0.01


@dataclass(frozen=True)
class Explanation:
    """A part of the difference, and how much of it: a mistake's (``variant``) or a term's (``term``)."""

    share: float
    variant: str | None = None
    term: Term | None = None


def nearest(
    reference: np.ndarray,
    submitted: np.ndarray,
    looks: Looks,
    terms: list[tuple[Term, float]],
    tolerance: float = 2.0,
) -> list[Explanation]:
    """When nothing fits: every mistake tried and every term out of scale (with the share of the difference the
    fit says it accounts for), ranked by how much of the submission's difference from the reference each
    accounts for, most first; those that account for less than :data:`NOTHING` are left out, but for the first
    (when it accounts for anything at all)."""
    found = image_level(reference, submitted)
    rows = _rows(reference, submitted, looks, candidates(looks, [t for t, _ in terms]), (found, tolerance, None))
    base = rows.error(())
    out = [Explanation(share, n) for n, share in found.items()]
    if base > 0:
        out += [Explanation(max(0.0, 1.0 - rows.error((n,)) / base), n) for n in rows.deltas]
    out += [Explanation(share, term=t) for t, share in terms]
    ranked = sorted(out, key=lambda e: -e.share)
    return [e for k, e in enumerate(ranked) if e.share >= NOTHING or (k == 0 and e.share > 0)]
