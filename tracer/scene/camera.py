"""Primary rays, exactly as the scene format defines them."""

from __future__ import annotations

import numpy as np

from schemas import Camera, Image

from .surfaces import unit
from .vec import plus

#: the most values (pixels × sub-samples of one row, or of one column) a per-column or per-row table may hold
TABLE_MAX = 1 << 20


def up_perpendicular(camera: Camera) -> bool:
    """Whether the camera's ``up`` is perpendicular to its view, ``look_at − position``, exactly, in the numbers
    the scene gives: then ``u = r × f`` is ``unit(up)`` up to rounding, and a student who uses ``up`` as it is
    (variant ``camera-up-as-given``) renders the reference."""
    view = np.subtract(np.asarray(camera.look_at, dtype=np.float64), np.asarray(camera.position, dtype=np.float64))
    return float(np.dot(view, np.asarray(camera.up, dtype=np.float64))) == 0.0


class CameraRays:
    """Generates the rays of a range of pixels, each with its n×n regular grid of sub-samples."""

    def __init__(
        self, camera: Camera, image: Image, origin: np.ndarray, half_pixel: bool = True, vertical_fov: bool = True
    ):
        eye = np.asarray(camera.position, dtype=np.float64) - origin
        target = np.asarray(camera.look_at, dtype=np.float64) - origin
        self.forward = unit(target - eye)
        self.right = unit(np.cross(self.forward, unit(np.asarray(camera.up, dtype=np.float64))))
        self.up = np.cross(self.right, self.forward)
        self.eye = eye
        self.orthographic = camera.type == "orthographic"
        self.h = camera.height / 2.0 if self.orthographic else float(np.tan(np.radians(camera.fov) / 2.0))
        self.width, self.height, self.n = image.width, image.height, image.samples
        self.offset = 0.5 if half_pixel else 0.0  # where a sub-sample sits in its cell (a variant drops the +0.5)
        #: the view window's half-width and half-height over h (a variant reads fov across the width)
        aspect = image.width / image.height
        self.scale_x, self.scale_y = (aspect, 1.0) if vertical_fov else (1.0, 1.0 / aspect)
        self._across: list[np.ndarray] | None = None
        self._down: list[np.ndarray] | None = None

    def rays(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Origins and unit directions, each ``((stop − start)·n², 3)``, pixel-major.

        Pixels are numbered row by row from the top left; within a pixel,
        sub-sample ``(a, b)`` comes at position ``b·n + a``.
        """
        return self.rays_of(np.arange(start, stop, dtype=np.int64))

    def _products(self, index: np.ndarray, size: int, scale: float, vector: np.ndarray, flip: bool) -> list[np.ndarray]:
        """Per entry of ``index`` (a column, or a row when ``flip``) and sub-sample, each component of
        ``x·right`` (or ``y·up``): three ``(len(index), n)`` arrays, each value as the contract's equations
        compute it."""
        offsets = (np.arange(self.n, dtype=np.float64) + self.offset) / self.n
        s = (index.astype(np.float64)[:, None] + offsets[None, :]) / size
        if flip:
            y = (1.0 - 2.0 * s) * scale * self.h
            return [y * vector[k] for k in range(3)]
        x = (2.0 * s - 1.0) * scale * self.h
        return [vector[k] * x for k in range(3)]

    def _tables(self) -> tuple[list[np.ndarray] | None, list[np.ndarray] | None]:
        """Per column and sub-sample column, each component of ``x·right`` (three (W, n) tables); per row and
        sub-sample row, each component of ``y·up`` (three (H, n)): made once per render, when no larger than
        :data:`TABLE_MAX` (a 16777216 × 1 image's would take 400 MiB per sub-sample; past it, the products of
        each batch's own columns or rows are made, the same values)."""
        if self._across is None and self.width * self.n <= TABLE_MAX:
            self._across = self._products(np.arange(self.width), self.width, self.scale_x, self.right, False)
        if self._down is None and self.height * self.n <= TABLE_MAX:
            self._down = self._products(np.arange(self.height), self.height, self.scale_y, self.up, True)
        return self._across, self._down

    def rays_of(self, pixel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`rays` of the pixels ``pixel (P,)``, in that order: each pixel's rays are the same wherever
        it is asked for.

        A sub-sample's direction is ``forward + (y·up + x·right)`` (unit), its x from its column and y from
        its row alone: each product comes from :meth:`_tables`, and only the sums are made per ray."""
        n = self.n
        across, down = self._tables()
        col, row = pixel % self.width, pixel // self.width
        if across is None:  # (a table too large to keep: this batch's columns alone, indexed from 0)
            col, cols = np.unique(col, return_inverse=True)[::-1]
            across = self._products(cols, self.width, self.scale_x, self.right, False)
        if down is None:
            row, rows = np.unique(row, return_inverse=True)[::-1]
            down = self._products(rows, self.height, self.scale_y, self.up, True)
        count = len(pixel) * n * n
        plane = np.empty((3, count)).T  # (rays, 3), its columns contiguous
        for k in range(3):  # ray (p, b, a): down[row_p, b] + across[col_p, a]
            if n == 1:
                np.add(np.take(down[k][:, 0], row), np.take(across[k][:, 0], col), out=plane[:, k])
            else:
                np.add(
                    np.take(down[k], row, axis=0)[:, :, None],
                    np.take(across[k], col, axis=0)[:, None, :],
                    out=plane[:, k].reshape(len(pixel), n, n),
                )
        if self.orthographic:
            return plus(self.eye, plane), np.broadcast_to(self.forward, plane.shape).copy()
        for k in range(3):
            np.add(self.forward[k], plane[:, k], out=plane[:, k])
        return np.broadcast_to(self.eye, plane.shape), unit(plane)  # (every origin the eye: one row, not copied)
