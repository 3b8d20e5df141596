"""Every endpoint and error, in-process."""

import gzip
import io
import json
import re
import subprocess
import sys

import numpy as np
import pytest
from fastapi.testclient import TestClient
from PIL import Image

import schemas
import tracer
from service.http.app import create_app
from service.images import grading
from service.settings import Settings
from tracer.image import png_chunk

from helpers import SCENES, scene_dict

JSON = {"content-type": "application/json"}
SCENE = (SCENES / "01_three_spheres.json").read_bytes()


def client(**settings):
    return TestClient(create_app(Settings(**settings)))


@pytest.fixture(scope="module")
def api():
    return client()


@pytest.fixture(scope="module")
def reference_png():
    return tracer.encode_png(tracer.render(schemas.load_scene(SCENE)))


def png_of(pixels):
    buf = io.BytesIO()
    Image.fromarray(pixels).save(buf, format="PNG")
    return buf.getvalue()


def test_render_gives_the_same_bytes_as_the_cli_path(api, reference_png):
    res = api.post("/render", content=SCENE, headers=JSON)
    assert res.status_code == 200 and res.headers["content-type"] == "image/png"
    assert res.content == reference_png
    assert float(res.headers["x-render-seconds"]) >= 0


def test_a_render_says_whether_it_came_from_the_cache(api):
    data = json.loads(SCENE)
    data["image"]["background"] = [0.011, 0.0, 0.0]  # rendered by no other test
    body = json.dumps(data)
    first, second = (api.post("/render", content=body, headers=JSON) for _ in range(2))
    assert (first.headers["x-cache"], second.headers["x-cache"]) == ("miss", "hit")
    assert first.content == second.content


def test_etag_and_if_none_match(api):
    etag = api.post("/render", content=SCENE, headers=JSON).headers["etag"]
    res = api.post("/render", content=SCENE, headers={**JSON, "if-none-match": etag})
    assert res.status_code == 304 and res.content == b"" and res.headers["etag"] == etag
    # whitespace and key order do not change the canonical scene
    reordered = json.dumps(dict(reversed(list(json.loads(SCENE).items()))), indent=4)
    assert api.post("/render", content=reordered, headers={**JSON, "if-none-match": etag}).status_code == 304
    for header in ("*", f'"other", W/{etag}', f"W/{etag}"):  # (any tag, and weak comparison: RFC 9110 13.1.2)
        assert api.post("/render", content=SCENE, headers={**JSON, "if-none-match": header}).status_code == 304
    assert api.post("/render", content=SCENE, headers={**JSON, "if-none-match": '"other"'}).status_code == 200


def test_query_overrides(api):
    res = api.post("/render?width=32&height=24&samples=2", content=SCENE, headers=JSON)
    assert tracer.decode_png(res.content).shape == (24, 32, 3)
    res = api.post("/render?width=0", content=SCENE, headers=JSON)
    assert res.status_code == 422 and res.json()["errors"][0]["path"] == "query.width"


def test_a_name_used_twice_is_a_located_422(api):
    data = json.loads(SCENE)
    data["lights"] = [{"type": "ambient", "color": 0.1, "name": "key"} for _ in range(2)]
    res = api.post("/render", content=json.dumps(data), headers=JSON)
    assert res.status_code == 422 and [e["path"] for e in res.json()["errors"]] == ["lights[1].name"]


def test_overrides_replace_values_but_neither_complete_nor_mend_a_scene(api):
    """A body the JSON Schema refuses (no image.height, a samples that is no number) stays refused, whatever the
    query says."""
    data = json.loads(SCENE)
    del data["image"]["height"]
    res = api.post("/render?width=16&height=12", content=json.dumps(data), headers=JSON)
    assert res.status_code == 422 and [e["path"] for e in res.json()["errors"]] == ["image.height"]
    data = json.loads(SCENE)
    data["image"]["samples"] = {}
    res = api.post("/render?samples=1", content=json.dumps(data), headers=JSON)
    assert res.status_code == 422 and [e["path"] for e in res.json()["errors"]] == ["image.samples"]
    assert "samples" not in json.loads(SCENE)["image"]  # an optional key the scene lacks is set by the query
    with_samples = json.loads(SCENE)
    with_samples["image"]["samples"] = 2
    by_query = api.post("/render?samples=2", content=SCENE, headers=JSON)
    assert by_query.status_code == 200
    assert by_query.content == api.post("/render", content=json.dumps(with_samples), headers=JSON).content


