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
from ..scene.rays import Among, Rays, Shadows
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


@dataclass(frozen=True)
class Query:
    """The shadow rays of one light (one emitter) at some points, made by :meth:`ShadowRays.cast` and decided by
    :meth:`ShadowRays.decide`: ``n`` rays; no ``shadows`` where the render casts none (every ray clear)."""

    n: int
    shadows: Shadows | None
    among: Among | None  # the proof's pairs of rays and surfaces (None: every surface)
    kind: np.ndarray | None  # (the acne variant's) the surface each ray's point lies on: its kind and index
    index: np.ndarray | None


#: no shadow rays: a light's or a sample's whose rays are all proven, or that lights no point that casts one
NONE = Query(0, None, None, None, None)
#: the rays of one run of lights (an area light's samples, or point, spot and directional lights in turn) decided
#: in one occlusion query (:meth:`ShadowRays.decide`): a run's stored reach and rays are a few slices' worth at
#: most, and at this size a query's fixed cost (a test per plane and per surface, the walk's passes) is a small
#: share of its rays' own
JOINED_RAYS = 1 << 16


def _joined(parts: list[np.ndarray]) -> np.ndarray:
    """``parts`` one after another, as one array laid out as the first (columns contiguous or rows)."""
    out = np.concatenate(parts)
    first = parts[0]
    if first.ndim == 2 and first.flags.f_contiguous and not first.flags.c_contiguous:
        return np.asfortranarray(out)
    return out


def join(queries: list[Query]) -> Query:
    """``queries`` (of one form: their lights all at points or all at infinity, all with pairs or all without)
    as one query of all their rays in turn: each query's rows numbered after the earlier queries', a light's
    position repeated for each of its rays, and the pairs put surface by surface again (a stable sort, so each
    surface's rays stay in order: :class:`tracer.scene.rays.Among`'s promise)."""
    if len(queries) == 1:
        return queries[0]
    shadows = [q.shadows for q in queries]
    assert all(s is not None for s in shadows)
    sh = [s for s in shadows if s is not None]
    rays = Rays(
        _joined([s.rays.origins for s in sh]),
        _joined([s.rays.dirs for s in sh]),
        np.concatenate([s.rays.from_kind for s in sh]),
        np.concatenate([s.rays.from_index for s in sh]),
        np.concatenate([s.rays.mag for s in sh]),
    )
    reach = np.concatenate([np.broadcast_to(s.reach, (len(s),)) for s in sh])
    ends = mag_end = None
    if sh[0].ends is not None:
        at = [(s.ends, s.mag_end, len(s)) for s in sh if s.ends is not None and s.mag_end is not None]
        ends = np.concatenate([np.broadcast_to(e, (k, 3)) for e, _, k in at])
        mag_end = np.concatenate([np.broadcast_to(m, (k,)) for _, m, k in at])
    among = None
    if queries[0].among is not None:
        first = np.cumsum([0] + [q.n for q in queries[:-1]])
        pairs = [(q.among, f) for q, f in zip(queries, first) if q.among is not None]
        kind = np.concatenate([a.kind for a, _ in pairs])
        index = np.concatenate([a.index for a, _ in pairs])
        order = np.argsort(kind.astype(np.int64) << 48 | index, kind="stable")
        rows = np.concatenate([a.rows + f for a, f in pairs])
        among = Among(rows[order], kind[order], index[order])
    kinds = [q.kind for q in queries if q.kind is not None]
    indices = [q.index for q in queries if q.index is not None]
    return Query(
        len(rays),
        Shadows(rays, reach, ends, mag_end),
        among,
        np.concatenate(kinds) if kinds else None,
        np.concatenate(indices) if indices else None,
    )


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
        return self.decide([self.cast(at, rows, reach, em, among)])[0]

    def cast(self, at: Points, rows: np.ndarray | None, reach: Reach, em: Emitter, among: Among | None = None) -> Query:
        """The shadow rays :meth:`blocked` tests, made now and decided later by :meth:`decide` (with other
        queries', in one occlusion query): they own their arrays, so the kernel's next :meth:`Kernel.reach` may
        overwrite ``reach``."""
        n = len(at.nv) if rows is None else len(rows)
        if not self.options.shadows:
            return Query(n, None, None, None, None)
        pick = picker(rows)
        # (a copy even of every row: of one point, the kernel's (1, 3) buffer is already C-contiguous, and would be
        # the rays' own directions until the next light's reach rewrote them)
        dirs = np.ascontiguousarray(pick(reach.to_light)) if rows is not None else np.array(reach.to_light, order="C")
        rays = self.spawner.shadow(at.hit, at.mag, rows, dirs, at.normal)
        dist = pick(reach.dist) if rows is not None else reach.dist.copy()
        spawn = self.spawner.offset
        if em.kind == "directional" or not self.options.shadow_to_light:  # (a variant's rays go on past the light)
            shadows = Shadows(rays, np.full(n, np.inf), None, None)
        elif spawn is not None and spawn.along != "ray":
            # a student's offset along the normal or the ray: as long as from the hit point to the light, from where
            # the ray starts (as the students' own do: the distance to the light is the hit point's), so that its far
            # end passes the light by as much as the offset moved it; no surface is exempt at the light
            shadows = Shadows(rays, dist, None, None)
        else:  # one light for every ray
            shadows = Shadows(rays, dist, em.position[None], self.world.magnitude(em.position[None]))
        if self.opaque is not None or self.options.acne:  # (no proof: a variant's rays; acne tests its own)
            among = None
        elif among is None:
            among = self.plan.shadow_pairs(em, rays, shadows.reach)
        kind, index = (pick(at.hit.kind), pick(at.hit.index)) if self.options.acne else (None, None)
        return Query(n, shadows, among, kind, index)

    def decide(self, queries: list[Query]) -> list[np.ndarray]:
        """Whether each ray of each of ``queries`` (:meth:`cast`) is blocked, each query's (n,) in turn.

        **Guarantee: the same answers as deciding each query alone** (:meth:`blocked`), in as few occlusion
        queries as their forms allow (one, for an area light's samples): the queries of one form (a light at
        a point or at infinity; with pairs of rays and surfaces or without) are joined into one batch of rays,
        their pairs renumbered and put surface by surface again, and the answers cut apart.  Whether a ray is
        blocked depends on that ray alone, never on the others in its batch: every exact test is elementwise over
        the rays (the same operations on the same numbers), a pair names its own ray, and the walk keeps each
        ray's nearest hit.  So joining saves each query's fixed cost (an exact test per plane and per surface,
        the walk's passes) and changes no bit."""
        out: list[np.ndarray] = [np.zeros(q.n, dtype=bool) for q in queries]
        forms: dict[tuple[bool, bool], list[int]] = {}
        for i, q in enumerate(queries):
            if q.shadows is not None and q.n:
                forms.setdefault((q.shadows.ends is None, q.among is None), []).append(i)
        for members in forms.values():
            joined = join([queries[i] for i in members])
            answer = self._occluded(joined)
            for i, part in zip(members, np.split(answer, np.cumsum([queries[i].n for i in members])[:-1])):
                out[i] = part
        return out

    def _occluded(self, q: Query) -> np.ndarray:
        """The occlusion of one query's rays, by the surfaces a variant's rays see, or the proof's pairs."""
        assert q.shadows is not None
        if self.opaque is not None:  # (no proof: the plan's bounds are every surface's)
            return self.opaque.occluded(q.shadows, self.intersector)
        if self.options.acne:
            assert q.kind is not None and q.index is not None
            return self._acne_blocked(q.shadows, q.kind, q.index)
        return self.intersector.occluded(q.shadows, q.among)

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
