"""An area light's penumbra: what a mixed point's shadow ray is proven to do from its direction and length.

A point :func:`tracer.proofs.culling.classify` leaves MIXED casts a shadow ray to every sample, each of which needs
testing only against the bounds that may block that point (``may_block``).  :class:`Penumbra` decides many of
those pairs of a ray and a bound from the ray's direction and length alone: the ray misses the bound, or a
solid sphere blocks it for sure.  The margins are :mod:`tracer.proofs.margins`'.
"""

from __future__ import annotations

import numpy as np

from ..scene.kinds import PLANE, SPHERE
from ..scene.rays import Among
from ..scene.vec import length, rows_of
from .bounds import Bounds, SurfacePoints, centre_side, plane_clear, sides_of
from .margins import MARGIN


class Penumbra:
    """An area light's mixed points (:func:`classify`) and the bounds that may block them, as pairs, with what a
    shadow ray of each pair is proven to do from its direction and length alone.

    **Proof.**  For a point P outside the ball (c, r) (by the module's margin, and not on the bound's own
    surface), at distance D from its centre, the ball subtends the cone of half-angle θ = asin(r / D) about
    â = (c − P)/D.  A shadow ray P + t·u (u the ray's own unit direction) towards a sample at distance d:

    * misses the ball, so meets no part of the bound's surface, when u·â < cos θ by a margin (its line
      passes farther than r from c), or when the ball lies wholly beyond the sample (D − r > d);
    * is blocked by a sphere (a bound that is the sphere itself) when u·â > cos θ by a margin (its line passes
      through the ball's inside) and the ball lies wholly before the sample (D + r < d): it enters the sphere
      at some 0 < t ≤ D < d.

    Each margin (2^-30 of the cosine, of the magnitudes for a distance) is far above the rounding of the
    float64 numbers compared and of the exact test that would decide the pair, which therefore decides alike.
    A point's own surface blocks none of the rays it casts towards samples it faces (``facing``: every ray
    cast, but in the variant that lights points from behind), as the rays leave it by identity: a flat
    surface never, a sphere seen from outside only heading inwards.
    A plane blocks none of a point's rays when the point and the parallelogram lie strictly on one side of it,
    or the point lies on it (and leaves it).  A ray whose pairs all miss and whose planes cannot block is
    clear; a ray one of whose pairs blocks is blocked; the rest are cast, against their undecided pairs."""

    def __init__(self, b: Bounds, at: SurfacePoints, may_block: np.ndarray, corners: np.ndarray, facing: bool):
        points, kind, index, outward = at.point, at.kind, at.index, at.outward
        self.bounds = b
        self.bound, self.point = np.nonzero(may_block)  # (P,) each: bound-major, as Among.of makes them
        p = [np.take(points[:, k], self.point) for k in range(3)]
        a = [b.center[self.bound, k] - p[k] for k in range(3)]
        with np.errstate(all="ignore"):
            dist = length(a[0], a[1], a[2])
            self.axis = [a[k] / dist for k in range(3)]
            scale = (
                np.maximum(np.maximum(np.abs(p[0]), np.abs(p[1])), np.abs(p[2]))
                + np.max(np.abs(b.center[self.bound]), axis=1)
                + b.radius[self.bound]
            )
            self.margin = MARGIN * scale
            grown, shrunk = b.radius[self.bound] + self.margin, b.radius[self.bound] - self.margin
            own = (b.kind[self.bound] == kind[self.point]) & (b.index[self.bound] == index[self.point])
            outside = np.isfinite(dist) & np.isfinite(scale) & (dist > grown) & ~own
            # u·â below this: the line misses the grown ball; above `inside`: it passes within the shrunk one
            self.miss_below = np.where(outside, np.sqrt(1.0 - (grown / dist) ** 2) - MARGIN, -np.inf)
            if facing:  # its own surface, which a ray towards a sample the point faces leaves for good
                on_sphere = b.kind[self.bound] == SPHERE
                towards = centre_side(rows_of(outward, self.point), rows_of(points, self.point), b.center[self.bound])
                self.miss_below[own & (~on_sphere | (towards >= 0))] = np.inf
            inside = np.sqrt(1.0 - np.maximum(shrunk, 0.0) ** 2 / dist**2) + MARGIN
            self.hit_above = np.where(outside & b.solid[self.bound] & (shrunk > 0), inside, np.inf)
            self.starts = np.where(outside, dist - grown, -np.inf)  # the ball's nearest and farthest reach along
            self.ends = np.where(outside, dist + grown, np.inf)  # any ray from the point
        # the planes that may block some ray of each point (not with the parallelogram strictly on its side)
        self.planes = np.zeros(len(kind), dtype=bool)
        for j, (p0, nrm) in enumerate(zip(b.plane_point, b.plane_normal)):
            q_side = (corners - p0) @ nrm
            side = sides_of(np.ascontiguousarray(points.T), p0, nrm)
            m = MARGIN * (np.max(np.abs(points), axis=1) + float(np.max(np.abs(p0))) + float(np.max(np.abs(corners))))
            self.planes |= ~(plane_clear(side, 0.0, q_side, m) | ((kind == PLANE) & (index == j)))

    def decide(self, lit: np.ndarray, to_light: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray, Among]:
        """For the rays of the points ``lit`` (mixed points, bool), in order, whose unit directions are
        ``to_light`` and lengths ``dist`` (per point, of every point): whether each is proven blocked, whether
        it must still be cast, and the pairs of the rays cast (numbered among them) that are not decided."""
        ray_of = np.cumsum(lit) - 1  # each lit point's ray
        n = int(ray_of[-1]) + 1 if len(ray_of) else 0
        pairs = np.flatnonzero(lit[self.point])
        at = self.point[pairs]
        x = np.take(to_light[:, 0], at) * np.take(self.axis[0], pairs)
        for k in (1, 2):
            x += np.take(to_light[:, k], at) * np.take(self.axis[k], pairs)
        d = np.take(dist, at)
        slack = MARGIN * d + np.take(self.margin, pairs)
        misses = (x < np.take(self.miss_below, pairs)) | (np.take(self.starts, pairs) > d + slack)
        blocks = (x > np.take(self.hit_above, pairs)) & (np.take(self.ends, pairs) < d - slack)
        rays = np.take(ray_of, at)
        blocked = np.zeros(n, dtype=bool)
        blocked[rays[blocks]] = True
        open_pairs = np.flatnonzero(~misses & ~blocks)
        cast = self.planes[lit].copy()
        cast[rays[open_pairs]] = True
        cast &= ~blocked
        keep = open_pairs[cast[rays[open_pairs]]]
        number = np.cumsum(cast) - 1  # each ray cast, numbered among them
        bound = self.bound[pairs[keep]]
        among = Among(number[rays[keep]], self.bounds.kind[bound], self.bounds.index[bound])
        return blocked, cast, among
