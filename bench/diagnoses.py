"""The same diagnoses before and after a change: ``python -m bench.diagnoses write FILE`` diagnoses a fixed set of
failing submissions and writes what each diagnosis says; ``python -m bench.diagnoses check FILE`` diagnoses them
again and names every one that now says something else.

The set: the eight examples at ``--size`` (160×120 by default), each with a submission per classic mistake
(:data:`tracer.scene.variants.VARIANTS`, rendered with it) and five that are none of them (the reference 1.25× and
0.7× as bright, shifted three pixels, noise, black).  The submissions that pass get no diagnosis and are
skipped.  One :func:`service.diagnosis.renders_of` serves every submission of a scene, as a class's cache does
(so the later ones find some renders made).  ``--calls`` prints instead where one cold diagnosis of each of the
bench's students spends its time: every render it asks the tracer for, by kind and by variant, against the
reference render.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

import schemas
from service.diagnosis import diagnose, renders_of
from service.diagnosis.combination import merged
from service.images.grading import grade
from tracer import Renderer
from tracer.scene.variants import VARIANTS

from .scenes import example

EXAMPLES = [
    "01_three_spheres",
    "02_all_lights",
    "03_soft_shadows",
    "04_whitted",
    "05_mesh",
    "06_orthographic",
    "07_spotlights",
    "08_antialiased",
]


def submissions(reference: np.ndarray, scene: Any) -> dict[str, np.ndarray]:
    """A failing student's images of ``scene`` for each classic mistake, and five that are none of them."""
    out = {name: Renderer(scene, VARIANTS[name][0]).pixels() for name in VARIANTS}
    linear = reference.astype(np.float64)
    out["brighter"] = np.clip(linear * 1.25, 0, 255).astype(np.uint8)
    out["darker"] = np.clip(linear * 0.7, 0, 255).astype(np.uint8)
    out["shifted"] = np.roll(reference, 3, axis=1)
    out["noise"] = np.random.default_rng(1).integers(0, 256, reference.shape, dtype=np.uint8)
    out["black"] = np.zeros_like(reference)
    return out


def diagnoses(width: int, height: int) -> Iterator[tuple[str, dict[str, Any] | None]]:
    """``(example/submission, what its diagnosis says)`` for every case of the set (None: it passes)."""
    for name in EXAMPLES:
        scene = schemas.validate_scene(example(name, width, height))
        reference = Renderer(scene).pixels()
        renders = renders_of(scene)
        for student, submitted in submissions(reference, scene).items():
            verdict = grade(reference, submitted, "")
            found = None if verdict.passed else diagnose(reference, submitted, verdict, renders).as_dict()
            yield f"{name}/{student}", found


#: the students of ``--calls`` unless ``--students`` says: four classic mistakes
CALLS = ("no-shadows", "blinn-phong", "no-ambient", "no-half-pixel")