def test_validate_valid_and_invalid_with_lines(api):
    assert api.post("/validate", content=SCENE, headers=JSON).json() == {"valid": True}
    bad = SCENE.replace(b'"radius": 0.7', b'"radius": -0.7')
    res = api.post("/validate", content=bad, headers=JSON)
    assert res.status_code == 422
    (err,) = res.json()["errors"]
    assert err["path"] == "objects[1].radius" and err["message"] == "must be > 0"
    assert bad.decode().splitlines()[err["line"] - 1].count("-0.7") == 1


@pytest.mark.parametrize("body", [b"", b"{", b"[]", b'{"a": NaN}', b"\xff\xfe", b"[" * 100_000])
def test_malformed_bodies_are_422(api, body):
    for path in ("/render", "/validate"):
        res = api.post(path, content=body, headers=JSON)
        assert res.status_code == 422, (path, body[:10])
        assert res.json()["errors"]


def test_wrong_content_type_is_415(api):
    assert api.post("/render", content=SCENE, headers={"content-type": "text/plain"}).status_code == 415
    assert api.post("/grade", content=SCENE, headers=JSON).status_code == 415


def test_an_encoded_body_is_415_not_read_as_json(api):
    """A gzipped body was read as JSON ("the document is not UTF-8 text"); the service takes bodies as sent."""
    for path in ("/render", "/validate"):
        res = api.post(path, content=gzip.compress(SCENE), headers={**JSON, "content-encoding": "gzip"})
        assert res.status_code == 415 and "content encoding 'gzip' is not taken" in res.json()["detail"], res.text
    assert api.post("/render", content=SCENE, headers={**JSON, "content-encoding": "identity"}).status_code == 200
    form = api.post("/grade", data={"scene": SCENE.decode()}, headers={"content-encoding": "br"})
    assert form.status_code == 415, form.text


def test_body_limit_is_413():
    api = client(max_body_bytes=1000)
    res = api.post("/render", content=SCENE, headers=JSON)
    assert res.status_code == 413 and "max_body_bytes" in res.json()["detail"]

    def chunks():  # no Content-Length: the limit applies while streaming
        for _ in range(10):
            yield b" " * 500

    res = api.post("/validate", content=chunks(), headers=JSON)
    assert res.status_code == 413


@pytest.mark.parametrize(
    "settings, patch, limit",
    [
        ({"max_pixels": 100}, {}, "max_pixels"),
        ({"max_samples": 2}, {"samples": 3}, "max_samples"),
        ({"max_depth": 2}, {"max_depth": 3}, "max_depth"),
        ({"max_cost": 1000}, {}, "max_cost"),
        ({"max_objects": 2}, {}, "max_objects"),
        ({"max_light_samples": 0}, {}, "max_light_samples"),
    ],
)
def test_scene_limits_name_the_limit(settings, patch, limit):
    data = scene_dict("01_three_spheres")
    data["image"].update(patch)
    res = client(**settings).post("/render", content=json.dumps(data), headers=JSON)
    assert res.status_code == 422 and limit in res.json()["detail"]


def test_too_many_faces_is_refused_before_validation():
    data = scene_dict("01_three_spheres")
    data["objects"].append({"type": "mesh", "material": "red", "vertices": [[0, 0, 0]], "faces": [[0, 0, 0]] * 50})
    res = client(max_triangles=10).post("/render", content=json.dumps(data), headers=JSON)
    assert res.status_code == 422 and "max_triangles" in res.json()["detail"]


