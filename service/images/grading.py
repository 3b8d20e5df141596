"""Comparing a submitted image with the reference render: the numbers and the verdict.

Differences are in 8-bit levels (0–255).  A pixel is *off* when its largest
channel difference exceeds the tolerance; it is *off even nearby* when, one
way or the other, nothing in its 3×3 neighbourhood matches within the
tolerance: the submitted pixel matches no reference pixel around it, or the
reference pixel is matched by no submitted pixel around it (:mod:`.nearby`).
That forgives anti-aliasing and one-pixel edge shifts, and not a thin
highlight that vanished.  A submission passes when the fraction of pixels off
even nearby is at most ``max_fraction`` and at most :data:`GROSS_ALLOWED` of
them are *grossly off*: more than :data:`GROSS_LEVELS` levels from anything
around them, as a colour that wrapped around instead of clamping is.  Pixels
the format leaves open (``open_pixels``) are not counted.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from tracer.image import RGBX_MODES, decode_rgbx, open_png

from . import ppm
from .figures import percent
from .nearby import BAND, distance, planes

if TYPE_CHECKING:
    from PIL import Image, ImageFile

DEFAULT_TOLERANCE = 2.0
DEFAULT_MAX_FRACTION = 0.001
#: a pixel off even nearby by more than this many levels is *grossly off*: no honest tracer's rounding, edge
#: or offset puts a pixel this far from everything around it (calibrated by tests/grade_matrix.py)
GROSS_LEVELS = 128
#: at most this many pixels may be grossly off, whatever the fraction allows
GROSS_ALLOWED = 0


class ImageError(ValueError):
    """A submitted image that cannot be graded (not a PNG or a PPM, corrupt, wrong size)."""


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
    grossly_off: int = 0  # pixels off even nearby by more than GROSS_LEVELS
    open_pixels: int = 0  # pixels the format leaves open, not counted

    def as_dict(self) -> dict[str, object]:
        return asdict(self)

    @property
    def reason(self) -> str:
        """Why it failed, in words (empty when it passed)."""
        if self.passed:
            return ""
        if self.fraction_off_nearby <= self.max_fraction:
            which = "1 pixel is" if self.grossly_off == 1 else f"{self.grossly_off} pixels are"
            return (
                f"{which} grossly off: more than {GROSS_LEVELS} levels from everything around them (a dot or "
                f"speckle of the wrong colour); at most {GROSS_ALLOWED} may be"
            )
        return (
            f"{percent(self.fraction_off_nearby)} of the pixels are off even nearby (nothing around them within "
            f"{self.tolerance:g} levels, one way or the other); at most {percent(self.max_fraction)} may be"
        )


def read_submission(data: bytes, expected: tuple[int, int]) -> np.ndarray:
    """Decode a submitted PNG or PPM (:mod:`service.images.ppm`) of ``expected = (width, height)`` safely: the size is
    checked on the header, before anything is decompressed or decoded, so the decoded pixels are bounded by the
    scene's size.

    A submission must be opaque: an alpha channel is accepted only when every pixel's alpha is full (a
    render has no transparent pixels, and what a transparent one should be compared as is a guess)."""
    declared = declared_size(data)
    if declared != expected:  # checked on the header, before anything is decompressed
        raise ImageError(f"image is {declared[0]}×{declared[1]} pixels, the scene is {expected[0]}×{expected[1]}")
    if ppm.is_ppm(data):
        try:
            return ppm.pixels(data, ppm.header(data))
        except ppm.PpmError as exc:
            raise ImageError(str(exc)) from None
    try:
        with open_png(data) as img:
            if img.format != "PNG":
                raise ImageError("image is not a PNG")
            if img.size != expected:
                raise ImageError(
                    f"image is {img.size[0]}×{img.size[1]} pixels, the scene is {expected[0]}×{expected[1]}"
                )
            low = _low_bytes(data, img)
            if img.mode in RGBX_MODES and "transparency" not in img.info:
                pixels = _scaled(decode_rgbx(img), low)
                if img.mode == "RGBA":
                    _opaque(pixels[:, :, 3])
                return np.ascontiguousarray(pixels[:, :, :3])
            img.load()
            if img.mode in WIDE_GRAY:
                return _wide_gray(img)
            if "A" in img.getbands() or "transparency" in img.info:
                rgba = _scaled(np.asarray(img.convert("RGBA")), low)
                _opaque(rgba[:, :, 3])
                return np.ascontiguousarray(rgba[:, :, :3])
            return _scaled(np.asarray(img.convert("RGB")), low)
    except ImageError:
        raise
    except Exception:  # Pillow raises many kinds for broken files
        raise ImageError(CORRUPT) from None


#: the modes Pillow gives a 16-bit grayscale PNG (by version and byte order); Pillow's own conversion to 8 bits
#: clips their values at 255, so they are scaled here
WIDE_GRAY = ("I;16", "I;16B", "I;16L", "I;16N", "I")
#: 16-bit colour layouts that Pillow decodes to 8 bits by each value's high byte, and the layout of the same
#: decoder that gives the low bytes: with both, a value v becomes round(v / 257) exactly
LOW_BYTES = {"RGB;16B": "RGB;16L", "RGBA;16B": "RGBA;16L"}


#: round(v / 257) for every 16-bit level v (257 is odd: no value lies halfway), so that converting an image is
#: one table lookup per value rather than a division
LEVELS = ((2 * np.arange(65536, dtype=np.uint32) + 257) // 514).astype(np.uint8)


def _to_8bit(wide: np.ndarray) -> np.ndarray:
    """16-bit levels (0–65535) to 8-bit ones, round(v / 257): 65535 is 255, and v·257 is v (never clipped)."""
    return LEVELS[np.clip(wide, 0, 65535)]


def _wide_gray(img: Image.Image) -> np.ndarray:
    """A 16-bit grayscale image as 8-bit RGB; a ``tRNS`` grey level (transparent pixels) is refused."""
    wide = np.asarray(img)
    if "transparency" in img.info:
        _opaque(np.where(wide == img.info["transparency"], 0, 255).astype(np.uint8))
    gray = _to_8bit(wide)
    return np.repeat(gray[:, :, None], 3, axis=2)


def _low_bytes(data: bytes, img: ImageFile.ImageFile) -> np.ndarray | None:
    """For a 16-bit colour PNG, the low byte of every value (decoded a second time); None for other PNGs."""
    tiles = getattr(img, "tile", [])
    if len(tiles) != 1 or tiles[0].args not in LOW_BYTES:
        return None
    with open_png(data) as again:
        again.tile = [again.tile[0]._replace(args=LOW_BYTES[tiles[0].args])]
        return decode_rgbx(again) if again.mode in RGBX_MODES else np.asarray(again.convert("RGBA"))


def _scaled(high: np.ndarray, low: np.ndarray | None) -> np.ndarray:
    """The 8-bit values of a 16-bit image from Pillow's high bytes and :func:`_low_bytes` (as is without them).

    Converted :data:`BAND` rows at a time in 16-bit integers: a 4096×4096 RGBA image is tens of short NumPy
    calls rather than a few long ones, so the server's other requests are not kept waiting behind it."""
    if low is None or low.shape != high.shape:
        return high
    out = np.empty(high.shape, np.uint8)
    for top in range(0, high.shape[0], BAND):
        rows = slice(top, top + BAND)
        wide = high[rows].astype(np.uint16) << 8
        wide |= low[rows]
        out[rows] = LEVELS[wide]
    return out


