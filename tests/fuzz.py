"""Differential fuzzing: phongray against the brute force of :mod:`reference`, on scenes of :mod:`generator`.

For each scene, three comparisons, each only where the brute force is clear:

* every primary ray: hit or miss, the same surface, t to a relative tolerance;
* every shadow decision from those hits: from the brute force's own hit point,
  leaving its surface, towards every light and area-light sample that faces it;
* every pixel: within one 8-bit level, and whether the format leaves it open
  (a tie between overlapping coplanar surfaces of two objects in its ray tree).

As a soak::

    python -m tests.fuzz --scenes 10000 --seed 0 --out fuzz-out

prints the number of disagreements and writes each disagreeing scene (and what
disagreed) to ``--out``.  ``tests/test_fuzz.py`` runs a bounded subset in CI.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import schemas  # noqa: E402
from tracer import Renderer  # noqa: E402
from tracer.exact.intersect import MISS, PLANE, SPHERE, TRIANGLE  # noqa: E402
from tracer.proofs.bounds import SurfacePoints, bounds_of  # noqa: E402
from tracer.proofs.cones import along_direction, on_lines, through_point  # noqa: E402
from tracer.proofs.culling import MIXED, SEEN, classify  # noqa: E402
from tracer.proofs.penumbra import Penumbra  # noqa: E402
from tracer.proofs.tiles import TILE, lit_tiles  # noqa: E402
from tracer.scene.lights import illuminate  # noqa: E402
from tracer.scene.rays import Rays, Shadows  # noqa: E402
from tracer.shade.shading import shading_normal  # noqa: E402

import generator  # noqa: E402
import reference  # noqa: E402

#: t of a primary hit may differ by this much, relative (plus the brute force's own uncertainty)
T_TOLERANCE = 2.0**-30
#: pixels may differ by this many 8-bit levels (rounding at a level's boundary)
LEVELS = 1


@dataclass
class Outcome:
    """What one scene gave: how much was compared, what disagreed, and a few examples."""

    seed: int
    family: str
    compared: Counter = field(default_factory=Counter)
    disagreed: Counter = field(default_factory=Counter)
    examples: list[str] = field(default_factory=list)
    error: str | None = None

    @property
    def bad(self) -> bool:
        return self.error is not None or sum(self.disagreed.values()) > 0

    def note(self, kind: str, compared: int, bad: np.ndarray, describe: list[str]) -> None:
        self.compared[kind] += compared
        count = int(np.count_nonzero(bad))
        if count:
            self.disagreed[kind] += count
            self.examples += describe[:3]


def _surface_map(renderer: Renderer, surfaces: list[reference.Surface]) -> dict[tuple[int, int], int]:
    """(phongray kind, index) → index in the brute force's surface list."""
    w = renderer.world
    by_owner = {(s.obj, s.face): k for k, s in enumerate(surfaces)}
    out: dict[tuple[int, int], int] = {}
    for kind, objects, faces in (
        (SPHERE, w.spheres.object, None),
        (PLANE, w.planes.object, None),
        (TRIANGLE, w.triangles.object, w.triangles.face),
    ):
        for i, obj in enumerate(objects):
            key = (int(obj), 0 if faces is None else int(faces[i]))
            if key in by_owner:
                out[(kind, i)] = by_owner[key]
    return out


def _identity(renderer: Renderer, surfaces: list[reference.Surface]) -> dict[int, tuple[int, int]]:
    return {v: k for k, v in _surface_map(renderer, surfaces).items()}


