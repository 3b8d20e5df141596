"""``python -m bench.calibrate``: the cost model's estimate against measured render times (docs/cost-model.md)."""

from __future__ import annotations

import json
import time
from typing import Any

import schemas
from service.admission.limits import estimated_cost, per_ray_factor
from tracer.render import Renderer

from .scenes import example, sphere_field


def nested(depth: int, size: int = 128) -> dict[str, Any]:
    """Four nested spheres whose materials both reflect and transmit."""
    mats = {
        "glass": {"reflectance": 0.2, "transmittance": 0.7, "ior": 1.5},
        "mirror": {"reflectance": 0.6, "transmittance": 0.3, "ior": 1.2},
    }
    objs = [
        {"type": "sphere", "material": ["glass", "mirror"][k % 2], "center": [0, 0, 0], "radius": 1.0 - 0.2 * k}
        for k in range(4)
    ]
    return {
        "camera": {"position": [0, 0, 3], "look_at": [0, 0, 0]},
        "image": {"width": size, "height": size, "max_depth": depth},
        "materials": mats,
        "objects": objs,
        "lights": [{"type": "point", "color": 1, "position": [2, 2, 2]}],
    }


def concentric(count: int, size: int) -> dict[str, Any]:
    objs = [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1.0 + k} for k in range(count)]
    return {
        "camera": {"position": [0, 0, 0.5], "look_at": [0, 0, 0]},
        "image": {"width": size, "height": size},
        "materials": {"m": {}},
        "objects": objs,
        "lights": [{"type": "point", "color": 1, "position": [0.2, 0.2, 0.2]}],
    }


def homework(width: int, height: int) -> dict[str, Any]:
    """The Cornell-box homework (examples/09_cornell_homework.json: a mirror ball, a glass ball, an area light
    and a spot, depth 5, 2×2 samples) at this size."""
    return example("09_cornell_homework", width, height)


def antialiased(name: str, width: int, height: int, samples: int) -> dict[str, Any]:
    data = example(name, width, height)
    data["image"]["samples"] = samples
    return data


def scenes() -> dict[str, dict[str, Any]]:
    """The calibration's scenes by name: the examples, course scenes and the hard cases of the cost model."""
    return {
        "01_three_spheres 640×480": example("01_three_spheres", 640, 480),
        "02_all_lights 320×240": example("02_all_lights", 320, 240),
        "03_soft_shadows 320×240": example("03_soft_shadows", 320, 240),
        "04_whitted 320×240": example("04_whitted", 320, 240),
        "04_whitted 640×480 2×2": antialiased("04_whitted", 640, 480, 2),
        "05_mesh 320×240": example("05_mesh", 320, 240),
        "07_spotlights 320×240": example("07_spotlights", 320, 240),
        "08_antialiased 320×240": example("08_antialiased", 320, 240),
        "Cornell homework 320×240 2×2": homework(320, 240),
        "Cornell homework 640×480 2×2": homework(640, 480),
        "10,000-sphere field 480×270": sphere_field(10000, 480, 270),
        "nested glass/mirror, depth 5, 128²": nested(5),
        "nested glass/mirror, depth 7, 128²": nested(7),
        "10,000 concentric spheres, eye inside, 32²": concentric(10_000, 32),
    }


def main() -> None:
    print(
        "| scene | estimated cost | counted cost | estimate ÷ counted | seconds | counted cost per second |\n"
        "|---|---|---|---|---|---|"
    )
    for name, data in scenes().items():
        scene = schemas.validate_scene(json.loads(json.dumps(data)))
        estimate = estimated_cost(scene)
        renderer = Renderer(scene)
        started = time.perf_counter()
        renderer.pixels()
        seconds = time.perf_counter() - started
        counted = renderer.spent * per_ray_factor(scene)
        print(
            f"| {name} | {estimate:.3g} | {counted:.3g} | {estimate / counted:.2f} | {seconds:.2f} | "
            f"{counted / seconds:.3g} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
