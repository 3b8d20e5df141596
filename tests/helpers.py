"""Shared helpers for the tests: scene files, moving scenes, comparing images."""

from __future__ import annotations

import copy
import json
import os
import shutil
import subprocess
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import schemas
import tracer

SCENES = Path(__file__).parent / "scenes"
EXAMPLES = sorted(p.stem for p in SCENES.glob("*.json"))


def measured(name: str, value: float) -> None:
    """Keep a time a test measured, for ``python -m bench.budgets`` (which sets ``PHONGRAY_MEASUREMENTS`` to a
    file): the tests assert outcomes, with bounds that hold on a busy machine; the latency budgets are the
    bench's, checked on a quiet one."""
    path = os.environ.get("PHONGRAY_MEASUREMENTS")
    if path:
        with open(path, "a") as f:
            f.write(json.dumps({"name": name, "value": value}, ensure_ascii=False) + "\n")


def scene_dict(name: str) -> dict[str, Any]:
    return json.loads((SCENES / f"{name}.json").read_text())


def reference(name: str) -> np.ndarray:
    return tracer.decode_png((SCENES / f"{name}.png").read_bytes())


def render_dict(data: dict[str, Any], **kwargs: Any) -> np.ndarray:
    return tracer.render(schemas.validate_scene(data), **kwargs)


def translated(data: dict[str, Any], shift: tuple[float, float, float]) -> dict[str, Any]:
    """The same scene moved by ``shift``: camera, objects and lights alike."""
    out = copy.deepcopy(data)
    s = np.asarray(shift, dtype=np.float64)

    def move(p: list[float]) -> list[float]:
        return [float(v) for v in np.asarray(p, dtype=np.float64) + s]

    cam = out["camera"]
    cam["position"], cam["look_at"] = move(cam["position"]), move(cam["look_at"])
    for obj in out.get("objects", []):
        for key in ("center", "point"):
            if key in obj:
                obj[key] = move(obj[key])
        if "vertices" in obj:
            obj["vertices"] = [move(v) for v in obj["vertices"]]
    for light in out.get("lights", []):
        for key in ("position", "corner"):
            if key in light:
                light[key] = move(light[key])
    return out


def smooth_octahedron(centre: tuple[float, float, float], radius: float, material: str) -> dict[str, Any]:
    """A mesh of eight faces with its corners' outward normals: a ball shaded smooth, whose normals, blended
    mid-face, are a vector of length 1/√3 before they are made unit (a mistake that leaves them so shows)."""
    axes = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    corners = [[c + radius * a for c, a in zip(centre, axis)] for axis in axes]
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return {"type": "mesh", "material": material, "vertices": corners, "faces": faces, "normals": axes}


def differing(a: np.ndarray, b: np.ndarray, tolerance: int = 2) -> float:
    """Fraction of pixels whose largest channel difference exceeds ``tolerance``."""
    d = np.abs(a.astype(np.int16) - b.astype(np.int16)).max(axis=2)
    return float(np.mean(d > tolerance))


def mean_abs(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean(np.abs(a.astype(np.float64) - b.astype(np.float64))))


def scaled(data: dict[str, Any], factor: float) -> dict[str, Any]:
    """The same scene scaled about the world origin (attenuation-free scenes look the same)."""
    out = copy.deepcopy(data)

    def mul(p: list[float]) -> list[float]:
        return [float(v) * factor for v in p]

    cam = out["camera"]
    cam["position"], cam["look_at"] = mul(cam["position"]), mul(cam["look_at"])
    if cam.get("type") == "orthographic":
        cam["height"] = cam.get("height", 2.0) * factor
    for mat in out.get("materials", {}).values():
        if "checker" in mat:
            mat["checker"]["size"] *= factor
    for obj in out.get("objects", []):
        for key in ("center", "point"):
            if key in obj:
                obj[key] = mul(obj[key])
        if "radius" in obj:
            obj["radius"] *= factor
        if "vertices" in obj:
            obj["vertices"] = [mul(v) for v in obj["vertices"]]
    for light in out.get("lights", []):
        for key in ("position", "corner", "edge_u", "edge_v"):
            if key in light:
                light[key] = mul(light[key])
    return out


