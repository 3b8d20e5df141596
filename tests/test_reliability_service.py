"""The service's side of issue 29, attack by attack: request bodies bounded per worker whatever the number of
connections, a form part as large as the body limit, every 16-bit PNG scaled to 8 bits exactly, and a request
with both Content-Length and Transfer-Encoding refused with its connection closed.  Every server here listens
on 127.0.0.1."""

import io
import json
import socket
import struct
import time
import zlib

import anyio
import numpy as np
import pytest
from PIL import Image
from starlette.testclient import TestClient

from bench import bodies
from service import client
from service.http.app import create_app
from service.http.middleware import BodyBudget
from service.images import grading
from service.images.grading import LEVELS, _to_8bit, read_submission
from service.settings import Settings
from tracer.image import PNG_SIGNATURE, png_chunk

from helpers import measured, scene_dict
from server import running_server

# --- helpers ---------------------------------------------------------------------------------------------------


def png16(values: np.ndarray, color_type: int) -> bytes:
    """A 16-bit PNG (big-endian samples, filter 0) of ``values``: (h, w) for gray (0), (h, w, 3) RGB (2),
    (h, w, 4) RGBA (6)."""
    h, w = values.shape[:2]
    raw = b"".join(b"\x00" + values[y].astype(">u2").tobytes() for y in range(h))
    return (
        PNG_SIGNATURE
        + png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, color_type, 0, 0, 0))
        + png_chunk(b"IDAT", zlib.compress(raw))
        + png_chunk(b"IEND", b"")
    )


def gray_scene() -> dict:
    """01_three_spheres with every colour grey, so that its render is grey (R = G = B) to the bit."""
    data = scene_dict("01_three_spheres")
    for material in data["materials"].values():
        for key in ("ambient", "diffuse"):
            material[key] = [sum(material[key]) / 3] * 3
    data["image"]["background"] = [0.07] * 3
    for light in data["lights"]:
        light["color"] = 0.9 if light["type"] != "ambient" else 1
    return data


@pytest.fixture(scope="module")
def app_client():
    with TestClient(create_app(Settings())) as c:
        yield c


def grade_form(c: TestClient, scene: bytes, image: bytes, scene_file: bool = False):
    files = {"image": ("a.png", image, "image/png")}
    if scene_file:
        return c.post("/grade", files={**files, "scene": ("scene.json", scene, "application/json")})
    return c.post("/grade", data={"scene": scene.decode()}, files=files)


# --- 16-bit PNGs ----------------------------------------------------------------------------------------------


def test_a_correct_render_saved_as_16_bit_gray_passes(app_client):
    scene = json.dumps(gray_scene()).encode()
    render = app_client.post("/render", content=scene, headers={"content-type": "application/json"})
    assert render.status_code == 200
    rgb = np.asarray(Image.open(io.BytesIO(render.content)).convert("RGB"))
    assert (rgb[..., 0] == rgb[..., 1]).all() and (rgb[..., 1] == rgb[..., 2]).all() and rgb.max() > 128
    wide = rgb[..., 0].astype(np.uint16) * 257  # how an 8-bit level is written at 16 bits
    for image in (png16(wide, 0), _pillow_png(Image.fromarray(wide))):  # ours, and Pillow's own I;16 writer
        answer = grade_form(app_client, scene, image)
        assert answer.status_code == 200, answer.text
        assert answer.json()["passed"] is True and answer.json()["max_error"] == 0, answer.json()


def test_a_correct_render_saved_as_rgb16_and_rgba16_passes(app_client):
    scene = json.dumps(scene_dict("01_three_spheres")).encode()
    render = app_client.post("/render", content=scene, headers={"content-type": "application/json"})
    rgb = np.asarray(Image.open(io.BytesIO(render.content)).convert("RGB")).astype(np.uint16) * 257
    rgba = np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 65535, np.uint16)], axis=2)
    for image in (png16(rgb, 2), png16(rgba, 6)):
        answer = grade_form(app_client, scene, image)
        assert answer.status_code == 200 and answer.json()["max_error"] == 0, answer.text