def compare(seed: int, data: dict[str, Any], family: str = "") -> Outcome:
    """Render one scene both ways and compare what is clear."""
    out = Outcome(seed, family)
    scene = schemas.validate_scene(data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        frame = reference.render(scene)
        renderer = Renderer(scene)
        picture = renderer.picture(threads=1)
        image = picture.pixels
        _rays(out, scene, renderer)
    clear = ~frame.unclear
    diff = np.abs(image.astype(np.int16) - frame.pixels().astype(np.int16)).max(axis=2)
    bad = clear & (diff > LEVELS)
    where = np.argwhere(bad)
    out.note(
        "pixel",
        int(clear.sum()),
        bad,
        [
            f"pixel (x={x}, y={y}): phongray {image[y, x].tolist()} brute force {frame.pixels()[y, x].tolist()}"
            for y, x in where[:3]
        ],
    )
    wrong = clear & (picture.open != frame.open)
    out.note(
        "open pixel",
        int(np.count_nonzero(clear & frame.open)),
        wrong,
        [
            f"pixel (x={x}, y={y}): phongray {'open' if picture.open[y, x] else 'decided'}, brute force "
            f"{'open' if frame.open[y, x] else 'decided'}"
            for y, x in np.argwhere(wrong)[:3]
        ],
    )
    return out


def _rays(out: Outcome, scene: Any, renderer: Renderer) -> None:
    surfaces = reference.surfaces_of(scene)
    to_ref = _surface_map(renderer, surfaces)
    to_phong = _identity(renderer, surfaces)
    origin = renderer.world.origin
    o, d, _ = reference.camera_rays(scene)
    ref = reference.closest(surfaces, o, d, np.full(len(o), -1))
    isect = renderer.intersector
    camera_rays = isect.rays(o - origin, d)
    hits = isect.closest(camera_rays)
    _same_by_cones(out, "hit by cones", hits, isect.closest(camera_rays, _cones(renderer, camera_rays)))
    bounds = bounds_of(renderer.world)
    if bounds is not None:  # the test of rays of their own directions (a mirror's), on these rays
        _same_by_cones(
            out,
            "hit by lines",
            hits,
            isect.closest(camera_rays, on_lines(bounds, camera_rays.origins, camera_rays.dirs)),
        )
    _proofs(out, renderer, camera_rays, hits)
    got = np.array([to_ref.get((int(k), int(i)), -2) if k != MISS else -1 for k, i in zip(hits.kind, hits.index)])
    clear = ~ref.unclear
    with np.errstate(invalid="ignore"):
        t_ok = (ref.surface < 0) | (
            np.abs(hits.t - ref.t) <= T_TOLERANCE * ref.t + reference.ERR * (np.abs(o).max(axis=1) + ref.t)
        )
    bad = clear & ((got != ref.surface) | ~t_ok)
    out.note(
        "hit",
        int(clear.sum()),
        bad,
        [
            f"primary ray {r}: phongray surface {got[r]} t={hits.t[r]!r}, brute force {ref.surface[r]} t={ref.t[r]!r}"
            for r in np.flatnonzero(bad)[:3]
        ],
    )
    # shadow decisions from the brute force's own clear hits
    rows = np.flatnonzero(clear & (ref.surface >= 0) & (got == ref.surface))
    if len(rows) == 0:
        return
    which = ref.surface[rows]
    p, shading = np.zeros((len(rows), 3)), np.zeros((len(rows), 3))
    for k in np.unique(which):
        sel = np.flatnonzero(which == k)
        r = rows[sel]
        p[sel], _, shading[sel] = reference.surface_point(surfaces[k], o[r], d[r], ref.t[r], ref.u[r], ref.w[r])
    kinds = np.array([to_phong[int(k)][0] for k in which], dtype=np.int8)
    indices = np.array([to_phong[int(k)][1] for k in which], dtype=np.int64)
    _mirrors(out, renderer, surfaces, to_ref, p, d[rows], shading, which, kinds, indices, bounds)
    for e_index, e in enumerate(reference.emitters_of(scene)[1]):
        L, dist, f, unclear_f = reference.illuminate(e, p)
        nl, unclear_nl = reference.n_dot_l(surfaces, which, e, shading, L)
        ask = np.flatnonzero((nl > 0) & (f > 0) & ~unclear_nl & ~unclear_f)
        if len(ask) == 0:
            continue
        blk, unclear_b = reference.blocked(surfaces, p[ask], L[ask], dist[ask], which[ask], e.position)
        ends = None if e.position is None else (e.position - origin)[None]
        rays = isect.rays(p[ask] - origin, np.ascontiguousarray(L[ask]), kinds[ask], indices[ask])
        shadows = Shadows.towards(rays, dist[ask], ends, renderer.world.origin_mag)
        mine = isect.occluded(shadows)
        among = _cones(renderer, rays, None if ends is None else ends[0], dist[ask])
        if among is not None:
            by_cones = isect.occluded(shadows, among)
            wrong = by_cones != mine
            out.note(
                "shadow by cones",
                len(mine),
                wrong,
                [
                    f"shadow ray {r} to light {e_index}: walked {mine[r]}, by cones {by_cones[r]}"
                    for r in np.flatnonzero(wrong)[:3]
                ],
            )
        bad = ~unclear_b & (mine != blk)
        out.note(
            "shadow",
            int(np.count_nonzero(~unclear_b)),
            bad,
            [
                f"shadow ray from surface {which[ask][r]} at {p[ask][r].tolist()} to light {e_index}: phongray "
                f"{'blocked' if mine[r] else 'clear'}, brute force {'blocked' if blk[r] else 'clear'}"
                for r in np.flatnonzero(bad)[:3]
            ],
        )


def _mirrors(
    out: Outcome,
    renderer: Renderer,
    surfaces: list,
    to_ref: dict,
    p: np.ndarray,
    d: np.ndarray,
    shading: np.ndarray,
    which: np.ndarray,
    kinds: np.ndarray,
    indices: np.ndarray,
    bounds: Any,
) -> None:
    """Mirror rays from the brute force's own clear hits, leaving their surfaces: phongray's walk (whatever the
    scene's materials, which may send none) against the brute force, and the pairs of rays of their own
    directions (tracer.proofs.cones.on_lines) against the walk, bit for bit."""
    mirror = d - 2.0 * np.sum(d * shading, axis=1)[:, None] * shading
    mirror /= np.linalg.norm(mirror, axis=1)[:, None]
    ref = reference.closest(surfaces, p, mirror, which)
    isect = renderer.intersector
    rays = isect.rays(p - renderer.world.origin, np.ascontiguousarray(mirror), kinds, indices)
    hits = isect.closest(rays)
    if bounds is not None:
        _same_by_cones(out, "hit by lines", hits, isect.closest(rays, on_lines(bounds, rays.origins, rays.dirs)))
    got = np.array([to_ref.get((int(k), int(i)), -2) if k != MISS else -1 for k, i in zip(hits.kind, hits.index)])
    clear = ~ref.unclear
    # t as exact as the numbers it comes from: the ray's origin (which phongray takes in the eye's frame, rounded
    # there), the hit surface's own (a planet's), and t itself; across the surface, that is, and along a ray that
    # grazes it, that much over the cosine (a mirror ray meets a planet far off nearly edge-on)
    mag = np.array([surfaces[k].mag if k >= 0 else 0.0 for k in ref.surface]) + float(
        np.max(np.abs(renderer.world.origin))
    )
    cosine = np.ones(len(p))
    for k in np.unique(ref.surface[ref.surface >= 0]):
        sel = np.flatnonzero(ref.surface == k)
        _, geo, _ = reference.surface_point(surfaces[k], p[sel], mirror[sel], ref.t[sel], ref.u[sel], ref.w[sel])
        cosine[sel] = np.abs(np.sum(geo * mirror[sel], axis=1))
    with np.errstate(invalid="ignore", divide="ignore"):
        t_ok = (ref.surface < 0) | (
            np.abs(hits.t - ref.t)
            <= T_TOLERANCE * ref.t
            + reference.ERR * (np.abs(p).max(axis=1) + ref.t + mag) / np.maximum(cosine, 2.0**-40)
        )
    bad = clear & ((got != ref.surface) | ~t_ok)
    out.note(
        "mirror hit",
        int(clear.sum()),
        bad,
        [
            f"mirror ray {r} from surface {which[r]}: phongray surface {got[r]} t={hits.t[r]!r}, brute force "
            f"{ref.surface[r]} t={ref.t[r]!r}"
            for r in np.flatnonzero(bad)[:3]
        ],
    )


def _proofs(out: Outcome, renderer: Renderer, camera_rays: Any, hits: Any) -> None:
    """Every shadow ray the proofs of tracer.proofs.culling spare (tiles of points a point or directional light
    reaches whole, points that see every sample of an area light), cast all the same from phongray's own hits
    that face the light: none is blocked."""
    world, isect = renderer.world, renderer.intersector
    bounds = bounds_of(world)
    got = np.flatnonzero(hits.kind != MISS)
    if bounds is None or len(got) == 0:
        return
    h = hits.take(got)
    normal = shading_normal(world, h, camera_rays.dirs[got])
    mag = np.max(np.abs(h.point), axis=1) + world.origin_mag
    for group in renderer.shading.groups:
        if group.corners is None:
            em = world.emitters[group.first]
            directional = em.kind == "directional"
            proven = np.repeat(
                lit_tiles(
                    bounds,
                    SurfacePoints(h.point, h.kind, h.index, normal),
                    None if directional else em.position,
                    em.direction if directional else None,
                ),
                TILE,
            )[: len(got)]
            samples = [em]
        else:
            culled = classify(bounds, SurfacePoints(h.point, h.kind, h.index, normal), group.corners)
            proven = culled.state == SEEN
            samples = world.emitters[group.first : group.end]
            _penumbra(out, renderer, h, normal, mag, culled, group)
        for em in samples:
            to_light, dist, factor = illuminate(em, h.point)
            rows = np.flatnonzero(proven & (np.sum(normal * to_light, axis=1) > 0) & (factor > 0))
            if len(rows) == 0:
                continue
            rays = Rays(h.point[rows], np.ascontiguousarray(to_light[rows]), h.kind[rows], h.index[rows], mag[rows])
            ends = None if em.kind == "directional" else em.position[None]
            shadows = Shadows.towards(rays, dist[rows], ends, world.origin_mag)
            blocked = isect.occluded(shadows)
            out.note(
                "shadow by proofs",
                len(rows),
                blocked,
                [
                    f"shadow ray from {h.point[r].tolist()} (surface {h.kind[r]}/{h.index[r]}) to light "
                    f"{group.light}, proven clear, is blocked"
                    for r in rows[np.flatnonzero(blocked)][:3]
                ],
            )


def _penumbra(
    out: Outcome, renderer: Renderer, h: Any, normal: np.ndarray, mag: np.ndarray, culled: Any, group: Any
) -> None:
    """An area light's mixed points' rays that tracer.proofs.penumbra.Penumbra decides without casting them, cast all
    the same: each proven blocked is blocked, each left uncast and not blocked is clear."""
    world, isect = renderer.world, renderer.intersector
    mixed = np.flatnonzero(culled.state == MIXED)
    if len(mixed) == 0:
        return
    bounds = bounds_of(world)
    pen = Penumbra(
        bounds,
        SurfacePoints(h.point[mixed], h.kind[mixed], h.index[mixed], normal[mixed]),
        culled.may_block[:, mixed],
        group.corners,
        True,
    )
    for em in world.emitters[group.first : group.end]:
        to_light, dist, factor = illuminate(em, h.point[mixed])
        lit = (np.sum(normal[mixed] * to_light, axis=1) > 0) & (factor > 0)
        if not lit.any():
            continue
        blocked, cast, _ = pen.decide(lit, to_light, dist)
        rows = mixed[lit]
        rays = Rays(h.point[rows], np.ascontiguousarray(to_light[lit]), h.kind[rows], h.index[rows], mag[rows])
        truth = isect.occluded(Shadows.towards(rays, dist[lit], em.position[None], world.origin_mag))
        wrong = (blocked & ~truth) | (~cast & ~blocked & truth)
        out.note(
            "shadow by proofs",
            len(rows),
            wrong,
            [
                f"penumbra ray from {h.point[r].tolist()} to a sample of light {group.light}: proven "
                f"{'blocked' if blocked[j] else 'clear'}, cast {'blocked' if truth[j] else 'clear'}"
                for j, r in zip(np.flatnonzero(wrong)[:3], rows[np.flatnonzero(wrong)[:3]])
            ],
        )


def _cones(renderer: Renderer, rays: Any, light: np.ndarray | None = None, reach: np.ndarray | None = None) -> Any:
    """The pairs :mod:`tracer.proofs.cones` proves for camera rays (from the eye, or along one direction) or for shadow
    rays towards ``light`` (or along one direction, for a directional light): None where no proof applies."""
    bounds, tris = bounds_of(renderer.world), renderer.world.triangles
    if bounds is None or len(rays) == 0:
        return None
    if reach is None and np.all(rays.origins == rays.origins[0]):  # camera rays from the eye
        return through_point(bounds, tris, rays.origins[0], rays.dirs, True)
    if light is not None and reach is not None:
        return through_point(bounds, tris, light, rays.dirs, False, float(np.max(reach)))
    if np.all(rays.dirs == rays.dirs[0]):  # one direction: an orthographic camera, a directional light
        return along_direction(bounds, tris, rays.origins, rays.dirs[0])
    return None


def _same_by_cones(out: Outcome, kind: str, walked: Any, by_cones: Any) -> None:
    """The hits found with :mod:`tracer.proofs.cones`' pairs are the walk's, bit for bit."""
    same = (
        (walked.kind == by_cones.kind)
        & (walked.index == by_cones.index)
        & ((walked.t == by_cones.t) | (np.isinf(walked.t) & np.isinf(by_cones.t)))
    )
    same &= np.all((walked.bary == by_cones.bary) | (walked.kind != TRIANGLE)[:, None], axis=1)
    out.note(
        kind,
        len(same),
        ~same,
        [
            f"camera ray {r}: walked surface {walked.kind[r]}/{walked.index[r]} t={walked.t[r]!r}, by cones "
            f"{by_cones.kind[r]}/{by_cones.index[r]} t={by_cones.t[r]!r}"
            for r in np.flatnonzero(~same)[:3]
        ],
    )


def run_seed(seed: int, width: int = 20, height: int = 15) -> Outcome:
    family, data = generator.scene(seed, width, height)
    try:
        return compare(seed, data, family)
    except Exception as exc:  # a crash is a disagreement too
        out = Outcome(seed, family)
        out.error = f"{type(exc).__name__}: {exc}"
        return out


def write(out: Outcome, folder: Path, width: int, height: int) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    _, data = generator.scene(out.seed, width, height)
    (folder / f"seed-{out.seed}.json").write_text(json.dumps(data, indent=1))
    lines = [f"seed {out.seed} ({out.family})"]
    if out.error:
        lines.append(f"error: {out.error}")
    lines += [f"{k}: {out.disagreed[k]} of {out.compared[k]} disagree" for k in sorted(out.disagreed)]
    lines += out.examples
    (folder / f"seed-{out.seed}.txt").write_text("\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.fuzz", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=1000, help="how many scenes (default 1000)")
    ap.add_argument("--seed", type=int, default=0, help="the first seed (default 0)")
    ap.add_argument("--out", type=Path, default=Path("fuzz-out"), help="where disagreeing scenes go")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="processes (default: every core)")
    ap.add_argument("--size", default="20x15", help="image size WxH (default 20x15)")
    args = ap.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    seeds = range(args.seed, args.seed + args.scenes)
    start = time.monotonic()
    bad: list[Outcome] = []
    compared: Counter = Counter()
    disagreed: Counter = Counter()
    families: Counter = Counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for done, out in enumerate(
            pool.map(run_seed, seeds, [width] * len(seeds), [height] * len(seeds), chunksize=4), 1
        ):
            compared.update(out.compared)
            disagreed.update(out.disagreed)
            if out.bad:
                bad.append(out)
                families[out.family] += 1
                write(out, args.out, width, height)
            if done % 500 == 0:
                print(f"{done} scenes, {len(bad)} disagreeing, {time.monotonic() - start:.0f} s", flush=True)
    print(
        f"{len(seeds)} scenes (seeds {seeds.start}..{seeds.stop - 1}, {width}x{height}) in "
        f"{time.monotonic() - start:.0f} s"
    )
    for kind in (
        "hit",
        "mirror hit",
        "shadow",
        "pixel",
        "open pixel",
        "hit by cones",
        "hit by lines",
        "shadow by cones",
        "shadow by proofs",
    ):
        print(f"  {kind}: {disagreed[kind]} disagreements in {compared[kind]} compared")
    crashed = sum(1 for o in bad if o.error)
    print(f"  crashes: {crashed}")
    print(f"disagreeing scenes: {len(bad)}" + (f" (by family: {dict(families)}; written to {args.out})" if bad else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
