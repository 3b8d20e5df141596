"""Render passes as files: a PNG to look at, or the values themselves as a NumPy ``.npy`` array.

The tracer gives each pass as numbers (:mod:`tracer.passes`); this module
chooses how they are shown, the same for ``phongray render --pass`` and
``POST /render?pass=``:

* the additive terms (``background``, ``ambient``, ``diffuse``, ``specular``,
  ``reflection``, ``refraction``) are stored as the image is: clamped to
  [0, 1], ``floor(255·v + 0.5)``;
* ``shadow``: the fraction of the light's samples that reach the first hit,
  black (none) to white (all);
* ``normal``: each component from −1..1 to 0..255 (``(n + 1) / 2``), the usual
  normal-map colours; pixels that hit nothing are black;
* ``depth``: white at the nearest hit to dark grey (48) at the farthest,
  linear in log t (a floor to the horizon still shows its near part); black
  for nothing hit;
* ``object``: a colour per object index (the same index, the same colour in
  every scene), black for nothing hit.

As ``.npy`` (``format=npy``, ``-o FILE.npy``) the values are the tracer's own:
float64 ``(H, W, 3)`` for the additive terms and the normal, float64
``(H, W)`` for shadow and depth (inf where nothing is hit), int64 ``(H, W)``
for object (−1 where nothing is hit).  The additive terms sum to the image's
linear value, before it is clamped.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from typing import Literal

import numpy as np

from schemas import Scene
from tracer import Renderer, encode_png
from tracer.budget import UNLIMITED, Budget
from tracer.image import quantize
from tracer.passes import ADDITIVE, LIGHT_TERMS, NAMES

Format = Literal["png", "npy"]
#: the darkest grey of a depth pass (the farthest hit); black is kept for nothing hit
FAR_GREY = 48.0
#: the golden-ratio step between the hues of consecutive object indices
HUE_STEP = 0.6180339887498949


#: the passes that can be of one light (``light=K``)
OF_A_LIGHT = (*LIGHT_TERMS, "shadow")


def check(scene: Scene, name: str, light: int | None) -> None:
    """ValueError for a light asked of a pass that has none, or of a light whose pass would be black for want
    of the term (an ambient light has no diffuse, specular or shadow)."""
    if light is None or not 0 <= light < len(scene.lights):
        return  # (every light; or one the scene does not have, which the tracer names)
    if name not in OF_A_LIGHT:
        raise ValueError(f"light: the {name} pass is the whole scene's, not a light's (only {', '.join(OF_A_LIGHT)} "
                         f"take a light)")
    if scene.lights[light].type == "ambient":
        raise ValueError(f"light: lights[{light}] is an ambient light, which has no {name} (it lights every point "
                         f"alike, unshadowed, in the ambient pass); choose another light, or no light")


def values(scene: Scene, name: str, light: int | None = None, threads: int | None = None,
           cancel: Callable[[], bool] | None = None, budget: Budget = UNLIMITED) -> np.ndarray:
    """The pass ``name`` of ``scene`` (of light ``light`` alone where that applies), as the tracer gives it,
    within ``budget`` (else :class:`tracer.OverBudget`).  ValueError names an unknown pass, a light the scene
    does not have, or a light the pass cannot be of."""
    check(scene, name, light)
    wanted = [name, "object"] if name in ("normal", "depth") else [name]
    out = Renderer(scene).passes(wanted, light, threads=threads, cancel=cancel, budget=budget)
    if name == "normal":  # nothing hit: no normal (the tracer leaves zeros there)
        return np.where((out["object"] >= 0)[..., None], out["normal"], 0.0)
    return out[name]


def pixels(name: str, data: np.ndarray) -> np.ndarray:
    """``(H, W, 3) uint8`` pixels that show pass ``name``'s values ``data``."""
    if name not in NAMES:
        raise ValueError(f"pass: unknown pass '{name}' (one of {', '.join(NAMES)})")
    if name in ADDITIVE:
        return quantize(data)
    if name == "shadow":
        return np.repeat(quantize(data)[..., None], 3, axis=2)
    if name == "normal":
        shown = quantize((data + 1.0) / 2.0)
        return np.where(np.any(data != 0, axis=2)[..., None], shown, 0).astype(np.uint8)
    if name == "depth":
        hit = np.isfinite(data)
        grey = np.zeros(data.shape)
        if hit.any():
            logs = np.log(np.maximum(data[hit], np.finfo(np.float64).tiny))
            near, far = float(logs.min()), float(logs.max())
            span = far - near
            scaled = (logs - near) / span if span > 0 else np.zeros(len(logs))
            grey[hit] = 255.0 - (255.0 - FAR_GREY) * scaled
        return np.repeat(np.floor(grey + 0.5).astype(np.uint8)[..., None], 3, axis=2)
    return object_colours(data)


def object_colours(index: np.ndarray) -> np.ndarray:
    """A bright colour per object index (hues a golden-ratio step apart), black for −1."""
    hue = (index.astype(np.float64) * HUE_STEP) % 1.0
    k = (np.array([5.0, 3.0, 1.0]) + hue[..., None] * 6.0) % 6.0  # HSV to RGB at saturation 0.65, value 0.95
    rgb = 0.95 - 0.95 * 0.65 * np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0)
    return np.where((index >= 0)[..., None], quantize(rgb), 0).astype(np.uint8)


def encoded(name: str, data: np.ndarray, fmt: Format) -> bytes:
    """A pass's values as a PNG to look at, or as ``.npy`` bytes (no pickles: plain arrays only)."""
    if fmt == "npy":
        buf = io.BytesIO()
        np.save(buf, np.ascontiguousarray(data), allow_pickle=False)
        return buf.getvalue()
    return encode_png(pixels(name, data))
