"""The lines a scene's rays travel on, and the triangles Embree may see as they are.

Embree meets triangles in float32 (:mod:`tracer.exact.embree`): the ray and the
corners are rounded by up to :data:`tracer.proofs.margins.LINE_ERROR` (in the BVH's normalised
units), which moves where a ray crosses a triangle's plane by that much over
the sine of the angle between them.  A closed proxy (:mod:`tracer.exact.proxies`)
makes that harmless at any angle, at the price of four faces and four corners
of its own.  But when every ray the scene casts passes through one of a few
known points (the eye of a perspective camera, point lights, spots, the
corners' hull of an area light) or runs along a known direction (an
orthographic camera, a directional light), and no material sends rays
elsewhere (no mirror, no glass), most triangles of a mesh can go to Embree
as themselves, sharing the mesh's float32 corners, and still never be
missed.  A triangle is *plain* when, for every such point or direction:

* every ray meets its plane at a sine of at least :data:`tracer.proofs.margins.MIN_SINE`, so the
  float32 crossing lies within ``LINE_ERROR / MIN_SINE``
  (:data:`tracer.proofs.margins.CROSSING_SLACK`) of the float64 hit;
* each of its edges is shared by exactly one other face of its mesh (same
  corner indices), and the two faces lie on opposite sides of the plane
  through the edge and the point (or along the direction): a ray near the
  edge then crosses one of the two, which Embree's watertight test keeps;
* no point lies within :data:`tracer.proofs.margins.NEAR` of it (a ray starting or ending there).

Everything else (lone triangles, mesh borders, silhouettes, surfaces seen
edge-on) keeps its proxy, whose margin covers that displacement (see
:data:`tracer.exact.proxies.TRIANGLE_MARGIN`), and the walk looks that far past a
hit (:attr:`tracer.exact.proxies.Proxies.slack`).  Without known lines every
triangle keeps its proxy.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from ..scene.vec import length
from .margins import MIN_SINE, NEAR


@dataclass
class Sightlines:
    """Every ray passes through a point of the hull of one of ``hulls`` or runs along one of ``directions``."""

    hulls: list[np.ndarray] = field(default_factory=list)  # each (k, 3) local points
    directions: list[np.ndarray] = field(default_factory=list)  # each (3,) unit
    #: planes (point, unit normal) that rays start on along a direction (an orthographic camera's)
    starts: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)


def _same_sign(values: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(all > 0, all < 0) over the list, per row."""
    pos = np.ones(len(values[0]), dtype=bool)
    neg = pos.copy()
    for v in values:
        pos &= v > 0
        neg &= v < 0
    return pos, neg


def _folds(side1: list[np.ndarray], side2: list[np.ndarray]) -> np.ndarray:
    """Where an edge's two opposite corners are not on opposite sides of every plane through it (each list
    holds one corner's signed side per plane): a silhouette. Per edge, bool."""
    p1, n1 = _same_sign(side1)
    p2, n2 = _same_sign(side2)
    return ~((p1 & n2) | (n1 & p2))


#: one vector as its three columns: each a 1-D array of rows, or a float that every row shares
Columns = tuple  # (x, y, z)


def _minus(a: Columns, b: Columns) -> Columns:
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


def _dot(a: Columns, b: Columns) -> np.ndarray:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Columns, b: Columns) -> Columns:
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


def _columns(a: np.ndarray) -> Columns:
    return tuple(np.ascontiguousarray(a[..., k]) for k in range(3))


#: below this many triangles, the tests of :func:`plain_triangles` run one after another here: starting a pool's
#: threads would cost more than they spare
SIDE_BY_SIDE_MIN = 4096


@contextmanager
def _side_by_side(tasks: int, here: bool = False) -> Iterator[Callable[..., Future]]:
    """``run(f, *args)`` starts ``f(*args)`` (with floating-point warnings off) on a pool of up to as many
    threads as cores, and gives its future; every task has finished when the block ends.  With ``here`` (or one
    task, or one core), each runs at once in this thread instead: the same results, as finished futures."""

    def quiet(f: Callable[..., np.ndarray], *args: object) -> np.ndarray:
        with np.errstate(all="ignore"):
            return f(*args)

    workers = max(1, min(tasks, os.cpu_count() or 1))
    if here or workers == 1:

        def now(f: Callable[..., np.ndarray], *args: object) -> Future:
            done: Future = Future()
            try:
                done.set_result(quiet(f, *args))
            except BaseException as e:  # (raised where the pool's future would raise it: at its result)
                done.set_exception(e)
            return done

        yield now
        return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        yield lambda f, *args: pool.submit(quiet, f, *args)


