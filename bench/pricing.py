"""What fairness and explanation cost a class: the per-student Cornell-box homework graded three times, with
exact images, with honest images whose tracer offsets its rays, and with images that each make one classic
mistake, and each time against the exact class (ratios in one run, so a busy machine moves all three alike).

    python -m bench.pricing [--students 9] [--size 200] [--profile FILE.txt]
    python -m bench.pricing --single 640x480

Each student has a scene of their own (the glass ball moved a little), 2×2 samples, depth 5, as the homework
sets it.  The honest images are tests/student.py's tracer starting shadow and secondary rays 1e-3 along the
normal (a textbook's value, in a box 4 units across); the mistaken ones cycle through no-shadows, blinn-phong,
gamma and no-ambient (each of which the homework shows).  Every honest image must pass and every mistake be
named: the bench checks both, so that a speed-up that changes an answer is not reported as one.
``--profile`` writes where a mistaken image's grade spends its time (cProfile, cumulative, the top 40
functions), graded here in this process as a pool's process grades it, for one student of each mistake.
``--single WxH`` prices one image of the homework at that size instead, graded cold as ``phongray grade``
grades it (a process of its own, the reference rendered in it), in renders: the time of ``phongray render``
of the scene, then of grading an exact image, an honest one (the 1e-3 offset) and one of each mistake.
"""

from __future__ import annotations

import argparse
import copy
import cProfile
import io
import json
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import schemas
import tracer
from service.classgrade import ClassRun, grade_class
from service.work import pipeline

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import student  # noqa: E402

HOMEWORK = Path(__file__).resolve().parent.parent / "examples" / "09_cornell_homework.json"
MISTAKES = ("no-shadows", "blinn-phong", "gamma", "no-ambient")
KINDS = ("exact", "offset", "mistake")


def own_scene(k: int, size: int) -> dict:
    """Student ``k``'s homework scene: the glass ball moved ``0.02·k`` to the right."""
    data = json.loads(HOMEWORK.read_text())
    data["image"].update(width=size, height=size, samples=2, max_depth=5)
    glass = next(o for o in data["objects"] if o["type"] == "sphere" and o["material"] == "glass")
    glass["center"][0] += 0.02 * k
    return data


def image(kind: str, k: int, data: dict) -> bytes:
    scene = schemas.validate_scene(copy.deepcopy(data))
    if kind == "exact":
        return tracer.encode_png(tracer.render(scene))
    if kind == "offset":
        return tracer.encode_png(student.render(scene, (), student.Offset(1e-3)))
    return tracer.encode_png(student.render(scene, (MISTAKES[k % len(MISTAKES)],)))


def build(root: Path, kind: str, students: int, size: int) -> ClassRun:
    """A class on disk of ``students`` students, each with their own scene and an image of ``kind``."""
    scenes, subs, own = root / "scenes", root / "subs", root / "own"
    scenes.mkdir(parents=True)
    (scenes / "cornell.json").write_text(json.dumps(own_scene(0, size)))
    for k in range(students):
        name = f"student{k:02d}"
        data = own_scene(k + 1, size)
        (own / name).mkdir(parents=True)
        (own / name / "cornell.json").write_text(json.dumps(data))
        (subs / name).mkdir(parents=True)
        (subs / name / "cornell.png").write_bytes(image(kind, k, data))
    return ClassRun(scenes, subs, root / "report", student_scenes=own)


def checked(kind: str, rows: list[dict]) -> None:
    """Every exact or honest image passes; every mistaken one fails with its mistake named."""
    for row in rows:
        if kind == "mistake":
            k = int(row["student"].removeprefix("student"))
            assert row["status"] == "fail" and MISTAKES[k % len(MISTAKES)] in (row.get("mistakes") or []), row
        else:
            assert row["status"] == "pass", row


def timed(run: ClassRun, kind: str) -> float:
    started = time.perf_counter()
    outcome = grade_class(run)
    seconds = time.perf_counter() - started
    checked(kind, outcome.rows)
    return seconds


