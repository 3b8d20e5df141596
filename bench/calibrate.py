"""``python -m bench.calibrate``: the cost model's estimate against measured render times (docs/cost-model.md)."""

from __future__ import annotations

import json
import resource
import time
from typing import Any

import schemas
from service.limits import estimated_cost
from tracer.render import Renderer

from .scenes import example, sphere_field


def nested(depth: int, size: int = 128) -> dict[str, Any]:
    """Four nested spheres whose materials both reflect and transmit."""
    mats = {"glass": {"reflectance": 0.2, "transmittance": 0.7, "ior": 1.5},
            "mirror": {"reflectance": 0.6, "transmittance": 0.3, "ior": 1.2}}
    objs = [{"type": "sphere", "material": ["glass", "mirror"][k % 2], "center": [0, 0, 0], "radius": 1.0 - 0.2 * k}
            for k in range(4)]
    return {"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0]},
            "image": {"width": size, "height": size, "max_depth": depth}, "materials": mats, "objects": objs,
            "lights": [{"type": "point", "color": 1, "position": [2, 2, 2]}]}


def concentric(count: int, size: int) -> dict[str, Any]:
    objs = [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1.0 + k} for k in range(count)]
    return {"camera": {"position": [0, 0, 0.5], "look_at": [0, 0, 0]}, "image": {"width": size, "height": size},
            "materials": {"m": {}}, "objects": objs,
            "lights": [{"type": "point", "color": 1, "position": [0.2, 0.2, 0.2]}]}


def main() -> None:
    scenes = {"01_three_spheres 640×480": example("01_three_spheres", 640, 480),
              "02_all_lights 320×240": example("02_all_lights", 320, 240),
              "04_whitted 320×240": example("04_whitted", 320, 240),
              "03_soft_shadows 320×240": example("03_soft_shadows", 320, 240),
              "10,000-sphere field 480×270": sphere_field(10000, 480, 270),
              "nested glass/mirror, depth 5, 128²": nested(5), "nested glass/mirror, depth 7, 128²": nested(7),
              "10,000 concentric spheres, eye inside, 32²": concentric(10_000, 32)}
    print("| scene | cost | seconds | cost per second | peak RSS MiB |\n|---|---|---|---|---|")
    for name, data in scenes.items():
        scene = schemas.validate_scene(json.loads(json.dumps(data)))
        cost = estimated_cost(scene)
        started = time.perf_counter()
        Renderer(scene).pixels()
        seconds = time.perf_counter() - started
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"| {name} | {cost:.3g} | {seconds:.2f} | {cost / seconds:.3g} | {rss:.0f} |", flush=True)


if __name__ == "__main__":
    main()
