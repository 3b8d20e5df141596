"""Where one render's time goes, stage by stage: ``python -m bench.profile SCENE [--width W --height H]``.

``SCENE`` is a scene file, or the name of a ``phongray bench`` speed row (``three_spheres_1080p``, …) or of
an example (``03_soft_shadows``).  The render runs on one thread, so that every stage's time is its own.
The profile wraps the tracer's stage functions (nothing in ``tracer/`` knows of it) and gives each its
*exclusive* time: a stage's time less that of the stages it calls, so the rows add up to the render.  A
stage is named by where it is called from: the walk of camera and mirror rays (``closest hit › walk``) is
apart from the walk of a light's shadow rays (``lights[2] point › shadow rays › walk``), and every light's
shading and shadow rays are apart from every other light's.

Columns: milliseconds (the best of ``--runs`` renders by total), the share of the render, the calls, the
NumPy arrays the stage made and their megabytes (:mod:`bench.numpycount`, in one more render: the passes
over the data that write a new array; in-place work and views make none), and the rays it handled.
Scene set-up (the world's arrays, the BVH) and PNG encoding are timed apart, after the render's rows.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import json
import sys
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import schemas
import tracer
from tracer.render import Renderer

from .numpycount import counter
from .scenes import EXAMPLES, example, speed_scenes


def _n_first(args: tuple[Any, ...], res: Any) -> int:
    return len(args[0])


def _n_second(args: tuple[Any, ...], res: Any) -> int:
    return len(args[1])


def _n_result(args: tuple[Any, ...], res: Any) -> int:
    return len(res[0])


def _n_out(args: tuple[Any, ...], res: Any) -> int:
    return len(res)


@dataclass(frozen=True)
class Stage:
    """A function of the tracer timed as a stage: where it lives, its label, and how many rays it handled."""

    module: str
    name: str  # the attribute path in the module: "Renderer.direct", "illuminate"
    label: str
    rays: Callable[[tuple[Any, ...], Any], int] | None = None
    #: a light's own work: its label goes under the light the renderer is shading (``lights[k] type``)
    per_light: bool = False


def _direct_light(module: str, shade: str, area: str, blocked: str) -> list[Stage]:
    """The stages of direct light, in the module that shades (its functions by the names it calls them by)."""
    return [
        Stage(module, shade, "direct light", _n_out),
        Stage(module, "classify", "area-light culling", lambda a, r: len(getattr(r, "state", r))),
        *(
            Stage(module, name, "shading", per_light=True)
            for name in ("illuminate", "light_in_plane", "phong", "add_phong", "Kernel.reach", "Kernel.terms")
        ),
        Stage(module, area, "area light", per_light=True),
        Stage(module, blocked, "shadow rays", _n_out, per_light=True),
    ]


#: the stages, by the names the render calls them by (stages.py, and an older tracer's render.py, import their
#: helpers by name)
STAGES = [
    Stage("tracer.scene.camera", "CameraRays.rays", "camera rays", _n_result),
    Stage("tracer.exact.intersect", "Intersector.closest", "closest hit", _n_first),
    Stage("tracer.exact.intersect", "Intersector.occluded", "occlusion", _n_first),
    Stage("tracer.exact.intersect", "Intersector.nearest", "closest hit", _n_first),
    Stage("tracer.exact.intersect", "Intersector.describe", "hit reconstruction", lambda a, r: len(r.t)),
    Stage("tracer.exact.intersect", "Intersector._describe", "hit reconstruction", lambda a, r: len(a[2].t)),
    Stage("tracer.exact.intersect", "Intersector._direct", "direct tests"),
    Stage("tracer.exact.walk", "Walk.walk", "walk", _n_second),
    Stage("tracer.exact.pairs", "PairTests.test", "exact tests", _n_second),
    Stage("tracer.exact.embree", "Bvh.nearest", "Embree", _n_first),
    Stage("tracer.exact.embree", "Bvh.any_hit", "Embree", _n_first),
    Stage("tracer.render", "through_point", "cones", lambda a, r: len(a[3])),
    Stage("tracer.render", "along_direction", "cones", lambda a, r: len(a[2])),
    Stage("tracer.shade.direct", "through_point", "cones", lambda a, r: len(a[3])),
    Stage("tracer.shade.direct", "along_direction", "cones", lambda a, r: len(a[2])),
    Stage("tracer.stages", "resolve_material", "materials and checker", _n_out),
    Stage("tracer.stages", "shading_normal", "shading normals", _n_out),
    Stage("tracer.render", "resolve_material", "materials and checker", _n_out),
    Stage("tracer.render", "shading_normal", "shading normals", _n_out),
    *_direct_light("tracer.shade.direct", "DirectLight.shade", "area_terms", "ShadowRays.blocked"),
    Stage("tracer.shade.area", "classify", "area-light culling", lambda a, r: len(getattr(r, "state", r))),
    # (an older tracer's, where direct light was the renderer's own: profiled when the bench runs it)
    *_direct_light("tracer.render", "Renderer.direct", "Renderer._area_light", "Renderer._blocked"),
    Stage("tracer.render", "Renderer.secondary", "reflection and refraction", _n_out),
    Stage("tracer.render", "_accumulate", "adding up", _n_second),
    Stage("tracer.render", "quantize", "quantisation", _n_first),
    Stage("tracer.stages", "Spawner.bounce", "reflection and refraction", _n_out),
    Stage("tracer.stages", "Film.add", "adding up", _n_first),
    Stage("tracer.render", "Spawner.bounce", "reflection and refraction", _n_out),
    Stage("tracer.render", "Film.add", "adding up", _n_first),
    Stage("tracer.film", "quantize", "quantisation", _n_first),
]


@dataclass
class Row:
    seconds: float = 0.0
    calls: int = 0
    rays: int = 0
    arrays: int = 0
    nbytes: int = 0


@dataclass
class Clock:
    """Exclusive time per stage path: the innermost open stage is charged until it ends or calls another."""

    rows: dict[tuple[str, ...], Row] = field(default_factory=lambda: defaultdict(Row))
    stack: list[tuple[str, ...]] = field(default_factory=list)
    since: float = 0.0
    light: str = ""  # the light being shaded (``lights[k] type``), set by its first stage
    light_of: dict[int, str] = field(default_factory=dict)  # id(emitter) → its light's label

    def _charge(self) -> float:
        now = time.perf_counter()
        if self.stack:
            self.rows[self.stack[-1]].seconds += now - self.since
        self.since = now
        return now

    def push(self, stage: Stage, args: tuple[Any, ...]) -> None:
        self._charge()
        if stage.name == "illuminate":
            self.light = self.light_of.get(id(args[0]), "lights[?]")
        elif stage.name == "Renderer._area_light":  # (an older tracer's, when profiling it)
            self.light = self.light_of.get(id(args[6][0]), "lights[?]")
        elif stage.name == "DirectLight._area":
            self.light = self.light_of.get(id(args[0]), "lights[?]")
        elif stage.name == "area_terms":  # (its light group)
            self.light = self.light_of.get(id(args[1]), "lights[?]")
        elif stage.name == "Kernel.reach":  # (its emitter)
            self.light = self.light_of.get(id(args[0]), "lights[?]")
        parent = self.stack[-1] if self.stack else ()
        if stage.per_light and parent[:1] == ("direct light",):
            parent = (self.light,)
        if parent[-1:] == (stage.label,):  # (a stage calling itself, as the shadow walk's wrappers do)
            self.stack.append(parent)
        else:
            self.stack.append(parent + (stage.label,))

    def pop(self) -> tuple[str, ...]:
        self._charge()
        return self.stack.pop()

    def count(self, nbytes: int) -> None:
        row = self.rows[self.stack[-1] if self.stack else ("other",)]
        row.arrays += 1
        row.nbytes += nbytes


@contextmanager
def instrumented(clock: Clock) -> Iterator[None]:
    """Every :data:`STAGES` function wrapped to report to ``clock``, for the length of the block."""
    undo = []
    for stage in STAGES:
        module = importlib.import_module(stage.module)
        *path, attr = stage.name.split(".")
        owner: Any = module
        for part in path:
            owner = getattr(owner, part, None)
        if owner is None or not hasattr(owner, attr):  # (a stage an older tracer does not have, when profiling it)
            continue
        original = owner.__dict__[attr] if isinstance(owner, type) else getattr(owner, attr)

        def wrapped(*args: Any, _f: Callable[..., Any] = original, _s: Stage = stage, **kwargs: Any) -> Any:
            clock.push(_s, args[1:] if "." in _s.name else args)
            try:
                result = _f(*args, **kwargs)
            finally:
                key = clock.pop()
            row = clock.rows[key]
            row.calls += 1
            if _s.rays is not None:
                row.rays += _s.rays(args[1:] if "." in _s.name else args, result)
            return result

        setattr(owner, attr, functools.wraps(original)(wrapped))
        undo.append((owner, attr, original))
    try:
        yield
    finally:
        for owner, attr, original in reversed(undo):
            setattr(owner, attr, original)


def load(name: str, width: int | None, height: int | None) -> tuple[str, dict[str, Any]]:
    """A scene by file, speed-row or example name, at the size asked for."""
    path = Path(name)
    if path.is_file():
        data = json.loads(path.read_text())
    elif name in speed_scenes():
        data = speed_scenes()[name]
    elif (EXAMPLES / f"{name}.json").is_file():
        data = example(name)
    else:
        raise SystemExit(f"bench.profile: {name}: neither a scene file, a speed row nor an example")
    if width and height:
        data["image"].update(width=width, height=height)
    return path.stem if path.is_file() else name, data


def light_labels(renderer: Renderer) -> dict[int, str]:
    """Each emitter's and each light group's label, by id."""
    scene = renderer.scene
    out = {
        id(em): f"lights[{k}] {scene.lights[k].type}"
        for em, k in zip(renderer.world.emitters, renderer.emitter_light.tolist())
    }
    for group in getattr(getattr(renderer, "shading", None), "groups", []):
        out[id(group)] = f"lights[{group.light}] {scene.lights[group.light].type}"
    return out


def profile(data: dict[str, Any], runs: int = 3) -> dict[str, Any]:
    """Each stage's exclusive time (best render of ``runs``), calls, rays and NumPy arrays made."""
    scene = schemas.validate_scene(json.loads(json.dumps(data)))
    Renderer(scene).pixels(threads=1)  # warm: imports, caches
    best: Clock | None = None
    best_total = best_setup = 0.0
    counts: dict[str, int] = {}
    for _ in range(runs):
        started = time.perf_counter()
        renderer = Renderer(scene)
        setup = time.perf_counter() - started
        clock = Clock(light_of=light_labels(renderer))
        with instrumented(clock):
            started = time.perf_counter()
            pixels = renderer.pixels(threads=1)
            total = time.perf_counter() - started
        if best is None or total < best_total:
            best, best_total, best_setup, counts = clock, total, setup, dict(renderer.counts)
    assert best is not None
    started = time.perf_counter()
    tracer.encode_png(pixels)
    png = time.perf_counter() - started
    # one more render, counting the arrays each stage makes (the counter's callbacks would skew its times)
    renderer = Renderer(scene)
    counting = Clock(light_of=light_labels(renderer))
    numpy_counter = counter(counting.count)
    if numpy_counter is not None:
        with instrumented(counting), numpy_counter:
            renderer.pixels(threads=1)
    rows = []
    staged = sum(r.seconds for r in best.rows.values())
    other = Row(seconds=max(0.0, best_total - staged))
    keys = sorted(set(best.rows) | set(counting.rows) | {("other",)}, key=_order)
    for key in keys:
        timed = other if key == ("other",) else best.rows.get(key, Row())
        made = counting.rows.get(key, Row())
        rows.append(
            {
                "stage": " › ".join(key),
                "ms": timed.seconds * 1e3,
                "share": timed.seconds / best_total,
                "calls": timed.calls,
                "rays": timed.rays,
                "arrays": made.arrays if numpy_counter else None,
                "mb": made.nbytes / 2**20 if numpy_counter else None,
            }
        )
    return {
        "width": scene.image.width,
        "height": scene.image.height,
        "render_s": best_total,
        "setup_s": best_setup,
        "png_s": png,
        "counts": counts,
        "rows": rows,
    }


