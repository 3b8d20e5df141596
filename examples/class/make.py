"""Rebuild the sample class: three tasks, five students, every kind of outcome.

    python examples/class/make.py

ada gets everything right; ben's lights image misses a light and his mirror image is shifted by a pixel
(forgiven by the neighbourhood measure: a pass); chen sent a text file named .png and an image of the wrong size;
dara has her own randomised spheres scene (and renders it right); eli sent nothing for two tasks.
"""

import copy
import json
from pathlib import Path

import numpy as np

import schemas
import tracer

HERE = Path(__file__).resolve().parent
EXAMPLES = HERE.parent
TASKS = {"spheres": "01_three_spheres", "lights": "02_all_lights", "mirror": "04_whitted"}


def render(data: dict) -> np.ndarray:
    return tracer.render(schemas.validate_scene(copy.deepcopy(data)))


def save(path: Path, pixels: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(tracer.encode_png(pixels))


def main() -> None:
    scenes = {task: json.loads((EXAMPLES / f"{name}.json").read_text()) for task, name in TASKS.items()}
    for task, data in scenes.items():
        (HERE / "scenes").mkdir(exist_ok=True)
        (HERE / "scenes" / f"{task}.json").write_text(json.dumps(data, indent=2) + "\n")
    right = {task: render(data) for task, data in scenes.items()}
    sub = HERE / "submissions"
    for task, pixels in right.items():
        save(sub / "ada" / f"{task}.png", pixels)
    save(sub / "ben" / "spheres.png", right["spheres"])
    dim = copy.deepcopy(scenes["lights"])
    dim["lights"] = dim["lights"][:-1]
    save(sub / "ben" / "lights.png", render(dim))
    save(sub / "ben" / "mirror.png", np.concatenate([right["mirror"][:, :1], right["mirror"][:, :-1]], axis=1))
    (sub / "chen").mkdir(parents=True, exist_ok=True)
    (sub / "chen" / "spheres.png").write_text("not an image\n")
    save(sub / "chen" / "lights.png", right["lights"][:60, :80])
    save(sub / "chen" / "mirror.png", right["mirror"])
    own = copy.deepcopy(scenes["spheres"])
    for obj in own["objects"]:
        if obj["type"] == "sphere":
            obj["center"][0] += 0.35
    (sub / "dara").mkdir(parents=True, exist_ok=True)
    (sub / "dara" / "spheres.json").write_text(json.dumps(own, indent=2) + "\n")
    save(sub / "dara" / "spheres.png", render(own))
    save(sub / "dara" / "lights.png", right["lights"])
    save(sub / "dara" / "mirror.png", right["mirror"])
    save(sub / "eli" / "spheres.png", right["spheres"])
    (sub / "eli" / "notes.txt").write_text("I ran out of time.\n")


if __name__ == "__main__":
    main()