@pytest.mark.parametrize("color_type, channels", [(0, 1), (2, 3), (6, 4)])
def test_16_bit_values_are_scaled_to_round_v_over_257(color_type, channels):
    rng = np.random.default_rng(29)
    values = rng.integers(0, 65536, (9, 13, channels), dtype=np.uint16)
    values[0, :4, 0] = [0, 128, 129, 65535]  # 0, 0.498 → 0, 0.502 → 1, 255
    if channels == 4:
        values[..., 3] = 65535
    image = png16(values[..., 0] if channels == 1 else values, color_type)
    got = read_submission(image, (13, 9))
    want = np.floor(values[..., :3].astype(np.float64) / 257 + 0.5).astype(np.uint8)
    if channels == 1:
        want = np.repeat(want[..., :1], 3, axis=2)
    assert got.dtype == np.uint8 and (got == want).all()
    assert list(got[0, :4, 0]) == [0, 0, 1, 255]


def test_a_transparent_grey_level_of_a_16_bit_gray_png_is_refused():
    values = np.full((4, 6), 1000, np.uint16)
    image = _pillow_png(Image.fromarray(values), transparency=1000)
    with pytest.raises(ValueError, match="not fully opaque"):
        read_submission(image, (6, 4))


def test_the_16_bit_table_is_round_v_over_257_for_every_level():
    levels = np.arange(65536)
    want = np.floor(levels / 257 + 0.5)
    assert LEVELS.dtype == np.uint8 and (LEVELS == want).all()
    assert list(_to_8bit(np.array([-5, 0, 65535, 70000], np.int32))) == [0, 0, 255, 255]  # mode I is clipped


def test_a_16_bit_image_is_read_the_same_in_one_band_or_many(monkeypatch):
    rng = np.random.default_rng(31)
    values = rng.integers(0, 65536, (23, 7, 3), dtype=np.uint16)
    image = png16(values, 2)
    whole = read_submission(image, (7, 23))
    monkeypatch.setattr(grading, "BAND", 5)  # 23 rows: four full bands and a short one
    assert (read_submission(image, (7, 23)) == whole).all()
    assert (whole == np.floor(values / 257 + 0.5)).all()


@pytest.mark.parametrize("mode", ["RGB", "RGBA", "L", "LA", "P", "1"])
def test_an_8_bit_png_of_every_mode_reads_as_pillow_shows_it(mode):
    rng = np.random.default_rng(37)
    rgb = Image.fromarray(rng.integers(0, 256, (17, 11, 3), dtype=np.uint8))
    img = rgb.quantize(16) if mode == "P" else rgb.convert(mode)
    image = _pillow_png(img)
    got = read_submission(image, (11, 17))
    want = np.asarray(Image.open(io.BytesIO(image)).convert("RGB"))
    assert got.dtype == np.uint8 and got.shape == (17, 11, 3) and got.flags.c_contiguous
    assert (got == want).all()


@pytest.mark.parametrize("bits", [8, 16])
def test_one_transparent_pixel_of_an_rgba_png_is_refused_by_its_place(bits):
    values = np.full((6, 9, 4), 255 if bits == 8 else 65535, np.uint16)
    values[4, 7, 3] = 254 if bits == 8 else 65406  # 65406 / 257 = 254.5 - 1/514: rounds down to 254
    image = _pillow_png(Image.fromarray(values.astype(np.uint8), "RGBA")) if bits == 8 else png16(values, 6)
    with pytest.raises(ValueError, match=r"image has 1 pixel that is not fully opaque \(at x = 7, y = 4\)"):
        read_submission(image, (9, 6))
    values[4, 7, 3] = 255 if bits == 8 else 65407  # the lowest 16-bit alpha that rounds to 255
    image = _pillow_png(Image.fromarray(values.astype(np.uint8), "RGBA")) if bits == 8 else png16(values, 6)
    assert read_submission(image, (9, 6)).shape == (6, 9, 3)


def _pillow_png(img: Image.Image, **options) -> bytes:
    buf = io.BytesIO()
    img.save(buf, format="PNG", **options)
    return buf.getvalue()