def test_busy_service_answers_503_with_retry_after():
    res = client(max_concurrent_renders=0).post("/render", content=SCENE, headers=JSON)
    assert res.status_code == 503 and res.headers["retry-after"] == "1"


def test_render_timeout_is_503():
    res = client(render_timeout=0.0).post("/render", content=SCENE, headers=JSON)
    assert res.status_code == 503 and "render_timeout" in res.json()["detail"]


def grade(api, scene=SCENE, image=b"", **fields):
    return api.post("/grade", data={"scene": scene.decode(), **fields}, files={"image": ("s.png", image, "image/png")})


def test_grading_the_reference_passes_with_zero_error(api, reference_png):
    res = grade(api, image=reference_png)
    body = res.json()
    assert res.status_code == 200 and body["passed"] is True
    assert body["mean_abs_error"] == 0 and body["max_error"] == 0 and body["psnr"] is None
    assert body["tolerance"] == 2 and len(body["reference_sha256"]) == 64


def test_grading_an_image_with_a_light_removed_fails(api):
    data = scene_dict("02_all_lights")
    submitted = tracer.render(schemas.validate_scene({**data, "lights": data["lights"][:-1]}))
    res = grade(api, scene=json.dumps(data).encode(), image=tracer.encode_png(submitted))
    body = res.json()
    assert res.status_code == 200 and body["passed"] is False
    assert body["fraction_off_nearby"] > 0.001 and body["psnr"] > 0


def test_a_failing_grade_comes_with_its_diagnosis_and_a_pass_without(api, reference_png):
    from tracer.scene.variants import VARIANTS

    spec = api.get("/openapi.json").json()
    scene = schemas.load_scene(SCENE)
    gamma = tracer.encode_png(tracer.Renderer(scene, VARIANTS["gamma"][0]).pixels())
    body = grade(api, image=gamma).json()
    assert body["passed"] is False and component(spec, "GradeAnswer").is_valid(body)
    assert body["diagnosis"]["causes"][0]["variant"] == "gamma"
    assert body["diagnosis"]["sentence"].startswith("Likely: gamma 1/2.2 applied to the output")
    assert grade(api, image=gamma, diagnose="false").json()["diagnosis"] is None
    assert grade(api, image=reference_png).json()["diagnosis"] is None
    assert grade(api, image=gamma, diagnose="maybe").status_code == 422


def test_a_diagnosis_past_the_render_timeout_says_so():
    from service.render.scenekey import scene_key
    from tracer.scene.variants import VARIANTS

    api = client(render_timeout=0.0)
    text = SCENE.replace(b'"background": [0.05, 0.07, 0.12]', b'"background": [0.05, 0.07, 0.13]')
    scene = schemas.load_scene(text)
    assert scene.image.background[2] == 0.13  # a scene no other test diagnoses
    api.app.state.service.cache.put(scene_key(scene), tracer.render_png(scene))  # only the diagnosis renders
    gamma = tracer.encode_png(tracer.Renderer(scene, VARIANTS["gamma"][0]).pixels())
    # the accepted variants cannot be checked in no time: the grade is not decided now, never failed for it
    late = grade(api, scene=text, image=gamma)
    assert late.status_code == 503 and "render_timeout" in late.json()["detail"] and "retry-after" in late.headers
    # once they are (kept from an earlier grade), only the diagnosis runs past the time, and says so
    from service.diagnosis.accepting import Failing, accept
    from service.images.grading import grade as graded

    reference, submitted = tracer.render(scene), tracer.decode_png(gamma)
    assert accept(scene, Failing(reference, submitted, graded(reference, submitted, ""))) is None
    body = grade(api, scene=text, image=gamma).json()
    assert body["passed"] is False
    assert body["diagnosis"]["sentence"] == "No diagnosis: its renders ran past the limit render_timeout = 0 s"


