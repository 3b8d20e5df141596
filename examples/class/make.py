"""Rebuild the sample class: three tasks, five students, every kind of outcome.

    python examples/class/make.py

ada gets everything right; ben's lights image misses a light and his mirror image is shifted by a pixel
(forgiven by the neighbourhood measure: a pass); chen sent a text file named .png and an image of the wrong size;
dara has her own randomised spheres scene, in the TA's student-scenes/ folder (and renders it right); eli sent
nothing for two tasks, and a scene of his own (ignored: students cannot change their task); frank's files come
as a learning-management system downloads them: Spheres.PNG, one folder deeper hw3/lights.png, and a JPEG
mirror.jpg; gus and hana made classic mistakes, which the report names: gus cast no shadow rays and used the
Blinn–Phong half vector, hana cast no shadow rays, left out attenuation and inverted the index of refraction.
tasks.json gives each task its points, and half of the spheres' for an image whose one fault is no shadows.
"""

import copy
import io
import json
from pathlib import Path

import numpy as np
from PIL import Image

import schemas
import tracer

HERE = Path(__file__).resolve().parent
EXAMPLES = HERE.parent
TASKS = {"spheres": "01_three_spheres", "lights": "02_all_lights", "mirror": "04_whitted"}


def render(data: dict, mistake: str | None = None) -> np.ndarray:
    from tracer.scene.variants import VARIANTS

    scene = schemas.validate_scene(copy.deepcopy(data))
    return tracer.Renderer(scene, VARIANTS[mistake][0]).pixels() if mistake else tracer.render(scene)


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
    (HERE / "student-scenes" / "dara").mkdir(parents=True, exist_ok=True)
    (HERE / "student-scenes" / "dara" / "spheres.json").write_text(json.dumps(own, indent=2) + "\n")
    save(sub / "dara" / "spheres.png", render(own))
    save(sub / "dara" / "lights.png", right["lights"])
    save(sub / "dara" / "mirror.png", right["mirror"])
    save(sub / "eli" / "spheres.png", right["spheres"])
    (sub / "eli" / "notes.txt").write_text("I ran out of time.\n")
    empty = {"camera": scenes["lights"]["camera"], "image": scenes["lights"]["image"]}
    (sub / "eli" / "lights.json").write_text(json.dumps(empty, indent=2) + "\n")  # a task of his own: ignored
    save(sub / "eli" / "lights.png", np.zeros_like(right["lights"]))
    save(sub / "frank" / "Spheres.PNG", right["spheres"])
    save(sub / "frank" / "hw3" / "lights.png", right["lights"])
    buf = io.BytesIO()
    Image.fromarray(right["mirror"]).save(buf, format="JPEG", quality=95)
    (sub / "frank" / "mirror.jpg").write_bytes(buf.getvalue())
    for student, mistakes in (
        ("gus", {"spheres": "no-shadows", "lights": "blinn-phong", "mirror": None}),
        ("hana", {"spheres": "no-shadows", "lights": "no-attenuation", "mirror": "ior-inverted"}),
    ):
        for task, mistake in mistakes.items():
            save(sub / student / f"{task}.png", render(scenes[task], mistake))
    points = {
        "spheres": {"points": 2, "deductions": {"no-shadows": 1}},
        "lights": {"points": 3},
        "mirror": {"points": 5, "tolerance": 3},
    }
    (HERE / "tasks.json").write_text(json.dumps(points, indent=2) + "\n")


if __name__ == "__main__":
    main()
