"""The grade's one measure of a pixel: how far it is, both ways, from matching anything around it.

For a submitted pixel p and a reference given as a range of values per pixel, ``[low, high]`` (the reference
itself: ``low = high``; the reference and renders of an accepted variant: their lowest and highest value):

* **forward**: the smallest, over the 3×3 neighbourhood q of p, of how far the submission's p lies outside
  the range at q.  A submitted pixel that matches nothing near it (a speckle, a shadow missing) is far.
* **backward**: the smallest, over q, of how far the submission's q lies outside the range at p.  A
  reference pixel that nothing near it in the submission matches (a highlight two pixels wide that vanished
  into a dark neighbourhood) is far, though each of the submission's pixels finds a dark reference pixel
  near it.

A pixel's *nearby distance* is the larger of the two, in 8-bit levels, the largest channel's (0–255): it is
*off even nearby* when that exceeds the tolerance.  An edge shifted by a pixel, or anti-aliased a little
differently, finds its match one pixel over both ways.  A pixel whose own values are within the tolerance is
never off (it is its own neighbour both ways).  The neighbourhood stops at the image's edge (edges repeat).
"""

from __future__ import annotations

import numpy as np

#: rows compared at once, so that the temporaries of a 4096×4096 comparison stay a few tens of MiB
BAND = 256


def planes(img: np.ndarray) -> np.ndarray:
    """(h, w, 3) → (3, h, w), each channel contiguous: the comparisons run over whole rows of bytes."""
    return np.ascontiguousarray(np.moveaxis(img, 2, 0))


def gap(low: np.ndarray, high: np.ndarray, value: np.ndarray) -> np.ndarray:
    """Per pixel, the largest channel distance (uint8) of ``value`` from the range ``[low, high]`` (``low`` ≤
    ``high``), each (3, …) planes of uint8; with ``low`` ``high``, the largest channel difference.  Exact in
    uint8: of the two differences one is 0."""
    d = [(np.maximum(low[c], value[c]) - value[c]) + (np.maximum(value[c], high[c]) - high[c]) for c in range(3)]
    return np.maximum(np.maximum(d[0], d[1]), d[2])


def _window(image: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Rows ``rows`` of an (H, W, 3) image as (3, len(rows), W + 2) planes, the first and last column repeated."""
    return planes(np.pad(image[rows], ((0, 0), (1, 1), (0, 0)), mode="edge"))


def distance(low: np.ndarray, high: np.ndarray, submitted: np.ndarray, top: int, bottom: int) -> np.ndarray:
    """The nearby distance (module docstring) of each pixel of rows ``top:bottom``, ``(bottom − top, W)`` uint8;
    ``low``, ``high`` and ``submitted`` are whole ``(H, W, 3) uint8`` images (``high`` may be ``low``)."""
    h, w, _ = submitted.shape
    rows = np.clip(np.arange(top - 1, bottom + 1), 0, h - 1)
    lo = _window(low, rows)
    hi = lo if high is low else _window(high, rows)
    sub = _window(submitted, rows)
    return distance_of_windows(lo, hi, sub)


def distance_of_windows(lo: np.ndarray, hi: np.ndarray, sub: np.ndarray) -> np.ndarray:
    """:func:`distance` of prepared windows: each ``(3, …, n + 2, W + 2)`` planes holding the rows of interest
    with one row above and below and one column either side (as :func:`_window` makes them); any leading axes
    between the channel and the rows are kept (several bands at once)."""
    n, w = sub.shape[-2] - 2, sub.shape[-1] - 2
    centre = (..., slice(1, n + 1), slice(1, w + 1))
    lo_c, hi_c, sub_c = lo[centre], hi[centre], sub[centre]
    forward = np.full(sub_c.shape[1:], 255, dtype=np.uint8)
    backward = np.full(sub_c.shape[1:], 255, dtype=np.uint8)
    for dy in range(3):
        for dx in range(3):
            around = (..., slice(dy, dy + n), slice(dx, dx + w))
            np.minimum(forward, gap(lo[around], hi[around], sub_c), out=forward)
            np.minimum(backward, gap(lo_c, hi_c, sub[around]), out=backward)
    return np.maximum(forward, backward)


def rows_distance(low: np.ndarray, high: np.ndarray, submitted: np.ndarray) -> np.ndarray:
    """The nearby distance of the middle row of each band of three rows: ``low``, ``high`` and ``submitted``
    ``(k, 3, W, 3)`` (each middle row with the rows above and below; ``high`` may be ``low``) → ``(k, W)``.
    Exact for those rows: a pixel's distance depends on its 3×3 neighbourhood alone."""

    def window(bands: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(np.moveaxis(np.pad(bands, ((0, 0), (0, 0), (1, 1), (0, 0)), mode="edge"), 3, 0))

    lo = window(low)
    hi = lo if high is low else window(high)
    return distance_of_windows(lo, hi, window(submitted))[:, 0, :]
