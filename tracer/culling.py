"""Area lights by proof: points that see every sample, or none, cast no shadow rays.

An area light's samples all lie in its parallelogram Q, so every shadow
segment from a point P lies in the pyramid with apex P over Q (the convex
hull of P and Q's corners).  For each point, :func:`classify` decides, from
the surfaces' bounds alone and with margins far above float64 rounding:

* **seen**: every surface's bound lies strictly outside one of the pyramid's
  five face planes (a plane: P and Q strictly on one side of it), so no
  surface meets any segment, and every sample is visible;
* **hidden**: some sphere covers Q as seen from P (every corner of Q lies
  strictly inside the sphere's cone from P, which is convex) and lies strictly
  between P and Q's plane, so every ray from P to Q enters it before it
  reaches the light: every sample is blocked;
* **mixed**: anything else (penumbrae, points near a surface), where the
  renderer casts every sample's ray as before.

The surface a point lies on is never its own blocker for the samples it faces
(leaving by identity), except a sphere seen from inside, which makes the point
mixed.  The decisions the proofs stand for are those the exact per-sample test
makes, far from its rounding, so the image keeps its bytes.  Scenes with more
than :data:`MAX_BOUNDS` surfaces skip the proofs (every point mixed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .shapes import PLANE, SPHERE, TRIANGLE
from .vec import cross, dot, most
from .world import World

SEEN, HIDDEN, MIXED = 0, 1, 2
#: the most surface bounds a scene may have for the proofs to be worth their cost per point
MAX_BOUNDS = 64
#: a proof's margin, relative to the magnitudes involved: far above the exact tests' float64 rounding
MARGIN = 2.0**-30


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


def bounds_of(world: World) -> Bounds | None:
    """The world's surfaces as bounds, or None when there are more than :data:`MAX_BOUNDS` of them."""
    sp, tr, pl = world.spheres, world.triangles, world.planes
    if len(sp.radius) + len(tr.v0) + len(pl.normal) > MAX_BOUNDS:
        return None
    corners = np.stack([tr.v0, tr.v0 + tr.e1, tr.v0 + tr.e2], axis=1)  # (T, 3, 3)
    mid = corners.mean(axis=1) if len(tr.v0) else np.zeros((0, 3))
    reach = np.sqrt(most(np.sum((corners - mid[:, None]) ** 2, axis=2))) if len(tr.v0) else np.zeros(0)
    return Bounds(center=np.concatenate([sp.center, mid]), radius=np.concatenate([sp.radius, reach * (1 + 2.0**-20)]),
                  kind=np.concatenate([np.full(len(sp.radius), SPHERE), np.full(len(tr.v0), TRIANGLE)]),
                  index=np.concatenate([np.arange(len(sp.radius)), np.arange(len(tr.v0))]),
                  solid=np.concatenate([np.ones(len(sp.radius), bool), np.zeros(len(tr.v0), bool)]),
                  plane_point=pl.point, plane_normal=pl.normal)


