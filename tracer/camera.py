"""Primary rays, exactly as the scene format defines them."""

from __future__ import annotations

import numpy as np

from schemas import Camera, Image

from .vec import along, plus, scaled
from .world import unit


class CameraRays:
    """Generates the rays of a range of pixels, each with its n×n regular grid of sub-samples."""

    def __init__(self, camera: Camera, image: Image, origin: np.ndarray, half_pixel: bool = True,
                 vertical_fov: bool = True):
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

    def rays(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Origins and unit directions, each ``((stop − start)·n², 3)``, pixel-major.

        Pixels are numbered row by row from the top left; within a pixel,
        sub-sample ``(a, b)`` comes at position ``b·n + a``.
        """
        return self.rays_of(np.arange(start, stop, dtype=np.int64))

    def rays_of(self, pixel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`rays` of the pixels ``pixel (P,)``, in that order: each pixel's rays are the same wherever
        it is asked for."""
        n, W, H = self.n, self.width, self.height
        i = (pixel % W).astype(np.float64)
        j = (pixel // W).astype(np.float64)
        offsets = (np.arange(n, dtype=np.float64) + self.offset) / n
        a = np.tile(offsets, n)  # varies fastest
        b = np.repeat(offsets, n)
        sx = (i[:, None] + a[None, :]).ravel() / W
        sy = (j[:, None] + b[None, :]).ravel() / H
        x = (2.0 * sx - 1.0) * self.scale_x * self.h
        y = (1.0 - 2.0 * sy) * self.scale_y * self.h
        plane = along(scaled(self.right, x), y, self.up)  # x·right + y·up
        if self.orthographic:
            return plus(self.eye, plane), np.broadcast_to(self.forward, plane.shape).copy()
        return np.broadcast_to(self.eye, plane.shape).copy(), unit(plus(self.forward, plane))