def calls(students: tuple[str, ...] = CALLS, width: int = 320, height: int = 240) -> None:
    """Prints where a cold diagnosis (one thread, as a class's worker runs it) spends its time, per example and
    student: each kind of render it asks for, by variant, as seconds and as a share of the reference render, and
    how many images' worth of rows it renders in all (a whole render, a band, rows or pixels alone), then those
    counts' least, mean and most over every student."""
    spent: dict[str, float] = defaultdict(float)
    count: dict[str, int] = defaultdict(int)
    rows: list[float] = [0.0]  # the current diagnosis's rows rendered
    worth: list[float] = []
    originals = {entry: getattr(Renderer, entry) for entry in ("pixels", "pixels_at", "diagnosis_passes")}

    def timed(entry: str) -> Any:
        def wrapper(self: Renderer, *args: Any, **kwargs: Any) -> Any:
            rows[0] += _rows_of(self, entry, args, kwargs)
            started = time.perf_counter()
            try:
                return originals[entry](self, *args, **kwargs)
            finally:
                what = ",".join(self.options.changes()) or "reference"
                key = f"{entry} of {what}" + (" (some pixels)" if kwargs.get("pixels") is not None else "")
                spent[key] += time.perf_counter() - started
                count[key] += 1

        return wrapper

    for entry in originals:
        setattr(Renderer, entry, timed(entry))
    try:
        for name in EXAMPLES:
            scene = schemas.validate_scene(example(name, width, height))
            started = time.perf_counter()
            reference = Renderer(scene).pixels(threads=1)
            render_s = time.perf_counter() - started
            for student in students:
                submitted = Renderer(scene, merged(student.split("+"))).pixels(threads=1)
                verdict = grade(reference, submitted, "")
                spent.clear()
                count.clear()
                rows[0] = 0.0
                started = time.perf_counter()
                diagnose(reference, submitted, verdict, renders_of(scene, threads=1))
                total = time.perf_counter() - started
                worth.append(rows[0] / height)
                print(
                    f"{name}, {student}: {total:.3f} s, {total / render_s:.1f}× its render ({render_s:.3f} s), "
                    f"{worth[-1]:.2f} images' worth of rows"
                )
                for key in sorted(spent, key=lambda k: -spent[k]):
                    print(f"  {key:48s} {count[key]:3d} calls {spent[key]:.3f} s {spent[key] / render_s:5.2f}×")
                rest = total - sum(spent.values())
                print(f"  {'grading, fitting and the rest':48s}           {rest:.3f} s {rest / render_s:5.2f}×")
    finally:
        for entry, original in originals.items():
            setattr(Renderer, entry, original)
    if worth:
        print(f"images' worth of rows: {min(worth):.2f}–{max(worth):.2f}, {sum(worth) / len(worth):.2f} on average")


def _rows_of(renderer: Renderer, entry: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> float:
    """How many of the image's rows a call of ``entry`` renders: the whole image, a band (``rows``), or the pixels
    given (rows of them, or pixels alone: as a share of a row each)."""
    img = renderer.scene.image
    if entry == "pixels_at":
        return len(args[0] if args else kwargs["pixels"]) / img.width
    if entry == "pixels" and kwargs.get("rows") is not None:
        top, bottom = kwargs["rows"]
        return float(bottom - top)
    if entry == "diagnosis_passes" and kwargs.get("pixels") is not None:
        return len(kwargs["pixels"]) / img.width
    return float(img.height)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.diagnoses", description=__doc__.split("\n\n")[0])
    parser.add_argument("action", nargs="?", choices=["write", "check"])
    parser.add_argument("file", nargs="?", type=Path, help="what the diagnoses say (JSON): written, or checked against")
    parser.add_argument("--size", default="160x120", help="the examples' size, WxH (default 160x120)")
    parser.add_argument("--calls", action="store_true", help="where one cold diagnosis spends its time, instead")
    parser.add_argument(
        "--students",
        help="with --calls: the students' mistakes, comma-separated, a student's "
        "several joined by + (no-shadows+gamma); default: four classic ones",
    )
    args = parser.parse_args(argv)
    if args.calls:
        calls(tuple(args.students.split(",")) if args.students else CALLS)
        return 0
    if args.action is None or args.file is None:
        parser.error("write FILE or check FILE (or --calls)")
    width, height = (int(v) for v in args.size.split("x"))
    started = time.perf_counter()
    if args.action == "write":
        out = dict(diagnoses(width, height))
        args.file.write_text(json.dumps(out, indent=0, sort_keys=True) + "\n")
        print(f"{len(out)} diagnoses written to {args.file} in {time.perf_counter() - started:.0f} s")
        return 0
    known: dict[str, Any] = json.loads(args.file.read_text())
    changed = missing = total = 0
    for case, found in diagnoses(width, height):
        total += 1
        if case not in known:
            missing += 1
            print(f"{case}: not in {args.file}")
        elif json.loads(json.dumps(found)) != known[case]:
            changed += 1
            print(f"{case}: was {json.dumps(known[case])[:300]}\n  now {json.dumps(found)[:300]}")
    print(
        f"{total - changed - missing} of {total} say the same, {changed} changed, {missing} not in the file "
        f"({time.perf_counter() - started:.0f} s)"
    )
    return 1 if changed or missing else 0


if __name__ == "__main__":
    sys.exit(main())
