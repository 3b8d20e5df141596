"""The surfaces as bounds for the proofs, and the geometry every proof shares: face normals, the plane rule,
a sphere seen from inside.

A proof (:mod:`tracer.proofs.culling`, :mod:`tracer.proofs.tiles`, :mod:`tracer.proofs.penumbra`,
:mod:`tracer.proofs.cones`) never looks
at a surface itself but at its bound: a sphere is its own bound, a triangle has the ball round its corners
(grown by :data:`tracer.proofs.margins.GROWTH`, as far as an exact test may accept a hit outside it), a plane is a
plane.  What the proofs share is here, written once, each with the error it brings.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..scene.kinds import SPHERE, TRIANGLE
from ..scene.shapes import plane_side
from ..scene.surfaces import Planes, Spheres, Triangles
from ..scene.vec import dot, length, minus, most, rows_of
from .margins import GROWTH, NORMAL_ERROR

#: the most surface bounds a scene may have for the proofs to be worth their cost per point
MAX_BOUNDS = 64


@dataclass(frozen=True)
class Bounds:
    """Every surface of a world as a bound: spheres (spheres, and triangles' enclosing spheres) and planes."""

    center: np.ndarray  # (K, 3) local
    radius: np.ndarray  # (K,)
    kind: np.ndarray  # (K,) SPHERE or TRIANGLE
    index: np.ndarray  # (K,) index within its kind
    solid: np.ndarray  # (K,) bool: a real sphere (its bound is itself), which can prove a point hidden
    plane_point: np.ndarray  # (Q, 3)
    plane_normal: np.ndarray  # (Q, 3)


class Surfaces(Protocol):
    """What :func:`bounds_of` reads of a world (:class:`tracer.scene.world.World`): its surfaces."""

    @property
    def spheres(self) -> Spheres: ...

    @property
    def triangles(self) -> Triangles: ...

    @property
    def planes(self) -> Planes: ...


def bounds_of(world: Surfaces) -> Bounds | None:
    """The world's surfaces as bounds, or None when there are more than :data:`MAX_BOUNDS` of them."""
    sp, tr, pl = world.spheres, world.triangles, world.planes
    if len(sp.radius) + len(tr.v0) + len(pl.normal) > MAX_BOUNDS:
        return None
    corners = np.stack([tr.v0, tr.v0 + tr.e1, tr.v0 + tr.e2], axis=1)  # (T, 3, 3)
    mid = corners.mean(axis=1) if len(tr.v0) else np.zeros((0, 3))
    reach = np.sqrt(most(np.sum((corners - mid[:, None]) ** 2, axis=2))) if len(tr.v0) else np.zeros(0)
    return Bounds(
        center=np.concatenate([sp.center, mid]),
        radius=np.concatenate([sp.radius, reach * (1 + GROWTH)]),
        kind=np.concatenate([np.full(len(sp.radius), SPHERE), np.full(len(tr.v0), TRIANGLE)]),
        index=np.concatenate([np.arange(len(sp.radius)), np.arange(len(tr.v0))]),
        solid=np.concatenate([np.ones(len(sp.radius), bool), np.zeros(len(tr.v0), bool)]),
        plane_point=pl.point,
        plane_normal=pl.normal,
    )


@dataclass(frozen=True)
class SurfacePoints:
    """Points on the scene's surfaces, as a proof reads them: each point, the surface it lies on (``kind``,
    ``index``: it leaves that surface by identity) and ``outward``, its normal that faces the samples it can be
    lit by."""

    point: np.ndarray  # (N, 3) local
    kind: np.ndarray  # (N,)
    index: np.ndarray  # (N,)
    outward: np.ndarray  # (N, 3)

    def take(self, rows: np.ndarray) -> SurfacePoints:
        return SurfacePoints(rows_of(self.point, rows), self.kind[rows], self.index[rows], rows_of(self.outward, rows))


def plane_clear(
    side: np.ndarray, reach: np.ndarray | float, far_side: np.ndarray, margin: np.ndarray | float
) -> np.ndarray:
    """**The plane rule.**  A plane blocks no segment from a point to any of the far points (an area light's
    corners, or a point light) when the point and every far point lie strictly on one side of it.  ``side
    (N,)`` is each point's ``(P − q)·n``, ``far_side (F,)`` the far points'; a point counts as on the far
    points' side when it lies beyond the plane by more than ``margin + reach`` (``reach``: the radius of a
    ball of points it stands for, 0 for a point), and the far points by more than ``margin``.  Shape (N,), bool.

    The far points' parallelogram (or the light) is convex, so every far point on one side puts every
    segment's far end there; the margin covers the rounding of the sides (a few 2^-53 of the magnitudes it is
    taken of, :data:`tracer.proofs.margins.MARGIN`).  A NaN side proves nothing (it compares False)."""
    if np.all(far_side > 0) or np.all(far_side < 0):
        return (
            (np.sign(side) == np.sign(far_side[0]))
            & (np.abs(side) > margin + reach)
            & (margin < float(np.min(np.abs(far_side))))
        )
    return np.zeros(len(side), dtype=bool)


def centre_side(outward: np.ndarray, points: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """``N·(P − c)`` for points ``P (N, 3)`` on spheres of centres ``c (N, 3)``, with ``N`` the normal that faces
    the samples the point can be lit by.  **A sphere seen from inside**: negative, the normal heads into the
    sphere, whose surface then may block the point's rays (they leave it inwards); NaN where the numbers are
    not finite (neither inside nor outside is proven).  Shape (N,)."""
    return dot(outward, minus(points, centres))


def inside_spheres(b: Bounds, at: SurfacePoints, rows: np.ndarray) -> np.ndarray:
    """Of the points ``rows`` (ascending), those on a sphere seen from inside it (:func:`centre_side`
    negative): rows, ascending."""
    rows = rows[at.kind[rows] == SPHERE]
    if len(rows) == 0:
        return rows
    centre = b.center[np.searchsorted(np.flatnonzero(b.kind == SPHERE), at.index[rows])]
    return rows[centre_side(rows_of(at.outward, rows), rows_of(at.point, rows), centre) < 0]


def sides_of(p: np.ndarray, point: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``(P − point)·normal`` for the points ``p (3, N)`` given by their columns. Shape (N,)."""
    return plane_side(p.T, point, normal)


Vector = tuple[np.ndarray, np.ndarray, np.ndarray] | np.ndarray


def face_normal(u: Vector, e: Vector) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unit normal ``u × e / |u × e|`` of the plane through a point and a segment, from ``u`` (the segment's
    start less the point) and ``e`` (the segment's end less its start), each by its three components (arrays
    that broadcast, or a 3-vector), each component one rounded subtraction of stored numbers (or exact); NaN
    where its direction is not known within :data:`tracer.proofs.margins.NORMAL_ERROR`.

    **Bound.**  Each rounded component is the true one times (1 + α), |α| ≤ μ = 2^-53.  A component
    ``u_i e_j − u_j e_i`` of the product then errs by at most γ₄·(|u_i e_j| + |u_j e_i|) (γ₄ = 4μ/(1 − 4μ): the
    two inputs' roundings, the product's and the difference's), so the vector by at most √2·γ₄·|u||e|, and its
    unit vector by at most twice that over |u × e|: 11.4μ·|u||e|/|u × e|.  With the lengths' own roundings
    (a few μ each) this is below 16μ·|u||e|/|n̂| as computed, which is kept at most NORMAL_ERROR; the division
    adds 2^-50 at most.  The error is large only where ``u`` lies almost along ``e`` (the point nearly in line
    with the segment), never because ``u`` is long: a point far from a short segment keeps its digits."""
    e0, e1, e2 = e[0], e[1], e[2]
    n0, n1, n2 = u[1] * e2 - u[2] * e1, u[2] * e0 - u[0] * e2, u[0] * e1 - u[1] * e0
    with np.errstate(all="ignore"):
        size = length(n0, n1, n2)
        reach = length(u[0], u[1], u[2]) * length(e0, e1, e2)
        known = size * NORMAL_ERROR >= 2.0**-49 * reach
        inverse = np.where(known & (size > 0), 1.0 / size, np.nan)
    return n0 * inverse, n1 * inverse, n2 * inverse
