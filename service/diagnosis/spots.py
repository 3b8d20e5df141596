"""Pixels of a render kept one by one (:class:`Spots`): a ladder's rung looked at only near the pixels that can
decide it (:func:`.settled.windows`), then, if it is looked at further, its rows made of those pixels and the rest."""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np

#: renders pixel numbers → their pixels ``(len, 3) uint8`` (:meth:`tracer.Renderer.pixels_at`)
Render = Callable[[np.ndarray], np.ndarray]


class Spots:
    """Per render (by key), the pixels rendered alone so far: an image ``(H, W, 3)`` and which of its pixels are
    there ``(H, W)``.  Every pixel is computed alone (:meth:`tracer.Renderer.pixels_at`), so those of a whole
    render and those rendered here are the same bytes, and a pixel kept here is never rendered again for the
    rows or the image it belongs to (:meth:`rows`)."""

    def __init__(self, height: int, width: int):
        self.height, self.width = height, width
        self.held: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self.lock = threading.Lock()

    def _copy(self, key: str) -> tuple[np.ndarray, np.ndarray]:
        with self.lock:
            held = self.held.get(key)
        if held is None:
            return np.zeros((self.height, self.width, 3), dtype=np.uint8), np.zeros((self.height, self.width), bool)
        return held[0].copy(), held[1].copy()

    def pixels(self, key: str, wanted: np.ndarray, render: Render, rows: dict[int, np.ndarray]) -> np.ndarray:
        """The render ``key`` where ``wanted`` (``(H, W)`` bool) is True, as ``(H, W, 3)`` (other pixels unset):
        those kept, or in its kept ``rows`` (row number → its pixels), taken; the rest rendered by ``render`` and
        kept."""
        image, have = self._copy(key)
        for r, row in rows.items():
            image[r], have[r] = row, True
        todo = np.flatnonzero(wanted & ~have)
        if len(todo):
            image.reshape(-1, 3)[todo] = render(todo)
            have.reshape(-1)[todo] = True
            with self.lock:
                self.held[key] = (image, have)
        return image

    def rows(self, key: str, numbers: np.ndarray, render: Render) -> np.ndarray:
        """Rows ``numbers`` of the render ``key`` (``(len, W, 3)``): its pixels kept taken, only the rest rendered."""
        with self.lock:
            held = self.held.get(key)
        everything = (numbers[:, None] * self.width + np.arange(self.width)[None, :]).ravel()
        if held is None:
            return render(everything).reshape(len(numbers), self.width, 3)
        out = held[0][numbers].reshape(-1, 3).copy()
        missing = ~held[1][numbers].reshape(-1)
        if missing.any():
            out[missing] = render(everything[missing])
        return out.reshape(len(numbers), self.width, 3)

    def has(self, key: str) -> bool:
        with self.lock:
            return key in self.held

    def drop(self, key: str) -> None:
        """Lets go of the pixels of ``key`` (its whole image is kept now)."""
        with self.lock:
            self.held.pop(key, None)

    def arrays(self) -> list[np.ndarray]:
        with self.lock:
            return [a for pair in self.held.values() for a in pair]
