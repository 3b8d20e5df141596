"""Comparing a submitted image with the reference render: the numbers and the verdict.

Differences are in 8-bit levels (0–255).  A pixel is *off* when its largest
channel difference exceeds the tolerance; it is *off even nearby* when no
reference pixel in its 3×3 neighbourhood is within the tolerance, which
forgives anti-aliasing and one-pixel edge shifts.  A submission passes when
the fraction of pixels off even nearby is at most ``max_fraction``.
"""

from __future__ import annotations

import io
import math
from dataclasses import asdict, dataclass

import numpy as np
from PIL import Image

from tracer.image import encode_png

DEFAULT_TOLERANCE = 2.0
DEFAULT_MAX_FRACTION = 0.001


class ImageError(ValueError):
    """A submitted image that cannot be graded (not a PNG, corrupt, wrong size)."""


@dataclass(frozen=True)
class Grade:
    passed: bool
    tolerance: float
    max_fraction: float
    mean_abs_error: float
    rmse: float
    psnr: float | None  # None for identical images (infinite PSNR)
    max_error: int
    fraction_off: float
    fraction_off_nearby: float
    width: int
    height: int
    reference_sha256: str

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def read_submission(data: bytes, expected: tuple[int, int], max_bytes: int) -> np.ndarray:
    """Decode a submitted PNG of ``expected = (width, height)`` safely: the size is checked before decoding."""
    if len(data) > max_bytes:
        raise ImageError(f"image is {len(data)} bytes, more than the limit of {max_bytes}")
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        raise ImageError("image is not a PNG")
    if len(data) < 24 or data[12:16] != b"IHDR":
        raise ImageError("image is truncated or corrupt (no IHDR header)")
    declared = (int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big"))
    if declared != expected:  # checked on the header, before anything is decompressed
        raise ImageError(f"image is {declared[0]}×{declared[1]} pixels, the scene is {expected[0]}×{expected[1]}")
    try:
        with Image.open(io.BytesIO(data)) as img:
            if img.format != "PNG":
                raise ImageError("image is not a PNG")
            if img.size != expected:
                raise ImageError(f"image is {img.size[0]}×{img.size[1]} pixels, the scene is "
                                 f"{expected[0]}×{expected[1]}")
            img.load()
            return np.asarray(img.convert("RGB"))
    except ImageError:
        raise
    except Exception as exc:  # Pillow raises many kinds for broken files
        raise ImageError(f"image is truncated or corrupt ({type(exc).__name__})") from None


def _difference(reference: np.ndarray, submitted: np.ndarray) -> np.ndarray:
    return np.abs(reference.astype(np.int16) - submitted.astype(np.int16)).max(axis=2)


def _nearby_difference(reference: np.ndarray, submitted: np.ndarray) -> np.ndarray:
    """Per pixel, the smallest largest-channel difference to any reference pixel in the 3×3 neighbourhood."""
    h, w, _ = reference.shape
    padded = np.pad(reference.astype(np.int16), ((1, 1), (1, 1), (0, 0)), mode="edge")
    sub = submitted.astype(np.int16)
    best = np.full((h, w), 255, dtype=np.int16)
    for dy in range(3):
        for dx in range(3):
            diff = np.abs(padded[dy:dy + h, dx:dx + w] - sub).max(axis=2)
            np.minimum(best, diff, out=best)
    return best


def grade(reference: np.ndarray, submitted: np.ndarray, reference_sha256: str,
          tolerance: float = DEFAULT_TOLERANCE, max_fraction: float = DEFAULT_MAX_FRACTION) -> Grade:
    diff = _difference(reference, submitted)
    channels = np.abs(reference.astype(np.float64) - submitted.astype(np.float64))
    mse = float(np.mean(channels**2))
    nearby = float(np.mean(_nearby_difference(reference, submitted) > tolerance))
    return Grade(
        passed=nearby <= max_fraction,
        tolerance=tolerance, max_fraction=max_fraction,
        mean_abs_error=float(np.mean(channels)), rmse=math.sqrt(mse),
        psnr=None if mse == 0 else 10 * math.log10(255.0**2 / mse),
        max_error=int(diff.max()), fraction_off=float(np.mean(diff > tolerance)),
        fraction_off_nearby=nearby, width=reference.shape[1], height=reference.shape[0],
        reference_sha256=reference_sha256,
    )


def heatmap(reference: np.ndarray, submitted: np.ndarray) -> bytes:
    """A PNG of the per-pixel difference: black where equal, through red and yellow to white at 64+ levels."""
    x = np.clip(_difference(reference, submitted) / 64.0, 0.0, 1.0)
    rgb = np.stack([np.clip(3 * x, 0, 1), np.clip(3 * x - 1, 0, 1), np.clip(3 * x - 2, 0, 1)], axis=2)
    return encode_png(np.floor(255 * rgb + 0.5).astype(np.uint8))
