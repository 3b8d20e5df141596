"""PPM, the image format of Netpbm that students' tracers write (*Ray Tracing in One Weekend* prints one): its
header read and checked, its pixels decoded.

A PPM is ``P3`` (the values as decimal text) or ``P6`` (the values as bytes): the magic number, the width, the
height and the maxval, separated by white space, then one white-space character and the raster.  A comment runs
from ``#`` to the end of its line and may stand wherever the header has white space.  phongray reads what that
specification writes, and refuses, with the reason, what a hostile or broken file may hold instead:

* a header longer than :data:`HEADER_LIMIT` bytes (comments included), or a number of more than
  :data:`DIGITS` digits, or a width or height of 0;
* a maxval other than 255: the grade compares 8-bit levels, so 255 is the one maxval whose values are those
  levels (a 16-bit PPM, maxval 65535, is refused by name rather than rounded);
* a raster that ends early, a P3 value above the maxval or of more than 3 digits, anything but numbers and
  white space among a P3's values, and anything but white space after the pixels (a program that prints its
  image must print nothing else to its standard output).

:func:`header` reads only the header, so that the size it declares is checked against the scene's before a
pixel is read or any memory is taken for them (:func:`service.images.grading.read_submission`); :func:`pixels` then
decodes the raster with NumPy, with no Python per value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracer.image import encode_png

#: the magic numbers of the PPMs read: text values, byte values
MAGICS = (b"P3", b"P6")
#: the most bytes a header may take (a real one takes a few dozen; GIMP's comment a few dozen more)
HEADER_LIMIT = 4096
#: the most digits a header's number may have (a width of a billion is none a scene has)
DIGITS = 9
#: the one maxval read
MAXVAL = 255
#: the white space of the format (ASCII's, as C's isspace)
WHITE = b" \t\n\v\f\r"


#: what each byte is among a P3's values: anything else, white space, a digit
OTHER, SPACE, DIGIT = 0, 1, 2
KINDS = np.zeros(256, np.uint8)
KINDS[list(WHITE)] = SPACE
KINDS[48:58] = DIGIT


class PpmError(ValueError):
    """A PPM that cannot be graded, and why (the words of :class:`service.images.grading.ImageError`)."""


@dataclass(frozen=True)
class Header:
    """What a PPM's header declares, and where its raster starts."""

    plain: bool  # P3 (text values); False: P6 (bytes)
    width: int
    height: int
    maxval: int
    start: int  # the offset of the raster


def is_ppm(data: bytes) -> bool:
    """Whether ``data`` begins as a PPM does (``P3`` or ``P6``)."""
    return data[:2] in MAGICS


def header(data: bytes) -> Header:
    """The header of PPM ``data``; :class:`PpmError` for one that is broken, hostile or not 8-bit."""
    at, numbers = 2, []
    for name in ("width", "height", "maxval"):
        at = _skip(data, at)
        end = at
        while end < len(data) and end < HEADER_LIMIT and 48 <= data[end] <= 57:
            end += 1
        if end == at:
            raise PpmError(_where(data, at, f"its {name}"))
        if end - at > DIGITS:
            raise PpmError(f"image is a PPM whose {name} has more than {DIGITS} digits; no scene is that large")
        numbers.append(int(data[at:end]))
        at = end
    width, height, maxval = numbers
    if end >= len(data) or data[end] not in WHITE:
        raise PpmError(_where(data, end, "the white space after its maxval"))
    if width < 1 or height < 1:
        raise PpmError(f"image is a PPM of {width}×{height} pixels; it has none")
    if maxval != MAXVAL:
        raise PpmError(
            f"image is a PPM of maxval {maxval}; only 8-bit PPMs (maxval 255) are graded: write 255 as its "
            f"maxval and each value as 0–255"
        )
    return Header(data[:2] == b"P3", width, height, maxval, end + 1)


def _skip(data: bytes, at: int) -> int:
    """The offset of the next token of the header: past white space and comments (``#`` to the end of the
    line); :class:`PpmError` past :data:`HEADER_LIMIT`."""
    while at < len(data) and at < HEADER_LIMIT:
        if data[at] in WHITE:
            at += 1
        elif data[at] == ord("#"):
            ends = (data.find(b"\n", at, HEADER_LIMIT), data.find(b"\r", at, HEADER_LIMIT))
            at = min((i for i in ends if i >= 0), default=min(len(data), HEADER_LIMIT))
        else:
            return at
    if at >= HEADER_LIMIT:
        raise PpmError(f"image is a PPM whose header is longer than {HEADER_LIMIT} bytes; a PPM's header is a line")
    return at