# --- form parts as large as the body limit -----------------------------------------------------------------------


def big_legal_scene(size: int) -> bytes:
    """01_three_spheres padded with spaces to ``size`` bytes: a legal scene of that size."""
    text = json.dumps(scene_dict("01_three_spheres")).encode()
    return text[:-1] + b" " * (size - len(text)) + b"}"


def test_a_1_1_mb_scene_as_a_text_part_is_graded(app_client):
    scene = big_legal_scene(1_100_000)
    render = app_client.post("/render", content=scene, headers={"content-type": "application/json"})
    for as_file in (False, True):
        answer = grade_form(app_client, scene, render.content, scene_file=as_file)
        assert answer.status_code == 200 and answer.json()["passed"] is True, answer.text


def test_a_scene_part_over_max_body_bytes_gets_413_naming_it(app_client):
    scene = big_legal_scene(8 * 1024 * 1024 + 10)
    for as_file in (False, True):
        answer = grade_form(app_client, scene, b"\x89PNG\r\n\x1a\n", scene_file=as_file)
        assert answer.status_code == 413, answer.text
        assert answer.json()["detail"].startswith("scene: ") and "max_body_bytes" in answer.json()["detail"]


# --- against a real server: the project's own client, framing, the budget --------------------------------------


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    settings = {"max_buffered_bytes": str(3 << 20), "buffer_wait": "0.5", "body_timeout": "5"}
    with running_server(tmp_path_factory.mktemp("reliability"), workers=1, **settings) as (url, proc):
        yield url


@pytest.fixture(scope="module")
def keyed(tmp_path_factory):
    with running_server(tmp_path_factory.mktemp("keyed"), api_key="k") as (url, proc):
        yield url


def port_of(url: str) -> int:
    return int(url.rsplit(":", 1)[1])


def test_the_projects_client_grades_a_1_1_mb_scene(server):
    scene = big_legal_scene(1_100_000)
    png = client.post_json(server, "/render", scene)
    answer = json.loads(client.post_form(server, "/grade", {"scene": scene}, {"image": ("a.png", png, "image/png")}))
    assert answer["passed"] is True and answer["max_error"] == 0


def read_all(sock: socket.socket, seconds: float) -> tuple[bytes, bool]:
    """Everything the server sends within ``seconds``, and whether it closed the connection meanwhile."""
    sock.settimeout(0.2)
    data, deadline = b"", time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            part = sock.recv(1 << 16)
        except TimeoutError:
            continue
        except ConnectionResetError:
            return data, True
        if not part:
            return data, True
        data += part
    return data, False


def smuggle(url: str, encoding: bytes, extra: bytes = b"") -> tuple[bytes, bool]:
    """A POST with both Content-Length and Transfer-Encoding and a GET smuggled after its chunked body: what the
    server sends back within 3 s, and whether it closed the connection."""
    smuggled = b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n"
    body = b"0\r\n\r\n" + smuggled
    head = (
        b"POST /validate HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: %d\r\n"
        b"Transfer-Encoding: %s\r\n%s\r\n" % (len(body), encoding, extra)
    )
    with socket.create_connection(("127.0.0.1", port_of(url)), timeout=5) as sock:
        sock.sendall(head + body)
        return read_all(sock, 3.0)


@pytest.mark.parametrize("encoding", [b"chunked", b"gzip, chunked"])
def test_content_length_with_transfer_encoding_gets_400_and_a_smuggled_request_no_answer(server, encoding):
    data, closed = smuggle(server, encoding)
    assert data.startswith(b"HTTP/1.1 4"), data
    assert data.count(b"HTTP/1.1 ") == 1, data  # the smuggled GET is never answered
    assert closed, "the connection stayed open"
    if encoding == b"chunked":  # (h11 itself refuses a coding other than chunked, also with a 400)
        assert data.startswith(b"HTTP/1.1 400") and b"Transfer-Encoding" in data, data


