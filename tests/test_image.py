"""Quantisation and PNG bytes (tracer/image.py)."""

import io
import zlib

import numpy as np
import pytest
from PIL import Image

from tracer.image import (
    DECODE_BLOCK,
    PNG_BAND,
    PNG_SIGNATURE,
    decode_png,
    decode_rgbx,
    encode_png,
    open_png,
    png_chunk,
    quantize,
)


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (5, 1), (PNG_BAND, 3), (PNG_BAND + 1, 33), (3 * PNG_BAND - 5, 17)])
def test_png_round_trips_through_pillow(shape):
    rng = np.random.default_rng(shape[0] * 1000 + shape[1])
    px = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
    data = encode_png(px)
    with Image.open(io.BytesIO(data)) as img:
        img.verify()  # chunk CRCs and structure
    with Image.open(io.BytesIO(data)) as img:
        assert img.mode == "RGB" and img.size == (shape[1], shape[0])
        assert np.array_equal(np.asarray(img), px)
    assert np.array_equal(decode_png(data), px)


def test_png_bytes_depend_only_on_the_pixels():
    px = np.random.default_rng(3).integers(0, 256, (300, 40, 3), dtype=np.uint8)
    strided = np.asfortranarray(px)  # another memory layout of the same pixels
    assert encode_png(px) == encode_png(px.copy()) == encode_png(strided)


def test_png_has_one_idat_of_unfiltered_rows():
    px = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    data = encode_png(px)
    at = data.index(b"IDAT")
    size = int.from_bytes(data[at - 4 : at], "big")
    raw = zlib.decompress(data[at + 4 : at + 4 + size])
    assert raw == b"\x00" + px[0].tobytes() + b"\x00" + px[1].tobytes()
    assert data.count(b"IDAT") == 1 and data.endswith(b"IEND\xaeB`\x82")


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((2, 2), np.uint8),
        np.zeros((2, 2, 4), np.uint8),
        np.zeros((2, 2, 3), np.float64),
        np.zeros((0, 2, 3), np.uint8),
    ],
)
def test_png_refuses_what_is_not_rgb_pixels(bad):
    with pytest.raises(ValueError):
        encode_png(bad)


def test_quantize_rounds_half_up_and_maps_nan_to_black():
    v = np.array([[0.0, 1.0, 0.3], [np.nan, 2.0, -1.0], [0.5 / 255, 1.5 / 255, np.inf]])
    assert quantize(v).tolist() == [[0, 255, 77], [0, 255, 0], [1, 2, 255]]


def _png(img: Image.Image) -> bytes:
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()


def _interlaced_png(px: np.ndarray) -> bytes:
    """An Adam7-interlaced 8-bit RGB PNG of ``px`` (what Pillow cannot write), every row unfiltered."""
    h, w = px.shape[:2]
    passes = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2))
    raw = b""
    for x0, y0, dx, dy in passes:
        sub = px[y0::dy, x0::dx]
        if sub.size:
            raw += b"".join(b"\x00" + row.tobytes() for row in sub)
    header = w.to_bytes(4, "big") + h.to_bytes(4, "big") + bytes([8, 2, 0, 0, 1])
    return PNG_SIGNATURE + png_chunk(b"IHDR", header) + png_chunk(b"IDAT", zlib.compress(raw)) + png_chunk(b"IEND", b"")


@pytest.mark.parametrize("mode", ["RGB", "RGBA", "L", "LA", "P", "1", "interlaced"])
def test_decode_png_reads_every_mode_as_pillow_shows_it(mode):
    px = np.random.default_rng(41).integers(0, 256, (13, 19, 3), dtype=np.uint8)
    rgb = Image.fromarray(px)
    if mode == "interlaced":
        data = _interlaced_png(px)
    else:
        data = _png(rgb.quantize(16) if mode == "P" else rgb.convert(mode))
    want = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))
    got = decode_png(data)
    assert got.shape == (13, 19, 3) and got.dtype == np.uint8 and got.flags.c_contiguous
    assert np.array_equal(got, want)
    if mode in ("RGB", "interlaced"):
        assert np.array_equal(got, px)


def test_a_highly_compressed_png_is_inflated_a_block_at_a_time():
    px = np.zeros((1500, 1000, 3), np.uint8)
    px[700, 300] = (1, 2, 3)
    data = encode_png(px)  # 4.5 MB of pixels in a few kilobytes
    assert DECODE_BLOCK < len(data) < 4 * DECODE_BLOCK
    with open_png(data) as img:
        assert img.decodermaxblock == DECODE_BLOCK
    assert np.array_equal(decode_png(data), px)


def test_decode_rgbx_gives_the_pixels_when_pillow_decodes_into_memory_of_its_own(monkeypatch):
    from PIL import ImageFile

    def own_memory(self):
        self.im = Image.core.new(self.mode, self.size)

    monkeypatch.setattr(ImageFile.ImageFile, "load_prepare", own_memory)
    px = np.random.default_rng(43).integers(0, 256, (9, 8, 3), dtype=np.uint8)
    with open_png(encode_png(px)) as img:
        got = decode_rgbx(img)
    assert got.shape == (9, 8, 4) and np.array_equal(got[:, :, :3], px) and (got[:, :, 3] == 255).all()
