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
(:meth:`tracer.exact.intersect.Intersector.occluded`, ``among``), with the same
exact tests, so the answer is the same; :class:`tracer.proofs.penumbra.Penumbra`
decides many of those rays from their direction and length alone.  A point
whose normal faces away from every corner of Q by more than rounding is lit
by no sample (:func:`faces_away`).

The surface a point lies on is never its own blocker for the samples it faces
(leaving by identity), except a sphere seen from inside, which makes the point
mixed.  The decisions the proofs stand for are those the exact per-sample test
makes, far from its rounding, so the image keeps its bytes.  Scenes with more
than :data:`tracer.proofs.bounds.MAX_BOUNDS` surfaces skip the proofs (every point
mixed).

**Precision, construction by construction.**  Every test compares a computed
number with a threshold grown by :data:`tracer.proofs.margins.MARGIN` (2^-30) of the magnitudes
involved, or a cosine with a slack of at least MARGIN; each number's own error
stays under a quarter of that at every scale and every ratio of sizes:

* a face or Q's plane (:func:`tracer.proofs.bounds.face_normal`): a long vector crossed with a short
  exact one, never two long ones, so its direction errs by at most
  NORMAL_ERROR (2^-33) whatever the ratio of Q's edges to its distance, or the
  face is declined; a distance to it then errs by at most 2^-32 of the
  magnitudes (:func:`_faces`);
* a point's side of a plane, ``(P − q)·n``: one rounded difference per
  component and a dot product, a few 2^-53 of ``|P − q|``;
* the hidden test's cosines (:func:`_hidden`) and the penumbra's
  (:class:`tracer.proofs.penumbra.Penumbra`): dot products of rounded differences over their
  lengths, absolute errors of a few 2^-53 against slacks of 2^-30 and more;
  cosines near 1 (a thin light far away) only lose proofs, never make one;
* a tile's ball (:func:`tracer.proofs.tiles.tiles_of`): its centre ``(lo + hi)/2`` errs by 2^-53
  of the coordinates' magnitude, absolute, which the margin (of the same
  magnitudes) covers even where the ball's radius is far smaller;
* a bound's distance from a segment or a ray (:func:`tracer.proofs.tiles.lit_tiles`): the nearest
  point's parameter and the offset across it err by a few 2^-53 of
  ``|centre − C|``, absolute, not of the distance itself: within the margin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.kinds import PLANE
from ..scene.vec import dot, length, minus, most
from .bounds import Bounds, SurfacePoints, face_normal, inside_spheres, plane_clear, sides_of
from .margins import MARGIN, NORMAL_ERROR
from .tiles import TILE, inside_tiles, tiles_of

SEEN, HIDDEN, MIXED = 0, 1, 2


@dataclass(frozen=True)
class Culled:
    """What :func:`classify` proved of N points and one area light."""

    state: np.ndarray  # (N,) int8: SEEN, HIDDEN or MIXED
    #: (K, N) bool: the bounds that may block some sample of each point (every other bound lies strictly outside
    #: one of the point's pyramid's faces, so its surface meets none of its shadow segments)
    may_block: np.ndarray


def classify(b: Bounds, at: SurfacePoints, corners: np.ndarray) -> Culled:
    """SEEN, HIDDEN or MIXED for each of the points ``at`` and the light's parallelogram ``corners (4, 3)``,
    in order round it, with the bounds that may block each point's samples (of the points SEEN, none).

    The points go a tile at a time first (:data:`TILE` consecutive points, neighbours on the image): a tile
    proven to see every sample (:func:`_seen_tiles`) is SEEN whole, and only the others' points are
    classified one by one.  A point of a SEEN tile sees every sample whatever the per-point proof would have
    made of it, so its shading is the same."""
    n = len(at.point)
    if not np.all(np.isfinite(_q_normal(corners))):  # Q's plane not known well enough: no proof at all
        return Culled(np.full(n, MIXED, dtype=np.int8), np.ones((len(b.radius), n), dtype=bool))
    if n >= 4 * TILE:
        seen = np.repeat(_seen_tiles(b, at, corners), TILE)[:n]
        if seen.any():
            rest = np.flatnonzero(~seen)
            state = np.full(n, SEEN, dtype=np.int8)
            may_block = np.zeros((len(b.radius), n), dtype=bool)
            if len(rest):
                part = _classify(b, at.take(rest), corners)
                state[rest] = part.state
                may_block[:, rest] = part.may_block
            return Culled(state, may_block)
    return _classify(b, at, corners)


def _seen_tiles(b: Bounds, at: SurfacePoints, corners: np.ndarray) -> np.ndarray:
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
    centre, reach_t, scale, one, tile_kind, tile_index = tiles_of(at)
    scale = scale + float(np.max(np.abs(corners)))
    margin_of = MARGIN * scale  # (at least every point's own margin)
    bound_part = MARGIN * (np.max(np.abs(b.center), axis=1, initial=0.0) + b.radius)
    q_normal = _q_normal(corners)
    with np.errstate(all="ignore"):
        apex_side = sides_of(centre, corners[0], q_normal)
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
            mine = one & (tile_kind == PLANE) & (tile_index == j)
            seen &= plane_clear(sides_of(centre, p0, nrm), reach_t, q_side, m) | mine
        # a tile with points on a sphere seen from inside it: left to the per-point tests
        seen[inside_tiles(b, at, seen)] = False
    return seen  # (NaN compares False above: no proof)


