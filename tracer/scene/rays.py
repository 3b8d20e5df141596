"""Named batches of rays: what travels between the stages, as struct-of-arrays.

A :class:`Rays` batch is N rays ``o + t·d`` (unit ``d``), each leaving a
surface by identity (``from_kind``, ``from_index``; kind MISS for none, see
:mod:`tracer.scene.shapes`), with the world magnitude of each origin, which scales
the rounding that decides whether it lies on a surface.  A :class:`Shadows`
batch is the shadow query: rays towards a light over a distance.  A
:class:`Work` batch is the renderer's work item: rays with the sub-sample each
serves and the weight it carries.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kinds import MISS
from .surfaces import magnitude
from .vec import rows_of


def shared_rows(a: np.ndarray | None, rows: np.ndarray, n: int = -1) -> np.ndarray | None:
    """``a[rows]``, except that a one-row ``a`` (one value shared by every ray) stays as it is, and so does
    an ``a`` of ``n`` rows when ``rows`` is all ``n`` of them."""
    if a is None or len(a) == 1 or len(rows) == n:
        return a
    return rows_of(a, rows)


@dataclass
class Rays:
    origins: np.ndarray  # (N, 3) local
    dirs: np.ndarray  # (N, 3) unit
    from_kind: np.ndarray  # (N,) int8: the kind of surface each ray leaves, MISS for none
    from_index: np.ndarray  # (N,) int64: its index within its kind, −1 for none
    mag: np.ndarray  # (N,) world magnitude of each origin: largest |coordinate|, local plus the local origin's

    @staticmethod
    def leaving(
        origins: np.ndarray,
        dirs: np.ndarray,
        origin_mag: float,
        from_kind: np.ndarray | None = None,
        from_index: np.ndarray | None = None,
        mag: np.ndarray | None = None,
    ) -> Rays:
        """Rays from ``origins``, leaving the surfaces given (or none); ``origin_mag`` is the world magnitude of
        the local origin, and ``mag`` the origins' magnitudes when the caller has them already."""
        n = len(origins)
        if from_kind is None or from_index is None:
            from_kind, from_index = np.full(n, MISS, dtype=np.int8), np.full(n, -1, dtype=np.int64)
        if mag is None:
            mag = magnitude(origins, origin_mag)
        return Rays(origins, dirs, from_kind, from_index, mag)

    def __len__(self) -> int:
        return len(self.origins)

    def take(self, rows: np.ndarray) -> Rays:
        """The rays ``rows`` only (no copies when that is all of them, in order)."""
        if len(rows) == len(self) and (len(rows) == 0 or (rows[0] == 0 and bool(np.all(np.diff(rows) == 1)))):
            return self
        return Rays(
            rows_of(self.origins, rows),
            rows_of(self.dirs, rows),
            self.from_kind[rows],
            self.from_index[rows],
            self.mag[rows],
        )


@dataclass
class Shadows:
    """Shadow rays: each blocked by a surface hit at a distance in (0, reach), except one through its light."""

    rays: Rays
    reach: np.ndarray  # (N,) distance to the light, inf for a directional light
    ends: np.ndarray | None  # the light's position: (N, 3), or (1, 3) for one light every ray shares; None: at infinity
    mag_end: np.ndarray | None  # (N,) or (1,): world magnitude of ``ends``

    @staticmethod
    def towards(rays: Rays, reach: np.ndarray, ends: np.ndarray | None, origin_mag: float) -> Shadows:
        mag_end = None if ends is None else magnitude(ends, origin_mag)
        return Shadows(rays, np.asarray(reach, dtype=np.float64), ends, mag_end)

    def __len__(self) -> int:
        return len(self.rays)

    def take(self, rows: np.ndarray) -> Shadows:
        n = len(self)
        reach = shared_rows(self.reach, rows, n)
        assert reach is not None
        return Shadows(self.rays.take(rows), reach, shared_rows(self.ends, rows, n), shared_rows(self.mag_end, rows, n))


@dataclass(frozen=True)
class Among:
    """A caller's proof of which spheres and triangles each ray of a batch may meet, as pairs (planes, which it
    does not name, are tested against every ray): :mod:`tracer.proofs.cones`, :mod:`tracer.proofs.culling`.  The pairs
    come surface by surface, each ray at most once per surface (as :meth:`of` makes them, and any subset keeps)."""

    rows: np.ndarray  # (P,) int64: the ray of each pair
    kind: np.ndarray  # (P,) SPHERE or TRIANGLE
    index: np.ndarray  # (P,) the surface's index within its kind

    @staticmethod
    def of(kinds: np.ndarray, indices: np.ndarray, may: np.ndarray) -> Among:
        """The pairs of a ``(K, N)`` matrix of which surfaces (``kinds``, ``indices``, each (K,)) each ray may
        meet, surface by surface."""
        k, rows = np.nonzero(may)
        return Among(rows, kinds[k], indices[k])


@dataclass
class Work:
    """The renderer's work item: rays, the sub-sample each one's colour goes to, and the weight it carries."""

    rays: Rays
    sample: np.ndarray  # (N,) int64: index of the sub-sample in its chunk
    weight: np.ndarray  # (N,) product of the reflectances and transmittances on the way
    depth: int  # 0 for camera rays
    #: (N,) int8, only when render passes are asked for: the branch of the ray tree from the first hit
    #: (:mod:`tracer.shade.passes`)
    branch: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.rays)

    def take(self, rows: np.ndarray) -> Work:
        return Work(
            self.rays.take(rows),
            self.sample[rows],
            self.weight[rows],
            self.depth,
            None if self.branch is None else self.branch[rows],
        )

    def slices(self, size: int) -> list[Work]:
        """The batch cut into slices of at most ``size`` rays, in order."""
        return [self.take(np.arange(k, min(k + size, len(self)))) for k in range(0, len(self), size)]


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
        return Hits(
            self.t[rows],
            self.kind[rows],
            self.index[rows],
            rows_of(self.point, rows),
            rows_of(self.normal, rows),
            rows_of(self.bary, rows),
            self.material[rows],
        )
