"""Tiles of neighbouring hit points, and the proof that a point or directional light reaches a tile whole.

Consecutive hit points are neighbours on the image: a tile of :data:`TILE` of them lies in a small ball.  A
proof made once for the ball holds for every point of the tile (:func:`lit_tiles` here for a point or a
directional light, :func:`tracer.proofs.culling.classify` for an area light), at the cost of one point's.  The margins
are :mod:`tracer.proofs.margins`'; a tile's centre errs by 2^-53 of its coordinates' magnitude, absolute, which the
margin (of the same magnitudes) covers even where the ball's radius is far smaller.
"""

from __future__ import annotations

import numpy as np

from ..scene.kinds import PLANE
from ..scene.vec import dot, length
from .bounds import Bounds, SurfacePoints, inside_spheres, plane_clear, sides_of
from .margins import MARGIN, SLACK

#: consecutive points proven at once (:func:`lit_tiles`, :func:`tracer.proofs.culling.classify`): neighbours on the
#: image lie close together.  Measured at 320×240: tiles of 16 points prove 53k of the soft-shadow example's 65k
#: seen points (and 59k of 72k in the all-lights example) in 3 ms, where the per-point proofs take 37 ms for
#: all; tiles of 64 prove 17k and 31k (a row's 64 pixels reach far), of 8 no more for their cost
TILE = 16


def inside_tiles(b: Bounds, at: SurfacePoints, candidate: np.ndarray) -> np.ndarray:
    """The tiles, among the ``candidate`` ones (T,), with a point on a sphere seen from inside it
    (:func:`tracer.proofs.bounds.inside_spheres`): tile numbers, ascending, possibly repeated."""
    rows = np.flatnonzero(np.repeat(candidate, TILE)[: len(at.kind)])
    return inside_spheres(b, at, rows) // TILE