def _classify(b: Bounds, at: SurfacePoints, corners: np.ndarray) -> Culled:
    """:func:`classify`, a point at a time.

    Computed a bound at a time on the points' contiguous columns (``(N,)`` arrays, no ``(N, K)`` or
    ``(N, K, 3)`` temporaries): the same tests as the docstring of this module states, whose margins are far
    above the rounding of any order of the sums."""
    kind, index = at.kind, at.index
    n = len(at.point)
    p = np.ascontiguousarray(at.point.T)  # (3, N): x, y and z, each contiguous
    scale = np.maximum(np.maximum(np.abs(p[0]), np.abs(p[1])), np.abs(p[2])) + float(np.max(np.abs(corners)))
    # the margin of bound k at a point: MARGIN·(scale + |centre_k| + r_k), the part of bound k a constant
    margin_of = MARGIN * scale
    bound_part = MARGIN * (np.max(np.abs(b.center), axis=1, initial=0.0) + b.radius)
    q_normal = _q_normal(corners)
    apex_side = sides_of(p, corners[0], q_normal)  # (N,)
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
            mine = (kind == PLANE) & (index == j)  # a point on this very plane, which it leaves
            seen &= plane_clear(sides_of(p, p0, nrm), 0.0, q_side, m) | mine
    hidden = _hidden(b, p, at, corners, side, margin_of) & ~flat
    # a sphere a point lies on blocks the samples it faces only when seen from inside
    inside = inside_spheres(b, at, np.arange(n))
    seen[inside] = False
    hidden[inside] = False
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


def _q_normal(corners: np.ndarray) -> np.ndarray:
    """The unit normal of the parallelogram ``corners (4, 3)``, :func:`face_normal` of its two edges from
    ``corners[0]``: within :data:`NORMAL_ERROR` of the true one (the edges are short vectors, exact to
    rounding), or NaN where the edges are too nearly parallel for that.  Its error in ``(c − q)·n`` for a point
    ``c`` is at most (NORMAL_ERROR + 2^-50)·|c − q|, under a quarter of the margin, as for the faces."""
    u = corners[1] - corners[0]
    return np.array(face_normal((u[0], u[1], u[2]), corners[3] - corners[0]), dtype=np.float64)


def _hidden(
    b: Bounds, p: np.ndarray, at: SurfacePoints, corners: np.ndarray, side: np.ndarray, margin_of: np.ndarray
) -> np.ndarray:
    """Points ``p (3, N)`` some solid sphere hides the whole parallelogram from. Shape (N,), bool.

    A sphere hides it when the point lies outside it, on the point's side of Q's plane beyond it, and every
    corner lies strictly inside its cone from the point: ``cos(corner) > cos(cone)``, compared as
    ``(C − P)·(q − P) > cos(cone)·|C − P|·|q − P|`` (both lengths positive), with no division."""
    hidden = np.zeros(p.shape[1], dtype=bool)
    solid = np.flatnonzero(b.solid)
    if len(solid) == 0:
        return hidden
    q_normal = _q_normal(corners)  # (as :func:`_classify` computes them: the same numbers)
    bound_part = MARGIN * (np.max(np.abs(b.center), axis=1, initial=0.0) + b.radius)
    to_q = [(q[0] - p[0], q[1] - p[1], q[2] - p[2]) for q in corners]
    length_q = [length(x, y, z) for x, y, z in to_q]
    for k in solid.tolist():
        c, r = b.center[k], float(b.radius[k])
        reach = margin_of + (r + bound_part[k])
        tx, ty, tz = c[0] - p[0], c[1] - p[1], c[2] - p[2]
        dist_c = length(tx, ty, tz)
        covered = dist_c > reach  # outside
        covered &= side * float((c - corners[0]) @ q_normal) > reach  # on P's side of Q, beyond it
        covered &= ~((b.kind[k] == at.kind) & (b.index[k] == at.index))
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = r / dist_c
            cos_cone = np.sqrt(np.maximum(0.0, 1.0 - ratio * ratio))
        cos_cone += MARGIN * 16
        for (qx, qy, qz), lq in zip(to_q, length_q):
            covered &= tx * qx + ty * qy + tz * qz > cos_cone * dist_c * lq
        hidden |= covered
    return hidden


def faces_away(p: np.ndarray, normal: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Points ``p (N, 3)`` whose ``normal`` faces away from all four ``corners (4, 3)`` of an area light by more
    than rounding (and whose numbers are finite): no sample can light them. Shape (N,), bool.

    **Proof.**  N·(S − P) is linear in the sample S, so where it is negative at the four corners it is negative
    over the whole parallelogram, and N·L ≤ 0 at every sample.  Each N·(corner − P) is a rounded difference and
    a dot product, a few 2^-53 of the magnitudes of the point and the corners; it is compared with
    :data:`tracer.proofs.margins.MARGIN` of the same magnitudes, at every scale."""
    scale = most(np.abs(p)) + float(np.max(np.abs(corners)))
    towards = [dot(normal, minus(c, p)) for c in corners]
    faces_some = np.maximum(np.maximum(towards[0], towards[1]), np.maximum(towards[2], towards[3]))
    finite = np.isfinite(faces_some) & (scale < 1e300) & np.isfinite(dot(normal, normal))
    return finite & (faces_some < -MARGIN * scale)
