"""Closest-hit and occlusion queries over every kind of surface a scene contains, decided in float64.

Planes, and spheres or triangles far larger than the rest (a planet under
tiny objects, a ground triangle reaching 10⁵ away), are tested exactly
against every ray: a scene has few.  The other triangles and spheres go to
the walk (:mod:`tracer.walk`), behind one Embree BVH of closed float32
proxies.  With no triangles and no small spheres, or no more than
:data:`DIRECT_MAX` of them, there is no walk and no Embree scene at all.

Rays leave surfaces by identity (:class:`tracer.rays.Rays`): they start at
the exact float64 hit point and never hit that surface there (see
:mod:`tracer.shapes`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from .embree import Bvh
from .rays import Rays, Shadows
from .shapes import MISS, PLANE, SPHERE, TRIANGLE, plane_separates, plane_t, sphere_t, triangle_t
from .sightlines import Sightlines
from .vec import along, divided, dot, most, rows_of
from .walk import Best, Walk
from .world import World, median_of, unit

__all__ = ["BIG", "DIRECT_MAX", "Hits", "Intersector", "MISS", "PLANE", "SPHERE", "TRIANGLE"]

#: a sphere or triangle this many times larger than the median one is tested directly, not through the BVH
BIG = 64.0
#: a scene with at most this many spheres and triangles tests them all directly, with no BVH: measured on
#: the Whitted example (two spheres) a third faster; three spheres at 160×120 (a small render, where building
#: the BVH is a large share) 9.7 against 11.3 ms of one core, equal at 320×240 and at 1080p; with more, the
#: BVH's broad phase (:meth:`tracer.walk.Walk.walk_few`) spares more tests than building it costs
DIRECT_MAX = 3


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


def _nothing() -> None:
    return None


class Intersector:
    """Closest hits and occlusion for a world.  ``lines``, when given, promises that every ray cast will lie
    on them (:mod:`tracer.sightlines`), which lets triangles go to Embree without proxies."""

    def __init__(self, world: World, lines: Sightlines | None = None):
        self.world = world
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
        walked_tris, walked_spheres = np.flatnonzero(~big_tri), np.flatnonzero(~big_sphere)
        self.walker = Walk(world, walked_tris, walked_spheres, lines) \
            if len(walked_tris) + len(walked_spheres) else None
        self._check: Callable[[], None] = _nothing

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
    def bvh(self) -> Bvh | None:
        return None if self.walker is None else self.walker.bvh

    def rays(self, origins: np.ndarray, dirs: np.ndarray, from_kind: np.ndarray | None = None,
             from_index: np.ndarray | None = None) -> Rays:
        """A batch of rays in this world (local ``origins``), leaving the surfaces given or none."""
        return Rays.leaving(origins, dirs, self.world.origin_mag, from_kind, from_index)

    # -- closest hit -------------------------------------------------------
    def closest(self, rays: Rays) -> Hits:
        """First hit at t > 0 of each ray."""
        n = len(rays)
        best = Best(np.full(n, np.inf))
        every = np.arange(n)
        for kind, k, t, u, v in self._direct(rays):
            best.offer(every, t, kind, np.full(n, k), u, v, unique=True)
        if self.walker is not None:
            self.walker.walk(best, rays)
        return self._describe(rays.origins, rays.dirs, best)

    # -- occlusion ---------------------------------------------------------
    def occluded(self, shadows: Shadows, among: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """True where a surface lies on the ray at a distance in (0, reach), other than one through the light
        itself. Shape (N,), bool.

        ``among`` (pairs ``rays, primitives`` of the walk's primitive ids, :meth:`tracer.walk.Walk.prim_of`)
        is the caller's proof that of the walk's primitives only those paired with a ray can block it
        (:mod:`tracer.culling`'s ``may_block``).  The walk is then not walked: each pair is tested with the
        walk's own exact test.  The answer is the same: the walk finds a ray blocked exactly when one of its
        primitives has an exact hit before the light (its guarantee), and by the proof every such primitive
        is paired with the ray.  Planes and the surfaces tested directly are tested as for any ray."""
        rays, reach, ends, mag_e = shadows.rays, shadows.reach, shadows.ends, shadows.mag_end
        n = len(rays)
        blocked = np.zeros(n, dtype=bool)
        if ends is not None and mag_e is not None:  # a plane blocks a segment exactly when it separates its ends
            pl = self.world.planes
            fk, fi = rays.from_kind, rays.from_index
            for k in range(len(pl.normal)):
                blocked |= plane_separates(rays.origins, ends, pl.point[k], pl.normal[k], rays.mag, mag_e,
                                           pl.mag[k], (fk == PLANE) & (fi == k))
        for _, _, t, _, _ in self._direct(rays, shadows):
            blocked |= t < reach
        if self.walker is not None and among is not None:
            rows, prims = among
            keep = ~blocked[rows]
            limit = np.broadcast_to(reach, (n,))
            best = Best(limit)
            self.walker.test_pairs(best, rays, rows[keep], prims[keep], shadows)
            blocked |= best.t < limit
        elif self.walker is not None:
            open_ = np.flatnonzero(~blocked)
            rest = shadows.take(open_)
            best = Best(rest.reach)
            self.walker.walk(best, rest.rays, rest)
            blocked[open_] = best.t < rest.reach
        return blocked

    # -- the parts -----------------------------------------------------------
    def _direct(self, rays: Rays, shadows: Shadows | None = None
                ) -> Iterator[tuple[int, int, np.ndarray, np.ndarray | None, np.ndarray | None]]:
        """The surfaces too large for the BVH, and the planes (but for shadows towards a light, which
        :func:`tracer.shapes.plane_separates` decides), against every ray: ``(kind, index, t, u, v)`` each."""
        w = self.world
        o, d, fk, fi, mag_o = rays.origins, rays.dirs, rays.from_kind, rays.from_index, rays.mag
        ends = reach = mag_e = None
        if shadows is not None:
            ends, reach, mag_e = shadows.ends, shadows.reach, shadows.mag_end
        for k in range(len(w.planes.normal) if ends is None else 0):
            yield PLANE, k, plane_t(o, d, w.planes.point[k], w.planes.normal[k], mag_o, w.planes.mag[k],
                                    (fk == PLANE) & (fi == k), ends, mag_e), None, None
        sp = w.spheres
        for m, k in enumerate(self.direct_spheres.tolist()):
            if m % 64 == 63:
                self.check()
            yield SPHERE, k, sphere_t(o, d, sp.center[k], sp.radius[k], mag_o, sp.mag[k], (fk == SPHERE) & (fi == k),
                                      ends, reach, mag_e), None, None
        tr = w.triangles
        for k in self.direct_triangles.tolist():
            t, u, v = triangle_t(o, d, tr.v0[k], tr.e1[k], tr.e2[k], tr.normal[k], mag_o, tr.mag[k],
                                 (fk == TRIANGLE) & (fi == k), ends, mag_e)
            yield TRIANGLE, k, t, u, v

    def _describe(self, origins: np.ndarray, dirs: np.ndarray, best: Best) -> Hits:
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
            point[r] = along(along(rows_of(tr.v0, k), best.uv[r, 0], rows_of(tr.e1, k)), best.uv[r, 1],
                             rows_of(tr.e2, k))
            normal[r], material[r] = rows_of(tr.normal, k), tr.material[k]
        return Hits(t=np.where(kind == MISS, np.inf, t), kind=kind, index=index, point=point, normal=normal,
                    bary=best.uv, material=material)
