"""The benchmark's scenes, built from the examples or generated."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

Scene = dict[str, Any]


def example(name: str, width: int | None = None, height: int | None = None) -> Scene:
    data = json.loads((EXAMPLES / f"{name}.json").read_text())
    if width:
        data["image"].update(width=width, height=height)
    return data


def torus_mesh(major: float, minor: float, nu: int, nv: int, center: tuple[float, float, float]) -> dict[str, Any]:
    """A smooth torus of ``2·nu·nv`` triangles with per-vertex normals."""
    u = np.linspace(0, 2 * math.pi, nu, endpoint=False)
    v = np.linspace(0, 2 * math.pi, nv, endpoint=False)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    ring = np.stack([np.cos(uu), np.zeros_like(uu), np.sin(uu)], axis=-1)
    normal = ring * np.cos(vv)[..., None] + np.array([0, 1.0, 0]) * np.sin(vv)[..., None]
    points = major * ring + minor * normal + np.asarray(center)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    return {
        "type": "mesh",
        "material": "torus",
        "vertices": np.round(points.reshape(-1, 3), 6).tolist(),
        "faces": faces.tolist(),
        "normals": np.round(normal.reshape(-1, 3), 6).tolist(),
    }


def mesh_scene(width: int = 640, height: int = 480) -> Scene:
    return {
        "camera": {"position": [0, 3, 6], "look_at": [0, 0.6, 0], "fov": 45},
        "image": {"width": width, "height": height, "background": [0.05, 0.06, 0.1]},
        "materials": {
            "floor": {"ambient": 0.08, "diffuse": 0.55, "specular": 0.2, "shininess": 10},
            "torus": {"ambient": [0.1, 0.05, 0.02], "diffuse": [0.7, 0.35, 0.15], "specular": 0.6, "shininess": 60},
        },
        "objects": [
            {"type": "plane", "material": "floor", "point": [0, 0, 0], "normal": [0, 1, 0]},
            torus_mesh(1.6, 0.55, 500, 208, (0, 0.9, 0)),
        ],
        "lights": [{"type": "ambient", "color": 1}, {"type": "point", "position": [-3, 6, 4], "color": 0.9}],
    }


def sphere_field(count: int, width: int = 1920, height: int = 1080) -> Scene:
    """``count`` spheres on a square grid over a floor, seen from above at an angle."""
    side = math.ceil(math.sqrt(count))
    rng = np.random.default_rng(7)
    spheres = []
    for k in range(count):
        x, z = (k % side - side / 2) * 1.0, (k // side - side / 2) * 1.0
        r = 0.25 + 0.15 * rng.random()
        spheres.append({"type": "sphere", "material": f"m{k % 3}", "center": [x, r, z], "radius": round(r, 4)})
    colours = [[0.7, 0.15, 0.1], [0.15, 0.6, 0.2], [0.15, 0.25, 0.7]]
    materials = {
        f"m{i}": {"ambient": [c * 0.15 for c in col], "diffuse": col, "specular": 0.5, "shininess": 60}
        for i, col in enumerate(colours)
    }
    materials["floor"] = {"ambient": 0.08, "diffuse": 0.55, "specular": 0.2, "shininess": 10}
    return {
        "camera": {"position": [0, side * 0.45 + 2, side * 0.7 + 3], "look_at": [0, 0, 0], "fov": 50},
        "image": {"width": width, "height": height, "background": [0.05, 0.06, 0.1]},
        "materials": materials,
        "objects": [{"type": "plane", "material": "floor", "point": [0, 0, 0], "normal": [0, 1, 0]}, *spheres],
        "lights": [
            {"type": "ambient", "color": 1},
            {"type": "point", "position": [-side * 0.3, side * 0.6 + 5, side * 0.4], "color": 0.9},
        ],
    }


def speed_scenes() -> dict[str, Scene]:
    """The fixed set of the speed table, by name."""
    return {
        "three_spheres_1080p": example("01_three_spheres", 1920, 1080),
        "three_spheres_4k": example("01_three_spheres", 3840, 2160),
        "all_lights_640": example("02_all_lights", 640, 480),
        "whitted_640": example("04_whitted", 640, 480),
        "mesh_208k_640": mesh_scene(),
        "spheres_10_1080p": sphere_field(10),
        "spheres_10000_1080p": sphere_field(10_000),
        "area_8x8_640": example("03_soft_shadows", 640, 480),
    }


def with_image(scene: Scene, **image: Any) -> Scene:
    out = copy.deepcopy(scene)
    out["image"].update(image)
    return out
