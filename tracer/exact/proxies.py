"""Closed float32 stand-ins for exact surfaces, and which of them lie close together.

Embree works in float32, so it only *finds candidates*; every hit is then
decided in float64 (:mod:`tracer.scene.shapes`).  For that to be exact, a ray that
hits a surface in float64 must hit its stand-in in float32.  Each triangle is
therefore replaced by a closed tetrahedron that contains the prism of its own
triangle grown by ``m`` in its plane and ``m`` thick on each side (four faces
where the prism has eight: Embree's build costs by the face), and each sphere
by a closed icosahedron whose
faces lie ``m`` outside the sphere, where ``m`` is many times the float32
rounding of the BVH's normalised coordinates.  Embree's watertight (robust)
mode then cannot let a ray through a proxy's surface.  Mesh faces that the
scene's rays can only meet squarely (:mod:`tracer.proofs.sightlines`) are the
exception: they go in as themselves, and their box stands in for the proxy's.

Embree reports only the nearest crossing; which other proxies a walk must
test there is the business of :mod:`tracer.exact.cells` (every proxy whose box
comes within :data:`REACH` of the crossing's part of a cell).

Primitive ids: triangles ``0..T-1``, then the proxied spheres ``T..T+S-1``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..proofs.margins import CROSSING_SLACK
from ..scene.vec import cross, dot, least, most, rows_of

#: proxy margin and walk step, relative to the BVH's half-size
MARGIN = 2.0**-17
STEP = 2.0**-19
#: how far (relative to the BVH's half-size) a proxy's box reaches into the cells it is registered in: far more
#: than the float32 rounding of a crossing and of a ray, and than the walk's step past a crossing
REACH = 2.0**-14
#: the margin of triangle proxies in a scene that also has plain triangles (:mod:`tracer.proofs.sightlines`): more than
#: a plain triangle's float32 crossing may stray, so a ray that strays near a proxied triangle still enters its proxy
TRIANGLE_MARGIN = 2.0**-14


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    """Unit-circumradius icosahedron: 12 vertices and its 20 faces, wound outward."""
    phi = (1.0 + np.sqrt(5.0)) / 2.0
    v = np.array(
        [
            [-1, phi, 0],
            [1, phi, 0],
            [-1, -phi, 0],
            [1, -phi, 0],
            [0, -1, phi],
            [0, 1, phi],
            [0, -1, -phi],
            [0, 1, -phi],
            [phi, 0, -1],
            [phi, 0, 1],
            [-phi, 0, -1],
            [-phi, 0, 1],
        ],
        dtype=float,
    )
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    edge = np.min(np.linalg.norm(v[1:] - v[0], axis=1))
    near = np.isclose(np.linalg.norm(v[:, None] - v[None, :], axis=2), edge)
    faces = np.array(
        [
            (a, b, c)
            for a in range(12)
            for b in range(a + 1, 12)
            for c in range(b + 1, 12)
            if near[a, b] and near[b, c] and near[a, c]
        ]
    )
    return v, faces


ICO_VERTICES, ICO_FACES = _icosahedron()
_n = np.cross(
    ICO_VERTICES[ICO_FACES[:, 1]] - ICO_VERTICES[ICO_FACES[:, 0]],
    ICO_VERTICES[ICO_FACES[:, 2]] - ICO_VERTICES[ICO_FACES[:, 0]],
)
#: circumradius over inradius of the icosahedron
ICO_SCALE = 1.0 / float(
    np.min(np.abs(np.einsum("ij,ij->i", _n / np.linalg.norm(_n, axis=1, keepdims=True), ICO_VERTICES[ICO_FACES[:, 0]])))
)
#: a tetrahedron over a triangle (base 0,1,2; apex 3) and an oriented box (corner bits x,y,z)
TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]])
BOX_FACES = np.array(
    [
        [0, 2, 3],
        [0, 3, 1],
        [4, 5, 7],
        [4, 7, 6],
        [0, 1, 5],
        [0, 5, 4],
        [2, 6, 7],
        [2, 7, 3],
        [0, 4, 6],
        [0, 6, 2],
        [1, 3, 7],
        [1, 7, 5],
    ]
)


#: proxies of one shape: primitive ids (k,), vertices (k, per, 3) and the faces of one proxy (f, 3)
Group = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass
class Proxies:
    vertices: np.ndarray  # (V, 3) local float64
    faces: np.ndarray  # (F, 3) int32 indices into vertices
    owner: np.ndarray  # (F,) int64 primitive id of each face
    lo: np.ndarray  # (P, 3) proxy bounding boxes
    hi: np.ndarray  # (P, 3)
    margin: float  # m
    reach: float  # how far a proxy's box reaches into the cells it is registered in
    step: float  # how far a walk steps past a reported crossing
    slack: float = 0.0  # how far past a hit a plain triangle's float32 crossing may lie (0: none are plain)


def triangle_prisms(v0: np.ndarray, e1: np.ndarray, e2: np.ndarray, normal: np.ndarray, m: float) -> list[Group]:
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
        verts = (
            cr[:, :1]
            + xs[:, bits[:, 0], None] * ax[:, None]
            + ys[:, bits[:, 1], None] * ay[:, None]
            + zs[:, bits[:, 2], None] * n[:, None]
        )
        groups.append((ids, verts, BOX_FACES))
    return groups


def sphere_icosahedra(center: np.ndarray, radius: np.ndarray, m: float) -> np.ndarray:
    """Vertices ``(S, 12, 3)`` of icosahedra whose faces lie ``m`` outside each sphere."""
    return center[:, None, :] + ((radius + m) * ICO_SCALE)[:, None, None] * ICO_VERTICES[None]


def build_proxies(
    v0: np.ndarray,
    e1: np.ndarray,
    e2: np.ndarray,
    normal: np.ndarray,
    center: np.ndarray,
    radius: np.ndarray,
    half_size: float,
    plain: np.ndarray | None = None,
    corner_ids: np.ndarray | None = None,
) -> Proxies:
    """Proxies for ``T`` triangles and ``S`` spheres (local coordinates) in a BVH of half-size ``half_size``.

    Triangles marked ``plain`` (:func:`tracer.proofs.sightlines.plain_triangles`) go in as themselves, each corner
    shared through ``corner_ids``; the others get proxies."""
    m = MARGIN * half_size
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
    groups = [
        (proxied[g], v, template)
        for g, v, template in triangle_prisms(
            rows_of(v0, proxied), rows_of(e1, proxied), rows_of(e2, proxied), rows_of(normal, proxied), tri_m
        )
    ]
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
    return Proxies(
        vertices=all_verts,
        faces=all_faces.astype(np.int32),
        owner=all_owner.astype(np.int64),
        lo=lo,
        hi=hi,
        margin=m,
        reach=REACH * half_size,
        step=STEP * half_size,
        slack=CROSSING_SLACK * half_size if some_plain else 0.0,
    )
