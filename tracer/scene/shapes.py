"""Exact float64 ray tests for spheres, planes and triangles, pair by pair.

Every test takes N rays and N surfaces (one surface per ray, broadcast where
the same surface serves every ray) and returns the ray parameter ``t`` of the
first hit with ``t > 0``, ``inf`` for none.  Directions are unit vectors.
For a shadow segment towards a light, :func:`plane_separates` decides a
plane by the sides of the segment's two ends instead.

A ray leaves a surface by identity: ``on_origin`` says that the ray's origin
lies on the surface (it starts from it, or from a surface coincident with it
there).  Such a ray never hits that surface at its origin: a plane or a
triangle not at all (the ray either leaves its plane or lies in it), a sphere
only at its far root when it heads inside.  ``on_end`` says that a shadow
ray's end (the light) lies on the surface: the surface does not block the
light there.  Whether a point lies on a surface is decided by
:func:`on_tolerance`: float64 rounding of the numbers involved, never a
distance picked by hand.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# the surface kinds (:mod:`tracer.scene.kinds`), named here too for the exact tests' callers
from .kinds import MISS as MISS
from .kinds import PLANE as PLANE
from .kinds import SPHERE as SPHERE
from .kinds import TRIANGLE as TRIANGLE
from .vec import along, cross, dot, minus

#: relative resolution: points closer than this (times the magnitudes involved, the world's largest coordinates
#: of the point and of the surface) are the same place.  Four units in the last place of half their sum: what
#: the rounding of the input (a scene moved by 10⁶ rounds its coordinates) and of a hit point in the eye's
#: frame leave, and no more, so that an eye 10⁻⁶ above a planet of radius 10⁹ (whose own numbers resolve
#: 1.2·10⁻⁷ there) is not on it.  Coplanar and coincident surfaces, moved and scaled, keep to it
#: (tests/test_exactness.py, tests/test_render.py, the fuzz test's moved scenes)
TOL = 2.0**-52
#: how near to 0 the cosine between a directional light and a flat surface's normal is parallel: a few
#: roundings of two unit vectors
PARALLEL = 2.0**-48
#: barycentric allowance, so that a ray through a shared mesh edge never slips between its faces
UV_TOL = 2.0**-40


def on_tolerance(point_magnitude: np.ndarray | float, surface_magnitude: np.ndarray | float) -> np.ndarray:
    """How far from a surface a point may be and still lie on it: float64 rounding of both."""
    return TOL * (np.asarray(point_magnitude) + surface_magnitude)


def sphere_t(
    origins: np.ndarray,
    dirs: np.ndarray,
    center: np.ndarray,
    radius: np.ndarray,
    mag_origin: np.ndarray,
    mag_sphere: np.ndarray,
    leaving: np.ndarray | None = None,
    ends: np.ndarray | None = None,
    reach: np.ndarray | None = None,
    mag_end: np.ndarray | None = None,
) -> np.ndarray:
    """First root t > 0 per ray, ``inf`` for none. Shape (N,).

    ``leaving`` (bool, N) marks rays that start from this very sphere.  With
    ``ends``/``reach`` (a shadow ray towards a light at ``ends``), a root at the
    light is not a hit when the light lies on the sphere.  Roots come from the
    numerically stable pair ``c/q, q`` and the discriminant from the distance
    of the centre to the ray's line, so a sphere of radius 1e6 is as exact as
    one of radius 1.
    """
    oc = minus(origins, center)
    b = dot(oc, dirs)
    perp = along(oc, -b, dirs)  # oc − b·dirs
    h = np.sqrt(dot(perp, perp))
    radius = np.broadcast_to(radius, b.shape)
    disc = (radius - h) * (radius + h)
    dist = np.sqrt(dot(oc, oc))
    # an origin on the sphere: one root is the origin itself, the other is the chord −2b (inward only)
    on = np.abs(dist - radius) <= on_tolerance(mag_origin, mag_sphere)
    if leaving is not None:
        on |= leaving
    at_end = None
    if ends is not None:
        assert reach is not None and mag_end is not None
        ec = minus(ends, center)
        at_end = np.abs(np.sqrt(dot(ec, ec)) - radius) <= on_tolerance(mag_end, mag_sphere)
    # only a ray whose line meets the sphere, or that starts or ends on it, can hit it: the rest stay at inf, and
    # the roots are found for the others alone (the same operations on the same numbers, so the same bits)
    may = (disc >= 0) | on if at_end is None else (disc >= 0) | on | at_end
    rows = np.flatnonzero(may)
    t = np.full(len(b), np.inf)
    if len(rows) == 0:
        return t

    reach_n = None if reach is None else np.broadcast_to(reach, b.shape)
    if 2 * len(rows) > len(b):  # most rays may: no gathering
        return _roots(b, disc, dist, radius, on, at_end, reach_n)
    t[rows] = _roots(
        b[rows],
        disc[rows],
        dist[rows],
        radius[rows],
        on[rows],
        None if at_end is None else at_end[rows],
        None if reach_n is None else reach_n[rows],
    )
    return t


def _roots(
    b: np.ndarray,
    disc: np.ndarray,
    dist: np.ndarray,
    radius: np.ndarray,
    on: np.ndarray,
    at_end: np.ndarray | None,
    reach: np.ndarray | None,
) -> np.ndarray:
    """:func:`sphere_t` for rays that may hit, from ``b = (o − c)·d``, the discriminant, the origin's distance
    from the centre and whether it starts (``on``) or ends (``at_end``, towards a light at ``reach``) on it."""
    c = (dist - radius) * (dist + radius)
    root = np.sqrt(np.maximum(disc, 0.0))
    q = -b - np.where(b >= 0, root, -root)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_a = np.where(q != 0, c / q, 0.0)
    near, far = np.minimum(t_a, q), np.maximum(t_a, q)
    t = np.where(near > 0, near, np.where(far > 0, far, np.inf))
    t = np.where(disc >= 0, t, np.inf)
    t = np.where(on, np.where(b < 0, -2.0 * b, np.inf), t)
    if at_end is not None:
        assert reach is not None
        # the light is a root; the other root is c / reach (their product is c)
        with np.errstate(divide="ignore", invalid="ignore"):
            other = np.where(c > 0, c / reach, np.inf)
        t = np.where(at_end, np.where(on, np.inf, other), t)
    return np.where(np.isfinite(t) & (t > 0), t, np.inf)


def plane_side(points: np.ndarray, point: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Signed distance ``(p − point)·normal`` of each of ``points (N, 3)`` from a plane (unit ``normal``),
    a column at a time with no ``(N, 3)`` difference made. Shape (N,)."""
    return (
        (points[..., 0] - point[..., 0]) * normal[..., 0]
        + (points[..., 1] - point[..., 1]) * normal[..., 1]
        + (points[..., 2] - point[..., 2]) * normal[..., 2]
    )


