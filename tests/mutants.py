"""Does the fuzz test catch a weakened walk?  Each mutant weakens one stop rule or guarantee of the walk, or
one of the proofs that spare rays their tests: an area light's culling, the cones of rays through a point or
along a direction.

    python -m tests.mutants [--scenes N]

copies the tracer, applies one mutant, runs the walk's tests against it (the
differential fuzz test on the CI subset's seeds, and the tests of the proxies'
and the cells' guarantees), and prints whether it was caught.  Every mutant must be caught; the command
exits 1 if one is not.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: (name, file under tracer/, text, replacement)
MUTANTS = [
    (
        "the origin's part of a cell is not tested",
        "walk.py",
        "            self._test_cells(best, inside, cell, but, batch)\n",
        "            pass\n",
    ),
    (
        "a hit anywhere settles a ray at its start",
        "walk.py",
        "settled = np.isfinite(best.t[inside]) & (best.t[inside] <= start[inside])",
        "settled = np.isfinite(best.t[inside])",
    ),
    (
        "a hit anywhere settles a walking ray",
        "walk.py",
        "settled = np.isfinite(best.t[live]) & (best.t[live] <= leave)",
        "settled = np.isfinite(best.t[live])",
    ),
    (
        "a crossing tests only the crossed primitive",
        "walk.py",
        "        self._test_cells(\n            best,\n            live[fresh],\n",
        "        if False: self._test_cells(\n            best,\n            live[fresh],\n",
    ),
    (
        "the walk jumps a part further than the part it tested",
        "walk.py",
        "start[live] = np.fmax(start[live] + tau + p.step, leave)",
        "start[live] = np.fmax(start[live] + tau + p.step, 2 * leave - start[live] - tau)",
    ),
    (
        "the walk starts at the origin's part without testing what contains the origin",
        "walk.py",
        "        inside = np.flatnonzero(from_prim >= 0)\n",
        "        inside = np.flatnonzero(from_prim >= 0)\n        start[inside] = 0.0\n        inside = inside[:0]\n",
    ),
    ("boxes are registered without reach", "proxies.py", "REACH = 2.0**-14", "REACH = 0.0"),
    (
        "members of a coplanar group keep the t of their own planes",
        "coplanar.py",
        "        out[rows[ok]] = shared[ok]\n",
        "        pass\n",
    ),
    ("no coplanar groups are made", "coplanar.py", "    a, b = a[keep], b[keep]\n", "    a, b = a[:0], b[:0]\n"),
    ("proxies have no margin", "proxies.py", "MARGIN = 2.0**-17", "MARGIN = 2.0**-40"),
    (
        "an area light is proven seen when its first bound lies outside its pyramid",
        "culling.py",
        "    for k in range(K):\n",
        "    for k in range(min(K, 1)):\n",
    ),
    (
        "an area light is proven hidden by a sphere that covers one corner",
        "culling.py",
        "zip(to_q, length_q)",
        "zip(to_q[:1], length_q[:1])",
    ),
    (
        "an area light's mixed points never meet their first bound",
        "culling.py",
        "np.logical_not(sep, out=may_block[k])",
        "np.logical_not(sep | (k == 0), out=may_block[k])",
    ),
    (
        "a ray through a point meets a ball only within half its angle",
        "cones.py",
        "cos = float(np.sqrt(1.0 - (r / dist) ** 2)) - SLACK",
        "cos = float(np.sqrt(1.0 - (0.5 * r / dist) ** 2)) - SLACK",
    ),
    (
        "a ray through a point meets a triangle only well inside its edges",
        "cones.py",
        "allow = 4.0 * grow / h + SLACK",
        "allow = -0.01",
    ),
    (
        "a ray along a direction meets a ball only within half its radius",
        "cones.py",
        "close = du * du + dv * dv <= (r * r) * (1.0 + SLACK)",
        "close = du * du + dv * dv <= 0.25 * (r * r)",
    ),
    (
        "a ray along a direction meets a triangle only well inside its edges",
        "cones.py",
        "levels.append(np.sum(p * m, axis=1) - grow)",
        "levels.append(np.sum(p * m, axis=1) + 0.01 * size)",
    ),
    (
        "a ray of its own direction meets a ball only within half its radius",
        "cones.py",
        "close = across <= grown * grown * (1.0 + SLACK)",
        "close = across <= 0.25 * grown * grown",
    ),
    (
        "an area light's faces are crossed from two long vectors, apex to corner twice",
        "culling.py",
        "        f = face_normal((a[0] - p[0], a[1] - p[1], a[2] - p[2]), c - a)\n",
        "        u, w = (a[0] - p[0], a[1] - p[1], a[2] - p[2]), (c[0] - p[0], c[1] - p[1], c[2] - p[2])\n"
        "        g = (u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0])\n"
        "        f = tuple(x / np.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]) for x in g)\n",
    ),
    (
        "a tile of points is proven to see an area light without its radius",
        "culling.py",
        "            reach = margin_of + (float(b.radius[k]) + bound_part[k]) + reach_t\n",
        "            reach = margin_of + (float(b.radius[k]) + bound_part[k])\n",
    ),
    (
        "a penumbra ray misses a bound whose cone it passes within half its radius",
        "penumbra.py",
        "np.sqrt(1.0 - (grown / dist) ** 2) - MARGIN",
        "np.sqrt(1.0 - (0.5 * grown / dist) ** 2) - MARGIN",
    ),
    (
        "a penumbra ray is blocked by a sphere beyond its sample",
        "penumbra.py",
        "blocks = (x > np.take(self.hit_above, pairs)) & (np.take(self.ends, pairs) < d - slack)",
        "blocks = x > np.take(self.hit_above, pairs)",
    ),
    (
        "a penumbra ray is never blocked by its own sphere",
        "penumbra.py",
        "self.miss_below[own & (~on_sphere | (towards >= 0))] = np.inf",
        "self.miss_below[own] = np.inf",
    ),
    (
        "a tile of points is proven lit whole without its radius",
        "tiles.py",
        "clear = apart > margin_of[None, :] + (b.radius + bound_part)[:, None] + reach_t[None, :]",
        "clear = apart > margin_of[None, :] + (b.radius + bound_part)[:, None]",
    ),
    (
        "a shadow walk stops before its light by a tenth",
        "walk.py",
        "            far = np.minimum(limit[live] + p.slack, t_out[live]) - s\n",
        "            far = np.minimum(limit[live] * 0.9, t_out[live]) - s\n",
    ),
    (
        "a walk of a few primitives asks Embree only up to nine tenths of its best hit",
        "walk.py",
        "        end = np.minimum(best.t + self.proxies.slack, t_out)\n",
        "        end = np.minimum(best.t * 0.9, t_out)\n",
    ),
    (
        "a walk of a few primitives tests all but the last one",
        "walk.py",
        "np.tile(np.arange(count), len(live))",
        "np.tile(np.arange(count - 1), len(live))",
    ),
]


def run(mutant: tuple[str, str, str, str] | None, scenes: int) -> bool:
    """True when the fuzz subset passes against the (mutated) tracer."""
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copytree(ROOT / "tracer", Path(tmp) / "tracer")
        if mutant is not None:
            _, name, old, new = mutant
            path = Path(tmp) / "tracer" / name
            text = path.read_text()
            assert text.count(old) == 1, f"the mutant's text is not in {name} once: {old!r}"
            path.write_text(text.replace(old, new))
        env = {**os.environ, "PYTHONPATH": tmp}
        if scenes:
            env["PHONGRAY_FUZZ_SCENES"] = str(scenes)
        names = (
            "test_proxies.py",
            "test_cells.py",
            "test_culling.py",
            "test_cones.py",
            "test_intersect.py",
            "test_coplanar.py",
            "test_fuzz.py",
        )
        tests = [str(ROOT / "tests" / name) for name in names]
        out = subprocess.run(
            [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", *tests],
            env=env,
            cwd=tmp,
            capture_output=True,
            text=True,
        )
        return out.returncode == 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.mutants", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=0, help="scenes per run (default: the CI subset's)")
    ap.add_argument("--only", default="", help="run only the mutants whose name holds this text")
    args = ap.parse_args(argv)
    chosen = [m for m in MUTANTS if args.only in m[0]]
    if not run(None, args.scenes):
        print("the fuzz subset fails on the tracer as it is: fix that first")
        return 1
    missed = 0
    for mutant in chosen:
        caught = not run(mutant, args.scenes)
        missed += not caught
        print(f"{'caught' if caught else 'MISSED'}: {mutant[0]}", flush=True)
    print(f"{len(chosen) - missed} of {len(chosen)} mutants caught")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
