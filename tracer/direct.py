"""Direct light at hit points: the ambient term, then every light's Phong terms where the light reaches.

A light is one :class:`LightGroup` of emitters (:mod:`tracer.lights`): a
point light, a spot or a directional light is one emitter, an area light its
grid of samples, all of one colour.  For each emitter: L, d and the intensity
factor at every point, shadow rays for the points it may light, and the
weights of the diffuse and the specular term, ``wd = w·(N·L)`` and
``ws = w·max(0, R·V)^n`` (``w`` the factor where the emitter reaches the
point, 0 elsewhere).  A light's weights are summed over its emitters, and its
colour is added once: ``color·(k_d·Σwd + k_s·Σws)``, the contract's sum over
an area light's samples of ``color/(nu·nv)·(k_d·(N·L) + k_s·(R·V)^n)``
gathered into one product per light (the same value to within rounding: a
light of one emitter gets exactly its own term).

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
from functools import partial

import numpy as np

from schemas import AreaLight, Scene

from .bounds import SurfacePoints
from .culling import HIDDEN, MIXED, SEEN, classify, faces_away
from .intersect import MISS, SPHERE, TRIANGLE, Hits, Intersector
from .lights import LIGHT_TYPES, Emitter, area_corners, illuminate
from .passes import BRANCH_PASS, Tally
from .penumbra import Penumbra
from .planner import ProofPlan
from .rays import Among, Rays, Shadows, Work
from .shading import add_phong, light_in_plane, phong, planes_holding
from .tiles import TILE, lit_tiles
from .variants import Options, Spawn, add_clamped
from .vec import columns, dot, rows_of, scaled
from .world import World, max_abs, unit


@dataclass(frozen=True)
class LightGroup:
    """One light of the scene as the emitters ``first..end − 1`` it became (all of one colour)."""

    light: int  # its index in ``scene.lights``
    first: int
    end: int
    #: an area light's parallelogram: its four local corners, in order round it; None for the other lights
    corners: np.ndarray | None = None


def light_groups(scene: Scene, origin: np.ndarray) -> list[LightGroup]:
    """The scene's lights that emit (every type but ambient), in order, with their emitters' span."""
    groups, first = [], 0
    for k, light in enumerate(scene.lights):
        count = LIGHT_TYPES[type(light)].count(light)
        if count:
            corners = area_corners(light, origin) if isinstance(light, AreaLight) else None
            groups.append(LightGroup(k, first, first + count, corners))
        first += count
    return groups


@dataclass
class Points:
    """The hit points being shaded, with what every light's terms read: the facing shading ``normal``, the
    rays' ``dirs``, N·V and the points' world magnitudes (where their shadow rays start), each per point."""

    hit: Hits
    normal: np.ndarray  # (N, 3), columns contiguous
    dirs: np.ndarray  # (N, 3)
    nv: np.ndarray  # (N,) N·V with V = −D
    mag: np.ndarray  # (N,)
    shininess: np.ndarray  # (N,)

    def take(self, rows: np.ndarray) -> Points:
        return Points(self.hit.take(rows), rows_of(self.normal, rows), rows_of(self.dirs, rows), self.nv[rows],
                      self.mag[rows], self.shininess[rows])


#: a light's terms at the points: Σwd, Σws and, when asked for, how many emitters reach each point and face it
Terms = tuple[np.ndarray, np.ndarray, np.ndarray | None]


class DirectLight:
    """The direct-light stage of a renderer: :meth:`shade` gives the colour of hit points."""

    def __init__(self, world: World, options: Options, intersector: Intersector, groups: list[LightGroup],
                 plan: ProofPlan, stop: Callable[[], None], count: Callable[[str, int], None]):
        self.world, self.options, self.intersector, self.groups = world, options, intersector, groups
        #: which proofs spare which shadow rays (:mod:`tracer.planner`)
        self.plan = plan
        self.stop, self.count = stop, count
        #: the emitters some flat surface's plane holds (where N·L is rounding noise: light_in_plane)
        self.holds = planes_holding(world, world.emitters)
        #: where shadow rays start, off the surface in a variant of a student's offset (None: at the hit point)
        self.spawn: Spawn | None = None

    def shade(self, hit: Hits, mat: np.ndarray, normal: np.ndarray, dirs: np.ndarray, tally: Tally | None = None,
              work: Work | None = None) -> np.ndarray:
        """Ambient plus every light's Phong term where the light reaches the hit points. Shape (N, 3).

        With a ``tally`` (and the ``work`` the hits came from), the terms go to their passes too.
        """
        m, opt = self.world.materials, self.options
        # (N, 3) arrays whose columns are contiguous, each gathered a column at a time: every light adds to them
        # a column at a time (add_phong)
        colour, diffuse, specular = columns(len(mat)), columns(len(mat)), columns(len(mat))
        for k in range(3):
            np.take(m.ambient[:, k], mat, out=colour[:, k])
            colour[:, k] *= self.world.ambient[k]
            np.take(m.diffuse[:, k], mat, out=diffuse[:, k])
            np.take(m.specular[:, k], mat, out=specular[:, k])
        if not opt.ambient:
            colour = np.zeros_like(colour)
        if not opt.specular:
            specular = np.zeros_like(specular)
        first = tally is not None and work is not None and work.depth == 0
        if first:
            assert tally is not None and work is not None
            tally.add("ambient", work.sample, scaled(colour, work.weight))
        # N·V, the same for every light; the magnitudes where every light's shadow rays start
        at = Points(hit, normal, dirs, -dot(normal, dirs), max_abs(hit.point) + self.world.origin_mag,
                    m.shininess[mat])
        for group in self.groups:
            self.stop()  # a long chunk (many lights) stops early too
            color = self.world.emitters[group.first].color
            if not np.any(color > 0):
                continue
            counted = first and tally is not None and tally.counts(group.first)
            visible = counted and tally is not None and tally.visible is not None
            if group.corners is not None:
                terms = self._area(group, at, visible)
            else:
                terms = self._one(group.first, at, visible)
            if terms is None:
                continue
            wd, ws, reached = terms
            (add_clamped if opt.clamp_terms else add_phong)(colour, color, diffuse, specular, wd, ws)
            if counted:
                assert tally is not None and work is not None
                tally.add(tally.term("diffuse", group.first), work.sample,
                          scaled(color * scaled(diffuse, wd), work.weight))
                tally.add(tally.term("specular", group.first), work.sample,
                          scaled(color * scaled(specular, ws), work.weight))
                if reached is not None:
                    assert tally.visible is not None
                    np.add.at(tally.visible, work.sample, reached)
        if tally is not None and work is not None and work.branch is not None and work.depth > 0:
            for branch, name in BRANCH_PASS.items():
                sel = np.flatnonzero(work.branch == branch)
                if name is not None and len(sel):
                    tally.add(name, work.sample[sel], scaled(colour[sel], work.weight[sel]))
        return colour

    # -- one emitter: a point light, a spot or a directional light ----------------------------------------------
    def _one(self, e_index: int, at: Points, visible: bool) -> Terms | None:
        """The terms of a light of one emitter (``e_index``) at every point, or None where it reaches none."""
        opt, hit, em = self.options, at.hit, self.world.emitters[e_index]
        to_light, dist, factor = illuminate(em, hit.point)
        nl = dot(at.normal, to_light)
        if self.holds[e_index]:
            nl = light_in_plane(self.world, hit, em, nl, dist)
        facing = nl > 0
        lit = (facing | opt.specular_behind) & (factor > 0)
        weight = np.where(lit, factor, 0.0)
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
            clear = np.repeat(lit_tiles(bounds, SurfacePoints(sub.point, sub.kind, sub.index, normal),
                                        None if em.kind == "directional" else em.position,
                                        em.direction if em.kind == "directional" else None), TILE)[:len(sub.t)]
            rows = rows[~clear] if few else np.flatnonzero(lit & ~clear)
        every = len(rows) == len(nl)  # then no gathering: the rows are all of them, in order

        def pick(a: np.ndarray) -> np.ndarray:
            return a if every else rows_of(a, rows)

        if len(rows):
            self.count("shadow", len(rows))
            blocked = self.blocked(hit, pick, to_light, dist, em, at.mag, at.normal, len(rows))
            weight[rows[blocked]] = 0.0
        wd, ws = phong(at.shininess, np.maximum(nl, 0.0) if opt.specular_behind else nl,
                       self._rv(at.normal, nl, at.nv, to_light, at.dirs), weight)
        return wd, ws, ((weight > 0) & facing) if visible else None

    def _rv(self, normal: np.ndarray, nl: np.ndarray, nv: np.ndarray, to_light: np.ndarray,
            dirs: np.ndarray) -> np.ndarray:
        """R·V with R = 2(N·L)N − L and V = −D, or N·H with H = unit(L + V) for Blinn–Phong (a variant)."""
        if self.options.blinn:
            return dot(normal, unit(to_light - dirs))
        return 2.0 * nl * nv + dot(to_light, dirs)

    # -- an area light: its samples, with the culling's proofs -------------------------------------------------
    def _area(self, group: LightGroup, at: Points, visible: bool) -> Terms | None:
        """An area light's terms at every point, summed over its samples, or None where it reaches none.

        **Points no sample can light are not shaded.**  A point proven HIDDEN (:mod:`tracer.culling`) gets
        weight 0 from every sample, and so does a point whose normal faces away from all four corners by more
        than rounding (N·(S − P) is linear in the sample S, so it is negative over the whole parallelogram,
        and N·L ≤ 0 at every sample; not so for the variant that lights a point from behind).  Weight 0 at
        finite N·L (finite points, normals and distances: asked for) makes both terms 0, which is what such a
        point is given.

        **A point that sees every sample casts no shadow ray** (SEEN), and **a mixed point's shadow rays meet
        only the bounds that may block it** (``may_block``, the proof in :mod:`tracer.culling`): the walk is
        replaced by the exact tests of those surfaces (:meth:`tracer.intersect.Intersector.occluded`,
        ``among``), which decide the same.  Without bounds (too many surfaces, or a variant's shadow rays)
        every point is mixed and casts every ray.

        The points shaded are taken once, those that see every sample first, and each sample's terms are
        computed into buffers of theirs (the same operations as :meth:`_one` makes per emitter, and
        the same shadow rays)."""
        opt, hit, corners = self.options, at.hit, group.corners
        assert corners is not None
        n = len(hit.t)
        if n == 0:
            return None
        bounds = self.plan.light_bounds
        if bounds is not None:
            culled = classify(bounds, SurfacePoints(hit.point, hit.kind, hit.index, at.normal), corners)
            state, may_block = culled.state, culled.may_block
            idle = state == HIDDEN
        else:
            state, may_block, idle = np.full(n, MIXED, dtype=np.int8), None, np.zeros(n, dtype=bool)
        if self.plan.facing:
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
            penumbra = Penumbra(bounds, mixed, may_block[:, mixed_rows], corners, self.plan.facing)
        point = sub.hit.point
        # this light's buffers, each computed into in place: L, d, N·L, R·V, the specular power, the weight
        to_light, dist, tmp, nl_buf, rv, spec, weight = columns(m), *(np.empty(m) for _ in range(6))
        facing, pos = np.empty(m, dtype=bool), np.empty(m, dtype=bool)
        normal, dirs = np.asfortranarray(sub.normal), np.asfortranarray(sub.dirs)  # (read a column at a time)
        nv2 = 2.0 * sub.nv  # (2·(N·L)·(N·V) as 2.0 * nl * nv makes it: doubling is exact)
        sum_d, sum_s = np.zeros(m), np.zeros(m)
        reached = np.zeros(m, dtype=np.int64) if visible else None
        holds = self.holds[group.first:group.end]
        for e, em in enumerate(self.world.emitters[group.first:group.end]):
            self.stop()
            # L, d and the factor, as illuminate() computes them
            for k in range(3):
                np.subtract(em.position[k], point[:, k], out=to_light[:, k])
            _dot_into(dist, to_light, to_light, tmp)
            np.sqrt(dist, out=dist)
            factor = _factor(em, dist, tmp)
            for k in range(3):
                to_light[:, k] /= tmp
            nl = light_in_plane(self.world, sub.hit, em, _dot_into(nl_buf, normal, to_light, tmp), dist) \
                if holds[e] else _dot_into(nl_buf, normal, to_light, tmp)
            np.greater(nl, 0.0, out=facing)
            if opt.specular_behind:
                lit = np.asarray(factor > 0) & np.ones(m, dtype=bool)
            else:
                lit = facing if isinstance(factor, float) and factor > 0 else facing & (factor > 0)
            if isinstance(factor, float):
                np.multiply(lit, factor, out=weight)  # (factor or 0: np.where(lit, factor, 0.0))
            else:
                np.copyto(weight, np.where(lit, factor, 0.0))
            rows = ns + np.flatnonzero(lit[ns:])  # the mixed points' shadow rays; the seen points see it
            if len(rows) and penumbra is not None:  # rays decided by their pairs, the rest cast against theirs
                blocked, cast, pairs = penumbra.decide(lit[ns:], to_light[ns:], dist[ns:])
                if cast.any():
                    self.count("shadow", int(np.count_nonzero(cast)))
                    blocked[cast] = self.blocked(sub.hit, partial(rows_of, index=rows[cast]), to_light, dist, em,
                                                 sub.mag, sub.normal, int(np.count_nonzero(cast)), pairs)
                weight[rows[blocked]] = 0.0
            elif len(rows):
                self.count("shadow", len(rows))
                blocked = self.blocked(sub.hit, partial(rows_of, index=rows), to_light, dist, em, sub.mag,
                                       sub.normal, len(rows))
                weight[rows[blocked]] = 0.0
            # phong(), into the buffers: the same operations on the same numbers
            if opt.blinn:
                np.copyto(rv, self._rv(normal, nl, sub.nv, to_light, dirs))
            else:  # R·V = 2·(N·L)·(N·V) + L·D
                _dot_into(rv, to_light, dirs, tmp)
                np.multiply(nl, nv2, out=tmp)
                rv += tmp
            np.greater(rv, 0.0, out=pos)
            np.copyto(rv, 1.0, where=~pos)
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                np.power(rv, sub.shininess, out=spec)
            spec *= pos  # (where R·V ≤ 0 the power of 1, times 0)
            np.multiply(weight, np.maximum(nl, 0.0) if opt.specular_behind else nl, out=tmp)
            sum_d += tmp
            np.multiply(weight, spec, out=tmp)
            sum_s += tmp
            if reached is not None:
                reached += (weight > 0) & facing
        if every:
            return sum_d, sum_s, reached
        out_d, out_s = np.zeros(n), np.zeros(n)
        out_d[active], out_s[active] = sum_d, sum_s
        out_r = None
        if reached is not None:
            out_r = np.zeros(n, dtype=np.int64)
            out_r[active] = reached
        return out_d, out_s, out_r

    # -- shadow rays -------------------------------------------------------------------------------------------
    def blocked(self, hit: Hits, pick: Callable[[np.ndarray], np.ndarray], to_light: np.ndarray, dist: np.ndarray,
                em: Emitter, mag_points: np.ndarray, normal: np.ndarray, n: int,
                among: Among | None = None) -> np.ndarray:
        """Whether a shadow ray from each picked hit point to the light ``em`` is blocked. Shape (n,).  With
        ``among``, the proof that only those pairs of rays and surfaces can block
        (:meth:`tracer.intersect.Intersector.occluded`); without, rays to a point light or along a directional
        light's direction take theirs from :mod:`tracer.cones` when the scene has few enough surfaces."""
        opt = self.options
        if not opt.shadows:
            return np.zeros(n, dtype=bool)
        shadow_dirs = np.ascontiguousarray(pick(to_light))
        # from the exact hit point, leaving its surface by identity, to the light itself
        rays = Rays(pick(hit.point), shadow_dirs, pick(hit.kind), pick(hit.index), pick(mag_points))
        if self.spawn is not None:  # a student's offset: off the surface
            rays = self.spawn.leaving(rays, pick(hit.normal))
        if opt.acne:  # a student's shadow ray: its surface not left, half the points a hair below it
            below = np.ones(n, dtype=bool) if opt.acne_everywhere else \
                ((pick(hit.point).view(np.int64)[:, 0] >> 20) & 1).astype(bool)
            lowered = rays.origins - scaled(pick(normal), below * rays.mag * 2.0**-30)
            rays = Rays(lowered, shadow_dirs, np.full(n, MISS, dtype=np.int8), np.full(n, -1), rays.mag)
        if em.kind == "directional":
            shadows = Shadows(rays, np.full(n, np.inf), None, None)
        else:
            mag_light = max_abs(em.position[None]) + self.world.origin_mag
            shadows = Shadows(rays, pick(dist), em.position[None], mag_light)  # one light for every ray
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


def _dot_into(out: np.ndarray, a: np.ndarray, b: np.ndarray, tmp: np.ndarray) -> np.ndarray:
    """``a·b`` per row of two ``(N, 3)`` arrays into ``out``, summed in the order x, y, z (as
    :func:`tracer.vec.dot`), with ``tmp`` as scratch. Returns ``out``."""
    np.multiply(a[:, 0], b[:, 0], out=out)
    for k in (1, 2):
        np.multiply(a[:, k], b[:, k], out=tmp)
        out += tmp
    return out


def _factor(em: Emitter, dist: np.ndarray, safe: np.ndarray) -> np.ndarray | float:
    """An emitter's intensity factor at distances ``dist``, as :func:`tracer.lights.illuminate` gives it (a
    point or area light: no cone), and the distances to divide ``L`` by into ``safe`` (1 where d = 0)."""
    np.copyto(safe, dist)
    shortest = float(dist.min(initial=np.inf))
    if not shortest > 0:
        safe[~(dist > 0)] = 1.0
    c, lin, q = em.attenuation
    if lin == 0 and q == 0:  # c + 0·d + (0·d)·d is c wherever d is finite (at d = ∞, NaN: no light)
        if shortest > 0 and float(dist.max(initial=0.0)) < np.inf:
            return 1.0 / c if c > 0 else 0.0
        return np.where((dist > 0) & (dist < np.inf), 1.0 / c if c > 0 else 0.0, 0.0)
    denom = c + lin * dist + q * dist * dist
    return np.where((dist > 0) & (denom > 0), 1.0 / np.where(denom > 0, denom, 1.0), 0.0)

