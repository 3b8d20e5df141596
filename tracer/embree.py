"""The only module that talks to embreex.

Embree works in float32.  Callers hand in local (re-centred) float64 arrays;
this module casts them, runs the query and returns indices, leaving the exact
float64 work to :mod:`tracer.shapes`.  ``run()`` releases the GIL, so calls
from several threads on one committed scene run in parallel.
"""

from __future__ import annotations

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

#: far distance used for "no limit" (Embree wants a finite float32)
FAR = np.float32(3.0e38)


def _f32(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32)


def _far(t_max: np.ndarray) -> np.ndarray:
    """float32 far distances, rounded up so that no float64 hit before t_max is cut off."""
    t = np.asarray(t_max, dtype=np.float64)
    t = np.where(np.isfinite(t), np.minimum(t * (1.0 + 2.0**-20), float(FAR)), float(FAR))
    return _f32(t)


class TriangleIndex:
    """An Embree BVH over triangles given as corner arrays ``(T, 3, 3)`` (local coordinates)."""

    def __init__(self, corners: np.ndarray):
        self.count = len(corners)
        self._scene = rtcore_scene.EmbreeScene()
        vertices = _f32(corners.reshape(-1, 3))
        faces = np.arange(len(vertices), dtype=np.int32).reshape(-1, 3)
        TriangleMesh(self._scene, vertices, faces)
        # commit now, on this thread, so that later concurrent queries never race to commit
        self._scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), query="OCCLUDED")

    def closest(self, origins: np.ndarray, dirs: np.ndarray, t_max: np.ndarray) -> np.ndarray:
        """Index of the nearest triangle hit before ``t_max`` per ray, −1 for none. Shape (N,), int64."""
        if len(origins) == 0:
            return np.zeros(0, dtype=np.int64)
        prim = self._scene.run(_f32(origins), _f32(dirs), dists=_far(t_max), query="INTERSECT")
        return prim.astype(np.int64)

    def occluded(self, origins: np.ndarray, dirs: np.ndarray, t_max: np.ndarray) -> np.ndarray:
        """True where some triangle lies on the ray within (0, t_max). Shape (N,), bool."""
        if len(origins) == 0:
            return np.zeros(0, dtype=bool)
        t = np.asarray(t_max, dtype=np.float64)
        far = _f32(np.where(np.isfinite(t), t, float(FAR)))
        return self._scene.run(_f32(origins), _f32(dirs), dists=far, query="OCCLUDED") != -1
