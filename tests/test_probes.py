"""Probe scenes (service.programs.probes): each changes one thing of the task's scene, a pure function."""

import copy
import json
import math
from pathlib import Path

import pytest

from schemas import load_scene
from service.programs.probes import MAX_PROBES, Kind, probes

HERE = Path(__file__).parent / "programs"


def scene(name: str) -> dict:
    return json.loads((HERE / f"{name}.json").read_text())


def by_name(task: dict) -> dict:
    return {p.name: p for p in probes(task)}


def test_the_probes_of_a_scene_with_a_spot_and_a_point_light():
    task = scene("spot")
    found = by_name(task)
    assert list(found) == [
        "diffuse only",
        "specular only",
        "spot light 'key' alone",
        "point light 'fill' alone",
        "the camera moved",
    ]
    spot = found["spot light 'key' alone"]
    assert spot.kind is Kind.LIGHT and spot.scene["lights"] == [task["lights"][1]]
    assert spot.region is not None and spot.region["lights"][0]["inner_cutoff"] == 35
    assert found["point light 'fill' alone"].region is None
    diffuse = found["diffuse only"].scene["materials"]["red"]
    assert (diffuse["ambient"], diffuse["specular"], diffuse["diffuse"]) == (0, 0, [0.9, 0.2, 0.2])
    assert found["specular only"].scene["materials"]["red"]["diffuse"] == 0


def test_mirrors_and_glass_are_taken_out_one_at_a_time():
    found = by_name(scene("glass"))
    assert {"no glass", "no mirrors"} <= set(found)
    no_glass = found["no glass"].scene["materials"]
    assert no_glass["glass"]["transmittance"] == 0 and no_glass["mirror"]["reflectance"] == 0.7
    no_mirrors = found["no mirrors"].scene["materials"]
    assert no_mirrors["mirror"]["reflectance"] == 0 and no_mirrors["glass"]["transmittance"] == 0.8
    assert not any(p.kind is Kind.LIGHT for p in found.values())  # one point light: nothing to isolate


def test_the_camera_turns_about_the_point_it_looks_at():
    task = scene("glass")
    moved = by_name(task)["the camera moved"].scene["camera"]
    eye, at = task["camera"]["position"], task["camera"]["look_at"]
    assert moved["look_at"] == at and moved["position"] != eye
    assert math.dist(moved["position"], at) == pytest.approx(math.dist(eye, at), rel=1e-12)
    assert moved["position"][1] == eye[1]


def test_probes_are_valid_scenes_and_the_task_is_left_as_it_was():
    for name in ("spot", "glass"):
        task = scene(name)
        before = copy.deepcopy(task)
        for probe in probes(task):
            load_scene(json.dumps(probe.scene).encode())
            if probe.region is not None:
                load_scene(json.dumps(probe.region).encode())
        assert task == before
        assert probes(task) == probes(before)  # a pure function: the same probes every time


def test_at_most_the_fixed_number_of_probes_and_the_camera_is_kept():
    task = scene("spot")
    task["lights"] += [{"type": "point", "position": [x, 3, 2], "color": 0.1} for x in range(10)]
    found = probes(task)
    assert len(found) == MAX_PROBES
    assert found[-1].kind is Kind.CAMERA


def test_a_scene_without_specular_has_no_specular_probe():
    task = scene("glass")
    for material in task["materials"].values():
        material["specular"] = 0
    assert "specular only" not in by_name(task)
