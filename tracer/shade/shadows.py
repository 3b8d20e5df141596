"""Shadow rays: whether a light reaches hit points, the one object a point light's terms and an area light's ask.

A shadow ray runs from the exact hit point, leaving its surface by identity (:meth:`tracer.shade.spawn.Spawner.shadow`),
to the light: a surface hit at a distance in (0, d) blocks it, one through the light does not
(:meth:`tracer.exact.intersect.Intersector.occluded`).  :class:`ShadowRays` holds what every shadow query of a render
reads: the world and its options, the intersector, the proofs that spare rays (:mod:`tracer.proofs.planner`), the
spawner, and the budget's poll and count (:class:`Meter`).  :mod:`tracer.shade.direct` asks it for a point, spot or
directional light's rays, :mod:`tracer.shade.area` for an area light's samples'.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..exact.intersect import SPHERE, TRIANGLE, Intersector
from ..proofs.planner import ProofPlan
from ..scene.lights import Emitter
from ..scene.rays import Among, Shadows
from ..scene.variants import Options
from ..scene.world import World
from .kernel import Points, Reach
from .seethrough import Opaque
from .spawn import Spawner, picker


@dataclass(frozen=True)
class Meter:
    """What the lighting stages report to the render's budget: ``stop`` polled between lights and samples, and
    ``count`` the shadow rays cast (:class:`tracer.budget.RayCount`)."""

    stop: Callable[[], None]
    count: Callable[[str, int], None]


class ShadowRays:
    """The shadow rays of one render: :meth:`blocked` says which points a light does not reach."""

    def __init__(
        self, world: World, options: Options, intersector: Intersector, plan: ProofPlan, spawner: Spawner, meter: Meter
    ):
        self.world, self.options, self.intersector, self.spawner, self.meter = (
            world,
            options,
            intersector,
            spawner,
            meter,
        )
        #: which proofs spare which shadow rays (:mod:`tracer.proofs.planner`)
        self.plan = plan
        #: the opaque surfaces alone, for a variant's shadow rays that pass through transparent ones
        self.opaque = None if options.transparent_shadows else Opaque(world)

    def blocked(
        self, at: Points, rows: np.ndarray | None, reach: Reach, em: Emitter, among: Among | None = None
    ) -> np.ndarray:
        """Whether a shadow ray from each of the points ``at`` of ``rows`` (None: all of them, in order) to the
        light ``em`` (along ``reach.to_light``, over ``reach.dist``) is blocked. Shape (len(rows),).  With
        ``among``, the proof that only those pairs of rays and surfaces can block
        (:meth:`tracer.exact.intersect.Intersector.occluded`); without, rays to a point light or along a directional
        light's direction take theirs from :mod:`tracer.proofs.cones` when the scene has few enough surfaces."""
        n = len(at.nv) if rows is None else len(rows)
        if not self.options.shadows:
            return np.zeros(n, dtype=bool)
        pick = picker(rows)
        rays = self.spawner.shadow(at.hit, at.mag, rows, np.ascontiguousarray(pick(reach.to_light)), at.normal)
        spawn = self.spawner.offset
        if em.kind == "directional":
            shadows = Shadows(rays, np.full(n, np.inf), None, None)
        elif spawn is not None and spawn.along != "ray":
            # a student's offset along the normal: as long as from the hit point to the light, from where the ray
            # starts (as the students' own do: the distance to the light is the hit point's), so that its far end
            # passes the light by as much as the offset moved it; no surface is exempt at the light
            shadows = Shadows(rays, pick(reach.dist), None, None)
        else:  # one light for every ray
            shadows = Shadows(rays, pick(reach.dist), em.position[None], self.world.magnitude(em.position[None]))
        if self.opaque is not None:  # (no proof: the plan's bounds are every surface's)
            return self.opaque.occluded(shadows, self.intersector)
        if among is None:
            among = self.plan.shadow_pairs(em, rays, shadows.reach)
        if self.options.acne:
            return self._acne_blocked(shadows, pick(at.hit.kind), pick(at.hit.index))
        return self.intersector.occluded(shadows, among)

    def _acne_blocked(self, shadows: Shadows, kind: np.ndarray, index: np.ndarray) -> np.ndarray:
        """:meth:`tracer.exact.intersect.Intersector.occluded` of shadow rays that start on or below the surfaces
        ``kind, index`` without leaving them (the acne variant), which those surfaces mostly block: each ray is
        first tested against its own surface alone (and the planes), and only the rays that neither blocks are
        tested against every surface.  Blocked by the first test is blocked; the rest are decided by the
        second: the same answer as one test against every surface."""
        curved = np.flatnonzero((kind == SPHERE) | (kind == TRIANGLE))
        order = curved[np.argsort((kind[curved].astype(np.int64) << 48) | index[curved], kind="stable")]
        blocked = self.intersector.occluded(shadows, Among(order, kind[order], index[order]))  # surface by surface
        rest = np.flatnonzero(~blocked)
        if len(rest):
            blocked[rest] = self.intersector.occluded(shadows.take(rest))
        return blocked
