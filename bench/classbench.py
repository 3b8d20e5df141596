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
from service.classgrade import ClassRun, grade_class

TASKS = {"spheres": "01_three_spheres", "lights": "02_all_lights", "mirror": "04_whitted", "spots": "07_spotlights"}
STUDENTS = 40
EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def build(root: Path) -> tuple[Path, Path]:
    """The class on disk: shared scenes, each student's own 'spheres' scene (in the TA's ``own/`` folder), and a
    right image for every pair."""
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
        (root / "own" / folder.name).mkdir(parents=True)
        (root / "own" / folder.name / "spheres.json").write_text(json.dumps(own))
        (folder / "spheres.png").write_bytes(tracer.encode_png(tracer.render(schemas.validate_scene(own))))
        for task in ("lights", "mirror", "spots"):
            (folder / f"{task}.png").write_bytes(shared[task])
    return scenes, subs


def _serve(port: int) -> subprocess.Popen:
    env = {**os.environ, "PHONGRAY_RENDER_THREADS": "1", "PHONGRAY_MAX_CONCURRENT_RENDERS": "2"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "service.cli", "serve", "--host", "127.0.0.1", "--port", str(port), "--workers", "2"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
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
            outcome = grade_class(
                ClassRun(
                    scenes,
                    subs,
                    work / f"report-{mode}",
                    server=f"http://127.0.0.1:{port}" if proc else None,
                    student_scenes=work / "class" / "own",
                )
            )
            seconds = time.perf_counter() - started
        finally:
            if proc:
                proc.terminate()
                proc.wait(timeout=20)
        assert outcome.count("pass") == len(outcome.rows), outcome.summary()
        rows.append(
            {
                "mode": mode,
                "pairs": len(outcome.rows),
                "references": outcome.renders,
                "seconds": seconds,
                "pairs_per_s": len(outcome.rows) / seconds,
            }
        )
    return rows


def cluster_rows(work: Path, local_class: dict[str, Any] | None) -> dict[str, Any]:
    """The class and a 3840×2160 render on a 2-worker local Dask cluster (one thread each) against local runs,
    and the cost per task they imply, for the estimate of larger classes."""
    from distributed import LocalCluster

    from service.render.cluster import connect
    from service.render.cluster import render as render_on

    scenes, subs = work / "class", work / "class" / "subs"
    if not (scenes / "scenes").exists():
        build(work / "class")
    data = json.loads((EXAMPLES / "01_three_spheres.json").read_text())
    data["image"].update(width=3840, height=2160)
    scene = schemas.validate_scene(data)
    started = time.perf_counter()
    local_png = tracer.encode_png(tracer.render(scene))
    local_4k = time.perf_counter() - started
    if local_class is None:
        started = time.perf_counter()
        grade_class(ClassRun(scenes / "scenes", subs, work / "report-local-again", student_scenes=scenes / "own"))
        local_class_s = time.perf_counter() - started
    else:
        local_class_s = local_class["seconds"]
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, host="127.0.0.1"
    ) as lc:
        with connect(lc.scheduler_address) as client:
            client.run(lambda: None)  # workers up and importing
            started = time.perf_counter()
            pixels = render_on(client, scene.model_dump_json().encode(), 3840, 2160)
            cluster_4k = time.perf_counter() - started
            identical = tracer.encode_png(pixels) == local_png
        started = time.perf_counter()
        outcome = grade_class(
            ClassRun(
                scenes / "scenes",
                subs,
                work / "report-cluster",
                cluster=lc.scheduler_address,
                student_scenes=scenes / "own",
            )
        )
        cluster_class = time.perf_counter() - started
    assert identical and outcome.count("pass") == len(outcome.rows)
    pairs, refs = len(outcome.rows), outcome.renders
    # per task on one worker: the local class run spends its time on `refs` renders and `pairs` comparisons with
    # two processes; split it by the measured render-to-compare cost ratio of one of each
    one = json.loads((scenes / "scenes" / "spheres.json").read_text())
    started = time.perf_counter()
    ref_png = tracer.encode_png(tracer.render(schemas.validate_scene(one), threads=1))
    t_render = time.perf_counter() - started
    from service.classgrade.tasks import grade_task

    image = (subs / "student00" / "lights.png").read_bytes()
    started = time.perf_counter()
    grade_task((work / "report-cluster" / "references").iterdir().__next__().read_bytes(), image, 2.0, 0.001)
    t_grade = time.perf_counter() - started

    def estimate(students: int, tasks: int, workers: int) -> float:
        n_pairs, n_refs = students * tasks, students * tasks  # worst case: every pair has its own scene
        per_task_overhead = 0.002  # Dask scheduling, measured order of magnitude per task
        return (n_refs * (t_render + per_task_overhead) + n_pairs * (t_grade + per_task_overhead)) / workers

    return {
        "render_4k": {
            "local_s": local_4k,
            "cluster_s": cluster_4k,
            "ratio": cluster_4k / local_4k,
            "identical": identical,
        },
        "class": {
            "local_s": local_class_s,
            "cluster_s": cluster_class,
            "ratio": cluster_class / local_class_s,
            "pairs": pairs,
            "references": refs,
        },
        "per_task": {
            "render_s": t_render,
            "grade_s": t_grade,
            "png_bytes": len(ref_png),
            "scene_bytes": len(json.dumps(one)),
        },
        "estimate_500x10": {"workers_10_s": estimate(500, 10, 10), "workers_100_s": estimate(500, 10, 100)},
    }


