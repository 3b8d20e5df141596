"""Closest-hit and occlusion queries over every kind of surface a scene contains, decided in float64.

Planes, and spheres or triangles far larger than the rest (a planet under
tiny objects, a ground triangle reaching 10⁵ away), are tested exactly
against every ray: a scene has few.  The other triangles and spheres go to
the walk (:mod:`tracer.exact.walk`), behind one Embree BVH of closed float32
proxies.  With no triangles and no small spheres, or no more than
:data:`DIRECT_MAX` of them, there is no walk and no Embree scene at all.

Rays leave surfaces by identity (:class:`tracer.scene.rays.Rays`): they start at
the exact float64 hit point and never hit that surface there (see
:mod:`tracer.scene.shapes`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from ..proofs.sightlines import Sightlines
from ..scene.rays import Among, Hits, Rays, Shadows
from ..scene.shapes import MISS, PLANE, SPHERE, TRIANGLE, Segments, plane_separates, plane_t, sphere_t, triangle_t
from ..scene.surfaces import unit
from ..scene.vec import along, divided, dot, median_of, minus, most, rows_of
from ..scene.world import World
from .best import NO_HIT, Best
from .embree import Bvh
from .pairs import _ignored
from .ties import INDEX_MASK, KIND_SHIFT, Ties
from .walk import Walk

__all__ = ["BIG", "DIRECT_MAX", "Hits", "Intersector", "MISS", "PLANE", "SPHERE", "TRIANGLE"]

#: a sphere or triangle this many times larger than the median one is tested directly, not through the BVH
BIG = 64.0
#: a triangle paired with at least this many rays (:meth:`Intersector._among`) is tested against them as one
#: triangle against many rays; with fewer, pair by pair with the walk's other pairs (fewer, larger passes)
MANY = 4096
#: a scene with at most this many spheres and triangles tests them all directly, with no BVH: measured on
#: the Whitted example (two spheres) a third faster; three spheres at 160×120 (a small render, where building
#: the BVH is a large share) 9.7 against 11.3 ms of one core, equal at 320×240 and at 1080p; with more, the
#: BVH's broad phase (:meth:`tracer.exact.walk.Walk.walk_few`) spares more tests than building it costs
DIRECT_MAX = 3


def _nothing() -> None:
    return None


def _put(dst: np.ndarray, rows: np.ndarray, src: np.ndarray) -> None:
    """``dst[rows] = src`` for ``dst (N, 3)`` with contiguous columns and ``src`` ``(n, 3)`` or one ``(3,)``
    row, a column at a time (1-D scatters)."""
    for k in range(3):
        dst[:, k][rows] = src[..., k]


class Intersector:
    """Closest hits and occlusion for a world.  ``lines``, when given, promises that every ray cast will lie
    on them (:mod:`tracer.proofs.sightlines`), which lets triangles go to Embree without proxies."""

    def __init__(self, world: World, lines: Sightlines | None = None):
        self.world = world
        tris, spheres = world.triangles, world.spheres
        tri_extent = (
            most(most(np.abs(np.stack([tris.e1, tris.e2, tris.e1 - tris.e2], axis=1)))) if len(tris.v0) else np.zeros(0)
        )
        extents = np.concatenate([2.0 * spheres.radius, tri_extent])
        median = median_of(extents) if len(extents) else 0.0
        with np.errstate(over="ignore", invalid="ignore"):
            big_sphere = ~(2.0 * spheres.radius <= BIG * median) | ~np.isfinite(spheres.mag)
            big_tri = ~(tri_extent <= BIG * median)
        if len(extents) <= DIRECT_MAX:  # a handful of surfaces: testing each against every ray beats any BVH
            big_sphere[:], big_tri[:] = True, True
        self.direct_spheres = np.flatnonzero(big_sphere)
        self.direct_triangles = np.flatnonzero(big_tri)
        walked_tris, walked_spheres = np.flatnonzero(~big_tri), np.flatnonzero(~big_sphere)
        #: the order ties go by, and which are open (:mod:`tracer.exact.ties`)
        self.ties = Ties(
            world.materials,
            {SPHERE: spheres.material, PLANE: world.planes.material, TRIANGLE: tris.material},
            {SPHERE: spheres.object, PLANE: world.planes.object, TRIANGLE: tris.object},
            world.coplanar,
        )
        self.walker = (
            Walk(world, walked_tris, walked_spheres, lines, self.ties)
            if len(walked_tris) + len(walked_spheres)
            else None
        )
        self._check: Callable[[], None] = _nothing
        self._tested: Callable[[int], None] = _ignored

    @property
    def check(self) -> Callable[[], None]:
        """Called between walk passes and every few direct surfaces; raises to stop a render."""
        return self._check

    @check.setter
    def check(self, value: Callable[[], None]) -> None:
        self._check = value
        if self.walker is not None:
            self.walker.check = value

    @property
    def tested(self) -> Callable[[int], None]:
        """Told how many exact tests of a ray against a sphere or a triangle each batch makes (the walk's and
        the direct ones; planes are priced per ray)."""
        return self._tested

    @tested.setter
    def tested(self, value: Callable[[int], None]) -> None:
        self._tested = value
        if self.walker is not None:
            self.walker.tested = value

    @property
    def bvh(self) -> Bvh | None:
        return None if self.walker is None else self.walker.bvh

    def rays(
        self,
        origins: np.ndarray,
        dirs: np.ndarray,
        from_kind: np.ndarray | None = None,
        from_index: np.ndarray | None = None,
    ) -> Rays:
        """A batch of rays in this world (local ``origins``), leaving the surfaces given or none."""
        return Rays.leaving(origins, dirs, self.world.origin_mag, from_kind, from_index)

    # -- closest hit -------------------------------------------------------
    def closest(self, rays: Rays, among: Among | None = None) -> Hits:
        """First hit at t > 0 of each ray.  With ``among`` (see :meth:`_among`), only the spheres and triangles
        it pairs with a ray are tested against it, and nothing is walked."""
        return self.describe(rays, self.nearest(rays, among))

    def nearest(self, rays: Rays, among: Among | None = None) -> Best:
        """:meth:`closest` as the surface and parameter of each ray's first hit, before the hits are described
        (:meth:`describe`)."""
        n = len(rays)
        best = Best(np.full(n, np.inf), self.ties)
        for kind, k, t, u, v in self._direct(rays, among=among):
            best.offer_all(t, kind, k, u, v)
        if among is not None:
            self._among(best, rays, among)
        elif self.walker is not None:
            self.walker.walk(best, rays)
        return best

    # -- occlusion ---------------------------------------------------------
    def occluded(self, shadows: Shadows, among: Among | None = None) -> np.ndarray:
        """True where a surface lies on the ray at a distance in (0, reach), other than one through the light
        itself. Shape (N,), bool.  With ``among`` (see :meth:`_among`), only the spheres and triangles it pairs
        with a ray are tested against it, and nothing is walked."""
        rays, reach, ends, mag_e = shadows.rays, shadows.reach, shadows.ends, shadows.mag_end
        n = len(rays)
        blocked = np.zeros(n, dtype=bool)
        if ends is not None and mag_e is not None:  # a plane blocks a segment exactly when it separates its ends
            pl = self.world.planes
            segments = Segments(rays.origins, ends, rays.mag, mag_e)
            for k in range(len(pl.normal)):
                leaving = self._leaving(rays, PLANE, k)
                blocked |= plane_separates(segments, pl.point[k], pl.normal[k], pl.mag[k], leaving)
        for _, _, t, _, _ in self._direct(rays, shadows, among):
            blocked |= t < reach
        if among is not None:
            keep = ~blocked[among.rows]
            limit = np.broadcast_to(reach, (n,))
            best = Best(limit)
            self._among(best, rays, Among(among.rows[keep], among.kind[keep], among.index[keep]), shadows)
            blocked |= best.t < limit
        elif self.walker is not None:
            open_ = np.flatnonzero(~blocked)
            rest = shadows.take(open_)
            best = Best(rest.reach)
            self.walker.walk(best, rest.rays, rest)
            blocked[open_] = best.t < rest.reach
        return blocked

    # -- the parts -----------------------------------------------------------
    def _among(self, best: Best, rays: Rays, among: Among, shadows: Shadows | None = None) -> None:
        """Test each pair of ``among`` exactly, with the test :meth:`_direct` or the walk would make of it.

        ``among`` is the caller's proof that a sphere or triangle it does not pair with a ray has no exact hit
        on that ray at t > 0 (:mod:`tracer.proofs.cones`; :mod:`tracer.proofs.culling` for an area light's shadow rays).
        The walk, and the direct tests, give the nearest of the exact hits of every surface (for a shadow ray:
        whether there is one before the light), and every surface with an exact hit is paired with its ray;
        each pair is tested with the same function on the same numbers.  So the answer is the same, with no
        Embree query and no walk.

        The pairs come surface by surface (:meth:`tracer.scene.rays.Among.of`).  A triangle with many rays is tested
        as :meth:`_direct` tests it, against its rays alone (the walk's test gathers a triangle's 13 numbers per
        pair); the walk's other surfaces are tested together, pair by pair, as the walk tests them
        (:meth:`tracer.exact.walk.Walk.test_pairs`), and the rest surface by surface."""
        if len(among.rows) == 0:
            return
        key = among.kind.astype(np.int64) << 48 | among.index
        starts = np.r_[0, np.flatnonzero(key[1:] != key[:-1]) + 1, len(key)]
        size = np.diff(starts)
        prim = (
            self.walker.prim_of(among.kind[starts[:-1]], among.index[starts[:-1]])
            if self.walker is not None
            else np.full(len(size), -1, dtype=np.int64)
        )
        together = ((size < MANY) | (among.kind[starts[:-1]] != TRIANGLE)) & (prim >= 0)
        if together.any():
            assert self.walker is not None
            sel = np.repeat(together, size)
            self.walker.test_pairs(best, rays, among.rows[sel], np.repeat(prim[together], size[together]), shadows)
        alone = np.flatnonzero(~together)
        if len(alone) > 1:  # rays gathered once per surface: from contiguous columns, into contiguous columns
            rays = Rays(
                np.asfortranarray(rays.origins), np.asfortranarray(rays.dirs), rays.from_kind, rays.from_index, rays.mag
            )
        for m, g in enumerate(alone.tolist()):
            if m % 64 == 63:
                self.check()
            a, b = int(starts[g]), int(starts[g + 1])
            kind, k, rows = int(among.kind[a]), int(among.index[a]), among.rows[a:b]
            sub = shadows.take(rows) if shadows is not None else None
            self._tested(len(rows))
            t, u, v = self._surface_t(kind, k, rays.take(rows), sub)
            if shadows is not None:
                best.block(rows, t)
            else:  # (rows of one surface are distinct)
                best.offer(rows, t, kind, np.full(len(rows), k), u, v, unique=True)

    def _direct(
        self, rays: Rays, shadows: Shadows | None = None, among: Among | None = None
    ) -> Iterator[tuple[int, int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        """The surfaces too large for the BVH, and the planes (but for shadows towards a light, which
        :func:`tracer.scene.shapes.plane_separates` decides), against every ray: ``(kind, index, t, u, v)`` each.
        With ``among``, only the planes (the spheres and triangles are its pairs)."""
        w = self.world
        ends = shadows.ends if shadows is not None else None
        for k in range(len(w.planes.normal) if ends is None else 0):
            yield PLANE, k, *self._surface_t(PLANE, k, rays, shadows)
        if among is not None:
            return
        self._tested(len(rays) * (len(self.direct_spheres) + len(self.direct_triangles)))
        for m, k in enumerate(self.direct_spheres.tolist()):
            if m % 64 == 63:
                self.check()
            yield SPHERE, k, *self._surface_t(SPHERE, k, rays, shadows)
        for m, k in enumerate(self.direct_triangles.tolist()):
            if m % 64 == 63:
                self.check()
            yield TRIANGLE, k, *self._surface_t(TRIANGLE, k, rays, shadows)

    def _surface_t(
        self, kind: int, k: int, rays: Rays, shadows: Shadows | None
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """The exact test of one surface against every ray of ``rays`` (the rays of ``shadows``, if given):
        ``t, u, v`` (u, v for triangles only)."""
        w = self.world
        o, d, mag_o = rays.origins, rays.dirs, rays.mag
        ends = reach = mag_e = None
        if shadows is not None:
            ends, reach, mag_e = shadows.ends, shadows.reach, shadows.mag_end
        leaving = self._leaving(rays, kind, k)
        if kind == SPHERE:
            sp = w.spheres
            return sphere_t(o, d, sp.center[k], sp.radius[k], mag_o, sp.mag[k], leaving, ends, reach, mag_e), None, None
        if kind == PLANE:
            pl = w.planes
            t, u, v = plane_t(o, d, pl.point[k], pl.normal[k], mag_o, pl.mag[k], leaving, ends, mag_e), None, None
        else:
            tr = w.triangles
            corners = tr.v0[k], tr.e1[k], tr.e2[k], tr.normal[k]
            t, u, v = triangle_t(o, d, *corners, mag_o, tr.mag[k], leaving, ends, mag_e)
        groups = w.coplanar
        if groups is not None and shadows is None:  # a member of a coplanar group: its t on the group's plane
            t = groups.retime(t, o, d, int((groups.plane if kind == PLANE else groups.triangle)[k]))
        return t, u, v

    def _leaving(self, rays: Rays, kind: int, k: int) -> np.ndarray:
        """Which ``rays`` leave surface ``kind``, ``k``: they start from it, or from a member of its coplanar group
        (:mod:`tracer.scene.coplanar`). Shape (N,), bool."""
        leaving = (rays.from_kind == kind) & (rays.from_index == k)
        groups = self.world.coplanar
        if groups is None or kind == SPHERE:
            return leaving
        group = int((groups.plane if kind == PLANE else groups.triangle)[k])
        if group < 0:
            return leaving
        return leaving | groups.leaving(groups.of(rays.from_kind, rays.from_index), group)

    def describe(self, rays: Rays, best: Best, rows: np.ndarray | None = None) -> Hits:
        """The hits of ``best`` (of the rays ``rows`` alone, when given: those that hit something, say):
        points on their surfaces, normals and materials; ``point`` and ``normal`` with contiguous columns (what
        every later stage reads a column at a time)."""
        w = self.world
        if rows is None:
            t, key, uv = best.t, best.key, best.uv
        else:
            t, key, uv = best.t[rows], best.key[rows], rows_of(best.uv, rows)
        kind = np.where(key == NO_HIT, MISS, (key >> KIND_SHIFT) & 3).astype(np.int8)
        index = np.where(key == NO_HIT, -1, key & INDEX_MASK)
        n = len(t)

        def rays_of(sel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """The origins (one row, when every ray shares it) and directions of the rays ``sel`` of these."""
            at = sel if rows is None else rows[sel]
            o = rays.origins[0] if rays.origins.strides[0] == 0 else rows_of(rays.origins, at)
            return o, rows_of(rays.dirs, at)

        point = np.zeros((3, n)).T
        normal = np.zeros((3, n)).T
        material = np.zeros(n, dtype=np.int64)

        s = np.flatnonzero(kind == SPHERE)
        if len(s):
            k = index[s]
            o, d = rays_of(s)
            raw = along(o, t[s], d)
            centre = rows_of(w.spheres.center, k)
            nrm = unit(divided(minus(raw, centre), w.spheres.radius[k]))
            _put(point, s, along(centre, w.spheres.radius[k], nrm))
            _put(normal, s, nrm)
            material[s] = w.spheres.material[k]

        q = np.flatnonzero(kind == PLANE)
        if len(q):
            k = index[q]
            o, d = rays_of(q)
            raw = along(o, t[q], d)
            if len(w.planes.normal) == 1:  # (one plane: its numbers shared, not gathered)
                nrm, p0 = w.planes.normal[0], w.planes.point[0]
            else:
                nrm, p0 = rows_of(w.planes.normal, k), rows_of(w.planes.point, k)
            _put(point, q, along(raw, -dot(minus(raw, p0), nrm), nrm))
            _put(normal, q, nrm)
            material[q] = w.planes.material[k]

        r = np.flatnonzero(kind == TRIANGLE)
        if len(r):
            k = index[r]
            tr = w.triangles
            _put(point, r, along(along(rows_of(tr.v0, k), uv[r, 0], rows_of(tr.e1, k)), uv[r, 1], rows_of(tr.e2, k)))
            _put(normal, r, rows_of(tr.normal, k))
            material[r] = tr.material[k]
        return Hits(
            t=np.where(kind == MISS, np.inf, t),
            kind=kind,
            index=index,
            point=point,
            normal=normal,
            bary=uv,
            material=material,
        )