def tiles_of(at: SurfacePoints) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per tile of :data:`TILE` consecutive points: the centre C ``(3, T)`` of the box of its points (their
    exact minima and maxima), the radius R of the ball about C that holds the box (rounded up), the largest
    magnitude of its coordinates, whether its points all lie on one surface, and that surface (its first
    point's)."""
    points, kind, index = at.point, at.kind, at.index
    n = len(points)
    full = n // TILE * TILE
    lo, hi = np.empty((3, (n + TILE - 1) // TILE)), np.empty((3, (n + TILE - 1) // TILE))
    for k in range(3):  # a tile's minimum and maximum: a loop over its TILE places, on contiguous columns
        column = np.ascontiguousarray(points[:, k])
        whole = column[:full].reshape(-1, TILE)
        low, high = lo[k, : len(whole)], hi[k, : len(whole)]
        np.copyto(low, whole[:, 0])
        np.copyto(high, whole[:, 0])
        for j in range(1, TILE):
            np.minimum(low, whole[:, j], out=low)
            np.maximum(high, whole[:, j], out=high)
        if full < n:
            lo[k, -1], hi[k, -1] = column[full:].min(), column[full:].max()
    centre = (lo + hi) * 0.5
    reach = np.sqrt(np.sum((hi - lo) ** 2, axis=0)) * (0.5 * (1.0 + SLACK))
    scale = np.maximum(np.max(np.abs(lo), axis=0), np.max(np.abs(hi), axis=0))
    key = kind.astype(np.int64) << 48 | index
    edges = np.flatnonzero(key[1:] != key[:-1]) + 1  # where the surface changes: a tile holds one unless inside it
    one = np.ones(len(scale), dtype=bool)
    one[edges[edges % TILE != 0] // TILE] = False
    starts = np.arange(0, n, TILE)
    return centre, reach, scale, one, kind[starts], index[starts]


def lit_tiles(b: Bounds, at: SurfacePoints, position: np.ndarray | None, direction: np.ndarray | None) -> np.ndarray:
    """Which tiles of :data:`TILE` consecutive points a point light at ``position`` (or a directional light
    shining along ``direction``) reaches unblocked from every point. Shape (T,), bool.

    **Proof.**  A tile's points lie in the ball B about the centre C of their box, of radius R.  The shadow
    segment from a point P of B to the light A lies within R of the segment CA (its point λP + (1 − λ)A is
    λ|P − C| from λC + (1 − λ)A); a directional light's shadow ray from P along u = −direction lies within R of
    the ray from C along u.  A bound farther than its radius plus R (and the margin) from that segment, or
    ray, meets no shadow ray of the tile.  A plane with B strictly on one side of it, by more than R, blocks
    none when the light lies strictly on that side too (for a directional light: when u does not head
    towards the plane; a ray parallel to it never meets it).  The surface a tile's points all lie on is not
    their blocker (leaving it by identity) but for a sphere seen from inside, whose tiles, like those with
    numbers beyond proof, are left to their rays.

    **Holds for** the shadow rays of points that face the light (``outward``·L > 0), cast from the exact point
    and leaving its surface: a ray that leaves a sphere seen from outside meets it again only heading inwards,
    away from a light the point faces.  :meth:`tracer.proofs.planner.ProofPlan.lit_tile_bounds` applies it only so."""
    centre, reach_t, scale, one, tile_kind, tile_index = tiles_of(at)
    if position is not None:
        scale = scale + float(np.max(np.abs(position)))
    margin_of = MARGIN * scale
    with np.errstate(all="ignore"):
        seen = np.isfinite(scale) & np.isfinite(reach_t)
        if position is not None:  # the segment from C to the light: C + s·span, 0 ≤ s ≤ 1
            span = np.asarray(position, dtype=np.float64)[:, None] - centre
            length_sq = span[0] * span[0] + span[1] * span[1] + span[2] * span[2]
        else:
            assert direction is not None
            u = -np.asarray(direction, dtype=np.float64)
        if len(b.radius):  # every bound against every tile at once: (K, T)
            bound_part = MARGIN * (np.max(np.abs(b.center), axis=1, initial=0.0) + b.radius)
            rel = [b.center[:, i][:, None] - centre[i][None, :] for i in range(3)]  # bound centre − C
            way = [span[i][None, :] for i in range(3)] if position is not None else [u[i] for i in range(3)]
            along = rel[0] * way[0] + rel[1] * way[1] + rel[2] * way[2]
            if position is not None:  # the nearest point of the segment C + s·span, 0 ≤ s ≤ 1
                s = np.clip(along / length_sq[None, :], 0.0, 1.0)
            else:  # of the ray C + s·u, s ≥ 0
                s = np.maximum(along, 0.0)
            off = [rel[i] - s * way[i] for i in range(3)]
            apart = length(off[0], off[1], off[2])
            clear = apart > margin_of[None, :] + (b.radius + bound_part)[:, None] + reach_t[None, :]
            own = one[None, :] & (b.kind[:, None] == tile_kind[None, :]) & (b.index[:, None] == tile_index[None, :])
            seen &= np.all(clear | own, axis=0)
        for j, (p0, nrm) in enumerate(zip(b.plane_point, b.plane_normal)):
            m = MARGIN * (scale + float(np.max(np.abs(p0))))
            c_side = sides_of(centre, p0, nrm)
            mine = one & (tile_kind == PLANE) & (tile_index == j)
            if position is not None:  # the plane rule, the light the one far point
                light_side = np.array([float((np.asarray(position, dtype=np.float64) - p0) @ nrm)])
                away = plane_clear(c_side, reach_t, light_side, m)
            else:  # the shadow rays' own denominator, one for all, computed as their plane test computes it
                heading = float(dot(u[None], nrm[None])[0])
                away = np.abs(c_side) > m + reach_t
                away &= (heading == 0.0) | (np.sign(c_side) == np.sign(heading))
            seen &= away | mine
        seen[inside_tiles(b, at, seen)] = False
    return seen
