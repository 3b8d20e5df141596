"""Plain answers to clients that never read (service/http/waiting.py): a render's PNG and a grade's heat-map are
served as passes are, priced against max_answer_bytes and sent a chunk at a time, so that clients that never
read hold no more than the worker's answer budget, and the others are answered meanwhile."""

from __future__ import annotations

import json
import socket
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient
from test_answers import _connect, _form, _noise_png, _request

import schemas
import tracer
from service.http.app import create_app
from service.settings import Settings
from service.work.pipeline import compare

from helpers import SCENES
from server import running_server

SMALL = (SCENES / "01_three_spheres.json").read_bytes()
JSON = {"content-type": "application/json"}
#: room in the budget beyond the large answers held: a small answer still fits
ROOM = 1 << 18


def _bumpy(side: int, grid: int = 120) -> dict:
    """A mesh facing the camera with a random normal at each vertex, under a red, a green and a blue light: a
    PNG of about 2.9 bytes a pixel, cheap to render (one mesh, three lights, one sample)."""
    rng = np.random.default_rng(1)
    xs = np.round(np.linspace(-1, 1, grid), 4).tolist()
    faces = []
    for j in range(grid - 1):
        for i in range(grid - 1):
            a = j * grid + i
            faces += [[a, a + 1, a + grid], [a + 1, a + grid + 1, a + grid]]
    return {
        "camera": {"position": [0, 0, 0], "look_at": [0, 0, -1], "fov": 90},
        "image": {"width": side, "height": side, "samples": 1, "max_depth": 0},
        "materials": {"m": {"diffuse": [1, 1, 1]}},
        "objects": [
            {
                "type": "mesh",
                "vertices": [[x, y, -1.0] for y in xs for x in xs],
                "faces": faces,
                "normals": np.round(rng.normal(size=(grid * grid, 3)) + [0, 0, 2], 3).tolist(),
                "material": "m",
            }
        ],
        "lights": [
            {"type": "directional", "direction": [1, 0, -1], "color": [1, 0, 0]},
            {"type": "directional", "direction": [-1, 0.3, -1], "color": [0, 1, 0]},
            {"type": "directional", "direction": [0, -1, -1], "color": [0, 0, 1]},
        ],
    }


def _status(sock: socket.socket) -> tuple[int, dict[str, str]]:
    """The status and headers of the answer on ``sock``, read up to the body and no further."""
    head = b""
    while b"\r\n\r\n" not in head:
        piece = sock.recv(1)
        assert piece, "the connection closed before the answer's head"
        head += piece
    lines = head.decode().split("\r\n")
    headers = dict(line.split(": ", 1) for line in lines[1:] if ": " in line)
    return int(lines[0].split()[1]), {k.lower(): v for k, v in headers.items()}


def _ask(url: str, path: str, body: bytes, kind: str = "application/json") -> tuple[int, bytes]:
    request = urllib.request.Request(url + path, body, {"content-type": kind})
    try:
        with urllib.request.urlopen(request, timeout=600) as res:
            return res.status, res.read()
    except urllib.error.HTTPError as exc:
        with exc:
            return exc.code, exc.read()


def _held(url: str) -> int:
    with urllib.request.urlopen(url + "/healthz", timeout=60) as res:
        return int(json.loads(res.read())["answer_bytes"])


#: what a worker may hold of answers here: two of the large PNG (about 8.5 MB), not three
BUDGET = 20 << 20
#: an answer larger than the connection's buffers can take in (4 MiB of the kernel's, on loopback, and a chunk
#: of the server's): one that is not read holds its sender
BLOCKS = 6 << 20


def test_clients_that_never_read_a_large_png_hold_no_more_than_the_answer_budget(tmp_path: Path):
    # 400 clients re-asking a cached 18.7 MB PNG and never reading held 3.7 GB: each answer a whole copy queued
    scene = json.dumps(_bumpy(1700)).encode()
    with running_server(tmp_path, max_answer_bytes=str(BUDGET), send_timeout="600") as (url, _):
        status, png = _ask(url, "/render", scene)  # read whole, and cached
        assert status == 200 and len(png) > BLOCKS, len(png)
        fit = BUDGET // len(png)
        holders = [_connect(url) for _ in range(fit)]
        try:
            for sock in holders:  # answers begun, never read: each holds its price
                sock.sendall(_request(url, "/render", scene))
                assert _status(sock)[0] == 200
            assert fit * len(png) <= _held(url) <= BUDGET
            late = _connect(url)
            late.sendall(_request(url, "/render", scene))  # one more finds no room: 503, told when to come back
            status, headers = _status(late)
            late.close()
            assert status == 503 and int(headers["retry-after"]) >= 1
            # the others are answered meanwhile: a small render, a grade, /healthz
            assert _ask(url, "/render", SMALL)[0] == 200
            graded = _ask(url, "/grade", *_form(SMALL, _noise_png(160, 120)))
            assert graded[0] == 200 and json.loads(graded[1])["passed"] is False
            assert _held(url) <= BUDGET
        finally:
            for sock in holders:
                sock.close()
        for _ in range(1200):  # the clients gone, their answers let go (looked at until they are)
            if _held(url) == 0:
                break
            time.sleep(0.05)
        assert _held(url) == 0
        assert _ask(url, "/render", scene) == (200, png)


# -- priced in-process: a render's PNG and a grade's heat-map alike ---------------------------------------------


@pytest.fixture(scope="module")
def small_heat() -> tuple[bytes, bytes, bytes]:
    """The small scene's PNG, an image a little off it everywhere, and that image's raw heat-map."""
    png = tracer.render_png(schemas.load_scene(SMALL))
    pixels = tracer.decode_png(png).astype(np.int16) + np.random.default_rng(2).integers(0, 48, (120, 160, 3))
    off = tracer.encode_png(np.clip(pixels, 0, 255).astype(np.uint8))
    heat = compare(png, tracer.decode_png(off), 2, 0.001, "raw", True).heatmap
    assert heat is not None
    return png, off, heat


@pytest.mark.parametrize("what", ["render", "heat-map"])
def test_a_plain_answer_takes_its_price_from_the_answer_budget(small_heat, what: str):
    png, off, heat = small_heat
    api = TestClient(create_app(Settings(max_answer_bytes=4 * max(len(png), len(heat)))))

    def ask():
        if what == "render":
            return api.post("/render", content=SMALL, headers=JSON)
        return api.post("/grade?format=png&heatmap=raw", data={"scene": SMALL}, files={"image": ("s.png", off)})

    answers = api.app.state.service.answers
    assert ask().content == (png if what == "render" else heat) and answers.held == 0  # (given back once sent)
    taken = answers.total - 16  # every byte of the budget but a few held by answers being sent
    assert answers.take(taken)
    try:
        full = ask()
        assert full.status_code == 503 and "max_answer_bytes" in full.json()["detail"] and full.headers["retry-after"]
        graded = api.post("/grade", data={"scene": SMALL}, files={"image": ("s.png", off)})  # (JSON: not priced)
        assert graded.status_code == 200 and graded.json()["passed"] is False
    finally:
        answers.give(taken)
    assert ask().status_code == 200 and answers.held == 0


def test_a_plain_answer_larger_than_the_whole_budget_is_refused_naming_the_limit(small_heat):
    png, _, _ = small_heat
    api = TestClient(create_app(Settings(max_answer_bytes=len(png) - 1)))
    res = api.post("/render", content=SMALL, headers=JSON)
    assert res.status_code == 422 and "render: 160×120 pixels as png" in res.json()["detail"]
    assert "max_answer_bytes" in res.json()["detail"]
