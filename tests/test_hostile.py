"""Hostile input against a real server: each refused, with a 4xx that says why, in bounded memory, and not
after the work it would cost.

The bounds on time here catch a hang on a busy machine; the budgets (a refusal within 1 s, ...) are checked
on a quiet one by ``python -m bench.budgets``, from what these tests measure."""

import io
import json
import socket
import struct
import time

import pytest
from PIL import Image

from tracer.image import png_chunk

from helpers import SCENES, measured
from server import rss_mib, running_server

SCENE = (SCENES / "01_three_spheres.json").read_bytes()
#: seconds: ten times a refusal's budget (1 s), so a refusal that waited for the work it refuses still fails
REFUSED_WITHIN = 10.0


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with running_server(tmp_path_factory.mktemp("hostile")) as (url, proc):
        yield url, proc


def raw_request(url, head: bytes, body_chunks=(), read_timeout=60.0):
    """Send a hand-made HTTP request; return (status, headers+body text, seconds)."""
    host, port = url.removeprefix("http://").split(":")
    started = time.perf_counter()
    with socket.create_connection((host, int(port)), timeout=read_timeout) as sock:
        sock.sendall(head)
        try:
            for chunk in body_chunks:
                sock.sendall(chunk)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the server answered and closed before we finished: that is the point
        data = b""
        try:
            while True:  # every request here says Connection: close, or gets closed on an error
                part = sock.recv(65536)
                if not part:
                    break
                data += part
                head_end = data.find(b"\r\n\r\n")
                if head_end > 0 and b"content-length:" in data[:head_end].lower():
                    length = int(data[:head_end].lower().split(b"content-length:")[1].split(b"\r\n")[0])
                    if len(data) >= head_end + 4 + length:
                        break
        except (TimeoutError, ConnectionResetError):
            pass
    seconds = time.perf_counter() - started
    head, _, body = data.partition(b"\r\n\r\n")
    try:
        text = json.dumps(json.loads(body), ensure_ascii=False)
    except ValueError:
        text = body.decode("latin-1")
    return int(data.split(b" ", 2)[1]), text, seconds


def post(url, path, body, content_type="application/json"):
    head = (
        f"POST {path} HTTP/1.1\r\nHost: x\r\nContent-Type: {content_type}\r\n"
        f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n"
    ).encode()
    return raw_request(url, head, [body])


def test_100_mb_body_is_refused_from_its_header(server):
    url, _ = server
    head = b"POST /render HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 100000000\r\n\r\n"
    status, text, seconds = raw_request(url, head, [b"{" + b" " * 65535])
    measured("hostile a 100 MB Content-Length: answered (s)", seconds)
    assert status == 413 and "max_body_bytes" in text and seconds < REFUSED_WITHIN


def test_endless_chunked_body_is_cut_at_the_limit(server):
    url, _ = server
    head = b"POST /render HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n"
    chunk = b"%x\r\n" % (1 << 20) + b" " * (1 << 20) + b"\r\n"
    status, text, seconds = raw_request(url, head, [chunk] * 12)
    measured("hostile an endless chunked body: answered (s)", seconds)
    assert status == 413 and seconds < 2 * REFUSED_WITHIN


