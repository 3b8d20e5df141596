"""The calibration of accepted variants: honest tracers' offset styles and the classic mistakes × scenes.

``python tests/offset_matrix.py [SCENE.json ...]`` (default: every example and the Cornell-box homework) renders
tests/student.py's tracer in each style and with each mistake, grades it as ``phongray grade`` does (the
reference, then the accepted variants), and prints a Markdown table: ``pass`` (the reference passes it),
``pass*`` (an accepted variant does), ``FAIL``, and ``—`` for a mistake the scene does not show (the
reference itself passes it).  tests/test_accepting.py checks its key cells.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parent.parent))

import student  # noqa: E402

from schemas import load_scene  # noqa: E402
from service.diagnosis.accepting import Failing, accept  # noqa: E402
from service.grading import grade  # noqa: E402
from tracer import Renderer  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENES = [*sorted((ROOT / "examples").glob("*.json")), ROOT / "examples" / "course" / "scenes" / "cornell.json"]
ROWS = {
    **{name: {"style": style} for name, style in student.STYLES.items()},
    "offset 5e-4": {"style": student.Offset(5e-4)},
    "t_min 5e-4": {"style": student.Offset(5e-4, "ray")},
    "offset 2e-3": {"style": student.Offset(2e-3)},
    **{name: {"mistakes": [name]} for name in student.MISTAKES},
}


def cell(scene, reference, name: str) -> str:  # noqa: ANN001
    image = student.render(scene, **ROWS[name])
    verdict = grade(reference, image, "")
    honest = "mistakes" not in ROWS[name]
    if verdict.passed:
        return "pass" if honest else "—"
    return "pass*" if accept(scene, Failing(reference, image, verdict)) else "FAIL"


def main(paths: list[Path]) -> None:
    scenes = {path.stem: load_scene(path.read_bytes()) for path in paths}
    references = {stem: Renderer(scene).pixels() for stem, scene in scenes.items()}
    print("| style / mistake | " + " | ".join(scenes) + " |")
    print("|---|" + "---|" * len(scenes))
    for name in ROWS:
        print(
            f"| {name} | " + " | ".join(cell(scene, references[stem], name) for stem, scene in scenes.items()) + " |",
            flush=True,
        )


if __name__ == "__main__":
    main([Path(p) for p in sys.argv[1:]] or SCENES)
