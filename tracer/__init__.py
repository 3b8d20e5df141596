"""The phongray tracer: ``render(scene)`` turns a validated scene into pixels."""

from collections.abc import Callable
from typing import Any

import numpy as np

from schemas import Scene

from .budget import Budget, OverBudget
from .image import decode_png, encode_png
from .render import ImageTooLarge, Picture, RenderCancelled, Renderer, render

__all__ = [
    "Budget",
    "ImageTooLarge",
    "OverBudget",
    "Picture",
    "RenderCancelled",
    "Renderer",
    "decode_png",
    "encode_png",
    "open_pixels",
    "render",
    "render_png",
]


def render_png(scene: Scene, **kwargs: Any) -> bytes:
    """Render a validated scene straight to PNG bytes."""
    return encode_png(render(scene, **kwargs))


def open_pixels(
    scene: Scene, threads: int | None = None, cancel: Callable[[], bool] | None = None
) -> np.ndarray | None:
    """The pixels of ``scene``'s image that the format leaves open (:class:`Picture`), ``(H, W)`` bool; None,
    with no render, for a scene with no surfaces of different objects in one plane, where none is."""
    from .scene.world import build_world

    with np.errstate(all="ignore"):
        if build_world(scene).coplanar is None:
            return None
    return Renderer(scene).picture(threads=threads, cancel=cancel).open
