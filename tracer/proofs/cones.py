"""Rays through one point, or along one direction: which surfaces each ray may meet, proved from their bounds.

Camera rays all leave the eye; a point light's (or a spot's) shadow rays all
run towards the light; an orthographic camera's rays, and a directional
light's shadow rays, all run along one direction.  Against a handful of
surfaces, a ray of such a batch is tested exactly only against the surfaces
it may meet (:class:`tracer.scene.rays.Among`), in place of Embree and the walk.
Two tests decide it, each from the surface's bound (:class:`tracer.proofs.bounds.Bounds`:
the sphere itself, or a sphere round a triangle) or the triangle itself:

* **A ball, through a point** ``A``: a ray along the line through ``A`` in
  the direction ``u`` (away from ``A``) meets the ball ``(c, r)``, with ``A``
  outside it at distance ``D = |c − A|``, only if the angle between ``u`` and
  ``c − A`` is at most ``asin(r / D)``: ``u·(c − A)/D ≥ √(1 − (r/D)²)``.
* **A triangle, through a point**: a ray from ``A`` meets the triangle only
  if its direction lies on the inner side of the three planes through ``A``
  and an edge: ``u·n_i ≥ 0``.  A hit point the exact test accepts may lie
  outside the triangle by its barycentric allowance and rounding, which
  :data:`tracer.proofs.margins.GROWTH` of the triangle's size bounds (as the walk's proxies and the
  area light's bounds assume); at a distance of at least ``h`` from ``A``
  (the distance of the triangle's plane), that is an angle of at most
  ``GROWTH·size / (h − GROWTH·size)``, which the test allows (four times
  ``GROWTH·size / h``, with ``h`` above four growths).  With ``A`` nearly in
  the triangle's plane, only the ball's test is made.
* **Along a direction** ``l``: the ray ``O + t·l`` (t > 0) meets the ball only
  if the ball's centre lies within ``r`` of its line and not wholly behind
  ``O``, and meets the triangle only if ``O`` lies on the inner side of the
  three planes along ``l`` through an edge (within the same growth).

A camera ray is ``eye + t·d`` exactly (its origin is the eye), so ``u = d``.
A shadow ray ``P + t·d`` towards a light at ``A`` (``d`` the computed unit
vector from ``P`` to ``A``) strays from the true segment ``PA`` by at most a
few units in the last place of its length, which :data:`tracer.proofs.margins.STRAY` bounds; each
surface is grown by that much, and ``u = −d``, whose angle to the true
direction is as small.  Every surface is grown by :data:`tracer.proofs.margins.MARGIN`
of the magnitudes involved, and every cosine compared with a slack of
:data:`tracer.proofs.margins.SLACK` (and :data:`tracer.proofs.margins.SLACK32` in float32),
far above the rounding of the tests here.  A proof that cannot be made (``A``
inside the ball, numbers that are not finite) leaves the surface paired with
every ray.  So a surface that an exact test finds hit by a ray is always
paired with it: the closest hit, and whether a shadow ray is blocked, come
out as the walk's, which tests every surface a ray may hit.
"""

from __future__ import annotations

import numpy as np

from ..scene.kinds import TRIANGLE
from ..scene.rays import Among
from ..scene.surfaces import Triangles
from ..scene.vec import length
from .bounds import Bounds, face_normal
from .margins import GROWTH, MARGIN, NORMAL_ERROR, SLACK, SLACK32, STRAY


def _pairs(kinds: list[int], indices: list[int], rows: list[np.ndarray]) -> Among:
    count = [len(r) for r in rows]
    if not rows:
        return Among(np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int8), np.zeros(0, dtype=np.int64))
    return Among(
        np.concatenate(rows).astype(np.int64, copy=False),
        np.repeat(np.array(kinds, dtype=np.int8), count),
        np.repeat(np.array(indices, dtype=np.int64), count),
    )


