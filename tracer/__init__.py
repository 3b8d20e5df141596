"""The phongray tracer: ``render(scene)`` turns a validated scene into pixels."""

from typing import Any

from schemas import Scene

from .budget import Budget, OverBudget
from .image import decode_png, encode_png
from .memory import tune_allocator
from .render import ImageTooLarge, Picture, RenderCancelled, Renderer, render

tune_allocator()

__all__ = [
    "Budget",
    "ImageTooLarge",
    "OverBudget",
    "Picture",
    "RenderCancelled",
    "Renderer",
    "decode_png",
    "encode_png",
    "render",
    "render_png",
]


def render_png(scene: Scene, **kwargs: Any) -> bytes:
    """Render a validated scene straight to PNG bytes."""
    return encode_png(render(scene, **kwargs))
