"""Direct light at hit points: the ambient term, then every light's Phong terms where the light reaches.

A light is one :class:`tracer.lights.LightGroup` of emitters: a
point light, a spot or a directional light is one emitter, an area light its
grid of samples, all of one colour.  For each emitter: L, d and the intensity
factor at every point, shadow rays for the points it may light, and the
weights of the diffuse and the specular term, ``wd = w·(N·L)`` and
``ws = w·max(0, R·V)^n`` (``w`` the factor where the emitter reaches the
point, 0 elsewhere).  A light's weights are summed over its emitters, and its
colour is added once: ``color·(k_d·Σwd + k_s·Σws)``, the contract's sum over
an area light's samples of ``color/(nu·nv)·(k_d·(N·L) + k_s·(R·V)^n)``
gathered into one product per light (the same value to within rounding: a
light of one emitter gets exactly its own term).  Every emitter's terms are
the one lighting kernel's (:mod:`tracer.kernel`), whatever its light's type;
an area light's loop over its samples is :mod:`tracer.area`'s.  What the
passes count is told to an observer (:class:`tracer.passes.Observer`).

Shadow rays run from the exact hit point, leaving its surface by identity,
to the light (:meth:`DirectLight.blocked`).  Two proofs spare them: in a scene
of few surfaces, a point or directional light's rays are tested only against
the surfaces their bounds allow (:mod:`tracer.cones`), and an area light's
points are sorted by :mod:`tracer.culling` into those that see every sample,
none, or some, whose rays meet only the surfaces that may block them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .bounds import SurfacePoints
from .intersect import MISS, SPHERE, TRIANGLE, Intersector
from .kernel import Kernel, Points, Reach
from .lights import Emitter, LightGroup
from .passes import UNOBSERVED, Observer, Seen
from .planner import ProofPlan
from .rays import Among, Hits, Rays, Shadows
from .seethrough import Opaque
from .shading import add_phong, planes_holding
from .spawn import Spawner, picker
from .surfaces import max_abs
from .tiles import TILE, lit_tiles
from .variants import Options, add_clamped
from .vec import columns, dot, rows_of, scaled
from .world import World

#: an area light's terms ``Σwd, Σws`` at the points, summed over its samples, or None where it reaches none
#: (:func:`tracer.area.area_terms`): the direct-light stage, the light, the points and the observer of its reach
AreaTerms = Callable[["DirectLight", LightGroup, Points, Seen], "tuple[np.ndarray, np.ndarray] | None"]


@dataclass(frozen=True)
class Meter:
    """What the direct-light stage reports to the render's budget: ``stop`` polled between lights and samples,
    and ``count`` the shadow rays cast (:class:`tracer.budget.RayCount`)."""

    stop: Callable[[], None]
    count: Callable[[str, int], None]


class DirectLight:
    """The direct-light stage of a renderer: :meth:`shade` gives the colour of hit points."""

    def __init__(
        self,
        world: World,
        options: Options,
        intersector: Intersector,
        groups: list[LightGroup],
        plan: ProofPlan,
        meter: Meter,
        area: AreaTerms,
    ):
        self.world, self.options, self.intersector, self.groups = world, options, intersector, groups
        #: an area light's loop over its samples (:func:`tracer.area.area_terms`), given by the renderer
        self.area = area
        #: which proofs spare which shadow rays (:mod:`tracer.planner`)
        self.plan = plan
        self.stop, self.count = meter.stop, meter.count
        #: the emitters some flat surface's plane holds (where N·L is rounding noise: light_in_plane)
        self.holds = planes_holding(world, world.emitters)
        #: where shadow rays are born (the renderer's, with a variant's offset when it has one)
        self.spawner = Spawner(world, options, None)
        #: the opaque surfaces alone, for a variant's shadow rays that pass through transparent ones
        self.opaque = None if options.transparent_shadows else Opaque(world)

    def shade(
        self, hit: Hits, mat: np.ndarray, normal: np.ndarray, dirs: np.ndarray, observer: Observer = UNOBSERVED
    ) -> np.ndarray:
        """Ambient plus every light's Phong term where the light reaches the hit points. Shape (N, 3).

        The ``observer`` is told the ambient term and every light's terms (the passes, :mod:`tracer.passes`).
        """
        m, opt = self.world.materials, self.options
        # (N, 3) arrays whose columns are contiguous, each gathered a column at a time: every light adds to them
        # a column at a time (add_phong)
        colour, diffuse, specular = columns(len(mat)), columns(len(mat)), columns(len(mat))
        ka = m.diffuse if opt.ambient_from_diffuse else m.ambient  # (a variant's k_d for k_a)
        for k in range(3):
            np.take(ka[:, k], mat, out=colour[:, k])
            colour[:, k] *= self.world.ambient[k]
            np.take(m.diffuse[:, k], mat, out=diffuse[:, k])
            np.take(m.specular[:, k], mat, out=specular[:, k])
        if not opt.ambient:
            colour = np.zeros_like(colour)
        if not opt.specular:
            specular = np.zeros_like(specular)
        observer.ambient(colour)
        # N·V, the same for every light; the magnitudes where every light's shadow rays start
        at = Points(hit, normal, dirs, -dot(normal, dirs), max_abs(hit.point) + self.world.origin_mag, m.shininess[mat])
        kernel: Kernel | None = None  # (one for every light of one emitter: its buffers are reused)
        for group in self.groups:
            self.stop()  # a long chunk (many lights) stops early too
            color = self.world.emitters[group.first].color
            if not np.any(color > 0):
                continue
            seen = observer.seen(group.first)
            if group.corners is not None:
                terms = self.area(self, group, at, seen)
            else:
                kernel = kernel or Kernel(self.world, opt, at)
                terms = self._one(kernel, group.first, seen)
            if terms is None:
                continue
            (add_clamped if opt.clamp_terms else add_phong)(colour, color, diffuse, specular, *terms)
            observer.light(group.first, color, diffuse, specular, terms)
        observer.shaded(colour)
        return colour

    # -- one emitter: a point light, a spot or a directional light ----------------------------------------------
    def _one(self, kernel: Kernel, e_index: int, seen: Seen) -> tuple[np.ndarray, np.ndarray] | None:
        """The terms of a light of one emitter (``e_index``) at every point, or None where it reaches none."""
        at, em = kernel.at, self.world.emitters[e_index]
        hit = at.hit
        reach = kernel.reach(em, bool(self.holds[e_index]))
        lit, weight = reach.lit, reach.weight
        if not lit.any():
            return None
        rows = np.flatnonzero(lit)
        bounds = self.plan.lit_tile_bounds(len(rows))
        if bounds is not None:
            # tiles of points every shadow ray of which is proven clear (tracer.tiles.lit_tiles) cast none; of
            # the lit points alone when they are few
            few = 2 * len(rows) < len(lit)
            sub = hit.take(rows) if few else hit
            normal = rows_of(at.normal, rows) if few else at.normal
            clear = np.repeat(
                lit_tiles(
                    bounds,
                    SurfacePoints(sub.point, sub.kind, sub.index, normal),
                    None if em.kind == "directional" else em.position,
                    em.direction if em.kind == "directional" else None,
                ),
                TILE,
            )[: len(sub.t)]
            rows = rows[~clear] if few else np.flatnonzero(lit & ~clear)
        if len(rows):
            self.count("shadow", len(rows))
            every = len(rows) == len(lit)  # then no gathering: the rows are all of them, in order
            weight[rows[self.blocked(at, None if every else rows, reach, em)]] = 0.0
        terms = kernel.terms(reach)
        seen(weight, reach.facing, None)
        return terms

    # -- shadow rays -------------------------------------------------------------------------------------------
    def blocked(
        self, at: Points, rows: np.ndarray | None, reach: Reach, em: Emitter, among: Among | None = None
    ) -> np.ndarray:
        """Whether a shadow ray from each of the points ``at`` of ``rows`` (None: all of them, in order) to the
        light ``em`` (along ``reach.to_light``, over ``reach.dist``) is blocked. Shape (len(rows),).  With
        ``among``, the proof that only those pairs of rays and surfaces can block
        (:meth:`tracer.intersect.Intersector.occluded`); without, rays to a point light or along a directional
        light's direction take theirs from :mod:`tracer.cones` when the scene has few enough surfaces."""
        opt, hit = self.options, at.hit
        n = len(at.nv) if rows is None else len(rows)
        if not opt.shadows:
            return np.zeros(n, dtype=bool)
        pick = picker(rows)
        shadow_dirs = np.ascontiguousarray(pick(reach.to_light))
        # from the exact hit point, leaving its surface by identity, to the light itself
        rays = self.spawner.spawn(hit, at.mag, rows, shadow_dirs, at.normal)
        if opt.acne:  # a student's shadow ray: its surface not left, half the points a hair below it
            below = (
                np.ones(n, dtype=bool)
                if opt.acne_everywhere
                else ((pick(hit.point).view(np.int64)[:, 0] >> 20) & 1).astype(bool)
            )
            lowered = rays.origins - scaled(pick(at.normal), below * rays.mag * 2.0**-30)
            rays = Rays(lowered, shadow_dirs, np.full(n, MISS, dtype=np.int8), np.full(n, -1), rays.mag)
        spawn = self.spawner.offset
        if em.kind == "directional":
            shadows = Shadows(rays, np.full(n, np.inf), None, None)
        elif spawn is not None and spawn.along == "normal":
            # a student's offset along the normal: as long as from the hit point to the light, from where the ray
            # starts (as the students' own do: the distance to the light is the hit point's), so that its far end
            # passes the light by as much as the offset moved it; no surface is exempt at the light
            shadows = Shadows(rays, pick(reach.dist), None, None)
        else:
            mag_light = max_abs(em.position[None]) + self.world.origin_mag
            shadows = Shadows(rays, pick(reach.dist), em.position[None], mag_light)  # one light for every ray
        if self.opaque is not None:  # (no proof: the plan's bounds are every surface's)
            return self.opaque.occluded(shadows, self.intersector)
        if among is None:
            among = self.plan.shadow_pairs(em, rays, shadows.reach)
        if opt.acne:
            return self._acne_blocked(shadows, pick(hit.kind), pick(hit.index))
        return self.intersector.occluded(shadows, among)

    def _acne_blocked(self, shadows: Shadows, kind: np.ndarray, index: np.ndarray) -> np.ndarray:
        """:meth:`tracer.intersect.Intersector.occluded` of shadow rays that start on or below the surfaces
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
