"""The same bytes before and after a change to the tracer: ``python -m bench.digests write FILE`` renders a fixed
corpus and writes each image's SHA-256 (and, beside it in ``FILE.npz``, the images themselves);
``python -m bench.digests check FILE`` renders it again and names every image whose bytes changed, with how many
pixels moved and by how many levels.

The corpus: the examples at their own size and at the per-student class's 320×240; each of the per-student
class's ten tasks for four students (their own cameras and spheres, :mod:`bench.classbench`); the speed rows at a
quarter of their size; every variant of the diagnosis (:mod:`tracer.scene.variants`) on four examples; the diagnosis
passes' linear colour of the examples; and ``--generated N`` scenes of the fuzzer's generator (hard cases:
rooms round the camera, glass with cores, lights on surfaces, huge beside tiny, far from the origin).  Images
render on ``--threads`` threads (two by default, as the bench's do; one, as a class's are, renders in smaller
chunks): a render's bytes depend on neither.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

import schemas
from tracer import Renderer
from tracer.scene.variants import VARIANTS

from .classbench import PER_STUDENT_TASKS, _jittered
from .scenes import EXAMPLES, example, speed_scenes

Job = tuple[str, dict[str, Any], str]  # name, scene, what to render ("image", a variant's name, "passes")


def _generated(count: int) -> Iterator[Job]:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    import generator  # type: ignore[import-not-found]

    for seed in range(count):
        family, data = generator.scene(seed, 48, 36)
        yield f"generated/{seed}-{family}", data, "image"


def corpus(generated: int) -> list[Job]:
    names = sorted(p.stem for p in EXAMPLES.glob("[0-9]*.json"))
    jobs: list[Job] = []
    for name in names:
        jobs.append((f"example/{name}", example(name), "image"))
        jobs.append((f"example/{name}@320x240", example(name, 320, 240), "image"))
        jobs.append((f"passes/{name}", example(name), "passes"))
    for student in (0, 13, 41, 79):
        for task, name in enumerate(PER_STUDENT_TASKS):
            jobs.append((f"student/{student}/{task}-{name}", _jittered(example(name), student, task), "image"))
    for row, data in speed_scenes().items():
        data["image"].update(width=data["image"]["width"] // 4, height=data["image"]["height"] // 4)
        jobs.append((f"speed/{row}@quarter", data, "image"))
    for name in ("02_all_lights", "04_whitted", "07_spotlights", "08_antialiased"):
        for variant in VARIANTS:
            jobs.append((f"variant/{name}/{variant}", example(name), variant))
    jobs += list(_generated(generated))
    return jobs


def _render(job: Job, threads: int = 2) -> tuple[str, str, np.ndarray]:
    name, data, what = job
    scene = schemas.validate_scene(data)
    if what == "passes":
        out = Renderer(scene).diagnosis_passes(threads=threads)["colour"]
    else:
        out = (Renderer(scene) if what == "image" else Renderer(scene, VARIANTS[what][0])).pixels(threads=threads)
    return name, hashlib.sha256(out.tobytes()).hexdigest(), out


def _each(jobs: list[Job], processes: int, threads: int) -> Iterator[tuple[str, str, np.ndarray]]:
    if processes <= 1:
        yield from (_render(job, threads) for job in jobs)
        return
    with ProcessPoolExecutor(processes) as pool:
        yield from pool.map(_render, jobs, [threads] * len(jobs), chunksize=4)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.digests", description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=["write", "check"])
    parser.add_argument("file", type=Path, help="the digests (JSON): written, or checked against")
    parser.add_argument("--generated", type=int, default=400, help="generated scenes in the corpus (default 400)")
    parser.add_argument("--processes", type=int, default=1, help="renders at once (default 1)")
    parser.add_argument("--threads", type=int, default=2, help="threads per render (default 2)")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    jobs = corpus(args.generated)
    arrays = Path(f"{args.file}.npz")
    if args.mode == "write":
        out, images = {}, {}
        for name, digest, image in _each(jobs, args.processes, args.threads):
            out[name], images[name] = digest, image
        args.file.write_text(json.dumps(out, indent=0, sort_keys=True) + "\n")
        np.savez_compressed(arrays, **images)
        print(f"{len(out)} digests written to {args.file} in {time.perf_counter() - started:.0f} s")
        return 0
    known: dict[str, str] = json.loads(args.file.read_text())
    before = np.load(arrays) if arrays.is_file() else None
    changed, missing = 0, 0
    for name, digest, image in _each(jobs, args.processes, args.threads):
        if name not in known:
            missing += 1
            print(f"{name}: not in {args.file}")
        elif known[name] != digest:
            changed += 1
            print(f"{name}: changed" + (f": {differences(before[name], image)}" if before is not None else ""))
    same = len(jobs) - changed - missing
    print(
        f"{same} of {len(jobs)} the same bytes, {changed} changed, {missing} not in the file "
        f"({time.perf_counter() - started:.0f} s)"
    )
    return 1 if changed or missing else 0


def differences(a: np.ndarray, b: np.ndarray) -> str:
    """How two images (or two linear colours) differ: the pixels that moved, and by how much at most."""
    moved = np.any(a != b, axis=-1)
    if a.dtype == np.uint8:
        return f"{int(moved.sum())} pixels moved, at most {int(np.max(np.abs(a.astype(int) - b.astype(int))))} levels"
    return f"{int(moved.sum())} pixels' colour moved, at most {float(np.max(np.abs(a - b))):.3g}"


if __name__ == "__main__":
    sys.exit(main())
