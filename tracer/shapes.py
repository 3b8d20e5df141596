"""Exact float64 ray tests for spheres, planes and (refining Embree's answer) triangles.

All rays here have unit directions.  A test returns the ray parameter ``t``
of the first hit with ``t > 0`` (``inf`` for none); hits behind the origin
never count.
"""

from __future__ import annotations

import numpy as np


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def sphere_t(origins: np.ndarray, dirs: np.ndarray, center: np.ndarray, radius: float) -> np.ndarray:
    """Nearest t > 0 on one sphere for every ray, ``inf`` for a miss. Shape (N,).

    The discriminant is formed from the distance of the centre to the ray's
    line, and the roots from the numerically stable pair ``c/q, q``, so that a
    sphere of radius 1e6 is as exact as one of radius 1.
    """
    oc = origins - center
    b = _dot(oc, dirs)
    perp = oc - b[:, None] * dirs
    h = np.sqrt(_dot(perp, perp))
    disc = (radius - h) * (radius + h)
    dist = np.sqrt(_dot(oc, oc))
    c = (dist - radius) * (dist + radius)
    root = np.sqrt(np.maximum(disc, 0.0))
    q = -b - np.where(b >= 0, root, -root)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_a = np.where(q != 0, c / q, 0.0)
    t_b = q
    near, far = np.minimum(t_a, t_b), np.maximum(t_a, t_b)
    t = np.where(near > 0, near, np.where(far > 0, far, np.inf))
    return np.where((disc >= 0) & np.isfinite(t), t, np.inf)


def plane_t(origins: np.ndarray, dirs: np.ndarray, point: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """t > 0 where each ray meets one plane, ``inf`` where it does not. Shape (N,)."""
    denom = dirs @ normal
    num = (point - origins) @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num / denom
    return np.where((denom != 0) & (t > 0) & np.isfinite(t), t, np.inf)


def triangle_hit(origins: np.ndarray, dirs: np.ndarray, v0: np.ndarray, e1: np.ndarray,
                 e2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Float64 Möller–Trumbore against one given triangle per ray: ``t, u, v``, each (N,).

    ``u, v`` are clamped into the triangle, so ``v0 + u·e1 + v·e2`` always lies
    on it.  ``t`` is ``inf`` where the ray, in float64, does not hit the
    triangle at t > 0.
    """
    p = np.cross(dirs, e2)
    det = _dot(e1, p)
    s = origins - v0
    qv = np.cross(s, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        u = _dot(s, p) * inv
        v = _dot(dirs, qv) * inv
        t = _dot(e2, qv) * inv
    ok = np.isfinite(t) & (t > 0)
    u = np.clip(np.nan_to_num(u), 0.0, 1.0)
    v = np.clip(np.nan_to_num(v), 0.0, 1.0)
    over = u + v > 1.0
    total = np.where(over, u + v, 1.0)
    u, v = np.where(over, u / total, u), np.where(over, v / total, v)
    return np.where(ok, t, np.inf), u, v


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    """Unit-circumradius icosahedron: 12 vertices and its 20 triangular faces."""
    phi = (1.0 + np.sqrt(5.0)) / 2.0
    v = np.array([[-1, phi, 0], [1, phi, 0], [-1, -phi, 0], [1, -phi, 0], [0, -1, phi], [0, 1, phi],
                  [0, -1, -phi], [0, 1, -phi], [phi, 0, -1], [phi, 0, 1], [-phi, 0, -1], [-phi, 0, 1]], dtype=float)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    # faces: the vertex triples that are mutually at edge length
    edge = np.min(np.linalg.norm(v[1:] - v[0], axis=1))
    near = np.isclose(np.linalg.norm(v[:, None] - v[None, :], axis=2), edge)
    faces = [(a, b, c) for a in range(12) for b in range(a + 1, 12) for c in range(b + 1, 12)
             if near[a, b] and near[b, c] and near[a, c]]
    return v, np.array(faces)


#: proxies are icosahedra: tighter than a box or an octahedron, so fewer rays test a sphere they miss
PROXY_VERTICES, PROXY_FACES = _icosahedron()
FACES_PER_PROXY = len(PROXY_FACES)
#: circumradius over inradius of the icosahedron: scaling it by this puts its faces at the sphere's radius
PROXY_SCALE = 1.0 / float(np.min(np.abs(np.einsum("ij,ij->i", np.cross(
    PROXY_VERTICES[PROXY_FACES[:, 1]] - PROXY_VERTICES[PROXY_FACES[:, 0]],
    PROXY_VERTICES[PROXY_FACES[:, 2]] - PROXY_VERTICES[PROXY_FACES[:, 0]]) / np.linalg.norm(np.cross(
        PROXY_VERTICES[PROXY_FACES[:, 1]] - PROXY_VERTICES[PROXY_FACES[:, 0]],
        PROXY_VERTICES[PROXY_FACES[:, 2]] - PROXY_VERTICES[PROXY_FACES[:, 0]]), axis=1, keepdims=True),
    PROXY_VERTICES[PROXY_FACES[:, 0]]))))


def sphere_proxy_half(radius: np.ndarray) -> np.ndarray:
    """Circumradius of the icosahedron around each sphere (before the float32 allowance)."""
    return radius * PROXY_SCALE * (1.0 + 2.0**-12)


def sphere_proxies(center: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Icosahedra that contain the spheres, as triangle corners ``(20·S, 3, 3)``.

    The faces of each lie at (slightly more than) the sphere's radius from its
    centre, with a further allowance so that the float32 cast of the corners
    can never cut into the sphere.  Any ray that meets a sphere crosses a face
    of its proxy first (or starts inside it and crosses the way out).
    """
    half = sphere_proxy_half(radius) + 2.0**-18 * (np.max(np.abs(center), axis=1, initial=0.0) + radius * 2)
    corners = center[:, None, :] + half[:, None, None] * PROXY_VERTICES[None, :, :]  # (S, 12, 3)
    return corners[:, PROXY_FACES].reshape(-1, 3, 3)