def _where(data: bytes, at: int, expected: str) -> str:
    """Why a header stops where it does: it ends, or holds something else."""
    if at >= len(data):
        return "image is truncated or corrupt: it ends in its PPM header; export it again"
    if at >= HEADER_LIMIT:
        return f"image is a PPM whose header is longer than {HEADER_LIMIT} bytes; a PPM's header is a line"
    return f"image is a PPM whose header is broken: byte {at} is not {expected}"


def pixels(data: bytes, head: Header) -> np.ndarray:
    """The pixels ``(H, W, 3) uint8`` of PPM ``data`` whose header is ``head``; :class:`PpmError` for a raster
    that ends early, holds a value it cannot, or is followed by anything but white space."""
    count = head.width * head.height * 3
    raw = memoryview(data)[head.start :]
    values = _text_values(raw, head) if head.plain else _byte_values(raw, count)
    return values.reshape(head.height, head.width, 3)


def _byte_values(raw: memoryview, count: int) -> np.ndarray:
    if len(raw) < count:
        raise PpmError(
            f"image is truncated: its PPM pixel data ends early ({len(raw)} of {count} bytes); export it again"
        )
    _only_white(raw[count:])
    return np.frombuffer(raw, np.uint8, count).copy()


def _only_white(rest: memoryview) -> None:
    extra = len(bytes(rest).strip(WHITE))
    if extra:
        raise PpmError(
            f"image has {extra} bytes after its PPM pixels; a PPM holds one image and nothing after it (a program "
            f"that prints its image prints its progress to standard error)"
        )


def _text_values(raw: memoryview, head: Header) -> np.ndarray:
    """A P3's values: each 1 to 3 decimal digits, separated by white space, at most the maxval, three for each
    pixel its header declares; read :data:`BLOCK` bytes at a time (each block ending in white space), so that
    the temporaries of a large file stay a few tens of MiB."""
    count = head.width * head.height * 3
    text = np.frombuffer(raw, np.uint8)
    kind = KINDS[text]  # one lookup per byte: a digit, white space, or anything else
    if (kind == OTHER).any():
        raise PpmError(
            f"image is a P3 PPM whose pixel data holds something other than numbers (byte "
            f"{int(np.argmax(kind == OTHER))} of it)"
        )
    out, found, at = np.empty(count, np.uint8), 0, 0
    while at < len(text):
        end = _block_end(kind, at)
        values = _block(text[at:end], kind[at:end] == DIGIT)
        out[found : found + len(values)] = values[: max(0, count - found)]
        found, at = found + len(values), end
    if found != count:
        raise PpmError(
            f"image is {'truncated' if found < count else 'a PPM with values after its pixels'}: its P3 pixel "
            f"data holds {found} values, and its {head.width}×{head.height} pixels are {count}"
        )
    return out


#: the bytes of a P3's values read at a time
BLOCK = 1 << 20


def _block_end(kind: np.ndarray, at: int) -> int:
    """Where the block of a P3's text that starts at ``at`` ends: after the last white space of its
    :data:`BLOCK` bytes (or, in none, after the next), so that no value is cut in two; or at the text's end."""
    end = at + BLOCK
    if end >= len(kind):
        return len(kind)
    spaces = np.flatnonzero(kind[at:end] == SPACE)
    if len(spaces):
        return at + int(spaces[-1]) + 1
    rest = kind[end:] == SPACE  # (a run of digits as long as a block: a value that is refused, once read)
    return end + int(np.argmax(rest)) + 1 if rest.any() else len(kind)


def _block(text: np.ndarray, digit: np.ndarray) -> np.ndarray:
    """The values of a block of a P3's text (whole values only: it ends in white space, or the file does)."""
    changes = np.flatnonzero(np.diff(digit.view(np.int8), prepend=np.int8(0), append=np.int8(0)))
    starts, ends = changes[0::2], changes[1::2]  # (a value's start, then its end, and so on)
    lengths = ends - starts
    if len(lengths) and int(lengths.max()) > 3:
        raise PpmError(f"image is a P3 PPM with a value of {int(lengths.max())} digits; each is 0–255")
    values = text[starts].astype(np.uint16) - 48
    for k in (1, 2):
        longer = np.flatnonzero(lengths > k)
        values[longer] = values[longer] * 10 + (text[starts[longer] + k] - 48)
    if len(values) and int(values.max()) > MAXVAL:
        raise PpmError(f"image is a P3 PPM with the value {int(values.max())}, above its maxval {MAXVAL}")
    return values


def viewable(data: bytes) -> bytes:
    """A graded submission as a browser shows it: a PNG as it is, a PPM as the PNG of its very pixels (lossless:
    the copy a class report shows beside the reference)."""
    if not is_ppm(data):
        return data

    return encode_png(pixels(data, header(data)))
