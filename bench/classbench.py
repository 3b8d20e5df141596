"""The class-grading row of ``phongray bench``: 40 students × 4 tasks at 320×240, one task randomised per
student (so 43 distinct scenes), graded from scratch locally (a process per core) and through a running
``phongray serve --workers 2``.  Pairs per second include rendering every reference."""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from typing import Any

import schemas
import tracer
from service.classgrade import grade_class

TASKS = {"spheres": "01_three_spheres", "lights": "02_all_lights", "mirror": "04_whitted", "spots": "07_spotlights"}
STUDENTS = 40
EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def build(root: Path) -> tuple[Path, Path]:
    """The class on disk: shared scenes, each student's own 'spheres' scene, and a right image for every pair."""
    scenes, subs = root / "scenes", root / "subs"
    scenes.mkdir(parents=True)
    shared = {}
    for task, name in TASKS.items():
        data = json.loads((EXAMPLES / f"{name}.json").read_text())
        data["image"].update(width=320, height=240)
        (scenes / f"{task}.json").write_text(json.dumps(data))
        shared[task] = tracer.encode_png(tracer.render(schemas.validate_scene(copy.deepcopy(data))))
    for k in range(STUDENTS):
        folder = subs / f"student{k:02d}"
        folder.mkdir(parents=True)
        own = json.loads((scenes / "spheres.json").read_text())
        for obj in own["objects"]:
            if obj["type"] == "sphere":
                obj["center"][0] += 0.01 * (k + 1)
        (folder / "spheres.json").write_text(json.dumps(own))
        (folder / "spheres.png").write_bytes(tracer.encode_png(tracer.render(schemas.validate_scene(own))))
        for task in ("lights", "mirror", "spots"):
            (folder / f"{task}.png").write_bytes(shared[task])
    return scenes, subs


def _serve(port: int) -> subprocess.Popen:
    env = {**os.environ, "PHONGRAY_RENDER_THREADS": "1", "PHONGRAY_MAX_CONCURRENT_RENDERS": "2"}
    proc = subprocess.Popen([sys.executable, "-m", "service.cli", "serve", "--host", "127.0.0.1", "--port", str(port),
                             "--workers", "2"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for _ in range(300):
        try:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/healthz", timeout=1).read()
            return proc
        except OSError:
            time.sleep(0.1)
    proc.kill()
    raise RuntimeError("the server did not start")


def class_rows(work: Path, port: int) -> list[dict[str, Any]]:
    scenes, subs = build(work / "class")
    rows = []
    for mode in ("local", "server"):
        proc = _serve(port) if mode == "server" else None
        try:
            started = time.perf_counter()
            outcome = grade_class(scenes, subs, work / f"report-{mode}", server=f"http://127.0.0.1:{port}"
                                  if proc else None)
            seconds = time.perf_counter() - started
        finally:
            if proc:
                proc.terminate()
                proc.wait(timeout=20)
        assert outcome.count("pass") == len(outcome.rows), outcome.summary()
        rows.append({"mode": mode, "pairs": len(outcome.rows), "references": outcome.renders, "seconds": seconds,
                     "pairs_per_s": len(outcome.rows) / seconds})
    return rows
