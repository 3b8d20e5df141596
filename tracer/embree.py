"""The only module that talks to embreex.

Embree works in float32.  Callers hand in local (re-centred) float64 arrays;
this module casts them, runs the query, and returns primitive indices and
float32 distances, leaving the exact float64 work to :mod:`tracer.shapes`.
``run()`` releases the GIL, so calls from several threads on one committed
scene run in parallel.
"""

from __future__ import annotations

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

#: far distance used for "no limit" (Embree wants a finite float32)
FAR = 3.0e38


def _f32(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32)


def _far(t_max: np.ndarray) -> np.ndarray:
    """float32 far distances, rounded up so that no float64 hit before ``t_max`` is cut off."""
    t = np.asarray(t_max, dtype=np.float64)
    return _f32(np.where(np.isfinite(t), np.minimum(t * (1.0 + 2.0**-20), FAR), FAR))


class Bvh:
    """An Embree BVH over triangles given as corners ``(T, 3, 3)`` in local coordinates."""

    def __init__(self, corners: np.ndarray):
        self.count = len(corners)
        # each triangle's plane as Embree sees it (float32 corners), for stepping past a triangle in float64
        seen = corners.astype(np.float32).astype(np.float64)
        normal = np.cross(seen[:, 1] - seen[:, 0], seen[:, 2] - seen[:, 0])
        self.plane_normal = normal
        self.plane_offset = np.einsum("ij,ij->i", normal, seen[:, 0])
        #: when a list, every query is appended to it as (query, origins, dirs, far), for benchmarks to replay
        self.record: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._scene = rtcore_scene.EmbreeScene()
        vertices = _f32(corners.reshape(-1, 3))
        TriangleMesh(self._scene, vertices, np.arange(len(vertices), dtype=np.int32).reshape(-1, 3))
        # commit now, on this thread, so that concurrent queries never race to commit
        self._scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), query="OCCLUDED")

    def first_hit(self, origins: np.ndarray, dirs: np.ndarray, t_max: np.ndarray) -> np.ndarray:
        """Index of the nearest triangle before ``t_max`` per ray, −1 for none. Shape (N,), int64."""
        if len(origins) == 0:
            return np.zeros(0, dtype=np.int64)
        o, d, far = _f32(origins), _f32(dirs), _far(t_max)
        if self.record is not None:
            self.record.append(("INTERSECT", o, d, far.copy()))
        return self._scene.run(o, d, dists=far, query="INTERSECT").astype(np.int64)

    def any_hit(self, origins: np.ndarray, dirs: np.ndarray, t_max: np.ndarray) -> np.ndarray:
        """True where some triangle lies on the ray within (0, t_max). Shape (N,), bool."""
        if len(origins) == 0:
            return np.zeros(0, dtype=bool)
        t = np.asarray(t_max, dtype=np.float64)
        far = _f32(np.where(np.isfinite(t), t, FAR))
        o, d = _f32(origins), _f32(dirs)
        if self.record is not None:
            self.record.append(("OCCLUDED", o, d, far.copy()))
        return self._scene.run(o, d, dists=far, query="OCCLUDED") != -1

    def replay(self, query: str, origins: np.ndarray, dirs: np.ndarray, far: np.ndarray) -> None:
        """Run one recorded query again, as Embree alone would (for benchmarks)."""
        self._scene.run(origins, dirs, dists=far.copy(), query=query)

    def distance_to_plane(self, prim: np.ndarray, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Float64 distance along each ray to the plane of triangle ``prim`` (0 where the ray runs along it)."""
        n = self.plane_normal[prim]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (self.plane_offset[prim] - np.einsum("ij,ij->i", n, origins)) / np.einsum("ij,ij->i", n, dirs)
        return np.where(np.isfinite(t) & (t > 0), t, 0.0)