def plain_triangles(
    v0: np.ndarray,
    e1: np.ndarray,
    e2: np.ndarray,
    normal: np.ndarray,
    corner_ids: np.ndarray,
    lines: Sightlines,
    half_size: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Which triangles Embree may meet as they are, for rays on ``lines``: ``plain (T,)`` bool, and ``mates
    (T, 3)``, a plain triangle's face across each of its edges (−1 for every edge of the others).

    A ray that leaves a plain triangle from a point of it towards a point of ``lines`` (or along one of its
    directions), as a shadow ray does, never meets a mate on the way: the plane through their shared edge
    and that point (or along that direction) has the triangle's open side, where the ray runs until it
    reaches the point, and the mate's closed side, which the mate never leaves.

    ``corner_ids (T, 3)``: the index of each corner in its mesh's shared
    corners (distinct across meshes; a lone triangle's corners are its own).
    The arithmetic runs on columns (1-D arrays), as :mod:`tracer.scene.vec` explains.
    """
    n_tri = len(v0)
    if n_tri == 0:
        return np.zeros(0, dtype=bool), np.zeros((0, 3), dtype=np.int64)
    stacked = np.stack([v0, v0 + e1, v0 + e2], axis=1)  # (T, 3, 3)
    flat = [np.ascontiguousarray(stacked[..., k]).reshape(-1) for k in range(3)]  # corner s of face f at 3 f + s
    corners = [tuple(a[s::3] for a in flat) for s in range(3)]
    nrm, base = _columns(normal), corners[0]
    near = NEAR * half_size
    lo_box = tuple(np.minimum(np.minimum(corners[0][k], corners[1][k]), corners[2][k]) for k in range(3))
    hi_box = tuple(np.maximum(np.maximum(corners[0][k], corners[1][k]), corners[2][k]) for k in range(3))

    # the tests of faces and of edges, each a mask of its own, run side by side (NumPy lets go of the GIL)
    def seen_squarely(points: list[tuple[float, ...]]) -> np.ndarray:
        """Faces every point sees at a sine of at least MIN_SINE, none of them near."""
        dist = [_dot(nrm, _minus(p, base)) for p in points]
        pos, neg = _same_sign(dist)
        nearest = np.min(np.abs(np.stack(dist)), axis=0)
        far = np.zeros(n_tri)
        ok = pos | neg
        for p in points:
            for c in corners:
                w = _minus(c, p)
                far = np.maximum(far, length(*w))
            gap = tuple(np.maximum(np.maximum(lo_box[k] - p[k], p[k] - hi_box[k]), 0.0) for k in range(3))
            ok &= ~(length(*gap) <= near)
        return ok & (nearest >= MIN_SINE * far)

    def seen_along(direction: tuple[float, ...]) -> np.ndarray:
        return np.abs(_dot(nrm, direction)) >= MIN_SINE

    def clear_of(point: tuple[float, ...], towards: tuple[float, ...]) -> np.ndarray:
        s = [_dot(_minus(c, point), towards) for c in corners]
        return np.minimum(np.minimum(s[0], s[1]), s[2]) > near

    face_tests: list[tuple[Callable[..., np.ndarray], tuple]] = [
        (seen_squarely, ([tuple(float(x) for x in p) for p in hull],)) for hull in lines.hulls
    ]
    face_tests += [(seen_along, (tuple(float(x) for x in d),)) for d in lines.directions]
    face_tests += [(clear_of, (tuple(float(x) for x in p), tuple(float(x) for x in n))) for p, n in lines.starts]
    with _side_by_side(len(face_tests) + len(lines.hulls) + len(lines.directions), n_tri < SIDE_BY_SIDE_MIN) as run:
        face_masks = [run(test, *args) for test, args in face_tests]
        plain = np.ones(n_tri, dtype=bool)
        # edges: slot s joins corners s and s+1; the corner opposite it is s+2
        a_id = np.concatenate([corner_ids[:, 0], corner_ids[:, 1], corner_ids[:, 2]])
        b_id = np.concatenate([corner_ids[:, 1], corner_ids[:, 2], corner_ids[:, 0]])
        lo, hi = np.minimum(a_id, b_id), np.maximum(a_id, b_id)
        key = lo * (int(corner_ids.max()) + 1) + hi
        order = np.argsort(key, kind="stable")
        key = key[order]
        run_start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        run_len = np.diff(np.r_[run_start, len(key)])
        lonely = np.repeat(run_len != 2, run_len)  # a border (1 face) or a seam of three or more
        plain[order[lonely] % n_tri] = False
        first = order[run_start[run_len == 2]]
        second = order[run_start[run_len == 2] + 1]
        f1, f2 = first % n_tri, second % n_tri
        slot = first // n_tri
        mates = np.full((n_tri, 3), -1, dtype=np.int64)
        mates[f1, slot] = f2
        mates[f2, second // n_tri] = f1

        def corner_of(face: np.ndarray, s: np.ndarray) -> Columns:
            at = 3 * face + s
            return tuple(a[at] for a in flat)

        ea, eb = corner_of(f1, slot), corner_of(f1, (slot + 1) % 3)
        c1, c2 = corner_of(f1, (slot + 2) % 3), corner_of(f2, (second // n_tri + 2) % 3)

        def folds_seen_from(points: list[tuple[float, ...]]) -> np.ndarray:
            """Edges where, seen from the points, the two faces lie on one side (a silhouette)."""
            planes = [(_cross(_minus(ea, p), _minus(eb, p)), p) for p in points]  # through the edge and p
            return _folds(
                [_dot(through, _minus(c1, p)) for through, p in planes],
                [_dot(through, _minus(c2, p)) for through, p in planes],
            )

        def folds_along(direction: tuple[float, ...]) -> np.ndarray:
            through = _cross(_minus(eb, ea), direction)
            return _folds([_dot(through, _minus(c1, ea))], [_dot(through, _minus(c2, ea))])

        edge_masks = [run(folds_seen_from, [tuple(float(x) for x in p) for p in hull]) for hull in lines.hulls]
        edge_masks += [run(folds_along, tuple(float(x) for x in d)) for d in lines.directions]
        for mask in face_masks:
            plain &= mask.result()
        for mask in edge_masks:
            fold = mask.result()
            plain[f1[fold]] = False
            plain[f2[fold]] = False
    mates[~plain] = -1
    return plain, mates