def profiled(size: int, out: Path) -> None:
    """Where a mistaken image's grade spends its time: one student of each mistake, graded in this process
    (the reference rendered first, outside the profile), as ``phongray grade`` grades it."""
    profile = cProfile.Profile()
    for k in range(len(MISTAKES)):
        data = own_scene(k + 1, size)
        scene = schemas.validate_scene(copy.deepcopy(data))
        reference, submitted = tracer.encode_png(tracer.render(scene)), image("mistake", k, data)
        explaining = pipeline.Explaining(lambda scene=scene: scene, pipeline.Checks(diagnose=True))
        profile.enable()
        pipeline.grade_png(reference, submitted, 2.0, 0.001, explaining=explaining)
        profile.disable()
    text = io.StringIO()
    pstats.Stats(profile, stream=text).sort_stats("cumulative").print_stats(40)
    out.write_text(text.getvalue())


def _cli(*argv: str) -> tuple[float, str]:
    """Seconds a ``phongray`` command takes in a process of its own, and what it printed."""
    cli = "import sys\nfrom service.cli import main\nsys.exit(main())"
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", cli, *argv], check=False, capture_output=True, text=True)
    return time.perf_counter() - started, done.stdout


def _answer_checked(name: str, printed: str) -> None:
    """An exact or honest image passes; a mistaken one fails with its mistake among the passing causes."""
    grade = json.loads(printed)
    if name in ("exact", "offset"):
        assert grade["passed"], grade["reason"]
        return
    causes = (grade.get("diagnosis") or {}).get("causes") or []
    assert not grade["passed"] and any(c["variant"] == name and c["passes"] for c in causes), grade["diagnosis"]


def single(width: int, height: int) -> None:
    """One image of each kind at ``width`` × ``height``, graded cold, against one cold render of the scene."""
    data = own_scene(1, width)
    data["image"].update(height=height)
    with tempfile.TemporaryDirectory(prefix="phongray-single-") as place:
        scene = Path(place, "cornell.json")
        scene.write_text(json.dumps(data))
        kinds = {"exact": "exact", "offset": "offset", **{m: "mistake" for m in MISTAKES}}
        for name, kind in kinds.items():
            k = MISTAKES.index(name) if kind == "mistake" else 0
            Path(place, f"{name}.png").write_bytes(image(kind, k, data))
        render, _ = _cli("render", str(scene), "-o", str(Path(place, "reference.png")))
        print(f"Cornell homework at {width}×{height}, 2×2 samples, depth 5: one render {render:.1f} s")
        print("| image | seconds | renders |")
        print("|---|---|---|")
        for name in kinds:
            seconds, printed = _cli("grade", str(scene), str(Path(place, f"{name}.png")), "--json")
            _answer_checked(name, printed)
            print(f"| {name} | {seconds:.1f} | {seconds / render:.2f} |")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--students", type=int, default=9)
    ap.add_argument("--size", type=int, default=200)
    ap.add_argument("--profile", type=Path, help="where a mistaken image's grade spends its time (cProfile text)")
    ap.add_argument("--single", metavar="WxH", help="price one image at this size, in renders")
    args = ap.parse_args(argv)
    if args.single:
        width, height = (int(n) for n in args.single.lower().split("x"))
        single(width, height)
        return
    with tempfile.TemporaryDirectory(prefix="phongray-pricing-") as place:
        runs = {kind: build(Path(place, kind), kind, args.students, args.size) for kind in KINDS}
        seconds = {kind: timed(run, kind) for kind, run in runs.items()}
    print(f"per-student Cornell homework, {args.students} students at {args.size}², 2×2 samples, depth 5")
    print("| class | seconds | × exact |")
    print("|---|---|---|")
    for kind in KINDS:
        print(f"| {kind} | {seconds[kind]:.1f} | {seconds[kind] / seconds['exact']:.2f} |")
    if args.profile:
        profiled(args.size, args.profile)


if __name__ == "__main__":
    main()