def plane_t(
    origins: np.ndarray,
    dirs: np.ndarray,
    point: np.ndarray,
    normal: np.ndarray,
    mag_origin: np.ndarray,
    mag_plane: np.ndarray | float,
    leaving: np.ndarray | None = None,
    ends: np.ndarray | None = None,
    mag_end: np.ndarray | None = None,
) -> np.ndarray:
    """t > 0 where each ray meets a plane, ``inf`` where it does not (or starts or ends on it). Shape (N,)."""
    n = np.asarray(normal, dtype=np.float64)
    dist = plane_side(origins, point, n)
    denom = dot(dirs, n)
    normal = n
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -dist / denom
    skip = np.abs(dist) <= on_tolerance(mag_origin, mag_plane)
    if leaving is not None:
        skip |= leaving
    if ends is not None:
        assert mag_end is not None
        skip |= np.abs(dot(*np.broadcast_arrays(ends - point, np.atleast_2d(normal)))) <= on_tolerance(
            mag_end, mag_plane
        )
    return np.where(~skip & (denom != 0) & (t > 0) & np.isfinite(t), t, np.inf)


@dataclass(frozen=True)
class Segments:
    """Segments from ``origins (N, 3)`` to ``ends`` (``(N, 3)``, or ``(1, 3)`` for one light shared by every
    segment), with the magnitudes of each end's coordinates, for the tolerance of a point on a plane."""

    origins: np.ndarray
    ends: np.ndarray
    mag_origin: np.ndarray
    mag_end: np.ndarray


