"""Closest-hit and occlusion queries over every kind of surface a scene contains, decided in float64.

Planes, and spheres or triangles far larger than the rest (a planet under
tiny objects, a ground triangle reaching 10⁵ away), are tested exactly
against every ray: a scene has few.  The other triangles and spheres share
one Embree BVH of closed float32 proxies (:mod:`tracer.proxies`).  Embree
names the nearest proxy crossing along a ray; that primitive and its
neighbours are tested exactly in float64, and the ray steps on past the
crossing.  The walk is bounded by distance (it ends at the best hit, plus the
size of any sphere proxy that contains the ray's start, or at the BVH's
bounding box), never by a count of candidates: every crossing is passed once.
A scene with plain mesh faces (:mod:`tracer.sightlines`) walks by cells
instead (:mod:`tracer.cells`): at a crossing, every primitive registered in
the crossing's part of a cell is tested, and the ray steps on from where it
leaves that part; a ray that starts on a surface first tests its start's.

Rays leave surfaces by identity (``from_kind``, ``from_index``): they start
at the exact float64 hit point and never hit that surface there (see
:mod:`tracer.shapes`).  A ray that starts on a BVH primitive first tests that
primitive's neighbours, which are all the proxies around its start, and walks
from the edge of its proxy's box; any other ray starts its walk where its
line enters the BVH's box, behind its origin if need be, so no proxy contains
the start of a walk.  With no triangles and no small spheres, or no more
than :data:`DIRECT_MAX` of them, there is no Embree scene at all.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .cells import Cells, build_cells
from .embree import Bvh, frame
from .proxies import Proxies, build_proxies
from .shapes import plane_separates, plane_t, sphere_t, triangle_t
from .sightlines import Sightlines, plain_triangles
from .vec import along, divided, dot, highest, lowest, most, rows_of
from .world import World, max_abs, median_of, unit

#: kinds of surface in :attr:`Hits.kind`
MISS, SPHERE, PLANE, TRIANGLE = 0, 1, 2, 3
#: a sphere or triangle this many times larger than the median one is tested directly, not through the BVH
BIG = 64.0
#: a scene with at most this many spheres and triangles tests them all directly, with no BVH: measured on
#: the Whitted example (two spheres) a third faster; from three on the BVH's broad phase wins on shadow rays
DIRECT_MAX = 2
#: (ray, primitive) pairs tested exactly at a time
PAIR_SLICE = 1 << 16
#: a hit this far inside a triangle, in each barycentric coordinate, is far from its edges beyond any rounding
INSIDE = 2.0**-24



@dataclass
class Hits:
    """The first surface hit by each ray of a batch of N rays."""

    t: np.ndarray  # (N,) ray parameter, inf for a miss
    kind: np.ndarray  # (N,) MISS, SPHERE, PLANE or TRIANGLE
    index: np.ndarray  # (N,) index within its kind, -1 for a miss
    point: np.ndarray  # (N, 3) local hit point, on the surface
    normal: np.ndarray  # (N, 3) unit geometric normal (outward for spheres)
    bary: np.ndarray  # (N, 2) barycentric u, v for triangles
    material: np.ndarray  # (N,) material id before the checker

    def take(self, rows: np.ndarray) -> Hits:
        """The hits of the rays ``rows`` only, as contiguous arrays."""
        return Hits(self.t[rows], self.kind[rows], self.index[rows], rows_of(self.point, rows),
                    rows_of(self.normal, rows), rows_of(self.bary, rows), self.material[rows])


def shared_rows(a: np.ndarray | None, rows: np.ndarray, n: int = -1) -> np.ndarray | None:
    """``a[rows]``, except that a one-row ``a`` (one value shared by every ray) stays as it is, and so does
    an ``a`` of ``n`` rows when ``rows`` is all ``n`` of them."""
    if a is None or len(a) == 1 or len(rows) == n:
        return a
    return rows_of(a, rows)


def _nothing() -> None:
    return None


def _gathered(*columns: np.ndarray) -> np.ndarray:
    """``(N, k)`` and ``(N,)`` arrays side by side in one ``(N, Σk)`` array, so that the walk gathers a ray's
    (or a primitive's) values with one row copy instead of one per array: pairs reach all over the tables, and
    a gather's cost is its cache misses (measured on 150k random rows of 208k: 4 ms against 20 ms for four
    ``(N, 3)`` arrays)."""
    return np.concatenate([c if c.ndim == 2 else c[:, None] for c in columns], axis=1)


def _columns_of(rows: np.ndarray) -> np.ndarray:
    """Gathered rows ``(n, k)`` as ``(k, n)`` columns, each contiguous: ``out[0:3].T`` is then an ``(n, 3)``
    view whose x, y and z (all :mod:`tracer.vec` reads) are contiguous, faster to compute on than the rows'
    own strided columns (measured: a triangle test 4.7 ms against 11.4 ms on 100k pairs, 2.7 ms to copy)."""
    return np.ascontiguousarray(rows.T)


def slab(origins: np.ndarray, dirs: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each ray's line enters and leaves the box ``lo..hi`` (empty when enter > leave). Each (N,).

    An axis at a time, on 1-D columns.  Along an axis the ray does not move on (a zero direction), the
    slab is all of the line when the origin lies in it (closed) and none of it otherwise."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    near = far = None
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for a in range(3):
            o, d = origins[:, a], dirs[:, a]
            la, ha = (lo[..., a], hi[..., a])
            inv = 1.0 / d
            t0 = (la - o) * inv
            t1 = (ha - o) * inv
            lo_t, hi_t = np.minimum(t0, t1), np.maximum(t0, t1)
            flat = d == 0
            if flat.any():
                inside = (o >= la) & (o <= ha)
                lo_t = np.where(flat, np.where(inside, -np.inf, np.inf), lo_t)
                hi_t = np.where(flat, np.where(inside, np.inf, -np.inf), hi_t)
            near = lo_t if near is None else np.maximum(near, lo_t)
            far = hi_t if far is None else np.minimum(far, hi_t)
    assert near is not None and far is not None
    return near, far


class _Best:
    """Running best hit per ray, updated so that the answer never depends on the order candidates come in."""

    def __init__(self, limit: np.ndarray):
        n = len(limit)
        self.t = limit.astype(np.float64, copy=True)
        self.key = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
        self.uv = np.zeros((n, 2))

    def offer(self, rows: np.ndarray, t: np.ndarray, kind: int | np.ndarray, index: np.ndarray,
              u: np.ndarray | None = None, v: np.ndarray | None = None, unique: bool = False) -> None:
        """Offer hits ``t`` of surfaces (kind, index) to rays ``rows``; rows may repeat unless ``unique``."""
        hit = np.isfinite(t)
        if not np.any(hit):
            return
        rows, t, index = rows[hit], t[hit], index[hit]
        kind = np.broadcast_to(kind, hit.shape)[hit]
        key = (kind.astype(np.int64) << 48) | index.astype(np.int64)
        if unique or len(rows) <= 1 or bool(np.all(rows[1:] > rows[:-1])):  # one hit per ray (as usual)
            pick = np.arange(len(rows))
        else:
            order = np.lexsort((key, t, rows))
            first = np.r_[True, rows[order][1:] != rows[order][:-1]]
            pick = order[first]
        r, tt, kk = rows[pick], t[pick], key[pick]
        better = (tt < self.t[r]) | ((tt == self.t[r]) & (kk < self.key[r]))
        r, pick = r[better], pick[better]
        self.t[r], self.key[r] = tt[better], kk[better]
        if u is not None and v is not None:
            self.uv[r, 0], self.uv[r, 1] = u[hit][pick], v[hit][pick]

    def block(self, rows: np.ndarray, t: np.ndarray) -> None:
        """For an any-hit walk, where only whether a ray's ``t`` falls below its limit matters: lower the
        rays ``rows`` (which may repeat) to hits ``t`` nearer than they have."""
        nearer = t < self.t[rows]
        self.t[rows[nearer]] = t[nearer]  # (of a repeated row, any of its nearer hits: each blocks it)

    @property
    def kind(self) -> np.ndarray:
        return np.where(self.key == np.iinfo(np.int64).max, MISS, self.key >> 48).astype(np.int8)

    @property
    def index(self) -> np.ndarray:
        return np.where(self.key == np.iinfo(np.int64).max, -1, self.key & ((1 << 48) - 1))


class Intersector:
    """Closest hits and occlusion for a world.  ``lines``, when given, promises that every ray cast will lie
    on them (:mod:`tracer.sightlines`), which lets triangles go to Embree without proxies."""

    def __init__(self, world: World, lines: Sightlines | None = None):
        self.world = world
        self.lines = lines
        #: called between walk passes and every few direct surfaces; raises to stop a render
        self.check: Callable[[], None] = _nothing
        tris, spheres = world.triangles, world.spheres
        tri_extent = most(most(np.abs(np.stack([tris.e1, tris.e2, tris.e1 - tris.e2], axis=1)))) \
            if len(tris.v0) else np.zeros(0)
        extents = np.concatenate([2.0 * spheres.radius, tri_extent])
        median = median_of(extents) if len(extents) else 0.0
        with np.errstate(over="ignore", invalid="ignore"):
            big_sphere = ~(2.0 * spheres.radius <= BIG * median) | ~np.isfinite(spheres.mag)
            big_tri = ~(tri_extent <= BIG * median)
        if len(extents) <= DIRECT_MAX:  # a handful of surfaces: testing each against every ray beats any BVH
            big_sphere[:], big_tri[:] = True, True
        self.direct_spheres = np.flatnonzero(big_sphere)
        self.direct_triangles = np.flatnonzero(big_tri)
        self.bvh: Bvh | None = None
        self.proxies: Proxies | None = None
        self.cells: Cells | None = None
        self._build(np.flatnonzero(~big_tri), np.flatnonzero(~big_sphere))

    def _build(self, bvh_tris: np.ndarray, bvh_spheres: np.ndarray) -> None:
        w = self.world
        tris, spheres = w.triangles, w.spheres
        self.n_tri = len(bvh_tris)
        self.prim_index = np.concatenate([bvh_tris, bvh_spheres]).astype(np.int64)
        self.tri_prim = np.full(len(tris.v0), -1, dtype=np.int64)
        self.tri_prim[bvh_tris] = np.arange(len(bvh_tris))
        self.sphere_prim = np.full(len(spheres.radius), -1, dtype=np.int64)
        self.sphere_prim[bvh_spheres] = np.arange(len(bvh_spheres)) + len(bvh_tris)
        if len(self.prim_index) == 0:
            return
        #: each triangle's v0, e1, e2, normal and magnitude in one row (T, 13); each sphere's centre, radius and
        #: magnitude (S, 5): what an exact test reads of it
        self.tri_rows = _gathered(tris.v0, tris.e1, tris.e2, tris.normal, tris.mag)
        self.sphere_rows = _gathered(spheres.center, spheres.radius, spheres.mag)
        every = len(bvh_tris) == len(tris.v0)  # as usual: then no copies

        def mine(a: np.ndarray) -> np.ndarray:
            return a if every else rows_of(a, bvh_tris)

        v0, e1, e2, normal, ids = mine(tris.v0), mine(tris.e1), mine(tris.e2), mine(tris.normal), mine(tris.corner_ids)
        center, radius = rows_of(spheres.center, bvh_spheres), spheres.radius[bvh_spheres]
        parts = [v0, v0 + e1, v0 + e2, center - radius[:, None], center + radius[:, None]]
        centre, half = frame(np.min([lowest(a) for a in parts if len(a)], axis=0),
                             np.max([highest(a) for a in parts if len(a)], axis=0))
        plain, mates = (None, None) if self.lines is None else \
            plain_triangles(v0, e1, e2, normal, ids, self.lines, half)
        some_plain = plain is not None and bool(plain.any())
        #: a plain triangle's faces across its edges, which a shadow ray leaving it never meets (n_tri, 3)
        self.mates = mates if some_plain else None
        self.proxies = p = build_proxies(v0, e1, e2, normal, center, radius, half, plain, ids)
        self.bvh = Bvh(p.vertices, p.faces, centre, half, commit=False)
        with ThreadPoolExecutor(max_workers=1) as pool:  # Embree builds its tree while the walk's cells are made
            committed = pool.submit(self.bvh.commit)
            self.cells = build_cells(p.lo, p.hi, p.reach)
            committed.result()
        self.box_lo = lowest(p.lo) - p.step * 4 - p.slack
        self.box_hi = highest(p.hi) + p.step * 4 + p.slack
        # each pass of a walk consumes at least one proxy-face crossing (a ray crosses a face once)
        self.max_steps = len(p.faces) + 2

    # -- closest hit -------------------------------------------------------
    def closest(self, origins: np.ndarray, dirs: np.ndarray, from_kind: np.ndarray | None = None,
                from_index: np.ndarray | None = None) -> Hits:
        """First hit at t > 0 of rays ``origins (N, 3)`` + t·``dirs (N, 3)`` (unit) that leave the surfaces
        ``(from_kind, from_index)`` (MISS for none)."""
        n = len(origins)
        fk, fi = self._from(n, from_kind, from_index)
        best = _Best(np.full(n, np.inf))
        mag_o = max_abs(origins) + self.world.origin_mag
        rows = np.arange(n)
        for kind, k, t, u, v in self._direct(origins, dirs, fk, fi, mag_o):
            best.offer(rows, t, kind, np.full(n, k), u, v, unique=True)
        if self.bvh is not None:
            self._walk(best, origins, dirs, fk, fi, mag_o)
        return self._describe(origins, dirs, best)

    # -- occlusion ---------------------------------------------------------
    def occluded(self, origins: np.ndarray, dirs: np.ndarray, reach: np.ndarray,
                 from_kind: np.ndarray | None = None, from_index: np.ndarray | None = None,
                 ends: np.ndarray | None = None, mag_o: np.ndarray | None = None) -> np.ndarray:
        """True where a surface lies on the ray at a distance in (0, reach). Shape (N,), bool.

        ``ends``, when given, is the light each ray goes to (at distance
        ``reach``): ``(N, 3)``, or ``(1, 3)`` for one light shared by every ray.
        A surface through it does not block it.  ``mag_o`` may bring
        :func:`max_abs` of the origins (plus the world's origin) when the
        caller has it already.
        """
        n = len(origins)
        fk, fi = self._from(n, from_kind, from_index)
        reach = np.asarray(reach, dtype=np.float64)
        if mag_o is None:
            mag_o = max_abs(origins) + self.world.origin_mag
        mag_e = None if ends is None else max_abs(ends) + self.world.origin_mag
        blocked = np.zeros(n, dtype=bool)
        if ends is not None and mag_e is not None:  # a plane blocks a segment exactly when it separates its ends
            pl = self.world.planes
            for k in range(len(pl.normal)):
                blocked |= plane_separates(origins, ends, pl.point[k], pl.normal[k], mag_o, mag_e, pl.mag[k],
                                           (fk == PLANE) & (fi == k))
        for _, _, t, _, _ in self._direct(origins, dirs, fk, fi, mag_o, ends, reach, mag_e, planes=ends is None):
            blocked |= t < reach
        if self.bvh is not None:
            open_ = np.flatnonzero(~blocked)

            def pick(a: np.ndarray | None) -> np.ndarray | None:  # no copies when every ray is still open
                return shared_rows(a, open_, n)

            best = _Best(pick(reach))
            self._walk(best, pick(origins), pick(dirs), pick(fk), pick(fi), pick(mag_o), pick(ends), pick(reach),
                       pick(mag_e), any_hit=True)
            blocked[open_] = best.t < pick(reach)
        return blocked

    # -- the parts -----------------------------------------------------------
    @staticmethod
    def _from(n: int, kind: np.ndarray | None, index: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        if kind is None or index is None:
            return np.zeros(n, dtype=np.int8), np.full(n, -1, dtype=np.int64)
        return kind, index

    def _direct(self, o: np.ndarray, d: np.ndarray, fk: np.ndarray, fi: np.ndarray, mag_o: np.ndarray,
                ends: np.ndarray | None = None, reach: np.ndarray | None = None, mag_e: np.ndarray | None = None,
                planes: bool = True) -> Iterator[tuple[int, int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        """Planes (unless not ``planes``) and the surfaces too large for the BVH, against every ray:
        ``(kind, index, t, u, v)`` each."""
        w = self.world
        for k in range(len(w.planes.normal) if planes else 0):
            yield PLANE, k, plane_t(o, d, w.planes.point[k], w.planes.normal[k], mag_o, w.planes.mag[k],
                                    (fk == PLANE) & (fi == k), ends, mag_e), None, None
        sp = w.spheres
        for m, k in enumerate(self.direct_spheres):
            if m % 64 == 63:
                self.check()
            yield SPHERE, k, sphere_t(o, d, sp.center[k], sp.radius[k], mag_o, sp.mag[k], (fk == SPHERE) & (fi == k),
                                      ends, reach, mag_e), None, None
        tr = w.triangles
        for k in self.direct_triangles:
            t, u, v = triangle_t(o, d, tr.v0[k], tr.e1[k], tr.e2[k], tr.normal[k], mag_o, tr.mag[k],
                                 (fk == TRIANGLE) & (fi == k), ends, mag_e)
            yield TRIANGLE, k, t, u, v

    def _test(self, best: _Best, rows: np.ndarray, prims: np.ndarray, rays: np.ndarray, from_prim: np.ndarray,
              ends: np.ndarray | None, reach: np.ndarray | None, mag_e: np.ndarray | None) -> None:
        """Test BVH primitives ``prims`` exactly against rays ``rows`` (pairs; either may repeat) of ``rays``,
        the walk's origin, direction and magnitude of each ray in one row (:meth:`_walk`)."""
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
                self._test_kind(best, is_tri, r[at:at + PAIR_SLICE], q[at:at + PAIR_SLICE], rays, from_prim,
                                ends, reach, mag_e)

    def _test_kind(self, best: _Best, is_tri: bool, r: np.ndarray, q: np.ndarray, rays: np.ndarray,
                   from_prim: np.ndarray, ends: np.ndarray | None, reach: np.ndarray | None,
                   mag_e: np.ndarray | None) -> None:
        """Rays ``r`` against primitives ``q`` of :meth:`_test`, all of one kind (triangles when ``is_tri``)."""
        k = np.take(self.prim_index, q)
        leaving = np.take(from_prim, r) == q
        e, me = shared_rows(ends, r), shared_rows(mag_e, r)
        any_hit = reach is not None  # a shadow walk: only whether something lies before the light matters
        u = v = None
        ray = _columns_of(rows_of(rays, r))  # one gather per pair for the ray, one for the primitive (_gathered)
        o, d, mag_o = ray[0:3].T, ray[3:6].T, ray[6]
        if is_tri:
            g = _columns_of(rows_of(self.tri_rows, k))
            t, u, v = triangle_t(o, d, g[0:3].T, g[3:6].T, g[6:9].T, g[9:12].T, mag_o, g[12], leaving, e, me,
                                 uv=not any_hit)
        else:
            g = _columns_of(rows_of(self.sphere_rows, k))
            t = sphere_t(o, d, g[0:3].T, g[3], mag_o, g[4], leaving, e, None if reach is None else reach[r], me)
        if any_hit:
            best.block(r, t)
        else:
            best.offer(r, t, TRIANGLE if is_tri else SPHERE, k, u, v)

    def _with_mates(self, prims: np.ndarray, where: np.ndarray) -> np.ndarray:
        """``prims (n,)`` (−1 for none) and, where ``where``, a plain triangle's mates (its faces across its
        edges, :func:`tracer.sightlines.plain_triangles`): ``(n, 4)`` primitive ids, −1 for none, or ``(n, 1)``
        in a scene without mates."""
        if self.mates is None:
            return prims[:, None]
        out = np.full((len(prims), 4), -1, dtype=np.int64)
        out[:, 0] = prims
        tri = np.flatnonzero(where & (prims >= 0) & (prims < self.n_tri))
        out[tri, 1:] = rows_of(self.mates, prims[tri])
        return out

    def _tested(self, best: _Best, rows: np.ndarray, prims: np.ndarray, any_hit: bool) -> np.ndarray:
        """What the rays ``rows``, having just tested the primitives ``prims`` they crossed, need not test again
        at that crossing (as :meth:`_with_mates` gives it).

        The primitive itself; and, for a camera ray that hits a plain triangle well inside it, its mates: the
        plane through a shared edge and the eye (or along the view) has the ray's line on the triangle's side,
        so the ray meets no mate anywhere.
        """
        inside = np.zeros(len(rows), dtype=bool)
        if not any_hit and self.mates is not None:
            tri = np.flatnonzero(prims < self.n_tri)
            k = self.prim_index[prims[tri]]
            u, v = best.uv[rows[tri], 0], best.uv[rows[tri], 1]
            inside[tri] = ((best.key[rows[tri]] == (TRIANGLE << 48) | k) & (u > INSIDE) & (v > INSIDE)
                           & (1.0 - u - v > INSIDE))
        return self._with_mates(prims, inside)

    def _walk(self, best: _Best, o: np.ndarray, d: np.ndarray, fk: np.ndarray, fi: np.ndarray, mag_o: np.ndarray,
              ends: np.ndarray | None = None, reach: np.ndarray | None = None, mag_e: np.ndarray | None = None,
              any_hit: bool = False) -> None:
        """Test, exactly, every BVH primitive that a ray could hit before its best hit (or, ``any_hit``, until one
        blocks it).

        **Guarantee.**  At every point of a walk, with ``s`` its position along the ray: every primitive whose
        proxy the ray (as Embree sees it, in float32) is inside anywhere in ``[s₀, s]`` has been tested, where
        ``s₀`` is where the walk began.  A primitive the float64 ray hits at ``t`` has the ray inside its proxy
        around ``t`` (a proxy holds its primitive grown by a margin far above float32 rounding), so every
        primitive hit at ``t ≤ s`` has been tested.

        **Start.**  A ray that leaves a BVH primitive first tests every member of the part of a cell that holds
        its origin (a proxy that contains the origin has a box that meets that part) and starts at the part's
        exit, with ``s₀ = 0``.  Any other ray starts where its line enters the BVH's box, behind its origin if
        need be (hits at t ≤ 0 never count): no proxy lies there.

        **Step.**  From ``s``, Embree names the nearest proxy-face crossing: no proxy is entered or left before
        it, so between ``s`` and the crossing the ray is inside only proxies it was inside at ``s`` (tested).  At
        the crossing, every member of the crossing's part of a cell is tested: every proxy that meets the part
        is one of them, and so (by the cells' reach, which is larger than the float32 rounding of the crossing
        and of the ray and the walk's step) is every proxy crossed within that rounding of the part.  The walk
        goes on from where the ray leaves the part (or a step past the crossing, when later).

        **Stop.**  A closest-hit walk stops once its best hit lies at or before the exit of the part it just
        tested (every primitive hit before that exit was tested: before the part's entry by the guarantee,
        within the part as a member), or once no crossing is left before its best hit (plus the slack of a plain
        triangle's float32 crossing) or the BVH box's exit.  An any-hit walk stops at the first blocker, or when
        no crossing is left before the light.  Each pass consumes a crossing, so the walk ends; should it not
        within :attr:`max_steps` passes, the rays still walking test every primitive (never silently wrong).
        """
        p, bvh, cells = self.proxies, self.bvh, self.cells
        assert p is not None and bvh is not None and cells is not None
        n = len(o)
        from_prim = np.full(n, -1, dtype=np.int64)
        tri = fk == TRIANGLE
        from_prim[tri] = self.tri_prim[fi[tri]]
        sph = fk == SPHERE
        from_prim[sph] = self.sphere_prim[fi[sph]]
        limit = best.t.copy()
        rays = _gathered(o, d, mag_o)
        t_in, t_out = slab(o, d, self.box_lo, self.box_hi)
        start = t_in.copy()
        # the region each ray tested last (a part of a cell; rounding may report a part twice)
        last = np.full(n, -2, dtype=np.int64)
        inside = np.flatnonzero(from_prim >= 0)
        if len(inside):  # every proxy that contains an origin meets the origin's part of a cell: test them now
            cell, lo, hi = cells.locate(rows_of(o, inside))
            q = from_prim[inside]  # a triangle is never met again by a ray that leaves it; a sphere may be
            # nor, on its way to a light, are a plain triangle's mates
            but = self._with_mates(np.where(q < self.n_tri, q, -1), np.full(len(q), any_hit))
            self._test(best, *cells.pairs(inside, cell, but), rays, from_prim, ends, reach, mag_e)
            start[inside] = slab(rows_of(o, inside), rows_of(d, inside), lo, hi)[1]
            last[inside] = cell
            if not any_hit:  # a hit inside the origin's part is the nearest there is
                settled = np.isfinite(best.t[inside]) & (best.t[inside] <= start[inside])
                start[inside[settled]] = np.inf

        def open_rows(rows: np.ndarray) -> np.ndarray:
            if any_hit:
                rows = rows[~(best.t[rows] < limit[rows])]
            end = np.minimum(best.t[rows], t_out[rows])
            return rows[(start[rows] < end) & (end > 0)]

        live = open_rows(np.arange(n))
        if any_hit and len(live):  # broad phase: a ray that crosses no proxy before its light is clear
            s = start[live]
            far = np.minimum(limit[live] + p.slack, t_out[live]) - s
            o_l, d_l = rows_of(o, live), rows_of(d, live)
            live = live[bvh.any_hit(along(o_l, s, d_l), d_l, far)]
        first = any_hit or self.mates is not None  # test the crossed primitive before the rest of its region
        for step in range(self.max_steps):
            if len(live) == 0:
                break
            self.check()
            s = start[live]
            # a plain triangle hit before best.t may be crossed in float32 up to p.slack after it
            far = np.minimum(best.t[live] + p.slack, t_out[live]) - s
            o_l, d_l = rows_of(o, live), rows_of(d, live)
            face, tau = bvh.nearest(along(o_l, s, d_l), d_l, far)
            found = np.flatnonzero(face >= 0)
            live, face, tau, s = live[found], face[found], tau[found], s[found]
            o_l, d_l = rows_of(o_l, found), rows_of(d_l, found)
            prim = p.owner[face]
            # after the first pass, the few rays left (grazing a surface, say) step a whole cell at a time
            region, lo, hi = cells.locate(along(o_l, s + tau, d_l), whole=step > 0)
            fresh = last[live] != region
            if first:  # the primitive crossed first: a ray it blocks needs no more
                rows = live[fresh]
                self._test(best, rows, prim[fresh], rays, from_prim, ends, reach, mag_e)
                if any_hit:
                    fresh[fresh] = ~(best.t[rows] < limit[rows])
            pairs = cells.pairs(live[fresh], region[fresh], self._tested(best, live[fresh], prim[fresh], any_hit)
                                if first else None)
            self._test(best, *pairs, rays, from_prim, ends, reach, mag_e)
            last[live] = region
            leave = slab(o_l, d_l, lo, hi)[1]
            start[live] = np.fmax(start[live] + tau + p.step, leave)
            if not any_hit:  # a hit before the ray leaves the part is the nearest there is
                settled = np.isfinite(best.t[live]) & (best.t[live] <= leave)
                live = live[~settled]
            live = open_rows(live)
        if len(live):  # (not seen: each pass consumes a crossing) every primitive, rather than a wrong answer
            every = np.arange(len(self.prim_index))
            self._test(best, np.repeat(live, len(every)), np.tile(every, len(live)), rays, from_prim, ends, reach,
                       mag_e)

    def _describe(self, origins: np.ndarray, dirs: np.ndarray, best: _Best) -> Hits:
        w = self.world
        t, kind, index = best.t, best.kind, best.index
        n = len(t)
        point = np.zeros((n, 3))
        normal = np.zeros((n, 3))
        material = np.zeros(n, dtype=np.int64)

        s = np.flatnonzero(kind == SPHERE)
        if len(s):
            k = index[s]
            raw = along(rows_of(origins, s), t[s], rows_of(dirs, s))
            centre = rows_of(w.spheres.center, k)
            nrm = unit(divided(raw - centre, w.spheres.radius[k]))
            point[s] = along(centre, w.spheres.radius[k], nrm)
            normal[s], material[s] = nrm, w.spheres.material[k]

        q = np.flatnonzero(kind == PLANE)
        if len(q):
            k = index[q]
            raw = along(rows_of(origins, q), t[q], rows_of(dirs, q))
            nrm, p0 = rows_of(w.planes.normal, k), rows_of(w.planes.point, k)
            point[q] = along(raw, -dot(raw - p0, nrm), nrm)
            normal[q], material[q] = nrm, w.planes.material[k]

        r = np.flatnonzero(kind == TRIANGLE)
        if len(r):
            k = index[r]
            tr = w.triangles
            point[r] = along(along(rows_of(tr.v0, k), best.uv[r, 0], rows_of(tr.e1, k)), best.uv[r, 1], rows_of(tr.e2, k))
            normal[r], material[r] = rows_of(tr.normal, k), tr.material[k]
        return Hits(t=np.where(kind == MISS, np.inf, t), kind=kind, index=index, point=point, normal=normal,
                    bary=best.uv, material=material)
