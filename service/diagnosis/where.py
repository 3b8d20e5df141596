"""Where a submission fails: the objects its failing pixels show and the lights that fall on them."""

from __future__ import annotations

import numpy as np

from ..images.grading import Grade
from .records import Share
from .renders import Renders


def where(
    reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders
) -> tuple[list[Share], list[Share]]:
    """The objects the failing pixels show and the lights that fall on them, each with its share.  The lights'
    terms at the failing pixels come a block at a time and are counted as they come, never held for all the
    lights at once."""
    diff = np.max(np.abs(reference.astype(np.int16) - submitted.astype(np.int16)), axis=2) > verdict.tolerance
    if renders.open is not None:
        diff &= ~renders.open
    count = int(diff.sum())
    if count == 0:
        return [], []
    lit_by = np.zeros(len(renders.lights), dtype=np.int64)  # failing pixels each light falls on
    shining = [k for k, kind in enumerate(renders.lights) if kind != "ambient"]

    def fold(first: int, part: dict[str, np.ndarray]) -> None:
        renders.check()
        for k in shining:
            lit_by[k] += int(np.count_nonzero((part[f"diffuse:{k}"] + part[f"specular:{k}"]).max(axis=1) > 1.0 / 255))

    found = renders.at(np.flatnonzero(diff), fold)  # (the passes of the failing pixels alone)
    objects = [
        Share(int(k), renders.objects[int(k)] if k >= 0 else "background", float(np.mean(found == k)))
        for k in np.unique(found)
    ]
    lights = [Share(k, renders.lights[k], int(lit_by[k]) / len(found)) for k in shining if lit_by[k]]
    return (sorted(objects, key=lambda s: -s.share), sorted(lights, key=lambda s: -s.share))
