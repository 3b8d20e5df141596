"""Closest-hit and occlusion queries over every kind of surface a scene contains.

Spheres and planes are tested exactly in float64.  Triangles go through an
Embree BVH (float32) and the hit it names is then recomputed in float64.
Only the kinds present in the scene cost anything: with no triangles there is
no Embree scene at all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .embree import TriangleIndex
from .shapes import plane_t, sphere_t, triangle_hit
from .world import World, unit

#: kinds of surface in :attr:`Hits.kind`
MISS, SPHERE, PLANE, TRIANGLE = 0, 1, 2, 3
#: relative spawn offsets: float64 work, and float32 work inside Embree
REL64 = 2.0**-44
REL32 = 2.0**-18


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
        return Hits(**{name: value[rows] for name, value in vars(self).items()})


class Intersector:
    def __init__(self, world: World):
        self.world = world
        tris = world.triangles
        self.has_triangles = len(tris.v0) > 0
        self.triangle_index: TriangleIndex | None = None
        if self.has_triangles:
            corners = np.stack([tris.v0, tris.v0 + tris.e1, tris.v0 + tris.e2], axis=1)
            self.triangle_index = TriangleIndex(corners)

    # -- closest hit -------------------------------------------------------
    def closest(self, origins: np.ndarray, dirs: np.ndarray) -> Hits:
        """First hit at t > 0 of rays ``origins (N, 3)`` + t·``dirs (N, 3)`` (unit)."""
        n = len(origins)
        w = self.world
        best = np.full(n, np.inf)
        kind = np.zeros(n, dtype=np.int8)
        index = np.full(n, -1, dtype=np.int64)
        bary = np.zeros((n, 2))
        for k in range(len(w.spheres.radius)):
            t = sphere_t(origins, dirs, w.spheres.center[k], w.spheres.radius[k])
            closer = t < best
            best[closer], kind[closer], index[closer] = t[closer], SPHERE, k
        for k in range(len(w.planes.normal)):
            t = plane_t(origins, dirs, w.planes.point[k], w.planes.normal[k])
            closer = t < best
            best[closer], kind[closer], index[closer] = t[closer], PLANE, k
        if self.triangle_index is not None:
            prim = self.triangle_index.closest(origins, dirs, best)
            sel = np.flatnonzero(prim >= 0)
            p = prim[sel]
            t, u, v = triangle_hit(origins[sel], dirs[sel], w.triangles.v0[p], w.triangles.e1[p], w.triangles.e2[p])
            closer = t < best[sel]
            rows = sel[closer]
            best[rows], kind[rows], index[rows] = t[closer], TRIANGLE, p[closer]
            bary[rows, 0], bary[rows, 1] = u[closer], v[closer]
        return self._describe(origins, dirs, best, kind, index, bary)

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
            nrm = unit(raw - w.spheres.center[k])
            point[s] = w.spheres.center[k] + w.spheres.radius[k, None] * nrm
            normal[s], material[s], scale[s] = nrm, w.spheres.material[k], w.spheres.scale[k]

        q = np.flatnonzero(kind == PLANE)
        if len(q):
            k = index[q]
            raw = origins[q] + t[q, None] * dirs[q]
            nrm = w.planes.normal[k]
            point[q] = raw - np.einsum("ij,ij->i", raw - w.planes.point[k], nrm)[:, None] * nrm
            normal[q], material[q] = nrm, w.planes.material[k]
            scale[q] = np.max(np.abs(w.planes.point[k]), axis=1)

        r = np.flatnonzero(kind == TRIANGLE)
        if len(r):
            k = index[r]
            tr = w.triangles
            point[r] = tr.v0[k] + bary[r, :1] * tr.e1[k] + bary[r, 1:] * tr.e2[k]
            normal[r], material[r] = tr.normal[k], tr.material[k]
            scale[r] = span32[r] = tr.span[k]

        magnitude = np.max(np.abs(point), axis=1)
        offset = REL64 * np.maximum(magnitude, scale)
        if self.has_triangles:
            offset = np.maximum(offset, REL32 * np.maximum(magnitude, span32))
        return Hits(t=t, kind=kind, index=index, point=point, normal=normal, bary=bary,
                    material=material, offset=offset)

    # -- occlusion -----------------------------------------------------------
    def occluded(self, origins: np.ndarray, dirs: np.ndarray, t_max: np.ndarray) -> np.ndarray:
        """True where any surface lies on the ray at a distance in (0, t_max). Shape (N,), bool."""
        w = self.world
        blocked = np.zeros(len(origins), dtype=bool)
        for k in range(len(w.spheres.radius)):
            blocked |= sphere_t(origins, dirs, w.spheres.center[k], w.spheres.radius[k]) < t_max
        for k in range(len(w.planes.normal)):
            blocked |= plane_t(origins, dirs, w.planes.point[k], w.planes.normal[k]) < t_max
        if self.triangle_index is not None:
            open_ = np.flatnonzero(~blocked)
            if len(open_):
                blocked[open_] = self.triangle_index.occluded(origins[open_], dirs[open_], t_max[open_])
        return blocked

    def light_end_offset(self, light_points: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """How far before a light a shadow ray stops, so that a surface through the light does not block it."""
        return REL32 * np.maximum(np.max(np.abs(light_points), axis=-1), distance)