def _corners(tris: Triangles, k: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Triangles ``k``'s corners (K, 3, 3), unit normals (K, 3), sizes (their longest edges) and world
    magnitudes (K,), all at once."""
    v0, e1, e2 = tris.v0[k], tris.e1[k], tris.e2[k]
    corners = np.stack([v0, v0 + e1, v0 + e2], axis=1)
    size = np.maximum(np.maximum(_norm(e1), _norm(e2)), _norm(e1 - e2))
    return corners, tris.normal[k], size, tris.mag[k]


def _norm(v: np.ndarray) -> np.ndarray:
    """|v| of each row of ``v (..., 3)``. Shape (...)."""
    return length(v[..., 0], v[..., 1], v[..., 2])


#: a triangle's three edge planes: unit normals, and the allowance (through a point) or the levels (along a
#: direction) of its test
Edges = tuple[list[np.ndarray], float]
Levels = tuple[list[np.ndarray], list[float]]


def through_point(
    b: Bounds, tris: Triangles, apex: np.ndarray, dirs: np.ndarray, away: bool, length: float = 0.0
) -> Among:
    """The surfaces each ray through ``apex`` may meet, as pairs (surface by surface).

    ``dirs (N, 3)`` are the rays' unit directions: leaving the apex when ``away`` (camera rays from the eye),
    or towards it (shadow rays to a light at the apex).  ``length`` is the longest of the shadow rays' segments
    (their stray grows with it); camera rays start at the apex itself and do not stray."""
    n = len(dirs)
    apex_mag = float(np.max(np.abs(apex)))
    sign = 1.0 if away else -1.0
    # unit directions lose nothing a cosine test needs in float32 (see SLACK32): half the bytes of every pass
    x, y, z = (dirs[:, a].astype(np.float32) for a in range(3))
    cos_of, scratch = np.empty(n, dtype=np.float32), np.empty(n, dtype=np.float32)
    stray = STRAY * length
    edges_of = _edges_through(tris, b, apex, apex_mag, sign, stray)
    kinds, indices, rows = [], [], []
    for j in range(len(b.radius)):
        c = b.center[j]
        r = float(b.radius[j]) + MARGIN * (apex_mag + float(np.max(np.abs(c))) + float(b.radius[j])) + stray
        a = c - apex
        dist = float(np.sqrt(a @ a))
        if np.isfinite(dist) and np.isfinite(r) and dist > r:
            a = a * (sign / dist)
            cos = float(np.sqrt(1.0 - (r / dist) ** 2)) - SLACK - SLACK32
            near = np.flatnonzero(_along(cos_of, scratch, x, y, z, a) >= _below(cos))
        else:  # the apex inside the ball (or numbers beyond proof): every ray may meet it
            near = np.arange(n)
        edges = edges_of.get(j)
        if edges is not None and len(near):
            near = near[_inside(edges, x[near], y[near], z[near])]
        if len(near):
            kinds.append(int(b.kind[j]))
            indices.append(int(b.index[j]))
            rows.append(near)
    return _pairs(kinds, indices, rows)


def _edges_through(
    tris: Triangles, b: Bounds, apex: np.ndarray, apex_mag: float, sign: float, stray: float
) -> dict[int, Edges]:
    """For each triangle among the bounds ``b`` (by its place there), the three planes through ``apex`` and an
    edge, as unit normals ``m`` (the triangle, seen along ``sign·u``, on their positive side), and the angle its
    growth allows (``m·u ≥ −allow``); none where they prove nothing (the apex nearly in the triangle's plane, an
    edge in line with it).  Every triangle at once."""
    which = np.flatnonzero(b.kind == TRIANGLE)
    if len(which) == 0:
        return {}
    corners, normal, size, mag = _corners(tris, b.index[which])
    grow = GROWTH * size + MARGIN * (apex_mag + mag) + stray
    rel = corners - apex  # (K, 3, 3)
    # every point of a triangle's plane is this far from the apex
    h = np.abs(rel[:, 0, 0] * normal[:, 0] + rel[:, 0, 1] * normal[:, 1] + rel[:, 0, 2] * normal[:, 2])
    with np.errstate(all="ignore"):
        allow = 4.0 * grow / h + SLACK + NORMAL_ERROR  # (the growth seen from h − grow away, the stray, the planes)
        ok = np.isfinite(h) & np.isfinite(grow) & (h > 4.0 * grow)  # else the apex (nearly) in its plane
        ms = []
        for i in range(3):  # each plane's normal from the apex-to-corner vector and the edge itself (face_normal)
            m, turn = _edge_plane(
                rel[:, i], corners[:, (i + 1) % 3] - corners[:, i], corners[:, (i + 2) % 3] - corners[:, i]
            )
            ok &= np.isfinite(turn)
            ms.append(m * (sign * turn)[:, None])  # unit, the triangle on its side
    return {int(j): ([m[t] for m in ms], float(allow[t])) for t, j in enumerate(which.tolist()) if ok[t]}


def _edge_plane(u: np.ndarray, e: np.ndarray, across: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row, the unit normal ``(K, 3)`` of the plane spanned by ``u`` and ``e``
    (:func:`tracer.proofs.bounds.face_normal`:
    within :data:`tracer.proofs.margins.NORMAL_ERROR` of the true one, each of ``u`` and ``e`` a rounded difference of
    stored numbers or exact), and the sign ``(K,)`` that turns it towards ``across`` (the third corner from the
    edge's start: a short vector), NaN where either is not known: the normal's direction, or a side nearer the
    plane than the normal's error and the product's rounding allow.

    An error of NORMAL_ERROR in a plane's direction moves a cosine compared with it by as much, and a level
    ``m·o`` by NORMAL_ERROR·|o − corner|: each test here allows at least MARGIN (2^-30) of the magnitudes, eight
    times more (and :data:`SLACK32` more again through a point)."""
    e = np.broadcast_to(e, u.shape)
    m = np.stack(face_normal((u[:, 0], u[:, 1], u[:, 2]), (e[:, 0], e[:, 1], e[:, 2])), axis=1)
    with np.errstate(invalid="ignore"):
        side = np.sum(across * m, axis=1)
        known = np.abs(side) > 2.0 * NORMAL_ERROR * _norm(across)
    return m, np.where(known, np.sign(side), np.nan)


def _inside(edges: Edges, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Which directions ``(x, y, z)`` (float32) lie on the inner side of the three planes through the apex,
    within the angle allowed: the module's second test. Shape (n,), bool."""
    ms, allow = edges
    keep = np.ones(len(x), dtype=bool)
    along, scratch = np.empty(len(x), dtype=np.float32), np.empty(len(x), dtype=np.float32)
    for m in ms:
        keep &= _along(along, scratch, x, y, z, m) >= _below(-allow - SLACK32)
    return keep


def _along(
    out: np.ndarray, scratch: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray, a: np.ndarray
) -> np.ndarray:
    """``x·a₀ + y·a₁ + z·a₂`` into ``out``, in float32 (``x, y, z`` float32, ``a`` a unit vector)."""
    np.multiply(x, np.float32(a[0]), out=out)
    np.multiply(y, np.float32(a[1]), out=scratch)
    out += scratch
    np.multiply(z, np.float32(a[2]), out=scratch)
    out += scratch
    return out


def _below(value: float) -> np.float32:
    """The largest float32 at or below ``value``."""
    low = np.float32(value)
    return low if float(low) <= value else np.nextafter(low, np.float32(-np.inf))


def along_direction(b: Bounds, tris: Triangles, origins: np.ndarray, direction: np.ndarray) -> Among:
    """The surfaces each ray ``origins + t·direction`` (t > 0, one unit direction for all) may meet, as pairs
    (surface by surface)."""
    ell = np.asarray(direction, dtype=np.float64)
    e1 = np.cross(ell, [1.0, 0.0, 0.0] if abs(ell[0]) < 0.6 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(ell, e1)
    ox, oy, oz = (np.ascontiguousarray(origins[:, a]) for a in range(3))
    u, v, w = (ox * e[0] + oy * e[1] + oz * e[2] for e in (e1, e2, ell))  # each origin across and along l
    origin_mag = float(np.max(np.abs(origins), initial=0.0))
    edges_of = _edges_along(tris, b, ell, origin_mag)
    kinds, indices, rows = [], [], []
    for j in range(len(b.radius)):
        c = b.center[j]
        r = float(b.radius[j]) + MARGIN * (origin_mag + float(np.max(np.abs(c))) + float(b.radius[j]))
        if np.isfinite(r) and np.all(np.isfinite(c)):
            du, dv = u - float(c @ e1), v - float(c @ e2)
            close = du * du + dv * dv <= (r * r) * (1.0 + SLACK)
            close &= w - float(c @ ell) <= r  # the ball not wholly behind the origin
            near = np.flatnonzero(close)
        else:
            near = np.arange(len(origins))
        edges = edges_of.get(j)
        if edges is not None and len(near):
            near = near[_beside(edges, ox[near], oy[near], oz[near])]
        if len(near):
            kinds.append(int(b.kind[j]))
            indices.append(int(b.index[j]))
            rows.append(near)
    return _pairs(kinds, indices, rows)


def _edges_along(tris: Triangles, b: Bounds, ell: np.ndarray, origin_mag: float) -> dict[int, Levels]:
    """For each triangle among the bounds ``b`` (by its place there), the three planes along ``ell`` through an
    edge, as unit normals ``m`` (the triangle on their positive side) and the level ``m·o`` must reach (within
    its growth); none where they prove nothing (an edge along the direction: the triangle seen edge-on).  Every
    triangle at once."""
    which = np.flatnonzero(b.kind == TRIANGLE)
    if len(which) == 0:
        return {}
    corners, _, size, mag = _corners(tris, b.index[which])
    grow = GROWTH * size + MARGIN * (origin_mag + mag)
    with np.errstate(all="ignore"):
        ok = np.isfinite(grow)
        ms, levels = [], []
        for i in range(3):
            p = corners[:, i]
            m, turn = _edge_plane(corners[:, (i + 1) % 3] - p, ell, corners[:, (i + 2) % 3] - p)
            ok &= np.isfinite(turn)
            m = m * turn[:, None]
            ms.append(m)
            levels.append(np.sum(p * m, axis=1) - grow)
    return {
        int(j): ([m[t] for m in ms], [float(level[t]) for level in levels])
        for t, j in enumerate(which.tolist())
        if ok[t]
    }


def _beside(edges: Levels, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Which origins ``(x, y, z)`` lie on the inner side of the three planes along the direction, within the
    growth: the module's fourth test. Shape (n,), bool."""
    keep = np.ones(len(x), dtype=bool)
    for m, level in zip(*edges):
        keep &= x * m[0] + y * m[1] + z * m[2] >= level
    return keep


def on_lines(b: Bounds, origins: np.ndarray, dirs: np.ndarray) -> Among:
    """The surfaces each ray ``origins + t·dirs`` (t > 0, unit directions of their own: a mirror's or glass's
    rays) may meet, as pairs (surface by surface): a bound's ball only if its centre lies within its radius of
    the ray's line and not wholly behind its origin (the test along one direction, ray by ray).  A triangle is
    paired with the rays that meet its bound."""
    n = len(origins)
    o = [np.ascontiguousarray(origins[:, k]) for k in range(3)]
    d = [np.ascontiguousarray(dirs[:, k]) for k in range(3)]
    origin_mag = np.maximum(np.maximum(np.abs(o[0]), np.abs(o[1])), np.abs(o[2]))
    kinds, indices, rows = [], [], []
    along, tmp = np.empty(n), np.empty(n)
    offset = [np.empty(n) for _ in range(3)]
    for j in range(len(b.radius)):
        c = b.center[j]
        r = float(b.radius[j])
        if not (np.isfinite(r) and np.all(np.isfinite(c))):
            near = np.arange(n)
        else:
            grown = r + MARGIN * (origin_mag + (float(np.max(np.abs(c))) + r))  # (N,)
            for k in range(3):
                np.subtract(c[k], o[k], out=offset[k])
            np.multiply(offset[0], d[0], out=along)  # (c − o)·d: how far along the ray the centre lies
            for k in (1, 2):
                np.multiply(offset[k], d[k], out=tmp)
                along += tmp
            for k in range(3):  # (c − o) − ((c − o)·d)·d: the centre's offset across the ray
                np.multiply(along, d[k], out=tmp)
                offset[k] -= tmp
            across = offset[0] * offset[0]
            for k in (1, 2):
                np.multiply(offset[k], offset[k], out=tmp)
                across += tmp
            close = across <= grown * grown * (1.0 + SLACK)
            close &= along >= -grown  # the ball not wholly behind the origin
            near = np.flatnonzero(close)
        if len(near):
            kinds.append(int(b.kind[j]))
            indices.append(int(b.index[j]))
            rows.append(near)
    return _pairs(kinds, indices, rows)