def _order(key: tuple[str, ...]) -> tuple[Any, ...]:
    """The stage order of a render: camera, closest hit, light by light, mirrors, the sums; the rest last."""
    top = ["camera rays", "closest hit", "materials and checker", "shading normals", "direct light"]
    head = key[0]
    if head.startswith("lights["):
        rank: tuple[Any, ...] = (4.5, int(head[7 : head.index("]")]))
    elif head in top:
        rank = (top.index(head), 0)
    else:
        rank = ({"reflection and refraction": 6, "adding up": 7, "quantisation": 8}.get(head, 9), 0)
    return rank + key[1:]


def table(name: str, result: dict[str, Any]) -> str:
    c = result["counts"]
    lines = [
        f"## {name} at {result['width']}×{result['height']}, one thread",
        "",
        f"Render {result['render_s'] * 1e3:.1f} ms (best of the runs); rays: {c['primary']} primary, "
        f"{c['shadow']} shadow, {c['secondary']} secondary. Apart from it: scene set-up "
        f"{result['setup_s'] * 1e3:.1f} ms, PNG {result['png_s'] * 1e3:.1f} ms.",
        "",
        "| stage | ms | share | calls | NumPy arrays | MB made | rays |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        arrays = "—" if r["arrays"] is None else str(r["arrays"])
        mb = "—" if r["mb"] is None else f"{r['mb']:.0f}"
        lines.append(
            f"| {r['stage']} | {r['ms']:.1f} | {100 * r['share']:.1f} % | {r['calls']} | {arrays} | {mb} | "
            f"{r['rays'] or ''} |"
        )
    totals = result["rows"]
    arrays = sum(r["arrays"] or 0 for r in totals)
    mb = sum(r["mb"] or 0 for r in totals)
    lines.append(f"| **all** | {result['render_s'] * 1e3:.1f} | 100 % | | {arrays} | {mb:.0f} | |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.profile", description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+", metavar="SCENE", help="a scene file, a speed row or an example name")
    parser.add_argument("--width", type=int)
    parser.add_argument("--height", type=int)
    parser.add_argument("--runs", type=int, default=3, help="renders timed; the fastest is shown (default 3)")
    parser.add_argument("--json", action="store_true", help="print the numbers as JSON")
    args = parser.parse_args(argv)
    out = {}
    for name in args.scenes:
        label, data = load(name, args.width, args.height)
        out[label] = profile(data, args.runs)
        if not args.json:
            print(table(label, out[label]))
    if args.json:
        json.dump(out, sys.stdout, indent=1)
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