#: what a PNG whose data cannot be decoded is told (whichever of Pillow's many errors it raised)
CORRUPT = "image is truncated or corrupt: its data ends early or is damaged; export it again as a PNG"


def declared_size(data: bytes, max_pixels: int | None = None) -> tuple[int, int]:
    """``(width, height)`` as a PNG's or a PPM's header declares it, before anything is decompressed or decoded;
    :class:`ImageError` for what is neither (naming the format it is, where known), a broken PPM header, or a
    size of more than ``max_pixels``."""
    if not data:
        raise ImageError("image is empty (0 bytes)")
    if ppm.is_ppm(data):
        try:
            head = ppm.header(data)
        except ppm.PpmError as exc:
            raise ImageError(str(exc)) from None
        size = (head.width, head.height)
    elif not data.startswith(b"\x89PNG\r\n\x1a\n"):
        kind = sniff(data)
        raise ImageError(f"image is {kind}; {REQUIRED}" if kind else f"image is not a PNG or a PPM; {REQUIRED}")
    elif len(data) < 24 or data[12:16] != b"IHDR":
        raise ImageError("image is truncated or corrupt: it ends before its PNG header; export it again as a PNG")
    else:
        size = (int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big"))
    if max_pixels is not None and size[0] * size[1] > max_pixels:
        raise ImageError(f"image is {size[0]}×{size[1]} pixels, more than the {max_pixels} phongray compares")
    return size


#: what a submission must be, said after what it is
REQUIRED = "PNG or PPM required"
#: how other image formats begin, so that a submission in one of them is named as what it is
SIGNATURES = (
    (b"P1", "a PBM (black and white Netpbm)"),
    (b"P4", "a PBM (black and white Netpbm)"),
    (b"P2", "a PGM (greyscale Netpbm)"),
    (b"P5", "a PGM (greyscale Netpbm)"),
    (b"P7", "a PAM (Netpbm)"),
    (b"\xff\xd8\xff", "a JPEG"),
    (b"GIF87a", "a GIF"),
    (b"GIF89a", "a GIF"),
    (b"BM", "a BMP"),
    (b"II*\x00", "a TIFF"),
    (b"MM\x00*", "a TIFF"),
    (b"%PDF", "a PDF"),
    (b"\x00\x00\x00\x0cjP  ", "a JPEG 2000"),
)


def sniff(data: bytes) -> str | None:
    """What kind of image other than PNG or PPM ``data`` is (``"a JPEG"``), from its first bytes; None if unknown."""
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return "a WebP"
    if data[4:12] in (b"ftypheic", b"ftypheix", b"ftypmif1", b"ftypavif"):
        return "a HEIF/AVIF"
    return next((kind for head, kind in SIGNATURES if data.startswith(head)), None)


def _opaque(alpha: np.ndarray) -> None:
    clear = alpha < 255
    count = int(np.count_nonzero(clear))
    if count:
        y, x = (int(v) for v in np.argwhere(clear)[0])
        which = "1 pixel that is" if count == 1 else f"{count} pixels that are"
        where = "at" if count == 1 else "the first at"
        raise ImageError(
            f"image has {which} not fully opaque ({where} x = {x}, y = {y}); "
            f"submit an opaque PNG (no alpha channel, or alpha 255 everywhere)"
        )


def _absdiff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.maximum(a, b) - np.minimum(a, b)  # |a − b| in uint8, without widening


def _largest(ref: np.ndarray, sub: np.ndarray) -> np.ndarray:
    """Per pixel, the largest channel difference of two (3, h, w) planes."""
    return np.maximum(np.maximum(_absdiff(ref[0], sub[0]), _absdiff(ref[1], sub[1])), _absdiff(ref[2], sub[2]))


def nearby_difference(reference: np.ndarray, submitted: np.ndarray, top: int, bottom: int) -> np.ndarray:
    """For rows ``top:bottom``, per pixel the nearby distance both ways (:func:`service.images.nearby.distance`) of two
    whole ``(H, W, 3) uint8`` images."""
    return distance(reference, reference, submitted, top, bottom)


@dataclass(frozen=True)
class Counts:
    """What a comparison counts of the pixels: off even nearby, and grossly off (neither where left open)."""

    off_nearby: int
    grossly_off: int


def count_off(near: np.ndarray, tolerance: float, open_rows: np.ndarray | None) -> Counts:
    """The pixels of nearby distances ``near`` off even nearby and grossly off, ``open_rows`` (the same shape,
    True: left open by the format) not counted."""
    if open_rows is not None:
        near = np.where(open_rows, 0, near)
    return Counts(int(np.count_nonzero(near > tolerance)), int(np.count_nonzero(near > GROSS_LEVELS)))


def range_counts(
    renders: list[np.ndarray], submitted: np.ndarray, tolerance: float, open_pixels: np.ndarray | None = None
) -> Counts:
    """The pixels of ``submitted`` off even nearby, and grossly off, against the range of ``renders`` (each
    ``(H, W, 3) uint8``): per pixel, the range from their lowest to their highest value, compared both ways over
    3×3 neighbourhoods (:mod:`service.images.nearby`).  With one render this is :func:`grade`'s own count; with renders
    of one variant at several amounts it forgives any amount between them, as far as a pixel's value moves between
    theirs (an offset shifts a glass ball's rim a little with each amount).  Rows are compared :data:`BAND` at a
    time; ``open_pixels`` are not counted."""
    h = submitted.shape[0]
    low, high = np.min(renders, axis=0), np.max(renders, axis=0)
    off, gross = 0, 0
    for top in range(0, h, BAND):
        bottom = min(top + BAND, h)
        counts = count_off(
            distance(low, high, submitted, top, bottom),
            tolerance,
            None if open_pixels is None else open_pixels[top:bottom],
        )
        off, gross = off + counts.off_nearby, gross + counts.grossly_off
    return Counts(off, gross)


def passes(counts: Counts, pixels: int, max_fraction: float) -> bool:
    """Whether counts of a comparison of ``pixels`` pixels pass: few enough off even nearby, and grossly off."""
    return counts.off_nearby / pixels <= max_fraction and counts.grossly_off <= GROSS_ALLOWED


def grade(
    reference: np.ndarray,
    submitted: np.ndarray,
    reference_sha256: str,
    tolerance: float = DEFAULT_TOLERANCE,
    max_fraction: float = DEFAULT_MAX_FRACTION,
    open_pixels: np.ndarray | None = None,
) -> Grade:
    """The grade of ``submitted`` against ``reference`` (each ``(H, W, 3) uint8``); ``open_pixels``, a boolean
    ``(H, W)`` mask, marks the pixels whose value the format leaves open (two coplanar surfaces overlap there):
    they are not counted against the submission, off or grossly off."""
    h, w, _ = reference.shape
    levels = np.arange(256, dtype=np.int64)
    histogram = np.zeros(256, dtype=np.int64)  # of every channel difference: exact sums from it
    max_error, off, off_nearby, gross = 0, 0, 0, 0
    for top in range(0, h, BAND):
        bottom = min(top + BAND, h)
        ref, sub = planes(reference[top:bottom]), planes(submitted[top:bottom])
        channels = [_absdiff(ref[c], sub[c]) for c in range(3)]
        for c in channels:
            histogram += np.bincount(c.ravel(), minlength=256)
        diff = np.maximum(np.maximum(channels[0], channels[1]), channels[2])
        band_off = int(np.count_nonzero(diff > tolerance))
        max_error = max(max_error, int(diff.max()))
        if band_off:  # only then can a pixel be off even nearby (it is its own neighbour, both ways)
            off += band_off
            counts = count_off(
                nearby_difference(reference, submitted, top, bottom),
                tolerance,
                None if open_pixels is None else open_pixels[top:bottom],
            )
            off_nearby, gross = off_nearby + counts.off_nearby, gross + counts.grossly_off
    values, pixels = 3 * h * w, h * w
    mse = int(histogram @ (levels * levels)) / values
    nearby = off_nearby / pixels
    return Grade(
        passed=passes(Counts(off_nearby, gross), pixels, max_fraction),
        tolerance=tolerance,
        max_fraction=max_fraction,
        mean_abs_error=int(histogram @ levels) / values,
        rmse=math.sqrt(mse),
        psnr=None if mse == 0 else 10 * math.log10(255.0**2 / mse),
        max_error=max_error,
        fraction_off=off / pixels,
        fraction_off_nearby=nearby,
        width=w,
        height=h,
        reference_sha256=reference_sha256,
        grossly_off=gross,
        open_pixels=0 if open_pixels is None else int(np.count_nonzero(open_pixels)),
    )
