"""Shadow rays of a student whose transparent objects cast no shadow (a variant of :mod:`tracer.scene.variants`).

The format makes every surface opaque to a shadow ray, glass too.  A student's shadow test that skips the
objects with k_t > 0 is imitated here exactly: the shadow rays are tested against a world of the opaque surfaces
alone (those whose own material, before its checker, has k_t = 0: the material a student's loop over the
objects reads), with the same exact tests as every other ray.  A shadow ray leaves its surface by identity
(:mod:`tracer.shade.spawn`), an index among the surfaces of its kind; that index is mapped onto the opaque world's,
and a ray leaving a transparent surface leaves none there (that surface is not in it).
"""

from __future__ import annotations

from dataclasses import fields, replace
from typing import TypeVar

import numpy as np

from ..exact.intersect import Intersector
from ..scene.coplanar import coplanar_groups
from ..scene.kinds import MISS, PLANE, SPHERE, TRIANGLE
from ..scene.rays import Rays, Shadows
from ..scene.world import World

Record = TypeVar("Record")


def _kept(record: Record, keep: np.ndarray) -> Record:
    """The surfaces ``keep`` of a record of one kind (every field holds one row per surface)."""
    return type(record)(**{f.name: getattr(record, f.name)[keep] for f in fields(record)})  # type: ignore[arg-type]


class Opaque:
    """The opaque surfaces of a world, and the occlusion of shadow rays by them alone."""

    def __init__(self, world: World):
        clear = world.materials.transmittance == 0
        keep = {
            SPHERE: clear[world.spheres.material],
            PLANE: clear[world.planes.material],
            TRIANGLE: clear[world.triangles.material],
        }
        #: per kind, each surface's index in the opaque world (−1: a transparent surface, not in it)
        self.index = {kind: np.where(k, np.cumsum(k) - 1, -1) for kind, k in keep.items()}
        planes, triangles = _kept(world.planes, keep[PLANE]), _kept(world.triangles, keep[TRIANGLE])
        self.world = replace(
            world,
            spheres=_kept(world.spheres, keep[SPHERE]),
            planes=planes,
            triangles=triangles,
            coplanar=coplanar_groups(planes, triangles),  # (of the surfaces kept, numbered as they are here)
        )
        self.intersector = Intersector(self.world)

    def occluded(self, shadows: Shadows, like: Intersector) -> np.ndarray:
        """:meth:`tracer.exact.intersect.Intersector.occluded` of ``shadows`` (rays of the whole world) by the opaque
        surfaces alone, polling and counting as ``like``, the render's own intersector, does. Shape (N,), bool."""
        self.intersector.check, self.intersector.tested = like.check, like.tested
        rays = shadows.rays
        kind, index = rays.from_kind.copy(), np.full(len(rays), -1, dtype=np.int64)
        for k, mapped in self.index.items():
            sel = np.flatnonzero(kind == k)
            if len(sel):
                index[sel] = mapped[rays.from_index[sel]]
        kind[index < 0] = MISS
        moved = Rays(rays.origins, rays.dirs, kind, index, rays.mag)
        return self.intersector.occluded(Shadows(moved, shadows.reach, shadows.ends, shadows.mag_end))
