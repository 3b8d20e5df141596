"""The heat-map explains the verdict: it marks the pixels the verdict counted, brighter and darker apart."""

import json

import numpy as np
import pytest
from fastapi.testclient import TestClient

import schemas
import tracer
from service.cli import main
from service.http.app import create_app
from service.images import grading, heatmap
from service.settings import Settings

from helpers import SCENES, scene_dict

SCENE = (SCENES / "02_all_lights.json").read_bytes()


@pytest.fixture(scope="module")
def reference():
    return tracer.render(schemas.load_scene(SCENE))


def marked(heat: np.ndarray, colour) -> np.ndarray:
    return np.all(heat == colour, axis=2)


def test_a_passing_one_pixel_shift_marks_nothing_that_decides(reference):
    shifted = np.concatenate([reference[:, :1], reference[:, :-1]], axis=1)
    grade = grading.grade(reference, shifted, "", 2, 0.001)
    heat = heatmap.verdict_pixels(reference, shifted, 2)
    assert grade.passed and grade.fraction_off > 0.01
    assert not marked(heat, heatmap.BRIGHTER).any() and not marked(heat, heatmap.DARKER).any()
    assert marked(heat, heatmap.FORGIVEN).mean() == pytest.approx(grade.fraction_off)  # the forgiven edges


def test_the_marked_pixels_are_those_the_verdict_counted_brighter_and_darker_apart(reference):
    data = scene_dict("02_all_lights")
    dimmer = tracer.render(schemas.validate_scene({**data, "lights": data["lights"][:-1]}))
    grade = grading.grade(reference, dimmer, "", 2, 0.001)
    heat = heatmap.verdict_pixels(reference, dimmer, 2)
    assert not grade.passed
    darker, brighter = marked(heat, heatmap.DARKER), marked(heat, heatmap.BRIGHTER)
    assert darker.mean() + brighter.mean() == pytest.approx(grade.fraction_off_nearby)
    assert darker.sum() > 0 and brighter.sum() == 0  # a light less: darker, never brighter
    other_way = heatmap.verdict_pixels(dimmer, reference, 2)  # the submission has a light too many: brighter
    assert marked(other_way, heatmap.BRIGHTER).sum() > 0 and marked(other_way, heatmap.DARKER).sum() == 0


def test_pixels_within_the_tolerance_show_the_reference_dimmed(reference):
    heat = heatmap.verdict_pixels(reference, reference, 2)
    assert np.array_equal(heat[:, :, 0], (reference.astype(int).sum(axis=2) // 10).astype(np.uint8))
    assert heat.max() <= 76


def test_the_legend_is_a_band_beneath_and_the_raw_difference_stays_available(reference):
    plain = heatmap.verdict_pixels(reference, 255 - reference, 2)
    framed = heatmap.with_legend(plain)
    assert framed.shape[0] == plain.shape[0] + heatmap.ROW * len(heatmap.LEGEND) + 4
    assert np.array_equal(framed[: plain.shape[0], : plain.shape[1]], plain)
    raw = heatmap.raw_pixels(reference, reference.copy())
    assert raw.max() == 0
    off = reference.copy()
    off[0, 0] = (reference[0, 0].astype(int) + 100) % 256
    assert tuple(heatmap.raw_pixels(reference, off)[0, 0]) == (255, 255, 255)  # 64+ levels: white


def test_http_gives_the_verdict_heat_map_with_its_legend_or_the_raw_one(reference):
    api = TestClient(create_app(Settings()))
    data = scene_dict("02_all_lights")
    dimmer = tracer.render(schemas.validate_scene({**data, "lights": data["lights"][:-1]}))
    form = {"scene": SCENE.decode()}
    files = {"image": ("s.png", tracer.encode_png(dimmer), "image/png")}
    framed = tracer.decode_png(api.post("/grade?format=png", data=form, files=files).content)
    plain = tracer.decode_png(api.post("/grade?format=png&legend=false", data=form, files=files).content)
    raw = tracer.decode_png(api.post("/grade?format=png&heatmap=raw&legend=false", data=form, files=files).content)
    assert np.array_equal(plain, heatmap.verdict_pixels(reference, dimmer, 2))
    assert np.array_equal(framed, heatmap.with_legend(plain))
    assert np.array_equal(raw, heatmap.raw_pixels(reference, dimmer))
    tolerant = api.post("/grade?format=png&legend=false", data={**form, "tolerance": "255"}, files=files).content
    assert not marked(tracer.decode_png(tolerant), heatmap.DARKER).any()  # drawn with the grade's own tolerance


def test_the_cli_writes_the_verdict_heat_map_with_its_legend(reference, tmp_path, capsys):
    image = tmp_path / "same.png"
    image.write_bytes(tracer.encode_png(reference))
    scene = tmp_path / "scene.json"
    scene.write_bytes(SCENE)
    assert main(["grade", str(scene), str(image), "--heatmap", str(tmp_path / "heat.png")]) == 0
    heat = tracer.decode_png((tmp_path / "heat.png").read_bytes())
    assert np.array_equal(heat, heatmap.with_legend(heatmap.verdict_pixels(reference, reference, 2)))
    assert main(["grade", str(scene), str(image), "--heatmap", str(tmp_path / "raw.png"), "--raw-heatmap"]) == 0
    raw = tracer.decode_png((tmp_path / "raw.png").read_bytes())
    assert np.array_equal(raw, heatmap.with_legend(heatmap.raw_pixels(reference, reference), "raw"))
    json.dumps(heatmap.LEGEND)  # (the legend is plain data: the report and the playground show the same words)
