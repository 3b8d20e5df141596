"""The walk's exact tests: (ray, primitive) pairs of the BVH's triangles and spheres, decided in float64.

A walk (:mod:`tracer.exact.walk`) names the pairs; here each pair gathers its ray (origin, direction, magnitude) and
its primitive (a triangle's corners, normal and magnitude, or a sphere's centre, radius and magnitude) as one
row of a packed table, and the exact test (:mod:`tracer.scene.shapes`) runs on contiguous columns.  A ray leaves the
surface it starts from by identity, and a member of a coplanar group leaves the group (:mod:`tracer.scene.coplanar`),
whose members' hits are timed on the group's plane.

Primitive ids: the walk's triangles ``0..T-1``, then its spheres ``T..T+S-1``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..scene.kinds import SPHERE, TRIANGLE
from ..scene.rays import Rays, Shadows, shared_rows
from ..scene.shapes import sphere_t, triangle_t
from ..scene.vec import rows_of
from ..scene.world import World
from .best import Best
from .ties import KIND_SHIFT, SURFACE_MASK, Ties

#: (ray, primitive) pairs tested exactly at a time
PAIR_SLICE = 1 << 16
#: a hit this far inside a triangle, in each barycentric coordinate, is far from its edges beyond any rounding
INSIDE = 2.0**-24


def _nothing() -> None:
    return None


def _ignored(n: int) -> None:
    return None


def gathered(*columns: np.ndarray) -> np.ndarray:
    """``(N, k)`` and ``(N,)`` arrays side by side in one ``(N, Σk)`` array, so that the walk gathers a ray's
    (or a primitive's) values with one row copy instead of one per array: pairs reach all over the tables, and
    a gather's cost is its cache misses (measured on 150k random rows of 208k: 4 ms against 20 ms for four
    ``(N, 3)`` arrays)."""
    return np.concatenate([c if c.ndim == 2 else c[:, None] for c in columns], axis=1)


def _columns_of(rows: np.ndarray) -> np.ndarray:
    """Gathered rows ``(n, k)`` as ``(k, n)`` columns, each contiguous: ``out[0:3].T`` is then an ``(n, 3)``
    view whose x, y and z (all :mod:`tracer.scene.vec` reads) are contiguous, faster to compute on than the rows'
    own strided columns (measured: a triangle test 4.7 ms against 11.4 ms on 100k pairs, 2.7 ms to copy)."""
    return np.ascontiguousarray(rows.T)


@dataclass(frozen=True)
class Batch:
    """The rays of one walk or one set of pairs, as the exact tests read them: a row per ray of origin,
    direction and magnitude (:func:`gathered`), the BVH primitive each leaves (−1 for none), the coplanar group
    it leaves (−1 for none; None in a world without groups), and the shadow query they are of (None: closest
    hits)."""

    table: np.ndarray
    from_prim: np.ndarray
    from_group: np.ndarray | None
    shadows: Shadows | None


class PairTests:
    """The exact tests of the walk's triangles ``tris`` and spheres ``spheres`` (indices within their kinds)."""

    def __init__(self, world: World, tris: np.ndarray, spheres: np.ndarray, ties: Ties):
        #: called between slices of exact tests; raises to stop a render
        self.check: Callable[[], None] = _nothing
        #: told how many exact tests each batch makes (:meth:`tracer.budget.RayCount.tested`)
        self.tested: Callable[[int], None] = _ignored
        tr, sp = world.triangles, world.spheres
        self.ties, self.groups = ties, world.coplanar
        self.n_tri = len(tris)
        self.prim_index = np.concatenate([tris, spheres]).astype(np.int64)
        self.tri_prim = np.full(len(tr.v0), -1, dtype=np.int64)
        self.tri_prim[tris] = np.arange(len(tris))
        self.sphere_prim = np.full(len(sp.radius), -1, dtype=np.int64)
        self.sphere_prim[spheres] = np.arange(len(spheres)) + len(tris)
        #: each triangle's v0, e1, e2, normal and magnitude in one row (T, 13); each sphere's centre, radius and
        #: magnitude (S, 5): what an exact test reads of it
        self.tri_rows = gathered(tr.v0, tr.e1, tr.e2, tr.normal, tr.mag)
        self.sphere_rows = gathered(sp.center, sp.radius, sp.mag)
        #: a plain triangle's faces across its edges (:mod:`tracer.proofs.sightlines`), set by the walk: (n_tri, 3)
        self.mates: np.ndarray | None = None

    def batch(self, rays: Rays, shadows: Shadows | None, table: np.ndarray | None = None) -> Batch:
        """The exact tests' view of ``rays`` (of ``shadows``, if a shadow query)."""
        if table is None:
            table = gathered(rays.origins, rays.dirs, rays.mag)
        from_group = None if self.groups is None else self.groups.of(rays.from_kind, rays.from_index)
        return Batch(table, self.prim_of(rays.from_kind, rays.from_index), from_group, shadows)

    def prim_of(self, kind: np.ndarray, index: np.ndarray) -> np.ndarray:
        """The walk's primitive id of each surface ``kind`` (SPHERE or TRIANGLE), ``index``; −1 for a surface
        not in the walk (planes, and the surfaces tested directly). Shape (N,)."""
        out = np.full(len(kind), -1, dtype=np.int64)
        tri, sph = kind == TRIANGLE, kind == SPHERE
        out[tri] = self.tri_prim[index[tri]]
        out[sph] = self.sphere_prim[index[sph]]
        return out

    def test(self, best: Best, rows: np.ndarray, prims: np.ndarray, batch: Batch) -> None:
        """Test BVH primitives ``prims`` exactly against rays ``rows`` of ``batch`` (pairs; either may repeat)."""
        self.tested(len(prims))
        tri = prims < self.n_tri
        n_tri = int(np.count_nonzero(tri))
        for is_tri, count in ((True, n_tri), (False, len(prims) - n_tri)):
            if count == 0:
                continue
            if count < len(prims):
                chosen = np.flatnonzero(tri == is_tri)
                r, q = np.take(rows, chosen), np.take(prims, chosen)
            else:  # (all of one kind, as in a mesh: no copies)
                r, q = rows, prims
            for at in range(0, count, PAIR_SLICE):  # bounded temporaries, and a render can stop between slices
                if at:
                    self.check()
                self._test_kind(best, is_tri, r[at : at + PAIR_SLICE], q[at : at + PAIR_SLICE], batch)

    def _test_kind(self, best: Best, is_tri: bool, r: np.ndarray, q: np.ndarray, batch: Batch) -> None:
        """Rays ``r`` against primitives ``q`` of :meth:`test`, all of one kind (triangles when ``is_tri``)."""
        k = np.take(self.prim_index, q)
        leaving = np.take(batch.from_prim, r) == q
        shadows = batch.shadows
        e = me = reach = None
        if shadows is not None:  # a shadow walk: only whether something lies before the light matters
            e, me, reach = shared_rows(shadows.ends, r), shared_rows(shadows.mag_end, r), shadows.reach[r]
        u = v = None
        ray = _columns_of(rows_of(batch.table, r))  # one gather per pair for the ray, one for the primitive
        o, d, mag_o = ray[0:3].T, ray[3:6].T, ray[6]
        if is_tri:
            group = None
            if self.groups is not None and batch.from_group is not None:  # a member leaves its group
                group = self.groups.triangle[k]
                leaving |= self.groups.leaving(np.take(batch.from_group, r), group)
            g = _columns_of(rows_of(self.tri_rows, k))
            t, u, v = triangle_t(
                o, d, g[0:3].T, g[3:6].T, g[6:9].T, g[9:12].T, mag_o, g[12], leaving, e, me, uv=shadows is None
            )
            if group is not None and shadows is None and self.groups is not None:  # timed on its group's plane
                t = self.groups.retime(t, o, d, group)
        else:
            g = _columns_of(rows_of(self.sphere_rows, k))
            t = sphere_t(o, d, g[0:3].T, g[3], mag_o, g[4], leaving, e, reach, me)
        if shadows is not None:
            best.block(r, t)
        else:
            best.offer(r, t, TRIANGLE if is_tri else SPHERE, k, u, v)

    def with_mates(self, prims: np.ndarray, where: np.ndarray) -> np.ndarray:
        """``prims (n,)`` (−1 for none) and, where ``where``, a plain triangle's mates (its faces across its
        edges, :func:`tracer.proofs.sightlines.plain_triangles`): ``(n, 4)`` primitive ids, −1 for none, or ``(n, 1)``
        in a scene without mates."""
        if self.mates is None:
            return prims[:, None]
        out = np.full((len(prims), 4), -1, dtype=np.int64)
        out[:, 0] = prims
        tri = np.flatnonzero(where & (prims >= 0) & (prims < self.n_tri))
        out[tri, 1:] = rows_of(self.mates, prims[tri])
        return out

    def done_with(self, best: Best, rows: np.ndarray, prims: np.ndarray, any_hit: bool) -> np.ndarray:
        """What the rays ``rows``, having just tested the primitives ``prims`` they crossed, need not test again
        at that crossing (as :meth:`with_mates` gives it).

        The primitive itself; and, for a camera ray that hits a plain triangle well inside it, its mates: the
        plane through a shared edge and the eye (or along the view) has the ray's line on the triangle's side,
        so the ray meets no mate anywhere.
        """
        inside = np.zeros(len(rows), dtype=bool)
        if not any_hit and self.mates is not None:
            tri = np.flatnonzero(prims < self.n_tri)
            k = self.prim_index[prims[tri]]
            u, v = best.uv[rows[tri], 0], best.uv[rows[tri], 1]
            surface = best.key[rows[tri]] & SURFACE_MASK
            inside[tri] = (surface == (TRIANGLE << KIND_SHIFT) | k) & (u > INSIDE) & (v > INSIDE)
            inside[tri] &= 1.0 - u - v > INSIDE
        return self.with_mates(prims, inside)
