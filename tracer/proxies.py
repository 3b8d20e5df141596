"""Closed float32 stand-ins for exact surfaces, and which of them lie close together.

Embree works in float32, so it only *finds candidates*; every hit is then
decided in float64 (:mod:`tracer.shapes`).  For that to be exact, a ray that
hits a surface in float64 must hit its stand-in in float32.  Each triangle is
therefore replaced by a closed tetrahedron that contains the prism of its own
triangle grown by ``m`` in its plane and ``m`` thick on each side (four faces
where the prism has eight: Embree's build costs by the face), and each sphere
by a closed icosahedron whose
faces lie ``m`` outside the sphere, where ``m`` is many times the float32
rounding of the BVH's normalised coordinates.  Embree's watertight (robust)
mode then cannot let a ray through a proxy's surface.  Mesh faces that the
scene's rays can only meet squarely (:mod:`tracer.sightlines`) are the
exception: they go in as themselves, and their box stands in for the proxy's.

Embree reports only the nearest crossing, and a walk that steps past it by
float32 noise may step past other crossings within that noise.  Those belong
to proxies that come within ``gap`` of the reported one: the *neighbours*,
found here once per scene, are tested in float64 together with every
candidate, so nothing is ever skipped.  Proxies of nested spheres whose
surfaces stay apart are not neighbours; instead the inner one records the
size of its containers (:attr:`Proxies.container`), which bounds how far past
a hit a ray must still look.

Primitive ids: triangles ``0..T-1``, then the proxied spheres ``T..T+S-1``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sightlines import SLACK
from .vec import cross, dot, least, lowest, most, rows_of
from .world import median_of

#: proxy margin, neighbour gap and walk step, relative to the BVH's half-size
MARGIN = 2.0**-17
GAP = 2.0**-15
STEP = 2.0**-19
#: the margin of triangle proxies in a scene that also has plain triangles (:mod:`tracer.sightlines`): more than a
#: plain triangle's float32 crossing may stray, so a ray that strays near a proxied triangle still enters its proxy
TRIANGLE_MARGIN = 2.0**-14
#: the most neighbour pairs a scene may have before its spheres leave the BVH
PAIR_BUDGET = 20_000_000


class TooManyOverlaps(ValueError):
    """So many proxies overlap in one place that exact neighbour sets would not fit in memory."""


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    """Unit-circumradius icosahedron: 12 vertices and its 20 faces, wound outward."""
    phi = (1.0 + np.sqrt(5.0)) / 2.0
    v = np.array([[-1, phi, 0], [1, phi, 0], [-1, -phi, 0], [1, -phi, 0], [0, -1, phi], [0, 1, phi],
                  [0, -1, -phi], [0, 1, -phi], [phi, 0, -1], [phi, 0, 1], [-phi, 0, -1], [-phi, 0, 1]], dtype=float)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    edge = np.min(np.linalg.norm(v[1:] - v[0], axis=1))
    near = np.isclose(np.linalg.norm(v[:, None] - v[None, :], axis=2), edge)
    faces = np.array([(a, b, c) for a in range(12) for b in range(a + 1, 12) for c in range(b + 1, 12)
                      if near[a, b] and near[b, c] and near[a, c]])
    return v, faces


ICO_VERTICES, ICO_FACES = _icosahedron()
_n = np.cross(ICO_VERTICES[ICO_FACES[:, 1]] - ICO_VERTICES[ICO_FACES[:, 0]],
              ICO_VERTICES[ICO_FACES[:, 2]] - ICO_VERTICES[ICO_FACES[:, 0]])
#: circumradius over inradius of the icosahedron
ICO_SCALE = 1.0 / float(np.min(np.abs(np.einsum("ij,ij->i", _n / np.linalg.norm(_n, axis=1, keepdims=True),
                                                  ICO_VERTICES[ICO_FACES[:, 0]]))))
#: a tetrahedron over a triangle (base 0,1,2; apex 3) and an oriented box (corner bits x,y,z)
TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]])
BOX_FACES = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                      [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])


#: proxies of one shape: primitive ids (k,), vertices (k, per, 3) and the faces of one proxy (f, 3)
Group = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass
class Proxies:
    vertices: np.ndarray  # (V, 3) local float64
    faces: np.ndarray  # (F, 3) int32 indices into vertices
    owner: np.ndarray  # (F,) int64 primitive id of each face
    lo: np.ndarray  # (P, 3) proxy bounding boxes
    hi: np.ndarray  # (P, 3)
    start: np.ndarray  # (P + 1,) neighbour lists: ids start[p]..start[p+1] of ``neighbours``
    neighbours: np.ndarray  # (K,) int64
    container: np.ndarray  # (P,) largest diameter of a sphere proxy that contains p's without being its neighbour
    margin: float  # m
    gap: float  # how near two proxies' boxes come to be neighbours
    step: float  # how far a walk steps past a reported crossing
    slack: float = 0.0  # how far past a hit a plain triangle's float32 crossing may lie (0: none are plain)


def triangle_prisms(v0: np.ndarray, e1: np.ndarray, e2: np.ndarray, normal: np.ndarray,
                    m: float) -> list[Group]:
    """Closed proxies of triangles, one group per shape: tetrahedra, and oriented boxes for slivers.

    The tetrahedron's base lies ``m`` below the triangle's plane and its apex a quarter of the inradius
    (at least ``16 m``) above the incentre; its base is grown about the incentre so that its section at
    ``m`` above the plane is still the triangle grown by ``m``: it contains that whole prism."""
    corners = np.stack([v0, v0 + e1, v0 + e2], axis=1)  # (T, 3, 3)
    a = np.linalg.norm(corners[:, 1] - corners[:, 2], axis=1)
    b = np.linalg.norm(corners[:, 2] - corners[:, 0], axis=1)
    c = np.linalg.norm(corners[:, 0] - corners[:, 1], axis=1)
    perimeter = a + b + c
    twice = cross(e1, e2)
    area2 = np.sqrt(dot(twice, twice))
    with np.errstate(divide="ignore", invalid="ignore"):
        inradius = area2 / perimeter
        grow = 1.0 + m / inradius
    prism = np.isfinite(grow) & (grow < 4.0)
    groups = []
    ids = np.flatnonzero(prism)
    if len(ids):
        cr = corners[ids]
        incenter = (a[ids, None] * cr[:, 0] + b[ids, None] * cr[:, 1] + c[ids, None] * cr[:, 2]) / perimeter[ids, None]
        height = np.maximum(inradius[ids] / 4.0, 16.0 * m)  # (h + m)/(h − m) ≤ 17/15: a base not much grown
        base_grow = grow[ids] * (height + m) / (height - m)  # the section at +m shrinks by (h − m)/(h + m)
        n = normal[ids]
        base = incenter[:, None] + base_grow[:, None, None] * (cr - incenter[:, None]) - m * n[:, None, :]
        apex = incenter + height[:, None] * n
        groups.append((ids, np.concatenate([base, apex[:, None]], axis=1), TET_FACES))
    ids = np.flatnonzero(~prism)  # slivers: an oriented box around the triangle
    if len(ids):
        cr, n = corners[ids], normal[ids]
        edges = np.stack([cr[:, 1] - cr[:, 0], cr[:, 2] - cr[:, 1], cr[:, 0] - cr[:, 2]], axis=1)
        longest = edges[np.arange(len(ids)), np.argmax(np.linalg.norm(edges, axis=2), axis=1)]
        ax = longest / np.linalg.norm(longest, axis=1, keepdims=True)
        ay = np.cross(n, ax)
        rel = cr - cr[:, :1]
        px, py = np.einsum("kij,kj->ki", rel, ax), np.einsum("kij,kj->ki", rel, ay)
        xs = np.stack([px.min(1) - m, px.max(1) + m], 1)
        ys = np.stack([py.min(1) - m, py.max(1) + m], 1)
        zs = np.stack([-m * np.ones(len(ids)), m * np.ones(len(ids))], 1)
        bits = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)])
        verts = (cr[:, :1] + xs[:, bits[:, 0], None] * ax[:, None] + ys[:, bits[:, 1], None] * ay[:, None]
                 + zs[:, bits[:, 2], None] * n[:, None])
        groups.append((ids, verts, BOX_FACES))
    return groups


def sphere_icosahedra(center: np.ndarray, radius: np.ndarray, m: float) -> np.ndarray:
    """Vertices ``(S, 12, 3)`` of icosahedra whose faces lie ``m`` outside each sphere."""
    return center[:, None, :] + ((radius + m) * ICO_SCALE)[:, None, None] * ICO_VERTICES[None]


def build_proxies(v0: np.ndarray, e1: np.ndarray, e2: np.ndarray, normal: np.ndarray, center: np.ndarray,
                  radius: np.ndarray, half_size: float, plain: np.ndarray | None = None,
                  corner_ids: np.ndarray | None = None, neighbours: bool = True) -> Proxies:
    """Proxies for ``T`` triangles and ``S`` spheres (local coordinates) in a BVH of half-size ``half_size``.

    Triangles marked ``plain`` (:func:`tracer.sightlines.plain_triangles`) go in as themselves, each corner
    shared through ``corner_ids``; the others get proxies.  Without ``neighbours`` the neighbour lists are
    left empty (:func:`find_neighbours` fills them in)."""
    m = MARGIN * half_size
    gap = GAP * half_size
    n_tri = len(v0)
    count = n_tri + len(radius)
    lo = np.full((count, 3), np.inf)
    hi = np.full((count, 3), -np.inf)
    verts, faces, owner, base = [], [], [], 0
    some_plain = plain is not None and corner_ids is not None and bool(plain.any())
    proxied = np.arange(n_tri)
    if some_plain:
        assert plain is not None and corner_ids is not None
        ids = np.flatnonzero(plain)
        first = rows_of(v0, ids)
        corners = np.stack([first, first + rows_of(e1, ids), first + rows_of(e2, ids)], axis=1)  # (k, 3, 3)
        shared = corner_ids[ids]
        table = np.zeros((int(corner_ids.max()) + 1, 3))  # (rows no plain triangle uses stay unused)
        table[shared.reshape(-1)] = corners.reshape(-1, 3)  # one float32 corner per shared corner
        lo[ids] = least(corners) - m  # holds the float32 triangle and any crossing Embree reports on it
        hi[ids] = most(corners) + m
        verts.append(table)
        faces.append(shared)
        owner.append(ids)
        base = len(table)
        proxied = np.flatnonzero(~plain)
    tri_m = TRIANGLE_MARGIN * half_size if some_plain else m
    groups = [(proxied[g], v, template) for g, v, template in
              triangle_prisms(*(rows_of(a, proxied) for a in (v0, e1, e2, normal)), tri_m)]
    if len(radius):
        groups.append((np.arange(len(radius)) + n_tri, sphere_icosahedra(center, radius, m), ICO_FACES))
    for ids, v, template in groups:  # v: (k, vertices per proxy, 3)
        k, per = v.shape[:2]
        lo[ids], hi[ids] = least(v), most(v)
        verts.append(v.reshape(-1, 3))
        faces.append((template[None] + base + per * np.arange(k)[:, None, None]).reshape(-1, 3))
        owner.append(np.repeat(ids, len(template)))
        base += k * per
    all_verts = np.concatenate(verts) if verts else np.zeros((0, 3))
    all_faces = np.concatenate(faces) if faces else np.zeros((0, 3), np.int64)
    all_owner = np.concatenate(owner) if owner else np.zeros(0, np.int64)
    p = Proxies(vertices=all_verts, faces=all_faces.astype(np.int32), owner=all_owner.astype(np.int64),
                lo=lo, hi=hi, start=np.zeros(count + 1, np.int64), neighbours=np.zeros(0, np.int64),
                container=np.zeros(count), margin=m, gap=gap, step=STEP * half_size,
                slack=SLACK * half_size if some_plain else 0.0)
    if neighbours:
        find_neighbours(p, n_tri, center, radius)
    return p


def find_neighbours(p: Proxies, n_tri: int, center: np.ndarray, radius: np.ndarray) -> None:
    """Fill in the neighbour lists (and containers) of proxies ``p`` of ``n_tri`` triangles and the spheres
    ``center``, ``radius``."""
    i, j = overlapping_pairs(p.lo - p.gap, p.hi + p.gap)
    if len(radius) and len(i):
        i, j, p.container = _separate_nests(i, j, n_tri, center, radius, p.margin, p.gap, p.container)
    p.start, p.neighbours = _csr(len(p.lo), i, j)


def _separate_nests(i: np.ndarray, j: np.ndarray, n_tri: int, center: np.ndarray, radius: np.ndarray, m: float,
                    gap: float, container: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Drop sphere pairs nested with room to spare; the inner one remembers its container's size."""
    both = (i >= n_tri) & (j >= n_tri)
    a, b = i[both] - n_tri, j[both] - n_tri
    d = np.linalg.norm(center[a] - center[b], axis=1)
    outer = (radius + m) * ICO_SCALE  # circumradius of each proxy
    inner = radius + m  # inradius
    box = np.sqrt(3.0) * outer  # the proxy's bounding box lies within this of its centre
    a_in_b = d + box[a] + gap <= inner[b]
    b_in_a = d + box[b] + gap <= inner[a]
    np.maximum.at(container, a[a_in_b] + n_tri, 2.0 * outer[b[a_in_b]])
    np.maximum.at(container, b[b_in_a] + n_tri, 2.0 * outer[a[b_in_a]])
    keep = np.ones(len(i), dtype=bool)
    keep[np.flatnonzero(both)[a_in_b | b_in_a]] = False
    return i[keep], j[keep], container