def test_one_pixel_shift_is_forgiven_by_the_neighbourhood_measure(api, reference_png):
    shifted = np.roll(tracer.decode_png(reference_png), 1, axis=1)
    body = grade(api, image=png_of(shifted)).json()
    assert body["fraction_off"] > 0.01 and body["fraction_off_nearby"] <= body["fraction_off"]


@pytest.mark.parametrize(
    "image, says",
    [
        (png_of(np.zeros((10, 10, 3), np.uint8)), "10×10 pixels, the scene is 160×120"),
        (b"GIF89a" + b"\0" * 100, "image is a GIF; PNG or PPM required"),
        (b"", "image is empty (0 bytes)"),
    ],
)
def test_bad_submissions_are_422(api, image, says):
    res = grade(api, image=image)
    assert res.status_code == 422 and says in res.json()["detail"]


def test_truncated_png_is_422(api, reference_png):
    res = grade(api, image=reference_png[: len(reference_png) // 2])
    detail = res.json()["detail"]
    assert res.status_code == 422 and detail.endswith(grading.CORRUPT), detail  # plain words, no class name
    assert "Error" not in detail


def test_png_bomb_is_refused_before_decoding(api):
    # a valid header declaring 50,000 × 50,000 pixels, with almost no data
    img = Image.new("RGB", (1, 1))
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    data = bytearray(buf.getvalue())
    import struct

    ihdr = struct.pack(">IIBBBBB", 50_000, 50_000, 8, 2, 0, 0, 0)
    data[8:33] = png_chunk(b"IHDR", ihdr)
    res = grade(api, image=bytes(data))
    assert res.status_code == 422 and "50000×50000" in res.json()["detail"]


def test_grade_form_errors(api, reference_png):
    assert grade(api, image=reference_png, tolerance="x").status_code == 422
    assert grade(api, image=reference_png, tolerance="-1").status_code == 422
    res = api.post("/grade", data={"scene": SCENE.decode()})
    assert res.status_code == 422 and "image: required" in res.json()["detail"]
    bad_scene = grade(api, scene=b'{"camera": {}}', image=reference_png)
    assert bad_scene.status_code == 422 and bad_scene.json()["errors"]
    twice = api.post(
        "/grade",
        data={"scene": SCENE.decode()},
        files=[("image", ("a.png", reference_png)), ("image", ("b.png", b"x"))],
    )
    assert twice.status_code == 422 and "image: given 2 times in the form" in twice.json()["detail"], twice.text


def test_heatmap(api, reference_png):
    res = api.post(
        "/grade?format=png&legend=false&heatmap=raw",
        data={"scene": SCENE.decode()},
        files={"image": ("s.png", reference_png, "image/png")},
    )
    assert res.status_code == 200 and res.headers["content-type"] == "image/png"
    heat = tracer.decode_png(res.content)
    assert heat.shape == (120, 160, 3) and heat.max() == 0


def test_the_scene_is_rendered_once_for_many_gradings(reference_png):
    api = client()
    for _ in range(5):
        assert grade(api, image=reference_png).json()["passed"]
    assert api.get("/healthz").json()["renders"] == 1


def test_schema_health_playground_docs(api):
    assert api.get("/schema").json()["required"] == ["camera", "image"]
    assert api.get("/healthz").json()["status"] == "ok"
    assert '"look_at"' in api.get("/").text
    for path in ("/", "/docs", "/redoc"):
        res = api.get(path)
        sources = re.findall(r'(?:src|href)="([^"]+)"', res.text)
        assert sources and all(u.startswith("/") for u in sources), sources  # the service's own assets only
        assert "default-src 'self'" in res.headers["content-security-policy"]
        for url in sources:
            assert api.get(url).status_code == 200, url
    spec = api.get("/openapi.json").json()
    assert {"/render", "/validate", "/grade", "/schema", "/healthz"} <= set(spec["paths"])
    assert "Scene" in spec["components"]["schemas"]


def test_api_key():
    api = client(api_key="s3cret")
    assert api.get("/healthz").status_code == 200
    assert api.get("/schema").status_code == 401
    assert api.post("/render", content=SCENE, headers=JSON).status_code == 401
    assert api.get("/schema", headers={"authorization": "Bearer s3cret"}).status_code == 200
    assert api.get("/schema", headers={"x-api-key": "s3cret"}).status_code == 200
    assert api.get("/schema", headers={"x-api-key": "wrong"}).status_code == 401
    for path in ("/docs", "/redoc", "/openapi.json", "/docs-assets/swagger-ui.css"):  # the docs stay open
        assert api.get(path).status_code == 200, path
    assert api.get("/openapi.json").json()["components"]["securitySchemes"]["apiKey"]["scheme"] == "bearer"


def test_a_syntax_error_is_marked_on_the_line_the_parser_names(api):
    res = api.post("/validate", content=b'{"camera": {\n  "x": 1,,\n}}', headers=JSON)
    (error,) = res.json()["errors"]
    assert res.status_code == 422 and error["line"] == 2 and error["message"].startswith("invalid JSON")


def test_a_server_worker_freezes_what_it_holds_after_start_up():
    """service.http.server.worker_app: a full garbage collection walks only what requests made, not the ~60k objects
    of the started app (which it would walk on the event loop's time)."""
    probe = "import gc; from service.http.server import worker_app; worker_app(); print(gc.get_freeze_count())"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert int(out) > 20_000


# -- the OpenAPI document describes the format and the answers ---------------------------------------------

from pathlib import Path  # noqa: E402

from jsonschema import Draft202012Validator  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def component(spec, name):
    """A validator of one of the OpenAPI document's component schemas (its $refs resolved within the document)."""
    return Draft202012Validator({"$ref": f"#/components/schemas/{name}", "components": spec["components"]})


def test_schema_and_openapi_accept_every_example(api):
    assert api.get("/schema").json() == schemas.json_schema()
    scene = component(api.get("/openapi.json").json(), "Scene")
    for path in sorted(ROOT.glob("examples/*.json")):
        assert scene.is_valid(json.loads(path.read_text())), path
    assert not scene.is_valid({"camera": {}, "image": {"width": 1, "height": 1}})


def test_try_it_out_sends_a_real_example_scene_that_renders(api):
    spec = api.get("/openapi.json").json()
    for path in ("/render", "/validate"):
        example = spec["paths"][path]["post"]["requestBody"]["content"]["application/json"]["example"]
        assert example == json.loads((ROOT / "examples" / "01_three_spheres.json").read_text())
    res = api.post("/render", json=example)
    assert res.status_code == 200 and res.content.startswith(b"\x89PNG")
    form = spec["paths"]["/grade"]["post"]["requestBody"]["content"]["multipart/form-data"]["schema"]
    assert json.loads(form["properties"]["scene"]["example"]) == example


def test_grade_and_the_error_list_have_response_models(api, reference_png):
    spec = api.get("/openapi.json").json()
    grade_200 = spec["paths"]["/grade"]["post"]["responses"]["200"]["content"]
    assert grade_200["application/json"]["schema"] == {"$ref": "#/components/schemas/GradeAnswer"}
    assert "image/png" in grade_200
    for path in ("/render", "/validate", "/grade"):
        answer = spec["paths"][path]["post"]["responses"]["422"]["content"]["application/json"]["schema"]
        assert answer == {"$ref": "#/components/schemas/ErrorAnswer"}, path
    passed = grade(api, image=reference_png).json()
    assert component(spec, "GradeAnswer").is_valid(passed) and passed["reason"] == ""
    invalid = api.post("/validate", content=SCENE.replace(b'"radius": 0.7', b'"radius": -0.7'), headers=JSON).json()
    assert component(spec, "ErrorAnswer").is_valid(invalid) and invalid["errors"][0]["line"]
    image = grade(api, image=b"GIF89a").json()
    assert component(spec, "ErrorAnswer").is_valid(image) and image["part"] == "image"
    assert not component(spec, "ErrorAnswer").is_valid({"errors": []})
