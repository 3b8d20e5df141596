"""The size of what the camera sees: the scale a student's ray offset is measured against.

A scene's bounding box says nothing of what an image shows: the classic
radius-1000 ground sphere, or one tiny sphere 2000 units away and out of view,
makes it thousands of times larger than the spheres in the picture.  What an
offset does to an image depends on how large it is beside what the pixels
show, so the scale is taken from the camera: the height of the view window at
the depth where the picture's surfaces lie (the median depth along the view
axis of the surfaces its pixel centres hit), or, for an orthographic camera,
the view window's height itself.  An offset of 10⁻³ of it is a thousandth of
the image's height at that depth: a quarter of a pixel at 240 rows.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..scene.camera import CameraRays

if TYPE_CHECKING:
    from ..scene.world import World
    from .intersect import Intersector

#: at most this many pixel centres along each side of the image are traced for the median depth
SIDE = 64


def sampled_pixels(width: int, height: int, side: int = SIDE) -> np.ndarray:
    """The pixel numbers of an evenly spaced grid of at most ``side`` × ``side`` pixels (every pixel of a small
    image), row by row: the same on every run."""
    cols = np.unique(np.linspace(0, width - 1, min(width, side)).round().astype(np.int64))
    rows = np.unique(np.linspace(0, height - 1, min(height, side)).round().astype(np.int64))
    return (rows[:, None] * width + cols[None, :]).ravel()


def visible_size(scene: object, world: World, intersector: Intersector, fallback: float) -> float:
    """The height of the view at the median depth of what the pixel centres of a grid hit (perspective), or the
    view window's height (orthographic); ``fallback`` when no sampled pixel sees a surface (then no ray leaves
    one that the camera sees) or the depth is not a positive finite number.

    Taken with the format's own camera (its sub-sample grid, vertical fov), whatever variant renders, so that
    every variant of a scene measures an offset against the same size."""
    image = scene.image.model_copy(update={"samples": 1})  # type: ignore[attr-defined]
    camera = CameraRays(scene.camera, image, world.origin)  # type: ignore[attr-defined]
    if camera.orthographic:
        return 2.0 * camera.h
    origins, dirs = camera.rays_of(sampled_pixels(camera.width, camera.height))
    best = intersector.nearest(intersector.rays(origins, dirs))
    hit = np.isfinite(best.t)
    if not hit.any():
        return fallback
    depth = best.t[hit] * (dirs[hit] @ camera.forward)
    size = 2.0 * camera.h * float(np.median(depth))
    return size if 0.0 < size < np.inf else fallback
