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
takes too).  The lights of one emitter that follow one another in the scene
are taken in runs: each light's rays are made as it comes, the run's decided
in one occlusion query (the same answer for every ray as its light's query
alone), and the terms added light by light in the scene's order, so the same
bits as one light after another.  Two proofs spare them: in a scene
of few surfaces, a point or directional light's rays are tested only against
the surfaces their bounds allow (:mod:`tracer.proofs.cones`), and an area light's
points are sorted by :mod:`tracer.proofs.culling` into those that see every sample,
none, or some, whose rays meet only the surfaces that may block them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..proofs.bounds import SurfacePoints
from ..proofs.tiles import TILE, lit_tiles
from ..scene.lights import LightGroup
from ..scene.rays import Hits
from ..scene.variants import add_clamped
from ..scene.vec import columns, dot, rows_of
from ..scene.world import World
from .area import area_terms
from .kernel import Kernel, Points, Reach
from .passes import UNOBSERVED, Observer
from .shading import add_phong, planes_holding
from .shadows import JOINED_RAYS, NONE, Query, ShadowRays

#: the points of a batch from which each light's shadow rays are decided alone: a query of this many rays makes
#: its fixed cost a small share already, and a run's copies of each light's reach cost more than they save (a
#: 320×240 render of 96 lights, batches of 11k to 33k points: 1.07× the time of each light alone when joined)
ALONE_FROM = 8192


class DirectLight:
    """The direct-light stage of a renderer: :meth:`shade` gives the colour of hit points."""

    def __init__(self, groups: list[LightGroup], shadows: ShadowRays):
        #: the render's shadow rays, with its world, options and proofs
        self.shadows = shadows
        self.world, self.options = shadows.world, shadows.options
        #: the lights that give light (a colour above 0), in the scene's order
        self.groups = [g for g in groups if np.any(self.world.emitters[g.first].color > 0)]
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
        into = _Into(self.world, colour, diffuse, specular, observer, opt.clamp_terms)
        kernel: Kernel | None = None  # (one for every light of one emitter: its buffers are reused)
        for run in self._runs(len(mat)):
            if run[0].corners is not None:  # an area light, alone
                self.shadows.meter.stop()  # a long chunk (many lights) stops early too
                group = run[0]
                seen = observer.seen(group.first)
                into.add(group.first, area_terms(self.shadows, group, at, seen, self.holds[group.first : group.end]))
            else:
                kernel = kernel or Kernel(self.world, opt, at)
                self._singles(run, kernel, into)
        observer.shaded(colour)
        return colour

    def _singles(self, run: list[LightGroup], kernel: Kernel, into: _Into) -> None:
        """A run of lights of one emitter each: their shadow rays made one light after another and decided in one
        query (:meth:`tracer.shade.shadows.ShadowRays.decide`: each ray the answer its light's query alone
        gives), then each light's terms added in the run's order, as one light after another would: the same
        bits, at the price of one query per run, not per light."""
        cast = [(group, self._cast(kernel, group.first, len(run) > 1)) for group in run]
        waiting = [(group, c) for group, c in cast if c is not None]
        for (group, c), blocked in zip(waiting, self.shadows.decide([c.query for _, c in waiting])):
            c.reach.shadowed(c.rows[blocked] if c.rows is not None else blocked, self.options.specular_shadowed)
            terms = kernel.terms(c.reach)
            into.observer.seen(group.first)(c.reach.weight, c.reach.facing, None)
            into.add(group.first, terms)

    def _runs(self, points: int) -> list[list[LightGroup]]:
        """The lights that give light, in their order, in runs whose shadow rays are decided together: an area
        light alone (its samples are joined by :mod:`tracer.shade.area`), and lights of one emitter (points, spots,
        directional lights) one after another, at most :data:`JOINED_RAYS` // ``points`` of them in a run (one,
        from :data:`ALONE_FROM` points)."""
        most = max(1, JOINED_RAYS // max(points, 1)) if points < ALONE_FROM else 1
        runs: list[list[LightGroup]] = []
        for group in self.groups:
            single = group.corners is None
            if single and runs and runs[-1][0].corners is None and len(runs[-1]) < most:
                runs[-1].append(group)
            else:
                runs.append([group])
        return runs

    # -- one emitter: a point light, a spot or a directional light ----------------------------------------------
    def _cast(self, kernel: Kernel, e_index: int, keep: bool) -> _Single | None:
        """Where a light of one emitter (``e_index``) reaches the points and its shadow rays, made and waiting to
        be decided (with ``keep``, its reach a copy of the kernel's buffers: the kernel goes on to the run's other
        lights before this one is decided), or None where it reaches none."""
        self.shadows.meter.stop()  # a long chunk (many lights) stops early too
        at, em = kernel.at, self.world.emitters[e_index]
        hit = at.hit
        reach = kernel.reach(em, bool(self.holds[e_index]))
        lit = reach.lit
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
        query = NONE
        given: np.ndarray | None = rows
        if len(rows):
            self.shadows.meter.count("shadow", len(rows))
            every = len(rows) == len(lit)  # then no gathering: the rows are all of them, in order
            given = None if every else rows
            query = self.shadows.cast(at, given, reach, em)
        # (kept: the kernel's buffers are rewritten by the next light's reach)
        return _Single(reach.kept() if keep else reach, given, query)


@dataclass(frozen=True)
class _Single:
    """A light of one emitter at the points, its shadow rays made and waiting to be decided: the ``query``'s
    answer for the ``rows`` of the points (None: all of them, in order) zeroes ``reach.weight`` where blocked."""

    reach: Reach
    rows: np.ndarray | None
    query: Query


@dataclass(frozen=True)
class _Into:
    """What every light's terms are added to: the colour (with the points' k_d and k_s), and the observer told."""

    world: World
    colour: np.ndarray
    diffuse: np.ndarray
    specular: np.ndarray
    observer: Observer
    clamp: bool  # (a variant's: each light's terms clamped as they are added)

    def add(self, first: int, terms: tuple[np.ndarray, np.ndarray] | None) -> None:
        """The terms of the light whose first emitter is ``first`` (None: it reaches no point) added, and told."""
        if terms is None:
            return
        color = self.world.emitters[first].color
        add = add_clamped if self.clamp else add_phong
        add(self.colour, color, self.diffuse, self.specular, *terms)
        self.observer.light(first, color, self.diffuse, self.specular, terms)
