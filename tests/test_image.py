"""Quantisation and PNG bytes (tracer/image.py)."""

import io
import zlib

import numpy as np
import pytest
from PIL import Image

from tracer.image import PNG_BAND, decode_png, encode_png, quantize


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
    size = int.from_bytes(data[at - 4:at], "big")
    raw = zlib.decompress(data[at + 4:at + 4 + size])
    assert raw == b"\x00" + px[0].tobytes() + b"\x00" + px[1].tobytes()
    assert data.count(b"IDAT") == 1 and data.endswith(b"IEND\xaeB`\x82")


@pytest.mark.parametrize("bad", [np.zeros((2, 2), np.uint8), np.zeros((2, 2, 4), np.uint8),
                                 np.zeros((2, 2, 3), np.float64), np.zeros((0, 2, 3), np.uint8)])
def test_png_refuses_what_is_not_rgb_pixels(bad):
    with pytest.raises(ValueError):
        encode_png(bad)


def test_quantize_rounds_half_up_and_maps_nan_to_black():
    v = np.array([[0.0, 1.0, 0.3], [np.nan, 2.0, -1.0], [0.5 / 255, 1.5 / 255, np.inf]])
    assert quantize(v).tolist() == [[0, 255, 77], [0, 255, 0], [1, 2, 255]]
