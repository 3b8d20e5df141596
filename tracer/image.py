"""From linear colour to stored 8-bit values and PNG bytes."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image


#: colours are summed in fixed point (:func:`tracer.render._accumulate`), a hair below their float value; a
#: value that lies on a rounding boundary (a background of 0.3 is 76.5 levels) still rounds up, as in float
NUDGE = 2.0**-22


def quantize(colour: np.ndarray) -> np.ndarray:
    """Clamp to [0, 1] and store ``floor(255·v + 0.5)``; NaN becomes 0. Same shape, uint8."""
    v = np.clip(np.nan_to_num(colour, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    return np.floor(255.0 * v + (0.5 + NUDGE)).astype(np.uint8)


def encode_png(pixels: np.ndarray) -> bytes:
    """An 8-bit RGB PNG of ``pixels (H, W, 3) uint8``; the same pixels always give the same bytes."""
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(pixels)).save(buf, format="PNG", compress_level=6)
    return buf.getvalue()


def decode_png(data: bytes) -> np.ndarray:
    """Pixels ``(H, W, 3) uint8`` of a PNG (any colour type, converted to RGB)."""
    with Image.open(io.BytesIO(data)) as img:
        return np.asarray(img.convert("RGB"))