def classify(b: Bounds, points: np.ndarray, kind: np.ndarray, index: np.ndarray, outward: np.ndarray,
             corners: np.ndarray) -> np.ndarray:
    """SEEN, HIDDEN or MIXED for each of ``points (N, 3)`` (on the surfaces ``kind, index``, whose normal
    ``outward`` faces the samples a point can be lit by) and the light's parallelogram ``corners (4, 3)``,
    in order round it. Shape (N,), int8."""
    n = len(points)
    scale = np.max(np.abs(points), axis=1) + float(np.max(np.abs(corners)))
    own = (b.kind[None, :] == kind[:, None]) & (b.index[None, :] == index[:, None])  # (N, K)
    margin = MARGIN * (scale[:, None] + np.max(np.abs(b.center), axis=1)[None, :] + b.radius[None, :])
    # the pyramid's faces: four sides through P and an edge of Q, and Q's own plane
    q_normal = np.cross(corners[1] - corners[0], corners[3] - corners[0])
    q_normal /= np.linalg.norm(q_normal)
    apex_side = dot(points - corners[0], q_normal)  # (N,)
    flat = np.abs(apex_side) <= MARGIN * scale * 16  # a point in Q's plane: no pyramid to speak of
    side = np.sign(apex_side)
    separated = np.zeros((n, len(b.radius)), dtype=bool)
    centre_side = (b.center - corners[0]) @ q_normal  # (K,)
    # beyond Q's plane, away from the point
    separated |= (-side[:, None] * centre_side[None, :]) > b.radius[None, :] + margin
    for k in range(4):
        a, c = corners[k], corners[(k + 1) % 4]
        face = cross(a - points, c - points)  # (N, 3): the plane through P, a and c
        length = np.sqrt(dot(face, face))
        with np.errstate(divide="ignore", invalid="ignore"):
            face = face / length[:, None]
        inner = dot(corners[(k + 2) % 4] - points, face)  # the far corner: inside
        out = -np.sign(inner)
        dist = (b.center @ face.T).T - dot(points, face)[:, None]  # (N, K) signed distances of the centres
        separated |= (out[:, None] * dist > b.radius[None, :] + margin) & (np.abs(inner) > 0)[:, None]
    separated |= own  # (the own surface faced by the samples is handled below)
    seen = np.all(separated, axis=1) & ~flat
    if len(b.plane_normal):  # a plane blocks no segment when P and Q lie strictly on one side of it
        for j, (p0, nrm) in enumerate(zip(b.plane_point, b.plane_normal)):
            q_side = (corners - p0) @ nrm
            m = MARGIN * (scale + float(np.max(np.abs(p0))))
            p_side = dot(points - p0, nrm)
            mine = (kind == PLANE) & (index == j)  # a point on this very plane, which it leaves
            if np.all(q_side > 0) or np.all(q_side < 0):
                same = (np.sign(p_side) == np.sign(q_side[0])) & (np.abs(p_side) > m) & \
                    np.all(np.abs(q_side)[None, :] > m[:, None], axis=1)
            else:
                same = np.zeros(n, dtype=bool)
            seen &= same | mine
    hidden = _hidden(b, points, own, corners, q_normal, side, margin, scale) & ~flat
    # a sphere a point lies on blocks the samples it faces only when seen from inside
    on_sphere = kind == SPHERE
    if on_sphere.any():
        rows = np.flatnonzero(on_sphere)
        centre_of = b.center[np.searchsorted(np.flatnonzero(b.kind == SPHERE), index[rows])]
        inside = dot(outward[rows], points[rows] - centre_of) < 0
        seen[rows[inside]] = False
        hidden[rows[inside]] = False
    out = np.full(n, MIXED, dtype=np.int8)
    out[seen] = SEEN
    out[hidden & ~seen] = HIDDEN
    return out


def _hidden(b: Bounds, points: np.ndarray, own: np.ndarray, corners: np.ndarray, q_normal: np.ndarray,
            side: np.ndarray, margin: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Points some solid sphere hides the whole parallelogram from. Shape (N,), bool."""
    solid = np.flatnonzero(b.solid)
    if len(solid) == 0:
        return np.zeros(len(points), dtype=bool)
    c, r = b.center[solid], b.radius[solid]
    m = margin[:, solid]
    to_c = c[None, :, :] - points[:, None, :]  # (N, K, 3)
    dist_c = np.sqrt(np.sum(to_c * to_c, axis=2))
    outside = dist_c > r[None, :] + m
    between = side[:, None] * ((c - corners[0]) @ q_normal)[None, :] > r[None, :] + m  # on P's side of Q
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_cone = np.sqrt(np.maximum(0.0, 1.0 - (r[None, :] / dist_c) ** 2))
        covered = outside & between & ~own[:, solid]
        for q in corners:
            to_q = q[None, :] - points
            cos_q = np.einsum("nkd,nd->nk", to_c, to_q) / (dist_c * np.sqrt(dot(to_q, to_q))[:, None])
            covered &= cos_q > cos_cone + MARGIN * 16
    return np.any(covered, axis=1)