@pytest.mark.parametrize(
    "name, body, says",
    [
        ("nested 100,000 deep", b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
        (
            "10^6 faces",
            json.dumps(
                {
                    **json.loads(SCENE),
                    "objects": [
                        {
                            "type": "mesh",
                            "material": "red",
                            "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                            "faces": [[0, 1, 2]] * 1_000_000,
                        }
                    ],
                },
                separators=(",", ":"),
            ).encode(),
            "max_triangles",
        ),
        ("NaN token", SCENE.replace(b'"fov": 42', b'"fov": NaN'), "NaN is not a JSON number"),
        ("Infinity token", SCENE.replace(b'"fov": 42', b'"fov": Infinity'), "Infinity is not a JSON number"),
        ("number beyond float64", SCENE.replace(b'"fov": 42', b'"fov": 1e999'), "must be a finite number"),
        (
            "overflowing camera",
            SCENE.replace(b'"position": [0, 1.8, 5.8]', b'"position": [0, 1.8, 1e308]').replace(
                b'"look_at": [0, 0.6, -0.4]', b'"look_at": [0, 0.6, -1e308]'
            ),
            "overflows",
        ),
        (
            "cost beyond the limit",
            SCENE.replace(b'"width": 160, "height": 120', b'"width": 4000, "height": 4000, "samples": 8'),
            "max_",
        ),
        ("not JSON at all", b"\x00\x01\x02 binary", "invalid JSON"),
    ],
)
def test_hostile_scene_is_refused_fast(server, name, body, says):
    url, _ = server
    status, text, seconds = post(url, "/render", body)
    measured(f"hostile scene {name}: answered (s)", seconds)
    assert 400 <= status < 500 and says in text, (name, status, text[-300:])
    assert seconds < REFUSED_WITHIN, (name, seconds)


def test_huge_but_finite_numbers_render_finite_pixels(server):
    """As large as phongray renders (coordinates and sizes up to 1e60; colours and attenuations any finite number):
    rendered; beyond that, refused at the place, never rendered wrong."""
    url, _ = server
    data = json.loads(SCENE)
    data["objects"].append({"type": "sphere", "material": "red", "center": [1e60, 1e60, -1e60], "radius": 1e60})
    data["lights"].append(
        {"type": "point", "position": [-1e60, 1e60, 1e60], "color": 1e308, "attenuation": [1e-308, 0, 1e308]}
    )
    status, text, seconds = post(url, "/render", json.dumps(data).encode())
    measured("hostile huge but finite numbers: rendered (s)", seconds)
    assert status == 200 and seconds < 5 * REFUSED_WITHIN
    data["objects"][-1]["radius"] = 1e300
    status, text, _ = post(url, "/render", json.dumps(data).encode())
    assert status == 422 and "objects[" in text and "radius" in text and "is too large" in text, text


def png_bomb() -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", (1, 1)).save(buf, format="PNG")
    data = bytearray(buf.getvalue())
    ihdr = struct.pack(">IIBBBBB", 50_000, 50_000, 8, 2, 0, 0, 0)
    data[8:33] = png_chunk(b"IHDR", ihdr)
    return bytes(data)


def multipart(scene: bytes, image: bytes) -> tuple[bytes, str]:
    boundary = "phongrayboundary"
    body = (
        (f'--{boundary}\r\nContent-Disposition: form-data; name="scene"\r\n\r\n').encode()
        + scene
        + (
            f'\r\n--{boundary}\r\nContent-Disposition: form-data; name="image"; filename="a.png"\r\n'
            f"Content-Type: image/png\r\n\r\n"
        ).encode()
        + image
        + f"\r\n--{boundary}--\r\n".encode()
    )
    return body, f"multipart/form-data; boundary={boundary}"


@pytest.mark.parametrize(
    "name, image, says",
    [
        ("PNG bomb", png_bomb(), "50000×50000"),
        ("corrupt PNG", b"\x89PNG\r\n\x1a\n" + b"\x00" * 40, "corrupt"),
        ("JPEG", b"\xff\xd8\xff\xe0" + b"\x00" * 100, "image is a JPEG; PNG or PPM required"),
    ],
)
def test_hostile_images_are_refused_fast(server, name, image, says):
    url, _ = server
    body, kind = multipart(SCENE, image)
    status, text, seconds = post(url, "/grade", body, kind)
    measured(f"hostile image {name}: answered (s)", seconds)
    assert status == 422 and says in text and seconds < REFUSED_WITHIN, (name, status, text[-300:])


@pytest.mark.parametrize(
    "path, kind",
    [
        ("/render", "text/plain"),
        ("/validate", "application/xml"),
        ("/grade", "application/json"),
        ("/render", "multipart/form-data"),
    ],
)
def test_wrong_content_types_are_415(server, path, kind):
    url, _ = server
    status, _, seconds = post(url, path, SCENE, kind)
    measured(f"hostile content type {kind} to {path}: answered (s)", seconds)
    assert status == 415 and seconds < REFUSED_WITHIN


def test_memory_stays_bounded_through_the_barrage(server):
    url, proc = server
    before = rss_mib(proc.pid)
    for _ in range(3):
        post(url, "/render", b"[" * 100_000)
        post(url, "/render", SCENE.replace(b'"fov": 42', b'"fov": NaN'))
        body, kind = multipart(SCENE, png_bomb())
        post(url, "/grade", body, kind)
    assert rss_mib(proc.pid) - before < 200
    status, _, _ = post(url, "/render", SCENE)
    assert status == 200