def run_autograder(bundle: Path, root: Path, files: dict[str, Path]) -> tuple[subprocess.CompletedProcess[str], dict]:
    """Lay ``root`` out as Gradescope does (the bundle in source/, the files in submission/) and run
    run_autograder there as Gradescope runs it; its output and results.json."""
    for folder in ("source", "submission", "results"):
        (root / folder).mkdir(parents=True)
    with zipfile.ZipFile(bundle) as archive:
        archive.extractall(root / "source")
    for name, path in files.items():  # (a name may hold a folder: hw3/cornell.png, as a zip's unpacking has it)
        (root / "submission" / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, root / "submission" / name)
    env = {**os.environ, "PHONGRAY_AUTOGRADER_ROOT": str(root), "PHONGRAY_AUTOGRADER_PYTHON": sys.executable}
    done = subprocess.run(
        ["bash", str(root / "source" / "run_autograder")],
        cwd=root,
        env=env,
        text=True,
        capture_output=True,
        timeout=600,
    )
    return done, json.loads((root / "results" / "results.json").read_text())


@dataclass(frozen=True)
class Process:
    """A live process that this process's tests started: its id, its parent's, the user it runs as and its args."""

    pid: int
    parent: int
    uid: int
    args: str


def own_processes() -> list[Process]:
    """This process's live descendants, zombies left out: every process its tests started, directly or through
    others (tests/conftest.py makes it the reaper of its orphans, so a daemon that double-forked is still among
    them), and nothing that other programs on the machine run, nor the tests of pytest-xdist's other processes
    (each its own process, a sibling of this one, not a descendant)."""
    live: dict[int, Process] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            args = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
            uid = entry.stat().st_uid
        except OSError:  # (gone meanwhile)
            continue
        fields = stat[stat.rfind(")") + 2 :].split()  # (after the command's name, which may hold spaces)
        if fields[0] != "Z":
            live[int(entry.name)] = Process(int(entry.name), int(fields[1]), uid, args)
    return [live[pid] for pid in sorted(_descendants(live, os.getpid()))]


def _descendants(live: dict[int, Process], root: int) -> set[int]:
    mine: set[int] = set()
    for _ in range(len(live)):  # (each round adds a generation; bounded by the number of processes)
        grown = {p.pid for p in live.values() if p.parent == root or p.parent in mine}
        if grown == mine:
            break
        mine = grown
    return mine


def left_in_sandboxes(word: str | None = None) -> list[str]:
    """This process's descendants that a student's run left: bubblewrap and everything under it, whatever user
    it runs as, and any process whose command line holds ``word`` (a hostile program's marker)."""
    own = own_processes()
    sandboxes = {p.pid for p in own if Path(p.args.split(" ", 1)[0]).name == "bwrap"}
    under = {p.pid for p in own if p.pid in sandboxes}
    for _ in range(len(own)):
        grown = under | {p.pid for p in own if p.parent in under}
        if grown == under:
            break
        under = grown
    return [f"{p.pid} uid {p.uid}: {p.args}" for p in own if p.pid in under or (word is not None and word in p.args)]


def share_renders(monkeypatch: Any) -> dict[tuple[str, Any], dict[int, np.ndarray]]:
    """Rendered rows kept for the rest of a test, by scene, options and row: a render asked for again, whole
    (:meth:`tracer.Renderer.pixels`) or a few of its rows (:meth:`~tracer.Renderer.pixels_of_rows`), is the
    one made before, and only rows not yet rendered are.  For tests of what a diagnosis makes of the renders
    it asks for, in which each of several diagnoses of one scene starts from nothing: every pixel is computed
    alone (both methods' docstrings, and tests/test_render.py), so a row is byte for byte the same row however
    it was asked for.  The rows are copied out, never shared; a render with a budget, a progress, a band or a
    cancel is made as asked."""
    kept: dict[tuple[str, Any], dict[int, np.ndarray]] = {}
    real_rows, real_pixels = tracer.Renderer.pixels_of_rows, tracer.Renderer.pixels

    def rows(self: Any, numbers: Any, threads: Any = None, chunk_rays: Any = None, cancel: Any = None) -> Any:
        if cancel is not None and cancel():
            return real_rows(self, numbers, threads, chunk_rays, cancel)  # (stopped as it would have been)
        mine = kept.setdefault((self.scene.model_dump_json(), self.options), {})
        wanted = [int(r) for r in np.asarray(numbers)]
        todo = sorted(set(wanted) - set(mine))
        if todo:
            mine.update(zip(todo, real_rows(self, np.array(todo, dtype=np.int64), threads, chunk_rays, cancel)))
        return np.stack([mine[r] for r in wanted]).copy()

    def pixels(self: Any, threads: Any = None, *args: Any, **kw: Any) -> Any:
        if args or any(v is not None for k, v in kw.items() if k != "cancel"):
            return real_pixels(self, threads, *args, **kw)
        return rows(self, np.arange(self.scene.image.height), threads, None, kw.get("cancel"))

    monkeypatch.setattr(tracer.Renderer, "pixels_of_rows", rows)
    monkeypatch.setattr(tracer.Renderer, "pixels", pixels)
    return kept
