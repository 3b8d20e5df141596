"""The held-out check of the diagnosis (issue 47): a second student's tracer (tests/student_oop.py), which the
diagnosis was not tuned on, makes each mistake alone and some pairs of classic ones on the eight examples; each
image is graded and diagnosed as ``phongray grade`` does it, and the table says what was made and what was named.

``python -m bench.heldout`` prints the table (Markdown) and the share of images whose every visible mistake is
named; ``--only EXAMPLE`` and ``--size WxH`` (64x48 by default, the student is pure Python) narrow it.  The
student's images are kept in ``--cache`` (a folder; none: made again), by example, size and mistakes.

A mistake is *visible* in an example when the student's image with it alone fails the grade (against the
reference and every accepted variant: an image that passes is not diagnosed); an image is
*named* when the diagnosis names every visible mistake made (as a cause it matches, or the one it comes closest
to); an honest image must pass, with no "Likely".
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

import schemas
from service.images.grading import grade
from service.work.pipeline import Graded, explain
from tracer import Renderer

from .scenes import example

TESTS = Path(__file__).resolve().parents[1] / "tests"
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
#: pairs of classic mistakes students make together (issue 47: "no shadow rays and Blinn–Phong together; no
#: attenuation and gamma together"), and a few more of kinds unlike each other
PAIRS = [
    ("no-shadows", "blinn-phong"),
    ("no-attenuation", "gamma"),
    ("no-ambient", "no-specular"),
    ("no-shadows", "gamma"),
    ("image-flipped", "no-attenuation"),
    ("no-half-pixel", "no-shadows"),
    ("specular-behind", "no-ambient"),
    ("horizontal-fov", "gamma"),
]


def student() -> Any:
    """tests/student_oop.py, imported as the tests import it."""
    if str(TESTS) not in sys.path:
        sys.path.insert(0, str(TESTS))
    import student_oop

    return student_oop


@dataclass(frozen=True)
class Case:
    example: str
    made: tuple[str, ...]  # the mistakes the student made (none: honest)
    visible: tuple[str, ...]  # those whose image alone fails the grade
    passed: bool  # the image passes the grade (against the reference or an accepted variant)
    named: tuple[str, ...]  # what the diagnosis names: causes it matches, or the closest
    sentence: str

    @property
    def ok(self) -> bool:
        if not self.made:
            return self.passed and not self.sentence.startswith("Likely")
        return set(self.visible) <= set(self.named) if not self.passed else not self.visible


def image(scene: Any, name: str, made: tuple[str, ...], cache: Path | None) -> np.ndarray:
    """The student's image of ``scene`` with mistakes ``made``, from ``cache`` when it is there."""
    size = f"{scene.image.width}x{scene.image.height}"
    path = None if cache is None else cache / f"{name}-{size}-{'+'.join(made) or 'honest'}.npy"
    if path is not None and path.is_file():
        return np.load(path)
    out = student().render(scene, list(made))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.save(path, out)
    return out


def named(found: dict[str, Any] | None) -> tuple[str, ...]:
    """The mistake ids a diagnosis (as JSON) names: the causes it matches, else the one it comes closest to (with
    the mistakes it comes closest to together with, when it is a combination: "comes closest to the reference
    rendered with both")."""
    if not found:
        return ()
    causes = found.get("causes") or []
    matched = [c["variant"] for c in causes if c.get("passes")]
    if matched:
        return tuple(matched)
    if not (causes and found.get("closest") and causes[0].get("variant")):
        return ()
    return (causes[0]["variant"], *(causes[0].get("together") or []))


def case(
    scene: Any, reference: np.ndarray, name: str, made: tuple[str, ...], cache: Path | None, visible: tuple[str, ...]
) -> Case:
    """Example ``name``'s image by the student, with mistakes ``made`` (``visible``: those that show), graded and
    diagnosed as ``phongray grade`` does it."""
    submitted = image(scene, name, made, cache)
    graded = explain(scene, Graded(grade(reference, submitted, ""), None), reference, submitted)
    found = (
        graded.diagnosis
        if graded.diagnosis is None or isinstance(graded.diagnosis, dict)
        else graded.diagnosis.as_dict()
    )
    return Case(name, made, visible, graded.grade.passed, named(found), (found or {}).get("sentence", ""))


def cases(name: str, size: tuple[int, int], cache: Path | None) -> list[Case]:
    """Every case of one example: honest, each mistake it can show alone, and the pairs of :data:`PAIRS`."""
    from tracer.scene.shown import unchanged

    oop = student()
    scene = schemas.validate_scene(example(name, *size))
    reference = Renderer(scene).pixels()
    shown = [m for m in oop.MISTAKES if not unchanged(m, scene)]
    fails: dict[str, bool] = {}
    out = []
    for made in [(), *((m,) for m in shown), *(p for p in PAIRS if all(m in shown for m in p))]:
        visible = tuple(m for m in made if fails.get(m, True))
        one = case(scene, reference, name, made, cache, visible)
        if len(made) == 1:
            fails[made[0]] = not one.passed
            one = replace(one, visible=made if not one.passed else ())
        out.append(one)
    return out


def table(rows: list[Case]) -> list[str]:
    lines = ["| example | mistakes made | visible | mistakes named | ok |", "|---|---|---|---|---|"]
    for c in rows:
        named_words = "passes" if c.passed else ", ".join(c.named) or "—"
        lines.append(
            f"| {c.example} | {', '.join(c.made) or 'honest'} | {', '.join(c.visible) or '—'} | "
            f"{named_words} | {'yes' if c.ok else 'NO'} |"
        )
    return lines


def summary(rows: list[Case]) -> str:
    wrong = [c for c in rows if c.made and c.visible]
    honest = [c for c in rows if not c.made]
    pairs = [c for c in wrong if len(c.made) == 2]
    return (
        f"{sum(c.ok for c in wrong)} of {len(wrong)} images with a visible mistake have every visible mistake "
        f"named ({100 * sum(c.ok for c in wrong) / max(len(wrong), 1):.0f} %); pairs {sum(c.ok for c in pairs)} "
        f"of {len(pairs)}; honest images passing with no 'Likely': {sum(c.ok for c in honest)} of {len(honest)}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.heldout", description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="64x48", help="the examples' size, WxH (default 64x48)")
    parser.add_argument("--only", action="append", help="an example (repeatable; default: all eight)")
    parser.add_argument("--cache", type=Path, default=None, help="a folder keeping the student's images")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    rows: list[Case] = []
    for name in args.only or EXAMPLES:
        rows += cases(name, (width, height), args.cache)
    print("\n".join(table(rows)))
    print()
    print(summary(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