def stable_order(keys: np.ndarray, bound: int) -> np.ndarray:
    """``np.argsort(keys, kind="stable")`` for integer keys in ``0..bound-1``, by 16-bit digits: NumPy sorts
    those by radix, two to three times faster than a comparison sort of the whole keys."""
    order: np.ndarray | None = None
    shift = 0
    while True:
        digit = ((keys if order is None else keys[order]) >> shift) & 0xFFFF
        step = np.argsort(digit.astype(np.uint16), kind="stable")
        order = step if order is None else order[step]
        shift += 16
        if bound <= 1 << shift:
            return order


def _csr(count: int, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    src = np.concatenate([i, j]).astype(np.int64)
    dst = np.concatenate([j, i]).astype(np.int64)
    order = stable_order(src, count)  # stable: the order of the pairs decides, so it is deterministic
    start = np.zeros(count + 1, dtype=np.int64)
    start[1:] = np.cumsum(np.bincount(src, minlength=count))
    return start, dst[order]


#: the 13 cells after a cell in (x, y, z) order among its 26 neighbours: each adjacent pair of cells once
_LATER = [(dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1) if (dx, dy, dz) > (0, 0, 0)]
_BITS = 21
_LAST = (1 << (_BITS - 1)) - 1  # cell coordinates are clipped to 0.._LAST, so a neighbour's key never wraps


def overlapping_pairs(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All pairs ``i < j`` of boxes that overlap. Each (K,), int64, in no particular (but a deterministic) order.

    Boxes up to four times the median size go into a uniform grid whose cell
    is as large as the largest of them, each box into the one cell of its low
    corner: two that overlap then sit in the same or adjacent cells.  The
    larger boxes are tested against every box directly.  Raises
    :class:`TooManyOverlaps` past :data:`PAIR_BUDGET`.
    """
    n = len(lo)
    if n < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    extent = most(hi - lo)
    median = median_of(extent)
    with np.errstate(invalid="ignore"):
        is_small = (extent <= 4.0 * median) if np.isfinite(median) else np.zeros(n, dtype=bool)
    small = np.flatnonzero(is_small)
    lo_a = [np.ascontiguousarray(lo[:, axis]) for axis in range(3)]
    hi_a = [np.ascontiguousarray(hi[:, axis]) for axis in range(3)]

    def overlapping(i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        keep = i != j
        for axis in range(3):  # adjacent cells are not overlapping boxes: test the boxes, an axis at a time
            keep &= (lo_a[axis][i] <= hi_a[axis][j]) & (lo_a[axis][j] <= hi_a[axis][i])
        return i[keep], j[keep]

    pairs_i, pairs_j = [], []
    if len(small):
        cell = float(np.max(extent[small])) * (1.0 + 2.0**-20)  # slack for the rounding of the cell coordinates
        if not (np.isfinite(cell) and cell > 0):
            cell = 1.0
        origin = lowest(lo[small])
        with np.errstate(over="ignore", invalid="ignore"):
            c = np.clip(np.floor((lo[small] - origin) / cell), 0, _LAST).astype(np.int64)
        key = (c[:, 0] << (2 * _BITS)) | (c[:, 1] << _BITS) | c[:, 2]
        order = np.argsort(key, kind="stable")
        index = np.int32 if n < 2**31 else np.int64  # half the memory of the candidate lists
        key, box = key[order], small[order].astype(index)
        # the boxes in cell order: the candidates of one cell then lie together in memory
        s_lo = [np.ascontiguousarray(a[box]) for a in lo_a]
        s_hi = [np.ascontiguousarray(a[box]) for a in hi_a]
        cells, first, members = np.unique(key, return_index=True, return_counts=True)
        first, members = first.astype(index), members.astype(index)
        own = np.repeat(np.arange(len(cells), dtype=index), members)  # each sorted box's cell
        pos = np.arange(len(key), dtype=index)
        total = 0
        for dx, dy, dz in [(0, 0, 0), *_LATER]:  # candidates an offset at a time, tested at once: little memory
            if (dx, dy, dz) == (0, 0, 0):  # the later boxes of its own cell
                s, count = pos + 1, first[own] + members[own] - pos - 1
            else:
                target = cells + ((dx << (2 * _BITS)) + (dy << _BITS) + dz)
                at = np.minimum(np.searchsorted(cells, target), len(cells) - 1)
                there = cells[at] == target
                s = first[at][own]
                count = np.where(there, members[at], 0)[own]
            total += int(count.sum(dtype=np.int64))
            if total > PAIR_BUDGET:
                raise TooManyOverlaps(f"more than {PAIR_BUDGET} candidate proxy pairs")
            a = np.repeat(pos, count)
            b = np.repeat(s - np.cumsum(count, dtype=index) + count, count) + np.arange(len(a), dtype=index)
            keep = (s_lo[0][a] <= s_hi[0][b]) & (s_lo[0][b] <= s_hi[0][a])  # x first: the test most boxes fail
            a, b = a[keep], b[keep]
            keep = ((s_lo[1][a] <= s_hi[1][b]) & (s_lo[1][b] <= s_hi[1][a])
                    & (s_lo[2][a] <= s_hi[2][b]) & (s_lo[2][b] <= s_hi[2][a]))
            i, j = box[a[keep]], box[b[keep]]
            pairs_i.append(i.astype(np.int64))
            pairs_j.append(j.astype(np.int64))
    big_ids = np.flatnonzero(~is_small)
    if len(big_ids) * n > PAIR_BUDGET:
        raise TooManyOverlaps(f"{len(big_ids)} large proxies among {n}")
    if len(big_ids):
        found = []
        for g in big_ids:
            hit = np.flatnonzero(np.all(lo <= hi[g], axis=1) & np.all(hi >= lo[g], axis=1))
            found.append(np.stack([np.full(len(hit), g), hit]))
        bi, bj = np.concatenate(found, axis=1)
        bi, bj = overlapping(np.minimum(bi, bj), np.maximum(bi, bj))  # (drops g itself)
        code = np.unique(bi * n + bj)  # a pair of two large boxes is found from both ends
        pairs_i.append(code // n)
        pairs_j.append(code % n)
    if not pairs_i:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    i, j = np.concatenate(pairs_i), np.concatenate(pairs_j)
    return np.minimum(i, j), np.maximum(i, j)
