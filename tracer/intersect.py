"""Closest-hit and occlusion queries over every kind of surface a scene contains.

Planes, and spheres far larger than the rest (a planet under tiny objects),
are tested exactly in float64 against every ray: a scene has few.  Triangles
and the other spheres share one Embree BVH: triangles as themselves, spheres
as enclosing icosahedra (:func:`~tracer.shapes.sphere_proxies`).  Embree names
the nearest candidate along the ray; a triangle is then recomputed in float64,
a sphere tested exactly in float64, and the ray goes on past that candidate.
It stops when no candidate is nearer than the best hit plus the largest proxy
diameter: a ray that starts inside a proxy never crosses its entry face, but
crosses its exit face within that margin of any hit on its sphere.  So a
sphere costs about log n, not n, and is still exact.  With no triangles and no
small spheres there is no Embree scene at all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .embree import Bvh
from .shapes import FACES_PER_PROXY, plane_t, sphere_proxies, sphere_proxy_half, sphere_t, triangle_hit
from .world import World, max_abs, unit

#: kinds of surface in :attr:`Hits.kind`
MISS, SPHERE, PLANE, TRIANGLE = 0, 1, 2, 3
#: relative spawn offsets: float64 work, and float32 work inside Embree
REL64 = 2.0**-44
REL32 = 2.0**-18
#: at most this many candidates are examined along one ray
MAX_PASSES = 256
#: a sphere this many times larger than the median one is tested directly, not through the BVH
BIG_SPHERE = 64.0
#: geometry beyond this distance cannot go through float32 (spheres are then tested directly)
FLOAT32_SAFE = 1e30


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
    offset: np.ndarray  # (N,) how far a ray leaving the point must start from it

    def take(self, rows: np.ndarray) -> "Hits":
        """The hits of the rays ``rows`` only, as contiguous arrays."""
        return Hits(self.t[rows], self.kind[rows], self.index[rows], self.point[rows], self.normal[rows],
                    self.bary[rows], self.material[rows], self.offset[rows])


class Intersector:
    def __init__(self, world: World):
        self.world = world
        tris, spheres = world.triangles, world.spheres
        self.n_triangles = len(tris.v0)
        self.has_triangles = self.n_triangles > 0
        self.has_spheres = len(spheres.radius) > 0
        radius = spheres.radius
        big = (radius > BIG_SPHERE * np.median(radius)) | (spheres.scale > FLOAT32_SAFE) if self.has_spheres \
            else np.zeros(0, dtype=bool)
        self.direct_spheres = np.flatnonzero(big)
        self.proxied = np.flatnonzero(~big)
        self.margin = 2.01 * float(np.max(sphere_proxy_half(radius[self.proxied]), initial=0.0))
        self.bvh: Bvh | None = None
        if self.has_triangles or len(self.proxied):
            corners = np.concatenate([
                np.stack([tris.v0, tris.v0 + tris.e1, tris.v0 + tris.e2], axis=1),
                sphere_proxies(spheres.center[self.proxied], radius[self.proxied]),
            ])
            self.bvh = Bvh(corners)

    # -- closest hit -------------------------------------------------------
    def closest(self, origins: np.ndarray, dirs: np.ndarray, outside: bool = False) -> Hits:
        """First hit at t > 0 of rays ``origins (N, 3)`` + t·``dirs (N, 3)`` (unit).

        ``outside`` promises that no origin lies inside a sphere proxy, which lets
        the walk stop at the first confirmed hit.
        """
        n = len(origins)
        w = self.world
        best = np.full(n, np.inf)
        kind = np.zeros(n, dtype=np.int8)
        index = np.full(n, -1, dtype=np.int64)
        bary = np.zeros((n, 2))
        for k in range(len(w.planes.normal)):
            t = plane_t(origins, dirs, w.planes.point[k], w.planes.normal[k])
            closer = t < best
            best[closer], kind[closer], index[closer] = t[closer], PLANE, k
        for k in self.direct_spheres:
            t = sphere_t(origins, dirs, w.spheres.center[k], w.spheres.radius[k])
            closer = t < best
            best[closer], kind[closer], index[closer] = t[closer], SPHERE, k
        if self.bvh is not None:
            self._walk(origins, dirs, best, kind, index, bary, 0.0 if outside else self.margin)
        return self._describe(origins, dirs, best, kind, index, bary)

    def _walk(self, origins: np.ndarray, dirs: np.ndarray, best: np.ndarray, kind: np.ndarray,
              index: np.ndarray, bary: np.ndarray, margin: float, any_hit: bool = False) -> None:
        """Visit Embree's candidates along each ray in order, updating the best hit in place.

        With ``any_hit`` a ray stops at the first hit nearer than its initial ``best``.
        """
        limit = best.copy() if any_hit else None
        assert self.bvh is not None
        live = np.arange(len(origins))
        skipped = np.zeros(len(origins))  # distance already walked along each ray
        tested = np.full(len(origins), -1, dtype=np.int64)  # the sphere each ray tested last
        for walk in range(MAX_PASSES):
            if len(live) == 0:
                break
            if walk == 0:
                o, d, start = origins, dirs, origins
                prim = self.bvh.first_hit(o, d, best + margin)
            else:
                o, d, s = origins[live], dirs[live], skipped[live]
                start = o + s[:, None] * d
                prim = self.bvh.first_hit(start, d, best[live] + margin - s)
            found = prim >= 0
            live, prim, o, d, start = live[found], prim[found], o[found], d[found], start[found]
            done = np.zeros(len(live), dtype=bool)
            tri = np.flatnonzero(prim < self.n_triangles)
            if len(tri):
                rows, p = live[tri], prim[tri]
                tr = self.world.triangles
                t, u, v = triangle_hit(o[tri], d[tri], tr.v0[p], tr.e1[p], tr.e2[p])
                real = np.isfinite(t)  # float64 confirms it; otherwise it was float32 noise: walk past it
                closer = real & (t < best[rows])
                r = rows[closer]
                best[r], kind[r], index[r] = t[closer], TRIANGLE, p[closer]
                bary[r, 0], bary[r, 1] = u[closer], v[closer]
                if margin == 0:  # nothing can be nearer than a confirmed triangle
                    done[tri[real]] = True
            sph = np.flatnonzero(prim >= self.n_triangles)
            if len(sph):
                k = self.proxied[(prim[sph] - self.n_triangles) // FACES_PER_PROXY]
                fresh = tested[live[sph]] != k  # leaving a proxy just entered: its sphere is already known
                sph, k = sph[fresh], k[fresh]
                rows = live[sph]
                tested[rows] = k
                t = sphere_t(o[sph], d[sph], self.world.spheres.center[k], self.world.spheres.radius[k])
                closer = t < best[rows]
                r = rows[closer]
                best[r], kind[r], index[r] = t[closer], SPHERE, k[closer]
            if limit is not None:
                done |= best[live] < limit[live]
            live, prim, start, d = live[~done], prim[~done], start[~done], d[~done]
            step = self.bvh.distance_to_plane(prim, start, d)
            noise = np.maximum(max_abs(start), step)  # float32 error scale of this candidate, to step past it
            is_tri = prim < self.n_triangles
            if np.any(is_tri):
                noise[is_tri] = np.maximum(noise[is_tri], self.world.triangles.span[prim[is_tri]])
            skipped[live] += step + REL32 * noise

    def _describe(self, origins: np.ndarray, dirs: np.ndarray, t: np.ndarray, kind: np.ndarray,
                  index: np.ndarray, bary: np.ndarray) -> Hits:
        w = self.world
        n = len(t)
        point = np.zeros((n, 3))
        normal = np.zeros((n, 3))
        material = np.zeros(n, dtype=np.int64)
        scale = np.zeros(n)
        span32 = np.zeros(n)

        s = np.flatnonzero(kind == SPHERE)
        if len(s):
            k = index[s]
            raw = origins[s] + t[s, None] * dirs[s]
            nrm = unit((raw - w.spheres.center[k]) / w.spheres.radius[k, None])
            point[s] = w.spheres.center[k] + w.spheres.radius[k, None] * nrm
            normal[s], material[s], scale[s] = nrm, w.spheres.material[k], w.spheres.scale[k]

        plane_hits = kind == PLANE
        for k in range(len(w.planes.normal)) if np.any(plane_hits) else ():
            q = np.flatnonzero(plane_hits & (index == k))
            raw = origins[q] + t[q, None] * dirs[q]
            nrm, p0 = w.planes.normal[k], w.planes.point[k]
            point[q] = raw - ((raw - p0) @ nrm)[:, None] * nrm
            normal[q], material[q] = nrm, w.planes.material[k]
            scale[q] = np.max(np.abs(p0))

        r = np.flatnonzero(kind == TRIANGLE)
        if len(r):
            k = index[r]
            tr = w.triangles
            point[r] = tr.v0[k] + bary[r, :1] * tr.e1[k] + bary[r, 1:] * tr.e2[k]
            normal[r], material[r] = tr.normal[k], tr.material[k]
            scale[r] = span32[r] = tr.span[k]

        magnitude = max_abs(point)
        offset = REL64 * np.maximum(magnitude, scale)
        if self.has_triangles:
            # clear of the triangle's own float32 noise inside Embree (which grows with its extent along
            # its normal) and of coincident triangles; what noise remains, the walk's float64 check catches
            offset = np.maximum(offset, REL32 * np.maximum(magnitude, span32))
        return Hits(t=t, kind=kind, index=index, point=point, normal=normal, bary=bary,
                    material=material, offset=offset)

    # -- occlusion -----------------------------------------------------------
    def occluded(self, origins: np.ndarray, dirs: np.ndarray, t_max: np.ndarray) -> np.ndarray:
        """True where any surface lies on the ray at a distance in (0, t_max). Shape (N,), bool."""
        w = self.world
        blocked = np.zeros(len(origins), dtype=bool)
        for k in range(len(w.planes.normal)):
            blocked |= plane_t(origins, dirs, w.planes.point[k], w.planes.normal[k]) < t_max
        for k in self.direct_spheres:
            blocked |= sphere_t(origins, dirs, w.spheres.center[k], w.spheres.radius[k]) < t_max
        if self.bvh is None:
            return blocked
        open_ = np.flatnonzero(~blocked)
        # broad phase: a ray that crosses no triangle and no proxy face within reach is clear; the rest
        # are walked exactly, so float32 noise in Embree (a false hit on the surface a ray leaves) never shadows
        maybe = self.bvh.any_hit(origins[open_], dirs[open_], t_max[open_] + self.margin)
        open_ = open_[maybe]
        best = np.where(blocked, -np.inf, t_max)  # a hit before t_max lowers best
        kind = np.zeros(len(origins), dtype=np.int8)
        index = np.full(len(origins), -1, dtype=np.int64)
        bary = np.zeros((len(origins), 2))
        sub = open_
        self._walk(origins[sub], dirs[sub], best_view := best[sub], kind[sub], index[sub], bary[sub],
                   self.margin, any_hit=True)
        blocked[sub] = best_view < t_max[sub]
        return blocked

    def light_end_offset(self, light_points: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """How far before a light a shadow ray stops, so that a surface through the light does not block it."""
        return REL32 * np.maximum(np.max(np.abs(light_points), axis=-1), distance)

    def outside_all_proxies(self, point: np.ndarray) -> bool:
        """True when ``point (3,)`` lies outside every sphere proxy, so rays from it need no margin."""
        if len(self.proxied) == 0:
            return True
        sp = self.world.spheres
        # outside the circumscribed sphere of every proxy (a conservative answer: "inside" only costs a margin)
        distance = np.linalg.norm(sp.center[self.proxied] - point, axis=1)
        return bool(np.all(distance > 1.01 * sphere_proxy_half(sp.radius[self.proxied]) + 2.0**-17 * (
            np.max(np.abs(sp.center[self.proxied]), axis=1) + 2 * sp.radius[self.proxied])))
