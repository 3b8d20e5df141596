"""Render passes as files: a PNG to look at, or the values themselves as a NumPy ``.npy`` array.

The tracer gives each pass as numbers (:mod:`tracer.shade.passes`); this module
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
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Literal

import numpy as np

from schemas import Scene, load_scene
from tracer import Renderer, encode_png
from tracer.budget import UNLIMITED, Budget
from tracer.image import quantize
from tracer.render import CHUNK_RAYS
from tracer.shade.passes import ADDITIVE, LIGHT_TERMS, NAMES

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
        raise ValueError(
            f"light: the {name} pass is the whole scene's, not a light's (only {', '.join(OF_A_LIGHT)} take a light)"
        )
    if scene.lights[light].type == "ambient":
        raise ValueError(
            f"light: lights[{light}] is an ambient light, which has no {name} (it lights every point "
            f"alike, unshadowed, in the ambient pass); choose another light, or no light"
        )


#: bytes per pixel of each pass's values (float64, three channels or one; object int64)
VALUE_BYTES = {**{name: 24 for name in ADDITIVE}, "normal": 24, "shadow": 8, "depth": 8, "object": 8}
#: rows a PNG of a pass is made from at a time (so that its conversion holds no full-size temporaries)
PNG_ROWS = 256
#: bytes of an answer handed to the connection at a time
CHUNK_BYTES = 1 << 20


def price(scene: Scene, name: str, fmt: Format) -> int:
    """The most bytes making pass ``name`` of ``scene`` as ``fmt`` holds at once: its values, the object pass a
    normal or a depth pass is rendered with, for a PNG its pixels and (at worst) the file, and a few chunks'
    tallies (:data:`tracer.render.CHUNK_RAYS` sub-samples on each core, about a kilobyte each)."""
    pixels = scene.image.width * scene.image.height
    held = pixels * VALUE_BYTES.get(name, 24)
    if name in ("normal", "depth"):
        held += pixels * 8
    if fmt == "png":
        held += pixels * 3 * 2 + 3 * PNG_ROWS * scene.image.width * 8 * 4
    return held + 2 * CHUNK_RAYS * 1024


def values(
    scene: Scene,
    name: str,
    light: int | None = None,
    threads: int | None = None,
    cancel: Callable[[], bool] | None = None,
    budget: Budget = UNLIMITED,
) -> np.ndarray:
    """The pass ``name`` of ``scene`` (of light ``light`` alone where that applies), as the tracer gives it,
    within ``budget`` (else :class:`tracer.OverBudget`).  ValueError names an unknown pass, a light the scene
    does not have, or a light the pass cannot be of."""
    check(scene, name, light)
    wanted = [name, "object"] if name in ("normal", "depth") else [name]
    out = Renderer(scene).passes(wanted, light, threads=threads, cancel=cancel, budget=budget)
    if name == "normal":  # nothing hit: no normal (the tracer leaves zeros there), in place
        out["normal"][out["object"] < 0] = 0.0
    return out[name]


@dataclass(frozen=True)
class PassFile:
    """A pass as a file: ``head`` then ``body`` (a ``.npy`` header and the array's own memory, or a PNG), sent a
    chunk at a time (:meth:`chunks`) without a joined copy."""

    head: bytes
    body: np.ndarray | bytes
    media: str

    @property
    def size(self) -> int:
        return len(self.head) + (self.body.nbytes if isinstance(self.body, np.ndarray) else len(self.body))

    def chunks(self, size: int = CHUNK_BYTES) -> Iterator[bytes]:
        if self.head:
            yield self.head
        raw = self.body.reshape(-1).view(np.uint8).data if isinstance(self.body, np.ndarray) else memoryview(self.body)
        for start in range(0, len(raw), size):
            yield bytes(raw[start : start + size])

    def joined(self) -> bytes:
        """The whole file as one ``bytes`` (the command line writes it; the cache keeps small ones)."""
        return b"".join(self.chunks())


def pixels(name: str, data: np.ndarray) -> np.ndarray:
    """``(H, W, 3) uint8`` pixels that show pass ``name``'s values ``data``, made :data:`PNG_ROWS` rows at a time
    (each pixel is shown alone; a depth pass's grey scale spans the whole image's hits)."""
    if name not in NAMES:
        raise ValueError(f"pass: unknown pass '{name}' (one of {', '.join(NAMES)})")
    span = _depth_span(data) if name == "depth" else None
    out = np.empty((*data.shape[:2], 3), dtype=np.uint8)
    for top in range(0, data.shape[0], PNG_ROWS):
        out[top : top + PNG_ROWS] = _shown(name, data[top : top + PNG_ROWS], span)
    return out


def _depth_span(data: np.ndarray) -> tuple[float, float] | None:
    """The log t of the nearest and the farthest hit of a depth pass (None: nothing hit): log grows with t, so
    taken band by band, the least and the greatest of the logs."""
    near = far = None
    for top in range(0, data.shape[0], PNG_ROWS):
        band = data[top : top + PNG_ROWS]
        hit = band[np.isfinite(band)]
        if len(hit):  # (the logs as the band's pixels take them below)
            logs = np.log(np.maximum(hit, np.finfo(np.float64).tiny))
            low, high = float(logs.min()), float(logs.max())
            near, far = (low, high) if near is None or far is None else (min(near, low), max(far, high))
    return None if near is None or far is None else (near, far)


def _shown(name: str, data: np.ndarray, span: tuple[float, float] | None) -> np.ndarray:
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
        if hit.any() and span is not None:
            logs = np.log(np.maximum(data[hit], np.finfo(np.float64).tiny))
            near, far = span
            width = far - near
            scaled = (logs - near) / width if width > 0 else np.zeros(len(logs))
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
    return as_file(name, data, fmt).joined()


def as_file(name: str, data: np.ndarray, fmt: Format) -> PassFile:
    """A pass's values as a PNG, or as a ``.npy`` file whose body is the array itself (no copy of it): the
    header :func:`numpy.save` writes, then the array's bytes in C order."""
    if fmt == "npy":
        array = np.ascontiguousarray(data)
        head = io.BytesIO()
        np.lib.format.write_array_header_1_0(head, np.lib.format.header_data_from_array_1_0(array))
        return PassFile(head.getvalue(), array, "application/x-npy")
    return PassFile(b"", encode_png(pixels(name, data)), "image/png")


def pass_task(scene: bytes, name: str, light: int | None, fmt: Format, seconds: float) -> bytes:
    """A pass file made on a Dask worker (:meth:`service.work.jobs.RenderService.pass_file`), stopped ``seconds``
    after its start there (:class:`tracer.RenderCancelled`, as the service's own render stops)."""
    deadline = time.monotonic() + seconds
    return encoded(name, values(load_scene(scene), name, light, 1, lambda: time.monotonic() > deadline), fmt)
