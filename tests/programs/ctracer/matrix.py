"""The C student tracer (ctracer.c) graded by phongray: every style and mistake × every example scene.

``python tests/programs/ctracer/matrix.py [SCENE.json ...]`` (default: examples/0*.json, the Cornell-box
homework among them) builds ctracer with gcc, renders each scene with each row's switches, grades the image as
``phongray grade`` does (the reference, then the accepted variants, then the diagnosis) and prints a Markdown
table: ``PASS``, ``PASS(the accepted variant's words)``, or ``FAIL(the mistake ids the diagnosis names)``,
``FAIL(~id)`` where it only comes closest to one, ``FAIL(unnamed)`` where it names none.  A mistake whose image
is the honest float64 image, byte for byte, is ``—`` (the scene does not show it); one that differs from it and
passes says how many pixels differ: ``PASS(8 px differ)``.  tests/test_ctracer.py uses the same helpers.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from schemas import Scene, load_scene  # noqa: E402
from service.work import pipeline  # noqa: E402
from tracer import Renderer, decode_png, encode_png  # noqa: E402

SOURCES = ("ctracer.c", "trace_core.h")
EXAMPLES = sorted((ROOT / "examples").glob("0*.json"))

#: the honest styles: name → (switches, the offset as a fraction of the scene's size, or None)
STYLES: dict[str, tuple[list[str], float | None]] = {
    "float64": ([], None),
    "float32": (["--float32"], None),
    "offset 1e-4": ([], 1e-4),
    "offset 1e-3": ([], 1e-3),
    "t_min 1e-4": (["--offset-along", "ray"], 1e-4),
    "t_min 1e-3": (["--offset-along", "ray"], 1e-3),
}


def build(folder: Path) -> Path:
    """ctracer compiled with gcc into ``folder`` (the build line of its header)."""
    for name in SOURCES:
        shutil.copy(HERE / name, folder / name)
    binary = folder / "ctracer"
    subprocess.run(
        ["gcc", "-O2", "-o", str(binary), str(folder / "ctracer.c"), "-lz", "-lm"],
        check=True,
        capture_output=True,
    )
    return binary


def mistakes(binary: Path) -> list[str]:
    """The ids of the mistakes ctracer makes (``ctracer --mistakes``): phongray's, and a few it has no id for."""
    listed = subprocess.run([str(binary), "--mistakes"], check=True, capture_output=True, text=True)
    return listed.stdout.split()


def scene_size(scene: dict[str, Any]) -> float:
    """The scene's size as phongray's accepted variants measure it: the largest side of the box around its
    spheres and triangles (planes not counted; 1 with none)."""
    points: list[list[float]] = []
    for obj in scene.get("objects", []):
        if obj["type"] == "sphere":
            points += [[c - obj["radius"] for c in obj["center"]], [c + obj["radius"] for c in obj["center"]]]
        elif obj["type"] in ("triangle", "mesh"):
            points += obj["vertices"]
    if not points:
        return 1.0
    side = max(max(p[k] for p in points) - min(p[k] for p in points) for k in range(3))
    return side or 1.0


def switches(row: str, scene: dict[str, Any]) -> list[str]:
    """ctracer's switches for a row: a style's name or a mistake's id."""
    if row not in STYLES:  # (a mistake)
        return ["--mistake", row]
    args, fraction = STYLES[row]
    return args + ([] if fraction is None else ["--offset", repr(fraction * scene_size(scene))])


def render(binary: Path, scene_path: Path, out: Path, args: list[str]) -> bytes:
    """The PNG ctracer writes for the scene with ``args``."""
    subprocess.run([str(binary), str(scene_path), str(out), *args], check=True, capture_output=True, timeout=300)
    return out.read_bytes()


class Grader:
    """Grades images of scenes as ``phongray grade`` does, each scene's reference rendered once."""

    def __init__(self) -> None:
        self.references: dict[Path, tuple[Scene, bytes]] = {}

    def reference(self, path: Path) -> tuple[Scene, bytes]:
        if path not in self.references:
            scene = load_scene(path.read_bytes())
            self.references[path] = (scene, encode_png(Renderer(scene).pixels()))
        return self.references[path]

    def grade(self, path: Path, image: bytes, diagnose: bool = True) -> dict[str, Any]:
        """The answer of ``phongray grade --json`` (``diagnose=False``: of ``--no-diagnosis``)."""
        scene, reference = self.reference(path)
        checks = pipeline.Checks(diagnose=diagnose)
        graded = pipeline.grade_png(reference, image, 2.0, 0.001, explaining=pipeline.Explaining(lambda: scene, checks))
        return graded.as_dict()


def cell(result: dict[str, Any]) -> str:
    """A grade in a few words: PASS, PASS(accepted variant), FAIL(named ids), FAIL(~closest), FAIL(unnamed)."""
    if result["passed"]:
        return "PASS" if result["accepted"] is None else f"PASS({result['accepted']})"
    causes = (result["diagnosis"] or {}).get("causes", [])
    named = [c["variant"] for c in causes if c["passes"]]
    if named:
        return "FAIL(" + ", ".join(named) + ")"
    if causes and result["diagnosis"].get("closest"):
        return f"FAIL(~{causes[0]['variant']})"
    return "FAIL(unnamed)"


def differing(image: bytes, honest: bytes) -> int:
    """How many pixels of two PNGs of one size differ."""
    a, b = decode_png(image), decode_png(honest)
    return int(np.count_nonzero(np.any(a != b, axis=2)))


def main(paths: list[Path]) -> None:
    import tempfile

    grader = Grader()
    with tempfile.TemporaryDirectory() as folder:
        binary = build(Path(folder))
        scenes = {path: json.loads(path.read_text()) for path in paths}
        honest = {path: render(binary, path, Path(folder) / "honest.png", []) for path in paths}
        print("| style / mistake | " + " | ".join(path.stem for path in paths) + " |")
        print("|---|" + "---|" * len(paths))
        wrong = mistakes(binary)
        for row in [*STYLES, *wrong]:
            cells = []
            for path in paths:
                image = render(binary, path, Path(folder) / "out.png", switches(row, scenes[path]))
                if row in wrong and image == honest[path]:
                    cells.append("—")
                    continue
                verdict = cell(grader.grade(path, image))
                if row in wrong and verdict == "PASS":
                    verdict = f"PASS({differing(image, honest[path])} px differ)"
                cells.append(verdict)
            print(f"| {row} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main([Path(p) for p in sys.argv[1:]] or EXAMPLES)
