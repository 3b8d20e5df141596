"""Lights of one emitter decided in runs, against each light's shadow rays decided alone, in one process:
``python -m bench.lights [--lights 96 --runs 3]``.

Two cases of the scene of :func:`bench.answers.many_lights` (a floor and a ball under a grid of dim point
lights): a diagnosis of a noisy 160×120 image (many small renders of rows, where a query's fixed cost counts),
and a whole 320×240 render on one thread.  Each is timed with the tracer as it is (a run of lights, one occlusion
query per shading step: :mod:`tracer.shade.direct`) and with every run one light long (``JOINED_RAYS = 1``, each
light its own query, as before runs); the best of ``--runs`` of each, and their ratio.  The images are compared
too: the two ways must give the same bytes.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

import schemas
from service.diagnosis import diagnose, renders_of
from service.images.grading import grade
from tracer import Renderer
from tracer.shade import direct

from .answers import many_lights


def _best(work: Callable[[], object], runs: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(runs):
        start = time.perf_counter()
        out = work()
        best = min(best, time.perf_counter() - start)
    return best, out


def _both(work: Callable[[], object], runs: int) -> tuple[float, float, object, object]:
    """The best time of ``work`` with runs of lights, then with every light alone, and what each gave."""
    joined, kept = direct.JOINED_RAYS, None
    together, a = _best(work, runs)
    try:
        direct.JOINED_RAYS = 1
        alone, kept = _best(work, runs)
    finally:
        direct.JOINED_RAYS = joined
    return together, alone, a, kept


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.lights", description=__doc__.split("\n\n")[0])
    parser.add_argument("--lights", type=int, default=96, help="point lights in the grid (default 96)")
    parser.add_argument("--runs", type=int, default=3, help="runs of each case; the best is kept (default 3)")
    args = parser.parse_args(argv)
    small = schemas.validate_scene(many_lights(args.lights, 160, 120, columns=8, colour=0.02))
    reference = Renderer(small).pixels()
    noise = np.random.default_rng(1).integers(0, 256, reference.shape, dtype=np.uint8)
    graded = grade(reference, noise, "")

    def diagnosis() -> object:
        return diagnose(reference, noise, graded, renders_of(small)).sentence()

    large = schemas.validate_scene(many_lights(args.lights, 320, 240, columns=8, colour=0.02))

    def render() -> object:
        return Renderer(large).pixels(threads=1).tobytes()

    print(f"{args.lights} point lights; best of {args.runs}; joined ÷ alone")
    for name, work in (("noise diagnosis 160×120", diagnosis), ("render 320×240, one thread", render)):
        together, alone, a, b = _both(work, args.runs)
        same = "the same" if a == b else "DIFFERENT"
        print(f"  {name}: {together:.2f} s against {alone:.2f} s, {together / alone:.2f}× ({same} result)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
