"""Area lights by proof: points that see every sample, or none, cast no shadow rays.

An area light's samples all lie in its parallelogram Q, so every shadow
segment from a point P lies in the pyramid with apex P over Q (the convex
hull of P and Q's corners).  For each point, :func:`classify` decides, from
the surfaces' bounds alone and with margins far above float64 rounding:

* **seen**: every surface's bound lies strictly outside one of the pyramid's
  five face planes (a plane: P and Q strictly on one side of it), so no
  surface meets any segment, and every sample is visible;
* **hidden**: some sphere covers Q as seen from P (every corner of Q lies
  strictly inside the sphere's cone from P, which is convex) and lies strictly
  between P and Q's plane, so every ray from P to Q enters it before it
  reaches the light: every sample is blocked;
* **mixed**: anything else (penumbrae, points near a surface), where the
  renderer casts every sample's ray.

A mixed point's rays need not meet every surface either: a bound that lies
strictly outside one of the point's five face planes meets none of its
segments, by the argument that proves a point seen, bound by bound.
``may_block`` keeps, per point, the bounds that no face plane separates, and
the shadow rays of a mixed point are tested against those surfaces alone
(:meth:`tracer.intersect.Intersector.occluded`, ``among``), with the same
exact tests, so the answer is the same.

The surface a point lies on is never its own blocker for the samples it faces
(leaving by identity), except a sphere seen from inside, which makes the point
mixed.  The decisions the proofs stand for are those the exact per-sample test
makes, far from its rounding, so the image keeps its bytes.  Scenes with more
than :data:`MAX_BOUNDS` surfaces skip the proofs (every point mixed).

**Precision, construction by construction.**  Every test compares a computed
number with a threshold grown by :data:`MARGIN` (2^-30) of the magnitudes
involved, or a cosine with a slack of at least MARGIN; each number's own error
stays under a quarter of that at every scale and every ratio of sizes:

* a face or Q's plane (:func:`face_normal`): a long vector crossed with a short
  exact one, never two long ones, so its direction errs by at most
  NORMAL_ERROR (2^-33) whatever the ratio of Q's edges to its distance, or the
  face is declined; a distance to it then errs by at most 2^-32 of the
  magnitudes (:func:`_faces`);
* a point's side of a plane, ``(P − q)·n``: one rounded difference per
  component and a dot product, a few 2^-53 of ``|P − q|``;
* the hidden test's cosines (:func:`_hidden`) and the penumbra's
  (:class:`Penumbra`): dot products of rounded differences over their
  lengths, absolute errors of a few 2^-53 against slacks of 2^-30 and more;
  cosines near 1 (a thin light far away) only lose proofs, never make one;
* a tile's ball (:func:`_tiles_of`): its centre ``(lo + hi)/2`` errs by 2^-53
  of the coordinates' magnitude, absolute, which the margin (of the same
  magnitudes) covers even where the ball's radius is far smaller;
* a bound's distance from a segment or a ray (:func:`lit_tiles`): the nearest
  point's parameter and the offset across it err by a few 2^-53 of
  ``|centre − C|``, absolute, not of the distance itself: within the margin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rays import Among
from .shapes import PLANE, SPHERE, TRIANGLE
from .vec import dot, most, rows_of
from .world import World

SEEN, HIDDEN, MIXED = 0, 1, 2
#: consecutive points proven SEEN at once (:func:`classify`): neighbours on the image lie close together.
#: Measured at 320×240: tiles of 16 points prove 53k of the soft-shadow example's 65k seen points (and 59k of
#: 72k in the all-lights example) in 3 ms, where the per-point proofs take 37 ms for all; tiles of 64 prove
#: 17k and 31k (a row's 64 pixels reach far), of 8 no more for their cost
TILE = 16
#: the most surface bounds a scene may have for the proofs to be worth their cost per point
MAX_BOUNDS = 64
#: a proof's margin, relative to the magnitudes involved: far above the exact tests' float64 rounding
MARGIN = 2.0**-30
#: how far a face's unit normal (:func:`face_normal`) may turn from the true face's and still serve a proof: the
#: error it brings to a separation, at most (NORMAL_ERROR + 2^-50)·√3 of the magnitudes, is under a quarter of
#: :data:`MARGIN` (:func:`_faces`)
NORMAL_ERROR = 2.0**-33


@dataclass(frozen=True)
class Bounds:
    """Every surface of a world as a bound: spheres (spheres, and triangles' enclosing spheres) and planes."""

    center: np.ndarray  # (K, 3) local
    radius: np.ndarray  # (K,)
    kind: np.ndarray  # (K,) SPHERE or TRIANGLE
    index: np.ndarray  # (K,) index within its kind
    solid: np.ndarray  # (K,) bool: a real sphere (its bound is itself), which can prove a point hidden
    plane_point: np.ndarray  # (Q, 3)
    plane_normal: np.ndarray  # (Q, 3)


def bounds_of(world: World) -> Bounds | None:
    """The world's surfaces as bounds, or None when there are more than :data:`MAX_BOUNDS` of them."""
    sp, tr, pl = world.spheres, world.triangles, world.planes
    if len(sp.radius) + len(tr.v0) + len(pl.normal) > MAX_BOUNDS:
        return None
    corners = np.stack([tr.v0, tr.v0 + tr.e1, tr.v0 + tr.e2], axis=1)  # (T, 3, 3)
    mid = corners.mean(axis=1) if len(tr.v0) else np.zeros((0, 3))
    reach = np.sqrt(most(np.sum((corners - mid[:, None]) ** 2, axis=2))) if len(tr.v0) else np.zeros(0)
    return Bounds(center=np.concatenate([sp.center, mid]), radius=np.concatenate([sp.radius, reach * (1 + 2.0**-20)]),
                  kind=np.concatenate([np.full(len(sp.radius), SPHERE), np.full(len(tr.v0), TRIANGLE)]),
                  index=np.concatenate([np.arange(len(sp.radius)), np.arange(len(tr.v0))]),
                  solid=np.concatenate([np.ones(len(sp.radius), bool), np.zeros(len(tr.v0), bool)]),
                  plane_point=pl.point, plane_normal=pl.normal)


@dataclass(frozen=True)
class Culled:
    """What :func:`classify` proved of N points and one area light."""

    state: np.ndarray  # (N,) int8: SEEN, HIDDEN or MIXED
    #: (K, N) bool: the bounds that may block some sample of each point (every other bound lies strictly outside
    #: one of the point's pyramid's faces, so its surface meets none of its shadow segments)
    may_block: np.ndarray


def classify(b: Bounds, points: np.ndarray, kind: np.ndarray, index: np.ndarray, outward: np.ndarray,
             corners: np.ndarray) -> Culled:
    """SEEN, HIDDEN or MIXED for each of ``points (N, 3)`` (on the surfaces ``kind, index``, whose normal
    ``outward`` faces the samples a point can be lit by) and the light's parallelogram ``corners (4, 3)``,
    in order round it, with the bounds that may block each point's samples (of the points SEEN, none).

    The points go a tile at a time first (:data:`TILE` consecutive points, neighbours on the image): a tile
    proven to see every sample (:func:`_seen_tiles`) is SEEN whole, and only the others' points are
    classified one by one.  A point of a SEEN tile sees every sample whatever the per-point proof would have
    made of it, so its shading is the same."""
    n = len(points)
    if not np.all(np.isfinite(_q_normal(corners))):  # Q's plane not known well enough: no proof at all
        return Culled(np.full(n, MIXED, dtype=np.int8), np.ones((len(b.radius), n), dtype=bool))
    if n >= 4 * TILE:
        seen = np.repeat(_seen_tiles(b, points, kind, index, outward, corners), TILE)[:n]
        if seen.any():
            rest = np.flatnonzero(~seen)
            state = np.full(n, SEEN, dtype=np.int8)
            may_block = np.zeros((len(b.radius), n), dtype=bool)
            if len(rest):
                part = _classify(b, rows_of(points, rest), kind[rest], index[rest], rows_of(outward, rest), corners)
                state[rest] = part.state
                may_block[:, rest] = part.may_block
            return Culled(state, may_block)
    return _classify(b, points, kind, index, outward, corners)


def _inside_spheres(b: Bounds, points: np.ndarray, kind: np.ndarray, index: np.ndarray, outward: np.ndarray,
                    candidate: np.ndarray) -> np.ndarray:
    """The points on a sphere whose ``outward`` normal faces its inside (a sphere seen from inside it), among
    those of the ``candidate`` tiles (T,): rows, ascending.  A column at a time."""
    on_sphere = np.flatnonzero((kind == SPHERE) & np.repeat(candidate, TILE)[:len(kind)])
    if len(on_sphere) == 0:
        return on_sphere
    which = np.searchsorted(np.flatnonzero(b.kind == SPHERE), index[on_sphere])
    facing = np.zeros(len(on_sphere))
    for k in range(3):  # N·(P − c), summed x, y, z
        offset = np.take(points[:, k], on_sphere) - np.take(b.center[:, k], which)
        facing += np.take(outward[:, k], on_sphere) * offset
    return on_sphere[facing < 0]


def _seen_tiles(b: Bounds, points: np.ndarray, kind: np.ndarray, index: np.ndarray, outward: np.ndarray,
                corners: np.ndarray) -> np.ndarray:
    """Which tiles of :data:`TILE` consecutive points see every sample. Shape (T,), bool.

    **Proof.**  A tile's points lie in the ball B about the centre C of their box, of radius R (half its
    diagonal, rounded up).  Every shadow segment from a point P of B to a point of the parallelogram Q lies in
    the hull of B and Q, and that hull lies within R of the pyramid with apex C over Q (a point
    λ(C + Ru) + (1 − λ)q is λRu from λC + (1 − λ)q); so on the outer side of each of that pyramid's face
    planes pushed out by R.  A bound farther than its radius plus R (and the margin) beyond one of those
    planes meets no segment of any point of the tile: the module's test for a point, from C, with every
    reach grown by R.  A plane with B and Q strictly on one side of it, by more than R for B, blocks none.
    The own-surface rule holds for a tile whose points all lie on one surface; a tile near Q's plane, with
    points on a sphere seen from inside it, or with numbers beyond proof is left to the per-point tests."""
    centre, reach_t, scale, one, tile_kind, tile_index = _tiles_of(points, kind, index)
    scale = scale + float(np.max(np.abs(corners)))
    margin_of = MARGIN * scale  # (at least every point's own margin)
    bound_part = MARGIN * (np.max(np.abs(b.center), axis=1, initial=0.0) + b.radius)
    q_normal = _q_normal(corners)
    with np.errstate(all="ignore"):
        apex_side = _plane_dot(centre, corners[0], q_normal)
        seen = np.abs(apex_side) > margin_of * 16 + reach_t  # every point of the ball off Q's plane
        seen &= np.isfinite(scale) & np.isfinite(reach_t)
        side = np.sign(apex_side)
        faces = _faces(centre, corners)
        for k in range(len(b.radius)):
            ck = b.center[k]
            reach = margin_of + (float(b.radius[k]) + bound_part[k]) + reach_t
            sep = -side * float((ck - corners[0]) @ q_normal) > reach
            for f, pf in faces:
                sep |= (ck[0] * f[0] + ck[1] * f[1] + ck[2] * f[2]) - pf > reach
            seen &= sep | (one & (b.kind[k] == tile_kind) & (b.index[k] == tile_index))
        for j, (p0, nrm) in enumerate(zip(b.plane_point, b.plane_normal)):
            q_side = (corners - p0) @ nrm
            m = MARGIN * (scale + float(np.max(np.abs(p0))))
            c_side = _plane_dot(centre, p0, nrm)
            mine = one & (tile_kind == PLANE) & (tile_index == j)
            if np.all(q_side > 0) or np.all(q_side < 0):
                same = (np.sign(c_side) == np.sign(q_side[0])) & (np.abs(c_side) > m + reach_t) & \
                    (m < float(np.min(np.abs(q_side))))
            else:
                same = np.zeros(len(c_side), dtype=bool)
            seen &= same | mine
        # a tile with points on a sphere seen from inside it: left to the per-point tests
        seen[_inside_spheres(b, points, kind, index, outward, seen) // TILE] = False
    return seen  # (NaN compares False above: no proof)


def _classify(b: Bounds, points: np.ndarray, kind: np.ndarray, index: np.ndarray, outward: np.ndarray,
              corners: np.ndarray) -> Culled:
    """:func:`classify`, a point at a time.

    Computed a bound at a time on the points' contiguous columns (``(N,)`` arrays, no ``(N, K)`` or
    ``(N, K, 3)`` temporaries): the same tests as the docstring of this module states, whose margins are far
    above the rounding of any order of the sums."""
    n = len(points)
    p = np.ascontiguousarray(points.T)  # (3, N): x, y and z, each contiguous
    scale = np.maximum(np.maximum(np.abs(p[0]), np.abs(p[1])), np.abs(p[2])) + float(np.max(np.abs(corners)))
    # the margin of bound k at a point: MARGIN·(scale + |centre_k| + r_k), the part of bound k a constant
    margin_of = MARGIN * scale
    bound_part = MARGIN * (np.max(np.abs(b.center), axis=1, initial=0.0) + b.radius)
    q_normal = _q_normal(corners)
    apex_side = _plane_dot(p, corners[0], q_normal)  # (N,)
    flat = np.abs(apex_side) <= margin_of * 16  # a point in Q's plane: no pyramid to speak of
    side = np.sign(apex_side)
    faces = _faces(p, corners)  # (and Q's own plane)
    K = len(b.radius)
    may_block = np.ones((K, n), dtype=bool)
    seen = ~flat
    for k in range(K):
        ck, rk = b.center[k], float(b.radius[k])
        reach = margin_of + (rk + bound_part[k])  # r_k + margin: the distance that separates
        # beyond Q's plane, away from the point
        sep = -side * float((ck - corners[0]) @ q_normal) > reach
        for f, pf in faces:
            sep |= (ck[0] * f[0] + ck[1] * f[1] + ck[2] * f[2]) - pf > reach
        np.logical_not(sep, out=may_block[k])
        # (the own surface faced by the samples is handled below)
        seen &= sep | ((b.kind[k] == kind) & (b.index[k] == index))
    if len(b.plane_normal):  # a plane blocks no segment when P and Q lie strictly on one side of it
        for j, (p0, nrm) in enumerate(zip(b.plane_point, b.plane_normal)):
            q_side = (corners - p0) @ nrm
            m = MARGIN * (scale + float(np.max(np.abs(p0))))
            p_side = _plane_dot(p, p0, nrm)
            mine = (kind == PLANE) & (index == j)  # a point on this very plane, which it leaves
            if np.all(q_side > 0) or np.all(q_side < 0):
                same = (np.sign(p_side) == np.sign(q_side[0])) & (np.abs(p_side) > m) & \
                    (m < float(np.min(np.abs(q_side))))
            else:
                same = np.zeros(n, dtype=bool)
            seen &= same | mine
    hidden = _hidden(b, p, kind, index, corners, q_normal, side, margin_of, bound_part) & ~flat
    # a sphere a point lies on blocks the samples it faces only when seen from inside
    on_sphere = kind == SPHERE
    if on_sphere.any():
        rows = np.flatnonzero(on_sphere)
        centre_of = b.center[np.searchsorted(np.flatnonzero(b.kind == SPHERE), index[rows])]
        inside = dot(outward[rows], points[rows] - centre_of) < 0
        seen[rows[inside]] = False
        hidden[rows[inside]] = False
    out = np.full(n, MIXED, dtype=np.int8)
    out[seen] = SEEN
    out[hidden & ~seen] = HIDDEN
    may_block[:, flat] = True  # (no pyramid to speak of: every bound may block)
    return Culled(out, may_block)


def _faces(p: np.ndarray, corners: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The side faces of the pyramids with apexes ``p (3, N)`` over the parallelogram ``corners (4, 3)``: four
    planes through an apex and an edge of Q, each as its unit normal ``(3, N)`` turned so that the pyramid lies
    on its negative side, and the apex's offset along it ``(N,)``.

    Each normal is :func:`face_normal` of the apex-to-corner vector and the edge itself (never the cross product
    of two apex-to-corner vectors, whose direction is good only to about 2^-52·D/e for a light at distance D
    with edges e: too little for a thin light far away).  Its direction is within :data:`NORMAL_ERROR` of the
    true face's, or it is NaN.  It is turned by the side of the far corner, ``(far − a)·n``, a short vector
    dotted with it: trusted only where that exceeds ``2·NORMAL_ERROR·|far − a|`` (the normal's error and the
    product's rounding), NaN otherwise.  A NaN face separates no bound.

    **What a proof may take from a face.**  For a bound centre ``c``, ``n̂·(c − P)`` (computed as
    ``n̂·c − n̂·P``) lies within ``(NORMAL_ERROR + 2^-50)·|c − P| + 2^-50·(|c| + |P|)`` of the true face's
    ``n·(c − P)``, and ``|c − P| ≤ √3·(max|c| + max|P|)``: under 2^-32 of the magnitudes, a quarter of the
    module's :data:`MARGIN`, which every separation test adds (``MARGIN`` of the apex's, the corners' and the
    bound's magnitudes).  So a bound found beyond a face by its radius plus the margin is beyond the true face
    by its radius, at every ratio of edge to distance and at every scale."""
    faces = []
    for k in range(4):
        a, c, far = corners[k], corners[(k + 1) % 4], corners[(k + 2) % 4]
        f = face_normal((a[0] - p[0], a[1] - p[1], a[2] - p[2]), c - a)
        across = far - a  # (3,): the far corner from the edge's start, short and exact to rounding
        with np.errstate(invalid="ignore"):
            inner = across[0] * f[0] + across[1] * f[1] + across[2] * f[2]
            known = np.abs(inner) > 2.0 * NORMAL_ERROR * float(np.sqrt(across @ across))
            turn = np.where(known, -np.sign(inner), np.nan)  # outward: the far corner on the negative side
        normal = np.stack([f[0] * turn, f[1] * turn, f[2] * turn])
        faces.append((normal, normal[0] * p[0] + normal[1] * p[1] + normal[2] * p[2]))
    return faces


Vector = tuple[np.ndarray, np.ndarray, np.ndarray] | np.ndarray


def face_normal(u: Vector, e: Vector) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unit normal ``u × e / |u × e|`` of the plane through a point and a segment, from ``u`` (the segment's
    start less the point) and ``e`` (the segment's end less its start), each by its three components (arrays
    that broadcast, or a 3-vector), each component one rounded subtraction of stored numbers (or exact); NaN
    where its direction is not known within :data:`NORMAL_ERROR`.

    **Bound.**  Each rounded component is the true one times (1 + α), |α| ≤ μ = 2^-53.  A component
    ``u_i e_j − u_j e_i`` of the product then errs by at most γ₄·(|u_i e_j| + |u_j e_i|) (γ₄ = 4μ/(1 − 4μ): the
    two inputs' roundings, the product's and the difference's), so the vector by at most √2·γ₄·|u||e|, and its
    unit vector by at most twice that over |u × e|: 11.4μ·|u||e|/|u × e|.  With the lengths' own roundings
    (a few μ each) this is below 16μ·|u||e|/|n̂| as computed, which is kept at most NORMAL_ERROR; the division
    adds 2^-50 at most.  The error is large only where ``u`` lies almost along ``e`` (the point nearly in line
    with the segment), never because ``u`` is long: a point far from a short segment keeps its digits."""
    e0, e1, e2 = e[0], e[1], e[2]
    n0, n1, n2 = u[1] * e2 - u[2] * e1, u[2] * e0 - u[0] * e2, u[0] * e1 - u[1] * e0
    with np.errstate(all="ignore"):
        length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        reach = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) * np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        known = length * NORMAL_ERROR >= 2.0**-49 * reach
        inverse = np.where(known & (length > 0), 1.0 / length, np.nan)
    return n0 * inverse, n1 * inverse, n2 * inverse


def _q_normal(corners: np.ndarray) -> np.ndarray:
    """The unit normal of the parallelogram ``corners (4, 3)``, :func:`face_normal` of its two edges from
    ``corners[0]``: within :data:`NORMAL_ERROR` of the true one (the edges are short vectors, exact to
    rounding), or NaN where the edges are too nearly parallel for that.  Its error in ``(c − q)·n`` for a point
    ``c`` is at most (NORMAL_ERROR + 2^-50)·|c − q|, under a quarter of the margin, as for the faces."""
    u = corners[1] - corners[0]
    return np.array(face_normal((u[0], u[1], u[2]), corners[3] - corners[0]), dtype=np.float64)


def _plane_dot(p: np.ndarray, point: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``(P − point)·normal`` for the points ``p (3, N)``. Shape (N,)."""
    return (p[0] - point[0]) * normal[0] + (p[1] - point[1]) * normal[1] + (p[2] - point[2]) * normal[2]


def _hidden(b: Bounds, p: np.ndarray, kind: np.ndarray, index: np.ndarray, corners: np.ndarray,
            q_normal: np.ndarray, side: np.ndarray, margin_of: np.ndarray, bound_part: np.ndarray) -> np.ndarray:
    """Points ``p (3, N)`` some solid sphere hides the whole parallelogram from. Shape (N,), bool.

    A sphere hides it when the point lies outside it, on the point's side of Q's plane beyond it, and every
    corner lies strictly inside its cone from the point: ``cos(corner) > cos(cone)``, compared as
    ``(C − P)·(q − P) > cos(cone)·|C − P|·|q − P|`` (both lengths positive), with no division."""
    hidden = np.zeros(p.shape[1], dtype=bool)
    solid = np.flatnonzero(b.solid)
    if len(solid) == 0:
        return hidden
    to_q = [(q[0] - p[0], q[1] - p[1], q[2] - p[2]) for q in corners]
    length_q = [np.sqrt(x * x + y * y + z * z) for x, y, z in to_q]
    for k in solid.tolist():
        c, r = b.center[k], float(b.radius[k])
        reach = margin_of + (r + bound_part[k])
        tx, ty, tz = c[0] - p[0], c[1] - p[1], c[2] - p[2]
        dist_c = np.sqrt(tx * tx + ty * ty + tz * tz)
        covered = dist_c > reach  # outside
        covered &= side * float((c - corners[0]) @ q_normal) > reach  # on P's side of Q, beyond it
        covered &= ~((b.kind[k] == kind) & (b.index[k] == index))
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = r / dist_c
            cos_cone = np.sqrt(np.maximum(0.0, 1.0 - ratio * ratio))
        cos_cone += MARGIN * 16
        for (qx, qy, qz), lq in zip(to_q, length_q):
            covered &= tx * qx + ty * qy + tz * qz > cos_cone * dist_c * lq
        hidden |= covered
    return hidden


def _tiles_of(points: np.ndarray, kind: np.ndarray, index: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per tile of :data:`TILE` consecutive points: the centre C ``(3, T)`` of the box of its points (their
    exact minima and maxima), the radius R of the ball about C that holds the box (rounded up), the largest
    magnitude of its coordinates, whether its points all lie on one surface, and that surface (its first
    point's)."""
    n = len(points)
    full = n // TILE * TILE
    lo, hi = np.empty((3, (n + TILE - 1) // TILE)), np.empty((3, (n + TILE - 1) // TILE))
    for k in range(3):  # a tile's minimum and maximum: a loop over its TILE places, on contiguous columns
        column = np.ascontiguousarray(points[:, k])
        whole = column[:full].reshape(-1, TILE)
        low, high = lo[k, :len(whole)], hi[k, :len(whole)]
        np.copyto(low, whole[:, 0])
        np.copyto(high, whole[:, 0])
        for j in range(1, TILE):
            np.minimum(low, whole[:, j], out=low)
            np.maximum(high, whole[:, j], out=high)
        if full < n:
            lo[k, -1], hi[k, -1] = column[full:].min(), column[full:].max()
    centre = (lo + hi) * 0.5
    reach = np.sqrt(np.sum((hi - lo) ** 2, axis=0)) * (0.5 * (1.0 + 2.0**-40))
    scale = np.maximum(np.max(np.abs(lo), axis=0), np.max(np.abs(hi), axis=0))
    key = kind.astype(np.int64) << 48 | index
    edges = np.flatnonzero(key[1:] != key[:-1]) + 1  # where the surface changes: a tile holds one unless inside it
    one = np.ones(len(scale), dtype=bool)
    one[edges[edges % TILE != 0] // TILE] = False
    starts = np.arange(0, n, TILE)
    return centre, reach, scale, one, kind[starts], index[starts]


def lit_tiles(b: Bounds, points: np.ndarray, kind: np.ndarray, index: np.ndarray, outward: np.ndarray,
              position: np.ndarray | None, direction: np.ndarray | None) -> np.ndarray:
    """Which tiles of :data:`TILE` consecutive points a point light at ``position`` (or a directional light
    shining along ``direction``) reaches unblocked from every point. Shape (T,), bool.

    **Proof.**  A tile's points lie in the ball B about the centre C of their box, of radius R.  The shadow
    segment from a point P of B to the light A lies within R of the segment CA (its point λP + (1 − λ)A is
    λ|P − C| from λC + (1 − λ)A); a directional light's shadow ray from P along u = −direction lies within R of
    the ray from C along u.  A bound farther than its radius plus R (and the margin) from that segment, or
    ray, meets no shadow ray of the tile.  A plane with B strictly on one side of it, by more than R, blocks
    none when the light lies strictly on that side too (for a directional light: when u does not head
    towards the plane; a ray parallel to it never meets it).  The surface a tile's points all lie on is not
    their blocker (leaving it by identity) but for a sphere seen from inside, whose tiles, like those with
    numbers beyond proof, are left to their rays."""
    centre, reach_t, scale, one, tile_kind, tile_index = _tiles_of(points, kind, index)
    if position is not None:
        scale = scale + float(np.max(np.abs(position)))
    margin_of = MARGIN * scale
    with np.errstate(all="ignore"):
        seen = np.isfinite(scale) & np.isfinite(reach_t)
        if position is not None:  # the segment from C to the light: C + s·span, 0 ≤ s ≤ 1
            span = np.asarray(position, dtype=np.float64)[:, None] - centre
            length_sq = span[0] * span[0] + span[1] * span[1] + span[2] * span[2]
        else:
            assert direction is not None
            u = -np.asarray(direction, dtype=np.float64)
        if len(b.radius):  # every bound against every tile at once: (K, T)
            bound_part = MARGIN * (np.max(np.abs(b.center), axis=1, initial=0.0) + b.radius)
            rel = [b.center[:, i][:, None] - centre[i][None, :] for i in range(3)]  # bound centre − C
            way = [span[i][None, :] for i in range(3)] if position is not None else [u[i] for i in range(3)]
            along = rel[0] * way[0] + rel[1] * way[1] + rel[2] * way[2]
            if position is not None:  # the nearest point of the segment C + s·span, 0 ≤ s ≤ 1
                s = np.clip(along / length_sq[None, :], 0.0, 1.0)
            else:  # of the ray C + s·u, s ≥ 0
                s = np.maximum(along, 0.0)
            off = [rel[i] - s * way[i] for i in range(3)]
            apart = np.sqrt(off[0] * off[0] + off[1] * off[1] + off[2] * off[2])
            clear = apart > margin_of[None, :] + (b.radius + bound_part)[:, None] + reach_t[None, :]
            own = one[None, :] & (b.kind[:, None] == tile_kind[None, :]) & (b.index[:, None] == tile_index[None, :])
            seen &= np.all(clear | own, axis=0)
        for j, (p0, nrm) in enumerate(zip(b.plane_point, b.plane_normal)):
            m = MARGIN * (scale + float(np.max(np.abs(p0))))
            c_side = _plane_dot(centre, p0, nrm)
            mine = one & (tile_kind == PLANE) & (tile_index == j)
            away = np.abs(c_side) > m + reach_t
            if position is not None:
                light_side = float((np.asarray(position, dtype=np.float64) - p0) @ nrm)
                away &= (np.sign(c_side) == np.sign(light_side)) & (abs(light_side) > m)
            else:  # the shadow rays' own denominator, one for all, computed as their plane test computes it
                heading = float(dot(u[None], nrm[None])[0])
                away &= (heading == 0.0) | (np.sign(c_side) == np.sign(heading))
            seen &= away | mine
        seen[_inside_spheres(b, points, kind, index, outward, seen) // TILE] = False
    return seen


class Penumbra:
    """An area light's mixed points (:func:`classify`) and the bounds that may block them, as pairs, with what a
    shadow ray of each pair is proven to do from its direction and length alone.

    **Proof.**  For a point P outside the ball (c, r) (by the module's margin, and not on the bound's own
    surface), at distance D from its centre, the ball subtends the cone of half-angle θ = asin(r / D) about
    â = (c − P)/D.  A shadow ray P + t·u (u the ray's own unit direction) towards a sample at distance d:

    * misses the ball, so meets no part of the bound's surface, when u·â < cos θ by a margin (its line
      passes farther than r from c), or when the ball lies wholly beyond the sample (D − r > d);
    * is blocked by a sphere (a bound that is the sphere itself) when u·â > cos θ by a margin (its line passes
      through the ball's inside) and the ball lies wholly before the sample (D + r < d): it enters the sphere
      at some 0 < t ≤ D < d.

    Each margin (2^-30 of the cosine, of the magnitudes for a distance) is far above the rounding of the
    float64 numbers compared and of the exact test that would decide the pair, which therefore decides alike.
    A point's own surface blocks none of the rays it casts towards samples it faces (``facing``: every ray
    cast, but in the variant that lights points from behind), as the rays leave it by identity: a flat
    surface never, a sphere seen from outside only heading inwards.
    A plane blocks none of a point's rays when the point and the parallelogram lie strictly on one side of it,
    or the point lies on it (and leaves it).  A ray whose pairs all miss and whose planes cannot block is
    clear; a ray one of whose pairs blocks is blocked; the rest are cast, against their undecided pairs."""

    def __init__(self, b: Bounds, points: np.ndarray, kind: np.ndarray, index: np.ndarray, outward: np.ndarray,
                 may_block: np.ndarray, corners: np.ndarray, facing: bool):
        self.bounds = b
        self.bound, self.point = np.nonzero(may_block)  # (P,) each: bound-major, as Among.of makes them
        p = [np.take(points[:, k], self.point) for k in range(3)]
        a = [b.center[self.bound, k] - p[k] for k in range(3)]
        with np.errstate(all="ignore"):
            dist = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
            self.axis = [a[k] / dist for k in range(3)]
            scale = np.maximum(np.maximum(np.abs(p[0]), np.abs(p[1])), np.abs(p[2])) + \
                np.max(np.abs(b.center[self.bound]), axis=1) + b.radius[self.bound]
            self.margin = MARGIN * scale
            grown, shrunk = b.radius[self.bound] + self.margin, b.radius[self.bound] - self.margin
            own = (b.kind[self.bound] == kind[self.point]) & (b.index[self.bound] == index[self.point])
            outside = np.isfinite(dist) & np.isfinite(scale) & (dist > grown) & ~own
            # u·â below this: the line misses the grown ball; above `inside`: it passes within the shrunk one
            self.miss_below = np.where(outside, np.sqrt(1.0 - (grown / dist) ** 2) - MARGIN, -np.inf)
            if facing:  # its own surface, which a ray towards a sample the point faces leaves for good
                on_sphere = b.kind[self.bound] == SPHERE
                towards = sum(np.take(outward[:, k], self.point) * -a[k] for k in range(3))  # N·(P − c)
                self.miss_below[own & (~on_sphere | (towards >= 0))] = np.inf
            inside = np.sqrt(1.0 - np.maximum(shrunk, 0.0) ** 2 / dist ** 2) + MARGIN
            self.hit_above = np.where(outside & b.solid[self.bound] & (shrunk > 0), inside, np.inf)
            self.starts = np.where(outside, dist - grown, -np.inf)  # the ball's nearest and farthest reach along
            self.ends = np.where(outside, dist + grown, np.inf)  # any ray from the point
        # the planes that may block some ray of each point (not with the parallelogram strictly on its side)
        self.planes = np.zeros(len(kind), dtype=bool)
        for j, (p0, nrm) in enumerate(zip(b.plane_point, b.plane_normal)):
            q_side = (corners - p0) @ nrm
            side = _plane_dot(np.ascontiguousarray(points.T), p0, nrm)
            m = MARGIN * (np.max(np.abs(points), axis=1) + float(np.max(np.abs(p0))) + float(np.max(np.abs(corners))))
            one_side = bool(np.all(q_side > 0) or np.all(q_side < 0)) and float(np.min(np.abs(q_side))) > 0
            clear = one_side & (np.sign(side) == np.sign(q_side[0])) & (np.abs(side) > m) & \
                (m < float(np.min(np.abs(q_side))))
            self.planes |= ~(clear | ((kind == PLANE) & (index == j)))

    def decide(self, lit: np.ndarray, to_light: np.ndarray, dist: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, Among]:
        """For the rays of the points ``lit`` (mixed points, bool), in order, whose unit directions are
        ``to_light`` and lengths ``dist`` (per point, of every point): whether each is proven blocked, whether
        it must still be cast, and the pairs of the rays cast (numbered among them) that are not decided."""
        ray_of = np.cumsum(lit) - 1  # each lit point's ray
        n = int(ray_of[-1]) + 1 if len(ray_of) else 0
        pairs = np.flatnonzero(lit[self.point])
        at = self.point[pairs]
        x = np.take(to_light[:, 0], at) * np.take(self.axis[0], pairs)
        for k in (1, 2):
            x += np.take(to_light[:, k], at) * np.take(self.axis[k], pairs)
        d = np.take(dist, at)
        slack = MARGIN * d + np.take(self.margin, pairs)
        misses = (x < np.take(self.miss_below, pairs)) | (np.take(self.starts, pairs) > d + slack)
        blocks = (x > np.take(self.hit_above, pairs)) & (np.take(self.ends, pairs) < d - slack)
        rays = np.take(ray_of, at)
        blocked = np.zeros(n, dtype=bool)
        blocked[rays[blocks]] = True
        open_pairs = np.flatnonzero(~misses & ~blocks)
        cast = self.planes[lit].copy()
        cast[rays[open_pairs]] = True
        cast &= ~blocked
        keep = open_pairs[cast[rays[open_pairs]]]
        number = np.cumsum(cast) - 1  # each ray cast, numbered among them
        bound = self.bound[pairs[keep]]
        among = Among(number[rays[keep]], self.bounds.kind[bound], self.bounds.index[bound])
        return blocked, cast, among