@pytest.mark.parametrize("extra", [b"", b"Authorization: Bearer wrong\r\n", b"X-API-Key: k\r\n"])
def test_content_length_with_transfer_encoding_gets_400_before_the_key_is_asked_for(keyed, extra):
    """With a key set, the 401 of a wrong key (or the answer of the right one) would keep the connection open."""
    data, closed = smuggle(keyed, b"chunked", extra)
    assert data.startswith(b"HTTP/1.1 400") and data.count(b"HTTP/1.1 ") == 1 and closed, data


def test_a_body_that_finds_no_room_in_the_budget_gets_503_with_retry_after(server):
    """A 3 MiB budget: one held 2 MiB body leaves no room for another, which waits 0.5 s and gets 503."""
    size = 2 << 20
    head = (
        b"POST /validate HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: %d\r\n"
        b"Connection: close\r\n\r\n" % size
    )
    body = b" " * (size - 2) + b"{}"
    with socket.create_connection(("127.0.0.1", port_of(server)), timeout=10) as holder:
        holder.sendall(head + body[:1000])  # holds its 2 MiB of the budget while its body trickles in
        time.sleep(0.3)
        with socket.create_connection(("127.0.0.1", port_of(server)), timeout=10) as late:
            started = time.monotonic()
            late.sendall(head)
            late.sendall(body)
            data, closed = read_all(late, 30.0)
            waited = time.monotonic() - started
        assert data.startswith(b"HTTP/1.1 503"), data
        assert b"retry-after: 1" in data.lower() and b"max_buffered_bytes" in data and closed
        measured("a body with no room in the buffer budget: refused after (s)", waited)
        assert 0.4 < waited < 10.0  # after buffer_wait = 0.5 s, not before; then at once, not at read_all's 30 s
        holder.sendall(body[1000:])  # the held body is still served
        answer, _ = read_all(holder, 5.0)
    assert answer.startswith(b"HTTP/1.1 422"), answer  # (the scene {} is invalid: it was read and validated)
    with socket.create_connection(("127.0.0.1", port_of(server)), timeout=10) as again:  # the budget is free again
        again.sendall(head + body)
        answer, _ = read_all(again, 5.0)
    assert answer.startswith(b"HTTP/1.1 422"), answer


def test_the_budget_serves_in_arrival_order_and_gives_up_after_its_wait():
    async def main() -> list[str]:
        budget, order = BodyBudget(10), []
        assert await budget.take(6, 0.0)

        async def wants(name: str, size: int, wait: float) -> None:
            got = await budget.take(size, wait)
            order.append(f"{name}:{got}")

        async with anyio.create_task_group() as tasks:
            tasks.start_soon(wants, "big", 8, 1.0)  # first in line: waits for the 6 held
            await anyio.sleep(0.01)
            tasks.start_soon(wants, "small", 2, 1.0)  # would fit now, but waits its turn behind "big"
            tasks.start_soon(wants, "impatient", 1, 0.05)
            await anyio.sleep(0.2)
            assert order == ["impatient:False"] and budget.held == 6
            budget.give(6)
            await anyio.sleep(0.01)
            assert order[1:] == ["big:True", "small:True"] and budget.held == 10
        budget.give(8)
        budget.give(2)
        assert budget.held == 0 and await budget.take(50, 0.0)  # more than the whole budget: runs alone
        assert budget.held == 10
        return order

    anyio.run(main)


def test_concurrent_16_mib_grades_hold_bounded_memory_and_healthz_answers():
    """The issue's attack at a test's scale: 48 concurrent 16 MiB /grade bodies on one worker (on 341e1da, 64 of
    them grew the worker by 2.4 GiB).  ``python -m bench.bodies`` runs the issue's 400 on 2 workers."""
    result = bodies.run(requests=48, workers=1, mib=16, source=bodies.HERE, env={})
    assert result["statuses"] == {"200": 48}, result  # (they wait their turn: none is refused)
    assert result["rss_peak_growth_mib"] <= 384, result
    measured("48 concurrent 16 MiB grades: worst /healthz (ms)", result["healthz_worst_ms"])
    assert result["healthz_failures"] == 0, result  # (its budget, 250 ms, is python -m bench.budgets's)
    assert result["healthz_worst_ms"] < 3000, result  # a stall's bound, not the budget
