"""A small line plot drawn with Pillow: time (log scale) against error."""

from __future__ import annotations

import math

from PIL import Image, ImageDraw

COLOURS = [(200, 60, 40), (40, 120, 200), (40, 160, 80), (150, 80, 170)]


def _ticks(lo: float, hi: float) -> list[float]:
    out, p = [], math.floor(math.log10(lo))
    while 10**p <= hi * 1.0001:
        for m in (1, 2, 5):
            v = m * 10**p
            if lo <= v <= hi:
                out.append(v)
        p += 1
    return out


def plot(
    series: list[tuple[str, list[tuple[float, float, str]]]],
    title: str,
    xlabel: str,
    ylabel: str,
    path: str,
    size: tuple[int, int] = (720, 440),
) -> None:
    """``series``: (label, [(x, y, annotation), ...]); x is drawn on a log scale.

    Pillow's built-in font has no "×", so labels spell it "x".
    """
    title = title.replace("×", "x")
    series = [(label.replace("×", "x"), pts) for label, pts in series]
    w, h = size
    left, right, top, bottom = 70, 20, 40, 50
    img = Image.new("RGB", size, "white")
    draw = ImageDraw.Draw(img)
    xs = [p[0] for _, pts in series for p in pts]
    ys = [p[1] for _, pts in series for p in pts]
    x_lo, x_hi = min(xs) / 1.3, max(xs) * 1.3
    y_hi = max(ys) * 1.1 or 1.0

    def at(x: float, y: float) -> tuple[float, float]:
        fx = (math.log10(x) - math.log10(x_lo)) / (math.log10(x_hi) - math.log10(x_lo))
        return left + fx * (w - left - right), h - bottom - (y / y_hi) * (h - top - bottom)

    draw.rectangle([left, top, w - right, h - bottom], outline="black")
    for x in _ticks(x_lo, x_hi):
        px, _ = at(x, 0)
        draw.line([px, h - bottom, px, h - bottom + 5], fill="black")
        draw.text((px - 12, h - bottom + 8), f"{x:g}", fill="black")
    for k in range(6):
        y = y_hi * k / 5
        _, py = at(x_lo, y)
        draw.line([left - 5, py, left, py], fill="black")
        draw.text((5, py - 6), f"{y:.3g}", fill="black")
    draw.text((left, 12), title, fill="black")
    draw.text(((w - len(xlabel) * 6) / 2, h - 18), xlabel, fill="black")
    draw.text((left + 5, top + 4), ylabel, fill=(90, 90, 90))
    for i, (label, pts) in enumerate(series):
        colour = COLOURS[i % len(COLOURS)]
        coords = [at(x, y) for x, y, _ in pts]
        if len(coords) > 1:
            draw.line(coords, fill=colour, width=2)
        for (px, py), (_, _, note) in zip(coords, pts):
            draw.ellipse([px - 3, py - 3, px + 3, py + 3], fill=colour)
            draw.text((px + 5, py - 14), note, fill=colour)
        draw.text((w - right - 200, top + 8 + 14 * i), label, fill=colour)
    img.save(path)
