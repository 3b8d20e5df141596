"""The confusion matrix of the grade: honest students' styles must pass, every visible mistake must fail and be named.

``python tests/offset_matrix.py [--scenes NAME,...] [--sections honest,alone,offset,pairs] [--pair-width 64]
[--flip] [--pairs A+B,...] [--out FILE.json]`` grades, as ``phongray grade`` does (the reference, the accepted
variants, the diagnosis), the images of three student tracers written from the scene format (tests/student.py,
float64 with every mistake a switch; tests/student_f32.py, single precision with its own intersections;
tests/student_oop.py, one ray at a time) on the eight examples, the Cornell-box homework and the hard scenes of
tests/hard_scenes/ (a glass box resting on a floor, a scene sized by a radius-1000 ground sphere, one with a far
tiny sphere out of view), and prints a Markdown table per section and the confusion matrix:

* ``honest``: offsets along the normal of 1e-4, 1e-3 and 3e-3 of the visible size (:mod:`tracer.exact.visible`), t_min
  of 1e-4 to 1e-2 of it, float32 and float64 tracers, 2×2 samples (on the scenes sampled once per pixel): each
  must pass (``pass``, or ``pass*`` as an accepted variant);
* ``alone``: each mistake of tests/student.py alone: ``—`` where the image is not visibly the reference's (the
  scene cannot show it: :func:`visibly_different`), else it must fail and be named (``named``; ``both`` when it is
  one of several readings);
* ``offset``: each mistake behind an honest offset (3e-3 of the visible size): named, and matched (so that its
  deduction applies);
* ``pairs``: every two mistakes together, at ``--pair-width`` pixels across (``--pairs`` picks some): named
  (both, or the visible one).

With ``--flip`` (``pip install flip-evaluator``), each image's largest ꟻLIP error against the reference is
computed too, and the matrix of the rule "fails when the largest ꟻLIP error exceeds 0.5" is printed beside
phongray's.  tests/test_rule.py and tests/test_accepting.py check the key cells.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from itertools import combinations
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402
import student  # noqa: E402
import student_f32  # noqa: E402
import student_oop  # noqa: E402

from schemas import load_scene  # noqa: E402
from service.diagnosis.offsets import visible_size  # noqa: E402
from service.diagnosis.records import matched  # noqa: E402
from service.images.grading import DEFAULT_MAX_FRACTION, DEFAULT_TOLERANCE, GROSS_LEVELS  # noqa: E402
from service.work import pipeline  # noqa: E402
from tracer import Renderer, encode_png  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENES = [
    *sorted((ROOT / "examples").glob("0*.json")),
    *sorted((Path(__file__).resolve().parent / "hard_scenes").glob("*.json")),
]
#: the honest styles: name → (tracer, amount × the visible size, along), "2x2": the scene at samples 2
HONEST = {
    "f64 offset 1e-4": ("f64", 1e-4, "normal"),
    "f64 offset 1e-3": ("f64", 1e-3, "normal"),
    "f64 offset 3e-3": ("f64", 3e-3, "normal"),
    "f64 t_min 1e-4": ("f64", 1e-4, "ray"),
    "f64 t_min 1e-3": ("f64", 1e-3, "ray"),
    "f64 t_min 1e-2": ("f64", 1e-2, "ray"),
    "f32 eps 1e-3": ("f32", 1e-3, "normal"),
    "f32 eps 3e-3": ("f32", 3e-3, "normal"),
    "f32 t_min 1e-3": ("f32", 1e-3, "ray"),
    "f32 t_min 1e-2": ("f32", 1e-2, "ray"),
    "f32 eps 1e-3 2x2": ("f32", 1e-3, "normal"),
    "f64 offset 1e-3 2x2": ("f64", 1e-3, "normal"),
    "oop eps 1e-4 (abs)": ("oop", 0.0, "normal"),
}
#: the honest offset a mistake hides behind in the ``offset`` section, × the visible size
BEHIND = 3e-3
FLIP_VISIBLE = 0.5


def _at_samples(scene, n: int):  # noqa: ANN001, ANN202
    return scene.model_copy(update={"image": scene.image.model_copy(update={"samples": n})})


def _sized(scene, width: int):  # noqa: ANN001, ANN202
    w, h = scene.image.width, scene.image.height
    if w <= width:
        return scene
    return scene.model_copy(
        update={"image": scene.image.model_copy(update={"width": width, "height": max(1, round(h * width / w))})}
    )


def honest_image(scene, style: str) -> tuple[Any, np.ndarray]:  # noqa: ANN001
    tracer, share, along = HONEST[style]
    if style.endswith("2x2"):
        scene = _at_samples(scene, 2)
    amount = share * visible_size(scene)
    if tracer == "f64":
        return scene, student.render(scene, style=student.Offset(amount, along))
    if tracer == "f32":
        return scene, student_f32.render(scene, student_f32.Style(amount, along))
    return scene, student_oop.render(scene)


def graded(scene, image: np.ndarray) -> pipeline.Graded:  # noqa: ANN001
    reference = encode_png(Renderer(scene).pixels())
    return pipeline.grade_png(reference, encode_png(image), 2.0, 0.001, explaining=pipeline.Explaining(lambda: scene))


def flip_error(scene, image: np.ndarray) -> float | None:  # noqa: ANN001
    """The largest ꟻLIP error of ``image`` against the reference (LDR, its defaults), None without the package."""
    try:
        import flip_evaluator as flip
    except ImportError:
        return None
    reference = Renderer(scene).pixels().astype(np.float32) / 255
    error_map, _, _ = flip.evaluate(reference, image.astype(np.float32) / 255, "LDR", applyMagma=False)
    return float(np.max(error_map))


def outcome(  # noqa: ANN201
    scene,  # noqa: ANN001
    image: np.ndarray,
    expected: set[str] | None,
    flip: bool,
    honest: np.ndarray | None = None,
):
    """One cell: the verdict, what it names, and (with ``flip``) the largest ꟻLIP error; a mistake's image that is
    the honest one (``honest``, by default the reference) is ``—``, a mistake the scene does not show."""
    reference = Renderer(scene).pixels()
    cell: dict[str, Any] = {"flip": flip_error(scene, image) if flip else None}
    if expected is not None and not visibly_different(image, reference if honest is None else honest):
        return {**cell, "verdict": "—"}
    found = graded(scene, image)
    cell["verdict"] = ("pass*" if found.accepted else "pass") if found.grade.passed else "FAIL"
    cell["accepted"] = found.accepted
    cell["off"] = found.grade.fraction_off_nearby
    cell["gross"] = found.grade.grossly_off
    if found.diagnosis is not None:
        said = found.diagnosis.as_dict()
        cell["ids"] = matched(said)
        cell["sentence"] = said["sentence"]
        cell["offset"] = said.get("offset")
    if expected is not None and cell["verdict"] == "FAIL":
        cell["named"] = naming(cell.get("ids") or [], expected)
    return cell


def naming(ids: list[str], expected: set[str]) -> str:
    """``named`` when the first id the image matches is the expected mistakes, ``both`` when they are one of
    the readings it matches, ``wrong`` when it matches others, ``unnamed`` when it matches none."""
    readings = [set(i.split("+")) for i in ids]
    if readings and readings[0] == expected:
        return "named"
    if expected in readings or (readings and expected <= set().union(*readings)):
        return "both"
    return "wrong" if readings else "unnamed"


def visibly_different(image: np.ndarray, other: np.ndarray) -> bool:
    """Whether two images differ as the grade's own allowance for honest tracers does not cover: more than the
    default tolerance in more than the default fraction of the pixels, or by more than GROSS_LEVELS anywhere.

    Measured pixel by pixel, not over neighbourhoods (so a shift the grade forgives still counts as a
    difference).  A mistake that changes less (50 pixels by 1 level where normals face the wrong way inside a
    closed ball; a deepest bounce cut off in 2 of 3072 pixels, the most by 61 levels at a shadow's fringe) is
    within what honest tracers differ by at that size (an honest one-ray-at-a-time tracer: 3 such pixels of
    up to 30 levels on 04_whitted at 64 pixels across), so no rule can fail it without failing them: it is
    not shown."""
    diff = np.abs(image.astype(np.int16) - other.astype(np.int16)).max(axis=2)
    return bool(
        np.count_nonzero(diff > DEFAULT_TOLERANCE) > DEFAULT_MAX_FRACTION * diff.size or diff.max() > GROSS_LEVELS
    )


def shown(scene, names: tuple[str, ...]) -> set[str]:  # noqa: ANN001
    """The mistakes of ``names`` the image shows: each whose undoing changes the image visibly
    (:func:`visibly_different`: the image made without it, the others kept, against the image made with all), so
    that a mistake another hides (acne with no shadow rays at all) or one that moves a few pixels by a level or
    two is not asked for."""
    image = student.render(scene, list(names))
    return {n for n in names if visibly_different(student.render(scene, [m for m in names if m != n]), image)}


def sections(
    scenes: dict[str, Any], which: list[str], pair_width: int, flip: bool, only: set[str] | None = None
) -> dict[str, dict]:
    out: dict[str, dict] = {s: {} for s in which}
    for stem, scene in scenes.items():
        if "honest" in which:
            for style in HONEST:
                if style.endswith("2x2") and scene.image.samples != 1:
                    continue  # (a scene sampled already: its own samples are the anti-aliased cell)
                made, image = honest_image(scene, style)
                out["honest"][(style, stem)] = outcome(made, image, None, flip)
                _progress("honest", style, stem, out["honest"][(style, stem)])
        if "alone" in which:
            for name in student.MISTAKES:
                cell = outcome(scene, student.render(scene, [name]), {name}, flip)
                out["alone"][(name, stem)] = cell
                _progress("alone", name, stem, cell)
        if "offset" in which:
            behind = student.Offset(BEHIND * visible_size(scene))
            honest = student.render(scene, style=behind)
            for name in student.MISTAKES:
                if name == "offset-too-large":
                    continue
                cell = outcome(scene, student.render(scene, [name], style=behind), {name}, flip, honest)
                out["offset"][(name, stem)] = cell
                _progress("offset", name, stem, cell)
        if "pairs" in which:
            small = _sized(scene, pair_width)
            for a, b in combinations(student.MISTAKES, 2):
                if {a, b} == {"depth-plus-one", "depth-minus-one"} or (only and f"{a}+{b}" not in only):
                    continue
                expected = shown(small, (a, b))
                image = student.render(small, [a, b])
                cell = outcome(small, image, expected or {"?"}, flip)
                out["pairs"][(f"{a} + {b}", stem)] = cell
                _progress("pairs", f"{a}+{b}", stem, cell)
    return out


def _progress(section: str, row: str, stem: str, cell: dict) -> None:
    print(
        f"  {section:6s} {row:40s} {stem:22s} {cell['verdict']:5s} {cell.get('named', '')}", file=sys.stderr, flush=True
    )


def symbol(cell: dict) -> str:
    if cell["verdict"] in ("pass", "—"):
        return cell["verdict"]
    if cell["verdict"] == "pass*":
        return "pass*"
    return "FAIL" + (
        ""
        if "named" not in cell
        else {"named": "", "both": " (both)", "wrong": " WRONG", "unnamed": " UNNAMED"}[cell["named"]]
    )


def table(cells: dict, scenes: list[str]) -> list[str]:
    rows = sorted({r for r, _ in cells}, key=list({r: 0 for r, _ in cells}).index)
    lines = ["| | " + " | ".join(scenes) + " |", "|---|" + "---|" * len(scenes)]
    for row in rows:
        lines.append(
            f"| {row} | " + " | ".join(symbol(cells[(row, s)]) if (row, s) in cells else "" for s in scenes) + " |"
        )
    return lines


def confusion(out: dict[str, dict], rule: str) -> list[str]:
    """The counts: honest passes and fails; mistakes (visible) failed and named, failed unnamed, passed."""
    lines = [f"**{rule}**", "", "| section | cells | right | wrong |", "|---|---|---|---|"]
    for section, cells in out.items():
        tally: Counter[str] = Counter()
        for cell in cells.values():
            if rule == "phongray":
                failed = cell["verdict"] == "FAIL"
            else:
                if cell.get("flip") is None or cell["verdict"] == "—":
                    continue
                failed = cell["flip"] > FLIP_VISIBLE
            if section == "honest":
                tally["honest passed" if not failed else "honest FAILED"] += 1
            elif cell["verdict"] == "—":
                tally["not shown"] += 1
            elif not failed:
                tally["mistake PASSED"] += 1
            elif rule == "phongray":
                tally[f"failed, {cell.get('named', 'unnamed')}"] += 1
            else:
                tally["failed"] += 1
        right = sum(v for k, v in tally.items() if k in ("honest passed", "failed, named", "failed, both", "failed"))
        wrong = sum(
            v
            for k, v in tally.items()
            if k not in ("honest passed", "failed, named", "failed, both", "failed", "not shown")
        )
        detail = ", ".join(f"{k} {v}" for k, v in sorted(tally.items()))
        lines.append(f"| {section} | {detail} | {right} | {wrong} |")
    return lines


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", help="comma-separated scene names (default: all)")
    ap.add_argument("--sections", default="honest,alone,offset,pairs")
    ap.add_argument("--pair-width", type=int, default=64)
    ap.add_argument("--flip", action="store_true")
    ap.add_argument("--pairs", help="comma-separated pairs to grade, as A+B in the order of student.MISTAKES")
    ap.add_argument("--out", help="write every cell as JSON here")
    args = ap.parse_args(argv)
    paths = [p for p in SCENES if not args.scenes or p.stem in args.scenes.split(",")]
    scenes = {p.stem: load_scene(p.read_bytes()) for p in paths}
    started = time.time()
    only = set(args.pairs.split(",")) if args.pairs else None
    out = sections(scenes, args.sections.split(","), args.pair_width, args.flip, only)
    for section, cells in out.items():
        print(f"\n### {section}\n")
        print("\n".join(table(cells, list(scenes))))
    print()
    print("\n".join(confusion(out, "phongray")))
    if args.flip:
        print()
        print("\n".join(confusion(out, f"ꟻLIP largest error > {FLIP_VISIBLE}")))
    print(f"\n({time.time() - started:.0f} s)")
    if args.out:
        Path(args.out).write_text(
            json.dumps({s: {f"{r} @ {c}": v for (r, c), v in cells.items()} for s, cells in out.items()}, indent=1)
        )


if __name__ == "__main__":
    main()