#: the per-student class: every student has an own scene for every task (the course's real workload)
PER_STUDENT = 80
PER_STUDENT_TASKS = [
    "01_three_spheres",
    "02_all_lights",
    "03_soft_shadows",
    "04_whitted",
    "05_mesh",
    "06_orthographic",
    "07_spotlights",
    "08_antialiased",
    "01_three_spheres",
    "04_whitted",
]


def _jittered(data: dict[str, Any], student: int, task: int) -> dict[str, Any]:
    """A student's own copy of a task's scene: the camera and every sphere moved a little, its own way."""
    out = copy.deepcopy(data)
    out["image"].update(width=320, height=240)
    step = 0.003 * (student + 1) * (1 + task % 3)
    out["camera"]["position"] = [c + step * s for c, s in zip(out["camera"]["position"], (1, 0.5, -0.5))]
    for obj in out["objects"]:
        if obj["type"] == "sphere":
            obj["center"] = [obj["center"][0] + step, *obj["center"][1:]]
    return out


def _render_file(scene_path: str, out: str) -> float:
    from service.classgrade.tasks import render_task

    started = time.perf_counter()
    png, why = render_task(Path(scene_path).read_bytes())
    assert png is not None, why
    Path(out).write_bytes(png)
    return time.perf_counter() - started


#: the mistakes a failing student of the per-student class made, in turn (each changes every task's image)
MISTAKES = ("no-shadows", "blinn-phong", "no-ambient", "no-half-pixel")


def failing(student: int, task: int, share: float) -> bool:
    """Whether a student's image of a task is a failing one, for ``share`` of the pairs, spread over both."""
    return (student * 7 + task * 3) % 100 < round(100 * share)


def _render_wrong(scene_path: str, out: str, mistake: str) -> None:
    """A failing student's image: the task's scene rendered with a classic mistake."""
    import tracer
    from tracer.scene.variants import VARIANTS

    scene = schemas.validate_scene(json.loads(Path(scene_path).read_text()))
    Path(out).write_bytes(tracer.encode_png(tracer.Renderer(scene, VARIANTS[mistake][0]).pixels(threads=1)))


def per_student_row(work: Path, share_failing: float = 0.0) -> dict[str, Any]:
    """80 students × 10 tasks at 320×240, every pair its own scene (800 distinct renders and comparisons),
    graded from scratch by ``grade-class`` with a process per core; beside it the same 800 renders alone in a
    pool of as many processes (the floor that class grading cannot go below without a faster tracer).  With
    ``share_failing``, that share of the pairs is a student's mistake (:data:`MISTAKES`, in turn), and every
    failing pair is diagnosed (cold: each has its own scene)."""
    from concurrent.futures import ProcessPoolExecutor

    root = work / ("per-student" if not share_failing else f"per-student-failing-{share_failing:g}")
    scenes, subs, own = root / "scenes", root / "subs", root / "own"
    scenes.mkdir(parents=True)
    jobs = []
    for t, name in enumerate(PER_STUDENT_TASKS):
        task = f"task{t:02d}"
        data = json.loads((EXAMPLES / f"{name}.json").read_text())
        data["image"].update(width=320, height=240)
        (scenes / f"{task}.json").write_text(json.dumps(data))
        for k in range(PER_STUDENT):
            student = f"student{k:02d}"
            (own / student).mkdir(parents=True, exist_ok=True)
            (subs / student).mkdir(parents=True, exist_ok=True)
            path = own / student / f"{task}.json"
            path.write_text(json.dumps(_jittered(data, k, t)))
            jobs.append((str(path), str(subs / student / f"{task}.png")))
    workers = os.cpu_count() or 1
    started = time.perf_counter()
    with ProcessPoolExecutor(workers) as pool:
        per_render = list(pool.map(_render_file, *zip(*jobs)))
    floor = time.perf_counter() - started
    wrong = [
        (scene, png, MISTAKES[k % len(MISTAKES)])
        for k, (scene, png) in enumerate(jobs)
        if failing(k % PER_STUDENT, k // PER_STUDENT, share_failing)
    ]
    if wrong:
        with ProcessPoolExecutor(workers) as pool:
            list(pool.map(_render_wrong, *zip(*wrong)))
    started = time.perf_counter()
    outcome = grade_class(ClassRun(scenes, subs, root / "report", student_scenes=own))
    seconds = time.perf_counter() - started
    assert outcome.count("fail") == len(wrong) and outcome.count("pass") == len(outcome.rows) - len(wrong), (
        outcome.summary()
    )
    pairs = len(outcome.rows)
    mode = "local, a scene per student" + (f", {100 * share_failing:.0f} % failing, diagnosed" if wrong else "")
    return {
        "mode": mode,
        "pairs": pairs,
        "references": outcome.renders,
        "failing": len(wrong),
        "seconds": seconds,
        "pairs_per_s": pairs / seconds,
        "renders_alone_s": floor,
        "render_mean_s": sum(per_render) / len(per_render),
        "workers": workers,
    }
