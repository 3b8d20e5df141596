"""Where every secondary ray is born: shadow rays towards a light, mirror and refracted rays.

A secondary ray starts at the exact float64 hit point and carries the
identity of the surface it leaves (:mod:`tracer.scene.shapes`: a plane or triangle
is never hit again, a sphere left outward never, inward only at its far
root), with the world magnitude of its origin, which scales the rounding that
decides whether it lies on another surface.  No epsilon moves it; only a
variant of a student's offset (:class:`tracer.scene.variants.Spawn`) moves it off
the surface, as that student's tracer did, and the acne variant's shadow rays
start on or just below it without leaving it (:meth:`Spawner.shadow`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..scene.kinds import MISS
from ..scene.rays import Hits, Rays, Work
from ..scene.variants import Options, Spawn
from ..scene.vec import rows_of, scaled
from ..scene.world import World
from .passes import REFLECTED, REFRACTED
from .shading import mirror, refract


def picker(rows: np.ndarray | None) -> Callable[[np.ndarray], np.ndarray]:
    """The rows ``rows`` of an array (None: all of them, in order, with no copy)."""
    if rows is None:
        return lambda a: a
    return lambda a: rows_of(a, rows)


def offset(spawn: Spawn, rays: Rays, normals: np.ndarray) -> Rays:
    """``rays`` (from hit points, leaving surfaces of normals ``normals``, (N, 3), shading or geometric as the
    student's offset is along) moved off them by a
    student's offset ``spawn``.  As a student's rays do, the moved rays carry no identity of the surface they
    leave: the offset alone keeps them off it, and they are traced as rays from anywhere are (a camera inside the
    scene's).

    Guarantee: each origin moves by exactly ``spawn.amount``, along the given normal to the side its direction
    points to (the normal's sign is taken from the direction), as a student's ``p ± ε·N`` does: on a mesh with
    normals, where the shading normal leans away from the face's, that is where a student's ray starts too.
    Along ``"ray"`` or ``"direction"``, each origin moves by exactly ``spawn.amount`` along its own direction."""
    points, dirs = rays.origins, rays.dirs
    if spawn.along in ("ray", "direction"):
        moved = points + spawn.amount * dirs
    else:
        side = np.where(np.einsum("ij,ij->i", dirs, normals) < 0, -spawn.amount, spawn.amount)
        moved = points + side[:, None] * normals
    return Rays.leaving(moved, dirs, 0.0, mag=rays.mag)


class Spawner:
    """Every secondary ray of a render: :meth:`spawn` is the one place a ray leaving a surface is made."""

    def __init__(self, world: World, options: Options, offset: Spawn | None):
        self.world, self.options = world, options
        #: where rays start, off the surface in a variant of a student's offset (None: at the hit point)
        self.offset = offset

    def spawn(self, hit: Hits, mag: np.ndarray, rows: np.ndarray | None, dirs: np.ndarray, shading: np.ndarray) -> Rays:
        """Rays along ``dirs (len(rows), 3)`` from the hit points ``rows`` of ``hit`` (None: all, in order),
        leaving their surfaces by identity; ``mag (N,)`` the world magnitudes of all of ``hit``'s points.  A
        student's offset moves them along the shading normals ``shading (N, 3)`` (on a mesh with normals, the
        one a student's tracer has at hand, interpolated), or along the geometric ones where the student's
        offset says so (the face's own normal, which other students use)."""
        pick = picker(rows)
        rays = Rays(pick(hit.point), dirs, pick(hit.kind), pick(hit.index), pick(mag))
        if self.offset is not None:  # a student's offset: off the surface
            rays = offset(self.offset, rays, pick(hit.normal if self.offset.along == "geometric" else shading))
        return rays

    def shadow(self, hit: Hits, mag: np.ndarray, rows: np.ndarray | None, dirs: np.ndarray, normal: np.ndarray) -> Rays:
        """Shadow rays along ``dirs`` from the hit points ``rows`` (as :meth:`spawn`); in the acne variant, a
        student's shadow rays: their surface not left, and half the points (every point, with
        ``acne_everywhere``) a hair (2^-30 of their magnitude) below it, against the facing ``normal (N, 3)``."""
        rays = self.spawn(hit, mag, rows, dirs, normal)
        if not self.options.acne:
            return rays
        pick, n = picker(rows), len(dirs)
        if self.options.acne_everywhere:
            below = np.ones(n, dtype=bool)
        else:  # (a bit of the point's x: half the points, the same ones on every run)
            below = ((pick(hit.point).view(np.int64)[:, 0] >> 20) & 1).astype(bool)
        lowered = rays.origins - scaled(pick(normal), below * rays.mag * 2.0**-30)
        return Rays(lowered, dirs, np.full(n, MISS, dtype=np.int8), np.full(n, -1), rays.mag)

    def magnitudes(self, hit: Hits) -> np.ndarray:
        """The world magnitudes of the hit points, where their rays start. Shape (N,)."""
        return self.world.magnitude(hit.point)

    def bounce(self, hit: Hits, mat: np.ndarray, normal: np.ndarray, work: Work) -> Work:
        """Mirror and refracted rays of the hits whose material asks for them: the next depth's work."""
        m = self.world.materials
        kr, kt = m.reflectance[mat], m.transmittance[mat]
        dirs, weight = work.rays.dirs, work.weight
        r = np.flatnonzero(weight * kr > 0)  # a weight that underflowed to 0 would only add 0·∞ = NaN
        t = np.flatnonzero(weight * kt > 0)
        if not self.options.reflections:  # (a variant's: mirror rays never traced)
            r = r[:0]
        if not self.options.refractions:  # (a variant's: refracted rays never traced)
            t = t[:0]
        out = np.concatenate(
            [
                mirror(dirs[r], normal[r]),
                refract(
                    dirs[t], hit.normal[t], m.ior[mat[t]], self.options.ior_inverted, self.options.exit_normal_flipped
                ),
            ]
        )
        both = np.concatenate([r, t])
        rays = self.spawn(hit, self.magnitudes(hit), both, out, normal)
        branch = None
        if work.branch is not None:  # the passes follow each branch of the tree from the first hit on
            branch = (
                work.branch[both]
                if work.depth > 0
                else np.concatenate([np.full(len(r), REFLECTED), np.full(len(t), REFRACTED)]).astype(np.int8)
            )
        return Work(
            rays, work.sample[both], np.concatenate([weight[r] * kr[r], weight[t] * kt[t]]), work.depth + 1, branch
        )