def plane_separates(
    segments: Segments, point: np.ndarray, normal: np.ndarray, mag_plane: float, leaving: np.ndarray | None = None
) -> np.ndarray:
    """True where the plane lies strictly between each segment's origin and its end (a light): the segment
    crosses it. Shape (N,), bool.

    Decided by the signs of the two ends' distances from the plane, which is
    exact where computing the crossing's ``t`` is not (a segment nearly
    parallel to the plane).  An end on the plane (within :func:`on_tolerance`),
    or an origin leaving it, is never blocked by it.
    """
    n = np.asarray(normal, dtype=np.float64)
    side_o, side_e = plane_side(segments.origins, point, n), plane_side(segments.ends, point, n)
    out = (side_o > 0) != (side_e > 0)
    out &= np.abs(side_o) > on_tolerance(segments.mag_origin, mag_plane)
    out &= np.abs(side_e) > on_tolerance(segments.mag_end, mag_plane)
    if leaving is not None:
        out &= ~leaving
    return out


def triangle_t(
    origins: np.ndarray,
    dirs: np.ndarray,
    v0: np.ndarray,
    e1: np.ndarray,
    e2: np.ndarray,
    normal: np.ndarray,
    mag_origin: np.ndarray,
    mag_triangle: np.ndarray,
    leaving: np.ndarray | None = None,
    ends: np.ndarray | None = None,
    mag_end: np.ndarray | None = None,
    uv: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Float64 Möller–Trumbore with the barycentric test decided exactly: ``t, u, v``, each (N,).

    ``t`` is ``inf`` where the ray misses the triangle (``u, v`` are then
    meaningless); where it hits, ``u, v`` are clamped into the triangle so that
    ``v0 + u·e1 + v·e2`` lies on it.  Without ``uv`` (a shadow ray needs only
    ``t``) they are returned as they come, unclamped.  The triangles are given
    per ray, ``(N, 3)`` each, or as one ``(3,)`` triangle for every ray.
    """
    if v0.ndim == 1:
        v0, e1, e2, normal = (np.broadcast_to(a, dirs.shape) for a in (v0, e1, e2, normal))
    p = cross(dirs, e2)
    det = dot(e1, p)
    s = origins - v0
    qv = cross(s, e1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = 1.0 / det
        u = dot(s, p) * inv
        v = dot(dirs, qv) * inv
        t = dot(e2, qv) * inv
    inside = (u >= -UV_TOL) & (v >= -UV_TOL) & (u + v <= 1.0 + UV_TOL)
    skip = np.abs(dot(s, normal)) <= on_tolerance(mag_origin, mag_triangle)
    if leaving is not None:
        skip |= leaving
    if ends is not None:
        assert mag_end is not None
        skip |= np.abs(dot(ends - v0, normal)) <= on_tolerance(mag_end, mag_triangle)
    ok = inside & ~skip & np.isfinite(t) & (t > 0)
    t = np.where(ok, t, np.inf)
    if not uv:
        return t, u, v
    u = np.fmin(np.fmax(u, 0.0), 1.0)  # clipped into 0..1, NaN to 0 (fmax drops a NaN)
    v = np.fmin(np.fmax(v, 0.0), 1.0)
    over = u + v > 1.0
    total = np.where(over, u + v, 1.0)
    return t, np.where(over, u / total, u), np.where(over, v / total, v)
