"""What naming a failing student's mistake costs: ``phongray bench``'s diagnosis section.

Per example at 320×240, a failing submission (the reference rendered without shadow rays, then with the
Blinn–Phong half vector: two failing students of one task) is graded as ``phongray grade`` grades it: the
reference render and the comparison, then the diagnosis.  The first failing pair of a scene renders every
variant and pass (cold); the second finds them in the cache by canonical scene (warm).
"""

from __future__ import annotations

import time
from typing import Any

import schemas
from service.diagnosis import CACHE, renders_needed
from service.images.grading import grade
from service.work.pipeline import Graded, explain
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
STUDENTS = ("no-shadows", "blinn-phong")


def diagnosis_rows() -> list[dict[str, Any]]:
    rows = []
    for name in EXAMPLES:
        scene = schemas.validate_scene(example(name, 320, 240))
        started = time.perf_counter()
        reference = Renderer(scene).pixels()
        render_s = time.perf_counter() - started
        timings, named = [], []
        CACHE.held.clear()
        for mistake in STUDENTS:
            submitted = Renderer(scene, VARIANTS[mistake][0]).pixels()
            started = time.perf_counter()
            verdict = grade(reference, submitted, "")
            found = explain(scene, Graded(verdict, None), reference, submitted)
            timings.append(time.perf_counter() - started)
            causes = [] if found.diagnosis is None else found.diagnosis.causes
            named.append(None if verdict.passed or not causes else causes[0].variant)
        rows.append(
            {
                "scene": name,
                "render_s": render_s,
                "renders": renders_needed(scene),
                "cold_s": timings[0],
                "warm_s": timings[1],
                "cold_over_render": timings[0] / render_s,
                "students": list(STUDENTS),
                "named": named,
            }
        )
    return rows


def report_lines(rows: list[dict[str, Any]]) -> list[str]:
    lines = [
        "## Diagnosis of a failing pair",
        "",
        "Per example at 320×240: a reference render, then two failing students of the task graded and "
        "diagnosed (" + " and ".join(STUDENTS) + "). Cold: the first failing pair renders every variant "
        "and pass of the scene; warm: the second finds them cached by canonical scene. Passing pairs cost "
        "nothing extra.",
        "",
        "| scene | reference render s | renders at most | cold s | cold ÷ render | warm s | named |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        named = ", ".join(f"{n or 'passes'}" for n in r["named"])
        lines.append(
            f"| {r['scene']} | {r['render_s']:.3f} | {r['renders']} | {r['cold_s']:.2f} | "
            f"{r['cold_over_render']:.1f} | {r['warm_s']:.3f} | {named} |"
        )
    return lines + [""]
