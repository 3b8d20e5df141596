"""Heat-maps of a submission against its reference: the verdict's own pixels, or the raw difference.

The *verdict* heat-map shows what decided the grade.  On the reference, dimmed
to grey, it marks every pixel that is *off even nearby* (the pixels the verdict
counts) in orange where the submission is brighter and in blue where it is
darker, and the pixels that are off but forgiven (a pixel in their 3×3
neighbourhood matches, both ways) in light grey.  A passing one-pixel shift is then a
few grey edges, not a wall of colour.  The *raw* heat-map is the per-pixel
difference itself, black where equal, through red and yellow to white at 64+
levels.  Both are the image's own size; :func:`with_legend` adds a band
beneath that says what the colours mean.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from tracer.image import encode_png

from .grading import BAND, _largest, nearby_difference, planes

Kind = Literal["verdict", "raw"]

#: the colours of the verdict heat-map, with what they mean (the legend of the PNG, the report and the playground)
BRIGHTER = (255, 128, 0)
DARKER = (0, 136, 255)
FORGIVEN = (200, 200, 200)
LEGEND = [
    (BRIGHTER, "off even nearby: brighter than the reference"),
    (DARKER, "off even nearby: darker than the reference"),
    (FORGIVEN, "off, but forgiven: a neighbour matches"),
    ((60, 60, 60), "within the tolerance (the reference, dimmed)"),
]
RAW_LEGEND = [
    ((0, 0, 0), "equal"),
    ((255, 0, 0), "21 levels off"),
    ((255, 255, 0), "43 levels off"),
    ((255, 255, 255), "64 or more levels off"),
]


def verdict_pixels(reference: np.ndarray, submitted: np.ndarray, tolerance: float) -> np.ndarray:
    """``(H, W, 3) uint8``: the verdict heat-map of two ``(H, W, 3) uint8`` images."""
    h, w, _ = reference.shape
    out = np.empty((h, w, 3), dtype=np.uint8)
    for top in range(0, h, BAND):
        bottom = min(top + BAND, h)
        ref, sub = planes(reference[top:bottom]), planes(submitted[top:bottom])
        grey = (ref.astype(np.uint16).sum(axis=0) // 10).astype(np.uint8)  # 0–76: the scene, dimmed
        band = np.repeat(grey[:, :, None], 3, axis=2)
        off = _largest(ref, sub) > tolerance
        if off.any():
            decisive = nearby_difference(reference, submitted, top, bottom) > tolerance
            sign = sub.astype(np.int16).sum(axis=0) - ref.astype(np.int16).sum(axis=0)
            band[off & ~decisive] = FORGIVEN
            band[decisive & (sign >= 0)] = BRIGHTER
            band[decisive & (sign < 0)] = DARKER
        out[top:bottom] = band
    return out


def raw_pixels(reference: np.ndarray, submitted: np.ndarray) -> np.ndarray:
    """``(H, W, 3) uint8``: the largest channel difference per pixel, black → red → yellow → white at 64 levels."""
    h, w, _ = reference.shape
    out = np.empty((h, w, 3), dtype=np.uint8)
    for top in range(0, h, BAND):
        diff = _largest(planes(reference[top : top + BAND]), planes(submitted[top : top + BAND]))
        x = np.clip(diff / 64.0, 0.0, 1.0)
        rgb = np.stack([np.clip(3 * x, 0, 1), np.clip(3 * x - 1, 0, 1), np.clip(3 * x - 2, 0, 1)], axis=2)
        out[top : top + BAND] = np.floor(255 * rgb + 0.5)
    return out


#: the legend band: a row of this many pixels per entry, and at least this wide
ROW = 16
LEGEND_WIDTH = 300


def with_legend(pixels: np.ndarray, kind: Kind = "verdict") -> np.ndarray:
    """The heat-map with a band beneath it that names each colour (the image keeps its place at the top left;
    the canvas is widened to fit the text if the image is narrow)."""
    from PIL import Image, ImageDraw, ImageFont

    entries = LEGEND if kind == "verdict" else RAW_LEGEND
    h, w, _ = pixels.shape
    width = max(w, LEGEND_WIDTH)
    canvas = Image.new("RGB", (width, h + ROW * len(entries) + 4), (255, 255, 255))
    canvas.paste(Image.fromarray(pixels), (0, 0))
    draw = ImageDraw.Draw(canvas)
    font = ImageFont.load_default(size=11)
    for i, (colour, text) in enumerate(entries):
        y = h + 3 + ROW * i
        draw.rectangle((4, y + 2, 15, y + 12), fill=colour, outline=(0, 0, 0))
        draw.text((21, y), text, fill=(0, 0, 0), font=font)
    return np.asarray(canvas)


def heatmap_png(
    reference: np.ndarray, submitted: np.ndarray, tolerance: float, kind: Kind = "verdict", legend: bool = False
) -> bytes:
    """The heat-map of ``kind`` as PNG bytes, with its legend band when ``legend``."""
    pixels = verdict_pixels(reference, submitted, tolerance) if kind == "verdict" else raw_pixels(reference, submitted)
    return encode_png(with_legend(pixels, kind) if legend else pixels)
