"""Render passes as files (service/render/passes.py): PNGs to look at and .npy values, from the CLI and /render."""

import io
import json

import numpy as np
import pytest
from fastapi.testclient import TestClient

import schemas
from service.cli import PASS_NAMES, main
from service.http.app import create_app
from service.http.routers.render import PassName
from service.render import passes
from service.settings import Settings
from tracer import Renderer, decode_png
from tracer.image import quantize
from tracer.shade.passes import ADDITIVE, NAMES

from helpers import SCENES

SCENE = (SCENES / "02_all_lights.json").read_bytes()


@pytest.fixture(scope="module")
def api():
    return TestClient(create_app(Settings()))


def npy(data: bytes) -> np.ndarray:
    return np.load(io.BytesIO(data), allow_pickle=False)


def test_the_names_are_the_tracers():
    assert PASS_NAMES == NAMES and PassName.__args__ == NAMES


def test_the_additive_passes_as_npy_sum_to_the_image(api):
    total = sum(
        npy(
            api.post(
                f"/render?pass={name}&format=npy", content=SCENE, headers={"content-type": "application/json"}
            ).content
        )
        for name in ADDITIVE
    )
    image = Renderer(schemas.load_scene(SCENE)).pixels()
    assert np.count_nonzero(quantize(total) != image) <= image.size // 1000


def test_a_lights_pass_over_http_is_the_cli_s_and_bad_names_are_422(api, tmp_path):
    (tmp_path / "s.json").write_bytes(SCENE)
    assert (
        main(
            ["render", str(tmp_path / "s.json"), "--pass", "shadow", "--light", "4", "-o", str(tmp_path / "shadow.png")]
        )
        == 0
    )
    res = api.post("/render?pass=shadow&light=4", content=SCENE, headers={"content-type": "application/json"})
    assert res.status_code == 200 and res.content == (tmp_path / "shadow.png").read_bytes()
    shown = decode_png(res.content)
    assert set(np.unique(shown)) - {0, 255} and shown.min() == 0 and shown.max() == 255  # penumbra, dark, lit
    bad = api.post("/render?pass=shadow&light=9", content=SCENE, headers={"content-type": "application/json"})
    assert bad.status_code == 422 and "the scene has 5 lights (0..4), not 9" in bad.json()["detail"]
    assert api.post("/render?pass=glow", content=SCENE, headers={"content-type": "application/json"}).status_code == 422


def test_object_depth_and_normal_show_what_was_hit():
    scene = schemas.validate_scene(json.loads((SCENES / "04_whitted.json").read_bytes()))
    obj = passes.values(scene, "object")
    depth, normal = passes.values(scene, "depth"), passes.values(scene, "normal")
    shown = {name: passes.pixels(name, v) for name, v in (("object", obj), ("depth", depth), ("normal", normal))}
    miss = obj < 0
    assert miss.any() and (~miss).any()
    for name in shown:
        assert np.all(shown[name][miss] == 0), name  # nothing hit is black in each
    hit = np.flatnonzero(~miss.ravel())
    near, far = hit[np.argmin(depth.ravel()[hit])], hit[np.argmax(depth.ravel()[hit])]
    flat = shown["depth"].reshape(-1, 3)
    assert flat[near, 0] == 255 and flat[far, 0] == 48
    colours = {tuple(shown["object"].reshape(-1, 3)[obj.ravel() == k][0]) for k in np.unique(obj[~miss])}
    assert len(colours) == len(np.unique(obj[~miss]))  # a colour per object
    assert np.allclose(np.linalg.norm(normal[~miss], axis=1), 1.0)


def test_a_pass_as_npy_is_plain_array_bytes_and_the_same_every_time(tmp_path):
    (tmp_path / "s.json").write_bytes(SCENE)
    for k in (1, 2):
        assert (
            main(
                [
                    "render",
                    str(tmp_path / "s.json"),
                    "--pass",
                    "diffuse",
                    "--light",
                    "1",
                    "--width",
                    "40",
                    "--height",
                    "30",
                    "-o",
                    str(tmp_path / f"d{k}.npy"),
                ]
            )
            == 0
        )
    data = (tmp_path / "d1.npy").read_bytes()
    assert data == (tmp_path / "d2.npy").read_bytes() and npy(data).shape == (30, 40, 3)
    assert npy(data).dtype == np.float64 and npy(data).max() > 0


@pytest.mark.parametrize(
    "name, light, says",
    [
        (
            "normal",
            1,
            "light: the normal pass is the whole scene's, not a light's (only diffuse, specular, shadow take a light)",
        ),
        ("object", 0, "light: the object pass is the whole scene's"),
        ("shadow", 0, "light: lights[0] is an ambient light, which has no shadow"),
        ("diffuse", 0, "light: lights[0] is an ambient light, which has no diffuse"),
    ],
)
def test_a_light_a_pass_cannot_be_of_is_refused_the_same_by_the_cli_and_http(api, tmp_path, capsys, name, light, says):
    assert json.loads(SCENE)["lights"][0]["type"] == "ambient"
    (tmp_path / "s.json").write_bytes(SCENE)
    out = tmp_path / "p.png"
    assert main(["render", str(tmp_path / "s.json"), "--pass", name, "--light", str(light), "-o", str(out)]) == 2
    assert capsys.readouterr().err.startswith(f"phongray: {tmp_path / 's.json'}: {says}") and not out.exists()
    res = api.post(f"/render?pass={name}&light={light}", content=SCENE, headers={"content-type": "application/json"})
    assert res.status_code == 422 and res.json()["detail"].startswith(says)


def test_a_pass_prints_one_summary_line_unless_quiet(tmp_path, capsys):
    (tmp_path / "s.json").write_bytes(SCENE)
    out = tmp_path / "shadow.png"
    args = [
        "render",
        str(tmp_path / "s.json"),
        "--pass",
        "shadow",
        "--light",
        "4",
        "--width",
        "40",
        "--height",
        "30",
        "-o",
        str(out),
    ]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert err.startswith(f"{out}: the shadow pass of light 4 (PNG) in ") and err.endswith(" s\n")
    assert err.count("\n") == 1
    assert main(["render", str(tmp_path / "s.json"), "--pass", "depth", "-o", str(tmp_path / "d.npy")]) == 0
    assert capsys.readouterr().err.startswith(f"{tmp_path / 'd.npy'}: the depth pass (values) in ")
    assert main([*args, "-q"]) == 0 and capsys.readouterr().err == ""
