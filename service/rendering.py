"""Rendering a validated scene here or on a Dask cluster: the one place that chooses, for the command line,
the service and class grading alike."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from schemas import Scene
from tracer import render


def render_pixels(scene: Scene, client: Any = None, threads: int | None = None,
                  cancel: Callable[[], bool] | None = None,
                  progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """``(H, W, 3) uint8`` pixels of ``scene``: on the cluster of the Dask ``client`` (in bands, the same bytes),
    else here on ``threads`` threads.  ``cancel()`` true stops it with :class:`tracer.RenderCancelled`; an
    image beyond what phongray renders raises :class:`tracer.ImageTooLarge`."""
    if client is not None:
        from .cluster import render as render_on

        return render_on(client, scene.model_dump_json().encode(), scene.image.width, scene.image.height,
                         cancelled=cancel or (lambda: False))
    return render(scene, threads=threads, progress=progress, cancel=cancel)
