"""The film: a chunk's sub-samples summed in fixed point, and the pixels they make, linear or as stored bytes.

Every contribution (a ray's background, a hit's direct light, times the
weight it carries) is added as an integer in units of ``1/fixed``, so the
sums, and the bytes of the image, do not depend on the order in which slices,
chunks or threads deliver them.  Contributions are never negative, so a
sub-sample at or above ``ceiling`` (twice the sub-samples of a pixel) already
saturates its pixel and is clamped there; NaN counts as nothing.
"""

from __future__ import annotations

import math

import numpy as np

from .image import quantize, wrapped
from .scene.variants import Options

#: the most rays a slice of a chunk's ray tree holds for which the fixed-point unit is the same whatever the slice
#: (the renderer's chunks on several threads: :data:`tracer.render.CHUNK_RAYS`): larger slices leave more room
UNIT_RAYS = 1 << 16
#: the film of a student whose colours are not clamped (a variant) saturates a sub-sample only this many times
#: above 1 (per sub-sample of its pixel, as the reference's does at 2): its pixels wrap around in 8 bits up to
#: there, 1024 times white, far brighter than any light a scene of a course gives a surface
UNCLAMPED_CEILING = 1024.0


class Film:
    """The sums of ``pixels`` pixels of ``per_pixel`` sub-samples each, added to by slices of at most
    ``slice_rays`` rays; ``unclamped``: for a student who stores colours unclamped (wrapped), whose sub-samples
    saturate only at :data:`UNCLAMPED_CEILING` (a fixed-point unit 2⁹ times the reference's, still
    far finer than a level)."""

    def __init__(self, pixels: int, per_pixel: int, slice_rays: int, unclamped: bool = False):
        n = pixels * per_pixel
        self.pixels, self.per_pixel = pixels, per_pixel
        self.acc = np.zeros((3, n), dtype=np.int64).T  # (n, 3), its columns contiguous (add)
        # a sub-sample this bright saturates its pixel: sums are clamped there
        self.ceiling = float((UNCLAMPED_CEILING if unclamped else 2) * per_pixel)
        # the fixed-point unit leaves room for a slice's worth of contributions on top of a clamped sum (for slices
        # of up to UNIT_RAYS, one unit whatever the slice: the same sums, and bytes, for every size)
        room = math.ceil(math.log2(max(slice_rays, UNIT_RAYS)))
        self.fixed = 2.0 ** (48 - math.ceil(math.log2(self.ceiling)) - max(0, room - 14))
        #: the sub-samples whose ray tree met a tie the format leaves open (:mod:`tracer.exact.ties`); None: none yet
        self.open: np.ndarray | None = None

    def opened(self, index: np.ndarray) -> None:
        """Sub-samples ``index`` met a tie the format leaves open."""
        if len(index):
            if self.open is None:
                self.open = np.zeros(self.pixels * self.per_pixel, dtype=bool)
            self.open[index] = True

    def open_pixels(self) -> np.ndarray:
        """Which pixels have an open sub-sample. Shape (pixels,), bool."""
        if self.open is None:
            return np.zeros(self.pixels, dtype=bool)
        return np.asarray(self.open.reshape(self.pixels, self.per_pixel).any(axis=1))

    def add(self, index: np.ndarray, values: np.ndarray, fresh: bool = False) -> None:
        """``acc[index] += values (len(index), 3)`` in fixed point; repeated indices are summed.

        ``fresh`` says that no index repeats and that the film holds nothing yet at ``index`` (a camera ray's
        contribution, its sample's first), so the sum is the value itself, at most ``ceiling``: a plain
        scatter instead of ``np.add.at``."""
        if not len(index):
            return
        ceiling, fixed = self.ceiling, self.fixed
        cap = np.int64(ceiling * fixed)
        for k in range(3):  # a column at a time: 1-D gathers and scatters
            # clipped into 0..ceiling, NaN to 0 (fmax drops a NaN, as nan_to_num and then clip would), in place
            v = np.fmax(values[:, k], 0.0)
            np.fmin(v, ceiling, out=v)
            v *= fixed
            units = np.rint(v, out=v).astype(np.int64)
            column = self.acc[:, k]
            if fresh:
                column[index] = units
            else:
                np.add.at(column, index, units)
                np.minimum(column, cap, out=column)

    def colour(self) -> np.ndarray:
        """Each pixel's linear colour: the mean of its sub-samples. Shape (pixels, 3)."""
        per_pixel = self.acc.reshape(self.pixels, self.per_pixel, 3).sum(axis=1)  # integers: exact in any order
        return per_pixel.astype(np.float64) / (self.fixed * self.per_pixel)


def stored(colour: np.ndarray, options: Options) -> np.ndarray:
    """Linear colours as the image stores them: 8-bit values (:func:`tracer.image.quantize`, or wrapped around
    in the variant that does not clamp them, :func:`tracer.image.wrapped`), after gamma 1/2.2 in the variant
    that applies it, and as a variant's student stores them (:meth:`tracer.scene.variants.Options.stored`).
    Same shape, uint8."""
    linear = colour if not options.gamma else np.clip(colour, 0.0, None) ** (1.0 / 2.2)
    return options.stored(quantize(linear) if options.clamp_colour else wrapped(linear))
