"""An area light at hit points: its grid of samples, each the lighting kernel's emitter, with the culling's proofs.

The points an area light may light are sorted once (:mod:`tracer.proofs.culling`):
those that see every sample, none, or some; then each sample runs the one
lighting kernel (:class:`tracer.shade.kernel.Kernel`) over the points that may see
it, and the samples' terms are summed: the contract's sum over an area light's
samples of ``color/(nu·nv)·(k_d·(N·L) + k_s·(R·V)^n)``, the colour added once
per light by :mod:`tracer.shade.direct`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..proofs.bounds import SurfacePoints
from ..proofs.culling import HIDDEN, MIXED, SEEN, classify, faces_away
from ..proofs.penumbra import Penumbra
from ..scene.lights import Emitter, LightGroup
from .kernel import Kernel, Points, Reach
from .passes import Seen
from .shadows import JOINED_RAYS, NONE, Query, ShadowRays


@dataclass
class Sorted:
    """The points an area light may light, taken once: those that see every sample first (``seen`` of them),
    then the mixed ones, with their pairs with the bounds that may block them (None: every ray cast whole)."""

    active: np.ndarray  # (M,) int64: the rows of the points shaded, among all
    every: bool  # the points shaded are all of them, in their own order
    seen: int
    at: Points  # the points shaded
    penumbra: Penumbra | None


def area_terms(
    shadows: ShadowRays, group: LightGroup, at: Points, seen: Seen, holds: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """An area light's terms ``Σwd, Σws`` at every point, summed over its samples, or None where it reaches none;
    ``shadows`` the render's shadow rays, ``holds`` which of its samples some flat surface's plane holds.

    **Points no sample can light are not shaded.**  A point proven HIDDEN (:mod:`tracer.proofs.culling`) gets
    weight 0 from every sample, and so does a point whose normal faces away from all four corners by more
    than rounding (N·(S − P) is linear in the sample S, so it is negative over the whole parallelogram,
    and N·L ≤ 0 at every sample; not so for the variant that lights a point from behind).  Weight 0 at
    finite N·L (finite points, normals and distances: asked for) makes both terms 0, which is what such a
    point is given.

    **A point that sees every sample casts no shadow ray** (SEEN), and **a mixed point's shadow rays meet
    only the bounds that may block it** (``may_block``, the proof in :mod:`tracer.proofs.culling`): the walk is
    replaced by the exact tests of those surfaces (:meth:`tracer.exact.intersect.Intersector.occluded`,
    ``among``), which decide the same.  Without bounds (too many surfaces, or a variant's shadow rays)
    every point is mixed and casts every ray.

    The points shaded are taken once, those that see every sample first, and each sample runs the kernel on
    them, with the same shadow rays as a point light's.  ``seen`` observes each sample's reach."""
    n = len(at.hit.t)
    if n == 0:
        return None
    points = _sort(shadows, group, at)
    if points is None:
        return None
    sum_d, sum_s = _samples(shadows, group, points, seen, holds)
    if points.every:
        return sum_d, sum_s
    out_d, out_s = np.zeros(n), np.zeros(n)
    out_d[points.active], out_s[points.active] = sum_d, sum_s
    return out_d, out_s


def _sort(shadows: ShadowRays, group: LightGroup, at: Points) -> Sorted | None:
    """The points of ``at`` that may see some of the light's samples, sorted (None: none may)."""
    hit, corners, plan = at.hit, group.corners, shadows.plan
    assert corners is not None
    n = len(hit.t)
    bounds = plan.light_bounds
    if bounds is not None:
        culled = classify(bounds, SurfacePoints(hit.point, hit.kind, hit.index, at.normal), corners)
        state, may_block = culled.state, culled.may_block
        idle = state == HIDDEN
    else:
        state, may_block, idle = np.full(n, MIXED, dtype=np.int8), None, np.zeros(n, dtype=bool)
    if plan.facing:
        idle |= faces_away(hit.point, at.normal, corners)
    seen_rows = np.flatnonzero(~idle & (state == SEEN))
    mixed_rows = np.flatnonzero(~idle & (state == MIXED))
    ns, m = len(seen_rows), len(seen_rows) + len(mixed_rows)
    if m == 0:
        return None
    active = np.concatenate([seen_rows, mixed_rows])
    every = m == n and (ns == 0 or ns == n)  # the points in their own order: no gathering
    sub = at if every else at.take(active)
    penumbra = None  # the mixed points' pairs with the bounds that may block them, decided where they can be
    if may_block is not None and len(mixed_rows):
        assert bounds is not None
        mixed = SurfacePoints(sub.hit.point[ns:], sub.hit.kind[ns:], sub.hit.index[ns:], sub.normal[ns:])
        penumbra = Penumbra(bounds, mixed, may_block[:, mixed_rows], corners, plan.facing)
    return Sorted(active, every, ns, sub, penumbra)


def _samples(
    shadows: ShadowRays, group: LightGroup, points: Sorted, seen: Seen, holds: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``Σwd, Σws`` over the light's samples at the sorted points, each sample the kernel's emitter, its shadow
    rays cast from the mixed points alone (the seen points see it).

    **The shadow rays of several samples are decided together**: the samples are taken in runs of at most
    :data:`JOINED_RAYS` points in all, each sample's rays made (and counted) as it comes, the run's rays then
    decided in one occlusion query (:meth:`tracer.shade.shadows.ShadowRays.decide`: the same answer for each
    ray as its sample's query alone), and the run's samples' terms summed in their order, as one sample after
    another would: so the same bits, at the price of one query per run, not per sample."""
    sub, meter = points.at, shadows.meter
    kernel = Kernel(shadows.world, shadows.options, sub)
    m = len(sub.nv)
    sum_d, sum_s = np.zeros(m), np.zeros(m)
    rows_seen = None if points.every else points.active
    emitters = shadows.world.emitters[group.first : group.end]
    run = max(1, JOINED_RAYS // max(m, 1))
    for first in range(0, len(emitters), run):
        cast = []
        for e in range(first, min(first + run, len(emitters))):
            meter.stop()
            cast.append(_cast(shadows, kernel, points, emitters[e], bool(holds[e]), run > 1))
        decided = shadows.decide([c.query for c in cast])
        for c, blocked in zip(cast, decided):
            c.apply(blocked, shadows.options.specular_shadowed)
            wd, ws = kernel.terms(c.reach)
            sum_d += wd
            sum_s += ws
            seen(c.reach.weight, c.reach.facing, rows_seen)
    return sum_d, sum_s


@dataclass
class _Cast:
    """One sample's reach at the sorted points and its shadow rays, made and waiting to be decided."""

    reach: Reach
    rows: np.ndarray  # the mixed points' rays (rows of the sorted points)
    proven: np.ndarray | None  # with the penumbra's proofs: which of them are proven blocked
    cast: np.ndarray | None  # and which are cast (the query's rays); None: every ray of ``rows`` is
    query: Query

    def apply(self, blocked: np.ndarray, specular: bool) -> None:
        """Zero the weight where the sample's shadow rays are blocked, ``blocked`` the query's answer (of the
        diffuse term alone, without ``specular``: :meth:`tracer.shade.kernel.Reach.shadowed`)."""
        if self.proven is not None:
            assert self.cast is not None
            self.proven[self.cast] = blocked
            blocked = self.proven
        self.reach.shadowed(self.rows[blocked], specular)


def _cast(shadows: ShadowRays, kernel: Kernel, points: Sorted, em: Emitter, holds: bool, keep: bool) -> _Cast:
    """The sample ``em``'s reach at the sorted points (a copy of the kernel's buffers, with ``keep``: the kernel
    goes on to other samples before this one is decided) and its shadow rays, counted."""
    sub, ns, penumbra, meter = points.at, points.seen, points.penumbra, shadows.meter
    reach = kernel.reach(em, holds)
    rows = ns + np.flatnonzero(reach.lit[ns:])  # the mixed points' shadow rays
    proven = cast = None
    if len(rows) and penumbra is not None:  # rays decided by their pairs, the rest cast against theirs
        proven, cast, pairs = penumbra.decide(reach.lit[ns:], reach.to_light[ns:], reach.dist[ns:])
        query = NONE
        if cast.any():
            meter.count("shadow", int(np.count_nonzero(cast)))
            query = shadows.cast(sub, rows[cast], reach, em, pairs)
    elif len(rows):
        meter.count("shadow", len(rows))
        query = shadows.cast(sub, rows, reach, em)
    else:
        query = NONE
    if keep:  # (the kernel's buffers are rewritten by the next sample's reach)
        reach = reach.kept()
    return _Cast(reach, rows, proven, cast, query)
