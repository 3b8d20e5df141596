"""From linear colour to stored 8-bit values and PNG bytes."""

from __future__ import annotations

import io
import struct
import zlib
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from PIL import ImageFile

#: colours are summed in fixed point (:meth:`tracer.film.Film.add`), a hair below their float value; a
#: value that lies on a rounding boundary (a background of 0.3 is 76.5 levels) still rounds up, as in float
NUDGE = 2.0**-22


def quantize(colour: np.ndarray) -> np.ndarray:
    """Clamp to [0, 1] and store ``floor(255·v + 0.5)``; NaN becomes 0. Same shape, uint8."""
    v = np.clip(np.nan_to_num(colour, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    return np.floor(255.0 * v + (0.5 + NUDGE)).astype(np.uint8)


def wrapped(colour: np.ndarray) -> np.ndarray:
    """:func:`quantize` of a student who does not clamp: ``floor(255·v + 0.5)`` kept modulo 256, as a cast of a
    larger integer to 8 bits keeps it (1.2 is 306, stored as 50); below 0 (never: light adds up) is 0, and NaN
    is 0. Same shape, uint8."""
    v = np.clip(np.nan_to_num(colour, nan=0.0, posinf=0.0, neginf=0.0), 0.0, 2.0**40)
    return (np.floor(255.0 * v + (0.5 + NUDGE)).astype(np.int64) & 0xFF).astype(np.uint8)


#: zlib level, chosen from ``phongray bench``'s PNG table: unfiltered rows at level 6 encode 1.5-3.3x faster than
#: Pillow's level 6 (adaptive row filters) on every bench image, and smaller on six of its eight; level 3 is
#: 2-3x faster again but up to twice the size, level 9 barely smaller and slower
PNG_LEVEL = 6
#: rows compressed at a time, so that encoding needs no second copy of a large image
PNG_BAND = 256
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_chunk(kind: bytes, data: bytes) -> bytes:
    """One PNG chunk: its length, ``kind``, ``data`` and their CRC-32."""
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(data, zlib.crc32(kind)))


def encode_png(pixels: np.ndarray, level: int = PNG_LEVEL) -> bytes:
    """An 8-bit RGB PNG of ``pixels (H, W, 3) uint8``; the same pixels always give the same bytes.

    Written here with zlib: no interlacing, every row with filter type 0
    (none), one IDAT chunk.  zlib releases the GIL while it compresses.
    """
    px = np.asarray(pixels)
    if px.ndim != 3 or px.shape[2] != 3 or px.dtype != np.uint8:
        raise ValueError(f"encode_png takes (H, W, 3) uint8 pixels, not {px.shape} {px.dtype}")
    h, w = px.shape[:2]
    if h < 1 or w < 1:
        raise ValueError(f"a PNG has at least one pixel, not {w}×{h}")
    z = zlib.compressobj(level)
    parts = []
    for top in range(0, h, PNG_BAND):
        band = px[top : top + PNG_BAND]
        rows = np.zeros((len(band), 1 + 3 * w), dtype=np.uint8)  # a leading 0 per row: filter type none
        rows[:, 1:] = band.reshape(len(band), 3 * w)
        parts.append(z.compress(rows.tobytes()))
    parts.append(z.flush())
    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)  # 8 bits per channel, RGB, deflate, no interlace
    return PNG_SIGNATURE + png_chunk(b"IHDR", header) + png_chunk(b"IDAT", b"".join(parts)) + png_chunk(b"IEND", b"")


#: compressed bytes handed to Pillow's inflater at a time: it holds the interpreter lock while it inflates, and
#: deflate expands a byte to at most about a kilobyte, so a call inflates at most about 4 MiB (a few ms) however
#: well the file compresses, and the server's other requests are not kept waiting behind one decode
DECODE_BLOCK = 4096


def open_png(data: bytes) -> ImageFile.ImageFile:
    """Pillow's image of PNG ``data``, not yet decoded, set to inflate :data:`DECODE_BLOCK` bytes at a time."""
    from PIL import Image  # only reading images needs Pillow; a render's start-up does without it

    img = Image.open(io.BytesIO(data))
    img.decodermaxblock = DECODE_BLOCK
    return img


#: the colour modes Pillow keeps at four bytes a pixel, and the layout of its raw buffer for each
RGBX_MODES = {"RGB": "RGBX", "RGBA": "RGBA"}


def decode_rgbx(img: ImageFile.ImageFile) -> np.ndarray:
    """Decode ``img`` (a :data:`RGBX_MODES` mode) into an array of its own: ``(H, W, 4) uint8``, RGBA or RGB and
    a padding byte.

    Pillow would allocate the image and zero it in one call that holds the interpreter lock: after a grade
    has handed its memory back to the OS, every page of a 4096×4096 image faults in during that call (50-100
    ms on a VM, while the server answers nothing else).  ``np.empty`` leaves the pages to fault in as the
    image is inflated, :data:`DECODE_BLOCK` bytes at a time; and no copy is made afterwards."""
    from PIL import Image

    pixels = np.empty((img.size[1], img.size[0], 4), np.uint8)
    target = Image.frombuffer(img.mode, img.size, pixels, "raw", RGBX_MODES[img.mode], 0, 1).im
    img.im = target
    img.load()
    if img.im is not target:  # a Pillow that decodes into memory of its own
        return np.asarray(img.convert("RGBA"))
    return pixels


def decode_png(data: bytes) -> np.ndarray:
    """Pixels ``(H, W, 3) uint8`` of a PNG (any colour type, converted to RGB)."""
    with open_png(data) as img:
        return np.asarray(img.convert("RGB"))
