"""Direct light at hit points: the ambient term, then every light's Phong terms where the light reaches.

A light is one :class:`tracer.scene.lights.LightGroup` of emitters: a
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
the one lighting kernel's (:mod:`tracer.shade.kernel`), whatever its light's type;
an area light's loop over its samples is :mod:`tracer.shade.area`'s.  What the
passes count is told to an observer (:class:`tracer.shade.passes.Observer`).

Shadow rays run from the exact hit point, leaving its surface by identity,
to the light (:class:`tracer.shade.shadows.ShadowRays`, which :mod:`tracer.shade.area`
takes too).  Two proofs spare them: in a scene
of few surfaces, a point or directional light's rays are tested only against
the surfaces their bounds allow (:mod:`tracer.proofs.cones`), and an area light's
points are sorted by :mod:`tracer.proofs.culling` into those that see every sample,
none, or some, whose rays meet only the surfaces that may block them.
"""

from __future__ import annotations

import numpy as np

from ..proofs.bounds import SurfacePoints
from ..proofs.tiles import TILE, lit_tiles
from ..scene.lights import LightGroup
from ..scene.rays import Hits
from ..scene.variants import add_clamped
from ..scene.vec import columns, dot, rows_of
from .area import area_terms
from .kernel import Kernel, Points
from .passes import UNOBSERVED, Observer, Seen
from .shading import add_phong, planes_holding
from .shadows import ShadowRays


class DirectLight:
    """The direct-light stage of a renderer: :meth:`shade` gives the colour of hit points."""

    def __init__(self, groups: list[LightGroup], shadows: ShadowRays):
        #: the render's shadow rays, with its world, options and proofs
        self.shadows = shadows
        self.world, self.options, self.groups = shadows.world, shadows.options, groups
        #: the emitters some flat surface's plane holds (where N·L is rounding noise: light_in_plane)
        self.holds = planes_holding(self.world, self.world.emitters)

    def shade(
        self, hit: Hits, mat: np.ndarray, normal: np.ndarray, dirs: np.ndarray, observer: Observer = UNOBSERVED
    ) -> np.ndarray:
        """Ambient plus every light's Phong term where the light reaches the hit points. Shape (N, 3).

        The ``observer`` is told the ambient term and every light's terms (the passes, :mod:`tracer.shade.passes`).
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
        at = Points(hit, normal, dirs, -dot(normal, dirs), self.world.magnitude(hit.point), m.shininess[mat])
        kernel: Kernel | None = None  # (one for every light of one emitter: its buffers are reused)
        for group in self.groups:
            self.shadows.meter.stop()  # a long chunk (many lights) stops early too
            color = self.world.emitters[group.first].color
            if not np.any(color > 0):
                continue
            seen = observer.seen(group.first)
            if group.corners is not None:
                terms = area_terms(self.shadows, group, at, seen, self.holds[group.first : group.end])
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
        bounds = self.shadows.plan.lit_tile_bounds(len(rows))
        if bounds is not None:
            # tiles of points every shadow ray of which is proven clear (tracer.proofs.tiles.lit_tiles) cast none; of
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
            self.shadows.meter.count("shadow", len(rows))
            every = len(rows) == len(lit)  # then no gathering: the rows are all of them, in order
            weight[rows[self.shadows.blocked(at, None if every else rows, reach, em)]] = 0.0
        terms = kernel.terms(reach)
        seen(weight, reach.facing, None)
        return terms
