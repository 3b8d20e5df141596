"""The walk: the BVH's primitives that a ray may hit, found through Embree and decided in float64.

The spheres and triangles given to a :class:`Walk` share one Embree BVH of
closed float32 proxies (:mod:`tracer.exact.proxies`) and one grid of cells over
their boxes (:mod:`tracer.exact.cells`).  Embree names the nearest proxy-face
crossing along a ray; every primitive registered in the crossing's part of a
cell is tested exactly in float64 (:mod:`tracer.scene.shapes`), and the ray steps on
from where it leaves that part.  :meth:`Walk.walk` states the guarantee and
derives every start and stop rule from it; ``python -m tests.mutants`` weakens
each rule in turn and shows that the walk's tests catch it.

Mesh faces that every ray of the scene meets squarely (:mod:`tracer.proofs.sightlines`)
go to Embree as themselves, without a proxy, and their *mates* (the faces
across their edges) are skipped where a ray provably cannot meet them.

Primitive ids: the walk's triangles ``0..T-1``, then its spheres ``T..T+S-1``.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..proofs.sightlines import Sightlines, plain_triangles
from ..scene.rays import Rays, Shadows
from ..scene.vec import along, highest, lowest, rows_of
from ..scene.world import World
from .best import Best, slab
from .cells import Cells, build_cells
from .embree import Bvh, frame
from .pairs import Batch, PairTests, gathered
from .proxies import Proxies, build_proxies
from .ties import Ties

#: candidates (ray, member of its part of a cell) made into pairs at a time: about 80 MiB of pairs at once
PAIR_GROUP = 1 << 20
#: a walk over primitives worth at most this many sphere tests per ray (a triangle counts :data:`TRIANGLE_COST`)
#: tests every primitive against each ray its broad phase keeps, instead of walking the cells
#: (:meth:`Walk.walk_few`): the cells' bookkeeping costs more than a few exact tests
FEW = 6
#: an exact triangle test's cost in sphere tests
TRIANGLE_COST = 2


class Walk:
    """The world's triangles ``tris`` and spheres ``spheres`` (indices within their kinds, not empty together)
    behind one Embree BVH and one grid of cells.  ``lines``, when given, promises that every ray cast will lie
    on them (:mod:`tracer.proofs.sightlines`), which lets mesh faces go to Embree without proxies."""

    def __init__(self, world: World, tris: np.ndarray, spheres: np.ndarray, lines: Sightlines | None, ties: Ties):
        #: the exact tests of the walk's primitives (their ids: triangles, then spheres)
        self.pairs = PairTests(world, tris, spheres, ties)
        self._check: Callable[[], None] = self.pairs.check
        tr, sp = world.triangles, world.spheres
        self.n_tri = len(tris)
        self.prim_index, self.sphere_prim = self.pairs.prim_index, self.pairs.sphere_prim
        every = len(tris) == len(tr.v0)  # as usual: then no copies

        def mine(a: np.ndarray) -> np.ndarray:
            return a if every else rows_of(a, tris)

        v0, e1, e2, normal, ids = mine(tr.v0), mine(tr.e1), mine(tr.e2), mine(tr.normal), mine(tr.corner_ids)
        center, radius = rows_of(sp.center, spheres), sp.radius[spheres]
        parts = [v0, v0 + e1, v0 + e2, center - radius[:, None], center + radius[:, None]]
        centre, half = frame(
            np.min([lowest(a) for a in parts if len(a)], axis=0), np.max([highest(a) for a in parts if len(a)], axis=0)
        )
        plain, mates = (None, None) if lines is None else plain_triangles(v0, e1, e2, normal, ids, lines, half)
        some_plain = plain is not None and bool(plain.any())
        #: a plain triangle's faces across its edges, which a shadow ray leaving it never meets (n_tri, 3)
        self.mates = self.pairs.mates = mates if some_plain else None
        self.proxies: Proxies = build_proxies(v0, e1, e2, normal, center, radius, half, plain, ids)
        p = self.proxies
        #: every primitive is tested against every ray the broad phase keeps (:meth:`walk_few`), and no cells are
        #: made; not with plain triangles, whose mates only the cell walk knows to skip
        self.few = self.mates is None and TRIANGLE_COST * len(tris) + len(spheres) <= FEW
        self.bvh = Bvh(p.vertices, p.faces, centre, half, commit=self.few)
        self.cells: Cells | None = None
        if not self.few:
            with ThreadPoolExecutor(max_workers=1) as pool:  # Embree builds its tree while the cells are made
                committed = pool.submit(self.bvh.commit)
                self.cells = build_cells(p.lo, p.hi, p.reach)
                committed.result()
        self.box_lo = lowest(p.lo) - p.step * 4 - p.slack
        self.box_hi = highest(p.hi) + p.step * 4 + p.slack
        # each pass of a walk consumes at least one proxy-face crossing (a ray crosses a face once)
        self.max_steps = len(p.faces) + 2

    @property
    def check(self) -> Callable[[], None]:
        """Called between walk passes and slices of exact tests; raises to stop a render."""
        return self._check

    @check.setter
    def check(self, value: Callable[[], None]) -> None:
        self._check = self.pairs.check = value

    @property
    def tested(self) -> Callable[[int], None]:
        """Told how many exact tests each batch makes (:meth:`tracer.budget.RayCount.tested`)."""
        return self.pairs.tested

    @tested.setter
    def tested(self, value: Callable[[int], None]) -> None:
        self.pairs.tested = value

    def _test_cells(
        self, best: Best, rows: np.ndarray, region: np.ndarray, but: np.ndarray | None, batch: Batch
    ) -> None:
        """:meth:`PairTests.test` of the pairs :meth:`Cells.pairs` makes of rays ``rows`` and their ``region``, but for
        ``but``, made and tested a group of rays at a time (:data:`PAIR_GROUP` candidates), so that what they
        hold is bounded; the best hits do not depend on the order pairs come in (:class:`Best`)."""
        cells = self.cells
        assert cells is not None
        for part in cells.groups(region, PAIR_GROUP):
            if part.start:
                self.check()
            self.pairs.test(best, *cells.pairs(rows[part], region[part], None if but is None else but[part]), batch)

    def test_pairs(
        self, best: Best, rays: Rays, rows: np.ndarray, prims: np.ndarray, shadows: Shadows | None = None
    ) -> None:
        """Test primitives ``prims`` exactly against ``rays`` ``rows`` (pairs; either may repeat), with the
        exact tests a walk makes, and no walk: for a caller that knows which primitives each ray can hit."""
        if len(rows):
            self.pairs.test(best, rows, prims, self.pairs.batch(rays, shadows))

    def prim_of(self, kind: np.ndarray, index: np.ndarray) -> np.ndarray:
        """The walk's primitive id of each surface (:meth:`PairTests.prim_of`). Shape (N,)."""
        return self.pairs.prim_of(kind, index)

    # -- the walk ---------------------------------------------------------------------------------------------
    def walk_few(self, best: Best, rays: Rays, shadows: Shadows | None = None) -> None:
        """:meth:`walk` for a BVH of a few primitives (:attr:`few`): the same answer, with no cells walked.

        **Guarantee.**  Every primitive that a ray could hit before its best hit (or, for ``shadows``, before its
        light) is tested exactly; so is every other primitive, for the rays that Embree cannot clear.

        **Broad phase.**  From where its line enters the BVH's box (behind its origin if need be), a ray is
        outside every proxy; a primitive the float64 ray hits at ``0 < t`` has the ray inside its proxy around
        ``t`` (its margin is far above float32 rounding), so the float32 ray crosses one of that proxy's faces
        between the box's entry and ``t``.  A ray that Embree finds crossing no proxy face before its best hit
        (the slack of a plain triangle's crossing is 0 here: there are none) or the box's exit therefore hits
        no primitive that would count: its best hit stands, and no test is needed.

        **Stop.**  Each kept ray tests every primitive once (its own by identity, as :mod:`tracer.scene.shapes` does
        for any ray leaving a surface); nothing is left to test, so the walk ends there.
        """
        o, d = rays.origins, rays.dirs
        t_in, t_out = slab(o, d, self.box_lo, self.box_hi)
        end = np.minimum(best.t + self.proxies.slack, t_out)
        live = np.flatnonzero((t_in < end) & (end > 0))
        if len(live) == 0:
            return
        s = t_in[live]
        o_l, d_l = rows_of(o, live), rows_of(d, live)
        live = live[self.bvh.any_hit(along(o_l, s, d_l), d_l, end[live] - s)]
        if len(live) == 0:
            return
        count = len(self.prim_index)
        self.pairs.test(
            best, np.repeat(live, count), np.tile(np.arange(count), len(live)), self.pairs.batch(rays, shadows)
        )

    def walk(self, best: Best, rays: Rays, shadows: Shadows | None = None) -> None:
        """Test, exactly, every BVH primitive that one of ``rays`` could hit before its best hit, or, for
        ``shadows`` (whose rays they are), before its light until one blocks it.

        **Guarantee.**  At every point of a walk, with ``s`` its position along the ray: every primitive whose
        proxy the ray (as Embree sees it, in float32) is inside anywhere in ``[s₀, s]`` has been tested, where
        ``s₀`` is where the walk began.  A primitive the float64 ray hits at ``t`` has the ray inside its proxy
        around ``t`` (a proxy holds its primitive grown by a margin far above float32 rounding), so every
        primitive hit at ``t ≤ s`` has been tested.

        **Start.**  A ray that leaves a BVH primitive first tests every member of the part of a cell that holds
        its origin (a proxy that contains the origin has a box that meets that part) and starts at the part's
        exit, with ``s₀ = 0``.  Any other ray starts where its line enters the BVH's box, behind its origin if
        need be (hits at t ≤ 0 never count): no proxy lies there.

        **Step.**  From ``s``, Embree names the nearest proxy-face crossing: no proxy is entered or left before
        it, so between ``s`` and the crossing the ray is inside only proxies it was inside at ``s`` (tested).  At
        the crossing, every member of the crossing's part of a cell is tested: every proxy that meets the part
        is one of them, and so (by the cells' reach, which is larger than the float32 rounding of the crossing
        and of the ray and the walk's step) is every proxy crossed within that rounding of the part.  The walk
        goes on from where the ray leaves the part (or a step past the crossing, when later).

        **Stop.**  A closest-hit walk stops once its best hit lies at or before the exit of the part it just
        tested (every primitive hit before that exit was tested: before the part's entry by the guarantee,
        within the part as a member), or once no crossing is left before its best hit (plus the slack of a plain
        triangle's float32 crossing) or the BVH box's exit.  A shadow walk stops at the first blocker, or when
        no crossing is left before the light.  Each pass consumes a crossing, so the walk ends; should it not
        within :attr:`max_steps` passes, the rays still walking test every primitive (never silently wrong).
        """
        if self.few:
            self.walk_few(best, rays, shadows)
            return
        w = self._begin(best, rays, shadows)
        p, live = self.proxies, w.open_rows(np.arange(len(rays)))
        if w.any_hit and len(live):  # broad phase: a ray that crosses no proxy before its light is clear
            s, limit, t_out = w.start[live], w.limit, w.t_out
            far = np.minimum(limit[live] + p.slack, t_out[live]) - s
            o_l, d_l = rows_of(rays.origins, live), rows_of(rays.dirs, live)
            live = live[self.bvh.any_hit(along(o_l, s, d_l), d_l, far)]
        for step in range(self.max_steps):
            if len(live) == 0:
                break
            self.check()
            live = w.open_rows(self._pass(w, live, step))
        if len(live):  # (not seen: each pass consumes a crossing) every primitive, rather than a wrong answer
            every = np.arange(len(self.prim_index))
            self.pairs.test(best, np.repeat(live, len(every)), np.tile(every, len(live)), w.batch)

    def _begin(self, best: Best, rays: Rays, shadows: Shadows | None) -> Walking:
        """A walk's start (:meth:`walk`): where each ray starts, and the part of a cell holding the origin of a
        ray that leaves a BVH primitive tested already."""
        cells = self.cells
        assert cells is not None  # (made for every walk but a few primitives')
        any_hit = shadows is not None
        o, d = rays.origins, rays.dirs
        batch = self.pairs.batch(rays, shadows, gathered(o, d, rays.mag))
        from_prim = batch.from_prim
        t_in, t_out = slab(o, d, self.box_lo, self.box_hi)
        w = Walking(
            best, shadows, best.t.copy(), batch, t_out, t_in.copy(), np.full(len(o), -2, dtype=np.int64), rays, any_hit
        )
        start = w.start
        inside = np.flatnonzero(from_prim >= 0)
        if len(inside):  # every proxy that contains an origin meets the origin's part of a cell: test them now
            cell, lo, hi = cells.locate(rows_of(o, inside))
            q = from_prim[inside]  # a triangle is never met again by a ray that leaves it; a sphere may be
            # nor, on its way to a light, are a plain triangle's mates
            but = self.pairs.with_mates(np.where(q < self.n_tri, q, -1), np.full(len(q), any_hit))
            self._test_cells(best, inside, cell, but, batch)
            start[inside] = slab(rows_of(o, inside), rows_of(d, inside), lo, hi)[1]
            w.last[inside] = cell
            if not any_hit:  # a hit inside the origin's part is the nearest there is
                settled = np.isfinite(best.t[inside]) & (best.t[inside] <= start[inside])
                start[inside[settled]] = np.inf
        return w

    def _pass(self, w: Walking, live: np.ndarray, step: int) -> np.ndarray:
        """One pass of a walk (:meth:`walk`'s step) for the rays ``live``: the nearest crossing of each, its part
        of a cell tested, the walk moved on past it.  Returns the rays still walking (before
        :meth:`Walking.open_rows`)."""
        p, cells, best, any_hit = self.proxies, self.cells, w.best, w.any_hit
        assert cells is not None
        start, last, limit = w.start, w.last, w.limit
        first = any_hit or self.mates is not None  # test the crossed primitive before the rest of its region
        s = start[live]
        # a plain triangle hit before best.t may be crossed in float32 up to p.slack after it
        far = np.minimum(best.t[live] + p.slack, w.t_out[live]) - s
        o_l, d_l = rows_of(w.rays.origins, live), rows_of(w.rays.dirs, live)
        face, tau = self.bvh.nearest(along(o_l, s, d_l), d_l, far)
        found = np.flatnonzero(face >= 0)
        live, face, tau, s = live[found], face[found], tau[found], s[found]
        o_l, d_l = rows_of(o_l, found), rows_of(d_l, found)
        prim = p.owner[face]
        # after the first pass, the few rays left (grazing a surface, say) step a whole cell at a time
        region, lo, hi = cells.locate(along(o_l, s + tau, d_l), whole=step > 0)
        fresh = last[live] != region
        if first:  # the primitive crossed first: a ray it blocks needs no more
            rows = live[fresh]
            self.pairs.test(best, rows, prim[fresh], w.batch)
            if any_hit:
                fresh[fresh] = ~(best.t[rows] < limit[rows])
        self._test_cells(
            best,
            live[fresh],
            region[fresh],
            self.pairs.done_with(best, live[fresh], prim[fresh], any_hit) if first else None,
            w.batch,
        )
        last[live] = region
        leave = slab(o_l, d_l, lo, hi)[1]
        start[live] = np.fmax(start[live] + tau + p.step, leave)
        if not any_hit:  # a hit before the ray leaves the part is the nearest there is
            settled = np.isfinite(best.t[live]) & (best.t[live] <= leave)
            live = live[~settled]
        return live


@dataclass
class Walking:
    """One walk under way (:meth:`Walk.walk`): its rays and their best hits, and where each ray's walk is."""

    best: Best
    shadows: Shadows | None  # the shadow query the rays are of
    limit: np.ndarray  # (N,) each ray's best hit (or its light) when the walk began
    batch: Batch  # the rays as the exact tests read them: a row each, what each leaves
    t_out: np.ndarray  # (N,) where each ray's line leaves the BVH's box
    start: np.ndarray  # (N,) where each ray's walk goes on from
    last: np.ndarray  # (N,) the part of a cell each ray tested last (rounding may report a part twice)
    rays: Rays
    any_hit: bool  # a shadow walk: any hit before the light will do

    def open_rows(self, rows: np.ndarray) -> np.ndarray:
        """The rays of ``rows`` still walking: not blocked (a shadow ray), and with some way left before their
        best hit (or light) and the BVH box's exit."""
        best, start = self.best, self.start
        if self.any_hit:
            rows = rows[~(best.t[rows] < self.limit[rows])]
        end = np.minimum(best.t[rows], self.t_out[rows])
        return rows[(start[rows] < end) & (end > 0)]
