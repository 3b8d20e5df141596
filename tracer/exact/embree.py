"""The only module that talks to embreex.

Embree works in float32.  Callers hand in local float64 arrays; this module
moves them into the BVH's own frame (centred on the BVH's bounding box and
scaled by a power of two to unit size, so precision depends on the geometry
alone, never on where the scene sits or how large it is), casts them, runs
the query, and returns face indices and float64 distances in local units.
The scene is built in Embree's robust (watertight) mode: a ray that passes
through a closed proxy always crosses its surface.  ``run()`` releases the
GIL, so calls from several threads on one committed scene run in parallel.
"""

from __future__ import annotations

import gc
import math
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

#: far distance used for "no limit" (Embree wants a finite float32)
FAR = 3.0e38


def _f32(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32)


def _as_objects(corners: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The float32 corners and int32 faces as object arrays of Python floats and of 3-tuples.

    embreex copies a mesh into Embree one value at a time through Python
    indexing (``vertices[i, 0]``, ``indices[i][0]``).  On a numeric array each
    access builds a NumPy scalar, or a row view and then a scalar; on an
    object array it hands back the stored float or tuple.  Measured on the
    bench mesh (194k corners, 275k faces): converting takes 0.1 s and the copy
    0.1 s, against 0.3–0.45 s for the copy from numeric arrays.  The floats
    hold float32 values exactly, so Embree receives the same corners.
    """
    a, b, c = faces.T.tolist()
    return corners.astype(np.float64).astype(object), np.fromiter(zip(a, b, c), dtype=object, count=len(faces))


@contextmanager
def _collector_paused() -> Iterator[None]:
    """No garbage collection inside the block (unless it was off already, when it stays off).  Python counts
    every tuple :func:`_as_objects` makes towards its next collection, which would walk the whole heap
    (a scene's own lists of tuples among it) many times over: 40 ms of a bench-mesh render."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def frame(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and half-size (a power of two) of the box ``lo..hi``."""
    centre = (lo + hi) / 2.0
    half = float(np.max(hi - lo)) / 2.0
    if not np.isfinite(half) or half <= 0:
        half = float(np.max(np.abs(centre), initial=0.0)) or 1.0
    return centre, 2.0 ** math.ceil(math.log2(half))


class Bvh:
    """An Embree BVH over proxy triangles ``vertices (V, 3)`` (local) and ``faces (F, 3)``."""

    def __init__(
        self, vertices: np.ndarray, faces: np.ndarray, centre: np.ndarray, half_size: float, commit: bool = True
    ):
        self.centre = centre
        self.half_size = half_size
        self.inv = 1.0 / half_size
        self.count = len(faces)
        #: when a list, every query is appended to it as (query, origins, dirs, far), for benchmarks to replay
        self.record: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._scene = rtcore_scene.EmbreeScene(robust=True)
        corners, faces = _f32((vertices - centre) * self.inv), np.ascontiguousarray(faces, dtype=np.int32)
        try:
            with _collector_paused():  # the copy's 10^5 tuples are dropped again before it ends: nothing to collect
                TriangleMesh(self._scene, *_as_objects(corners, faces))
        except (TypeError, ValueError):  # an embreex that reads typed arrays instead: hand it those
            self._scene = rtcore_scene.EmbreeScene(robust=True)
            TriangleMesh(self._scene, corners, faces)
        if commit:
            self.commit()

    def commit(self) -> None:
        """Build Embree's tree now (the first query would), so that concurrent queries never race to do it.
        Embree builds without the GIL: another thread may go on meanwhile, but must not query before this
        returns."""
        self._scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), query="OCCLUDED")

    def _rays(self, origins: np.ndarray, dirs: np.ndarray, far: np.ndarray) -> tuple[np.ndarray, ...]:
        o = np.empty((len(origins), 3), dtype=np.float32)  # (o − centre)·inv in float64, stored as float32
        for k in range(3):
            o[:, k] = (origins[:, k] - self.centre[k]) * self.inv
        d = _f32(dirs)
        f = np.asarray(far, dtype=np.float64) * self.inv
        f = _f32(np.where(np.isfinite(f), np.minimum(f * (1.0 + 2.0**-20) + 2.0**-20, FAR), FAR))
        return o, d, f

    def nearest(self, origins: np.ndarray, dirs: np.ndarray, far: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest proxy face crossed within ``far`` per ray: ``face`` (N,) int64, −1 for none, and its
        distance (N,) float64 in local units (float32 accuracy)."""
        if len(origins) == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        o, d, f = self._rays(origins, dirs, far)
        if self.record is not None:
            self.record.append(("INTERSECT", o, d, f.copy()))
        out = self._scene.run(o, d, dists=f, query="INTERSECT", output=1)
        return out["primID"].astype(np.int64), out["tfar"].astype(np.float64) * self.half_size

    def any_hit(self, origins: np.ndarray, dirs: np.ndarray, far: np.ndarray) -> np.ndarray:
        """True where some proxy face is crossed within ``far``. Shape (N,), bool."""
        if len(origins) == 0:
            return np.zeros(0, dtype=bool)
        o, d, f = self._rays(origins, dirs, far)
        if self.record is not None:
            self.record.append(("OCCLUDED", o, d, f.copy()))
        return self._scene.run(o, d, dists=f, query="OCCLUDED") != -1

    def replay(self, query: str, origins: np.ndarray, dirs: np.ndarray, far: np.ndarray) -> None:
        """Run one recorded query again, as Embree alone would (for benchmarks)."""
        self._scene.run(origins, dirs, dists=far.copy(), query=query)
