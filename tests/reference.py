"""A brute-force float64 tracer written straight from the scene format, for differential tests.

It shares nothing with ``tracer/`` but the validated scene: every ray is
tested against every surface in world coordinates, with no acceleration
structure and no shortcut.  It is slow (a Python loop over the surfaces, NumPy
over the rays) and meant for small images.

Every decision also says whether it is *clear*: far enough from the
numerical noise where two renderers that both follow the format may
honestly differ.  Unclear are a hit that ties with another surface, a ray
through a triangle's edge or grazing a sphere's outline, a ray origin or a
light within rounding distance of a surface but not clearly on it, N·L, a
spot's hard cone edge, a checker boundary or total internal reflection within
noise of its threshold.  A differential test compares only what is clear;
:func:`render` marks a pixel unclear when any ray of its tree met something
unclear.

The rules, as the format states them:

* the first hit is the smallest t > 0; a ray leaves the surface it starts
  from by identity (a plane or triangle is not hit again, a sphere left
  inward only at its far root), and a surface that passes through the ray's
  origin (within :data:`ON` of the magnitudes involved) is not hit there;
* a shadow segment is blocked by a surface hit at a distance in (0, d); a
  surface through the light's own position does not block it;
* a light that lies in the plane of a flat surface (plane, triangle, a mesh
  face without vertex normals) gives N·L = 0 there: it is skipped;
* where a ray meets several surfaces at one point, it meets the first in the
  order phongray states (scene-format.md): one that lets no light through
  before one that does, then spheres, planes, triangles, then the earlier
  object.  Flat surfaces of different objects in one plane whose boxes meet
  form groups (:func:`_coplanar`), their hits timed on the group's first
  member's plane so that a ray meets overlapping members at one t; a ray that
  leaves a member leaves the group, and one that meets members of two objects
  at its nearest t is *open* (:attr:`Hits.open`, :attr:`Frame.open`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: a point within ON × (the magnitudes involved) of a surface lies on it
ON = 2.0**-54
#: a point beyond OFF × (the magnitudes involved) from a surface is clearly off it; in between is unclear
OFF = 2.0**-44
#: how far a distance the brute force computes may be off, relative to the magnitudes involved
ERR = 2.0**-43
#: a dimensionless quantity (barycentric, cosine, relative gap) within GRAY of a threshold is unclear
GRAY = 2.0**-34
#: two flat surfaces of different objects are clearly in one plane with normals parallel within the first sine
#: and corners within the first distance (over the magnitudes of both), clearly not beyond the second: between,
#: which group they are in is unclear (phongray's own thresholds, 2^-26 and 2^-48, lie between)
SINE_IN, SINE_OUT = 2.0**-28, 2.0**-24
PLANE_IN, PLANE_OUT = 2.0**-50, 2.0**-46
#: how far apart (over the magnitudes) two surfaces' boxes may be and still meet
BOX_SLACK = 2.0**-48
#: the order of kinds in a tie, and where a rank keeps its flag of a surface that lets light through
KIND_ORDER = {"sphere": 1, "plane": 2, "triangle": 3}


def _v(a) -> np.ndarray:  # noqa: ANN001
    return np.asarray(a, dtype=np.float64)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.sum(a * b, axis=-1)`` to the bit, several times faster on many short vectors: the same products, added
    in the order the sum adds them (from +0.0, first to last: the trailing + 0.0 is that first +0.0, which only
    changes a sum of three -0.0)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2] + 0.0


def _norm(a: np.ndarray) -> np.ndarray:
    return np.sqrt(_dot(a, a))


def _unit(a: np.ndarray) -> np.ndarray:
    scale = np.max(np.abs(a), axis=-1, keepdims=True)
    scale = np.where(scale > 0, scale, 1.0)
    b = a / scale
    n = _norm(b)[..., None]
    return np.where(n > 0, b / np.where(n > 0, n, 1.0), 0.0)


def _mag(a: np.ndarray) -> np.ndarray:
    return np.max(np.abs(a), axis=-1)


@dataclass
class Surface:
    """One surface: a sphere, a plane or a triangle (a lone one or a mesh face)."""

    kind: str  # "sphere", "plane", "triangle"
    obj: int  # index in scene.objects
    face: int  # face index within a mesh, 0 otherwise
    material: str
    center: np.ndarray | None = None  # sphere
    radius: float = 0.0
    point: np.ndarray | None = None  # plane: its point; triangle: v0
    normal: np.ndarray | None = None  # unit geometric normal (planes and triangles)
    v: np.ndarray | None = None  # triangle corners (3, 3)
    vn: np.ndarray | None = None  # triangle vertex normals (3, 3), or None
    mag: float = 0.0  # largest magnitude of the numbers that define it
    rank: int = 0  # its place in a tie: the least first
    group: int = -1  # its coplanar group, −1 for none
    sure: bool = True  # whether its group (or none) is clear
    plane: tuple[np.ndarray, np.ndarray] | None = None  # its group's plane: a point and the unit normal

    @property
    def flat(self) -> bool:
        return self.kind != "sphere" and self.vn is None


def surfaces_of(scene) -> list[Surface]:  # noqa: ANN001
    """The scene's surfaces in object order, mesh faces in face order; zero-area faces are left out."""
    out: list[Surface] = []
    for k, obj in enumerate(scene.objects):
        if obj.type == "sphere":
            c = _v(obj.center)
            out.append(
                Surface(
                    "sphere",
                    k,
                    0,
                    obj.material,
                    center=c,
                    radius=float(obj.radius),
                    mag=float(_mag(c)) + float(obj.radius),
                )
            )
        elif obj.type == "plane":
            p = _v(obj.point)
            out.append(Surface("plane", k, 0, obj.material, point=p, normal=_unit(_v(obj.normal)), mag=float(_mag(p))))
        else:
            verts = _v(obj.vertices)
            faces = [(0, 1, 2)] if obj.type == "triangle" else obj.faces
            normals = None if obj.type == "triangle" or obj.normals is None else _v(obj.normals)
            for f, (i, j, m) in enumerate(faces):
                v = verts[[i, j, m]]
                n = _unit(np.cross(_unit(v[1] - v[0]), _unit(v[2] - v[0])))
                if not np.any(n != 0):
                    continue  # a face of zero area is never hit
                out.append(
                    Surface(
                        "triangle",
                        k,
                        f,
                        obj.material,
                        point=v[0],
                        normal=n,
                        v=v,
                        vn=None if normals is None else normals[[i, j, m]],
                        mag=float(np.max(np.abs(v))),
                    )
                )
    _rank(scene, out)
    _coplanar(out)
    return out


def _rank(scene, surfaces: list[Surface]) -> None:  # noqa: ANN001
    """Each surface's place in a tie: see-through last, then by kind, then by its place among its kind."""
    count = dict.fromkeys(KIND_ORDER, 0)
    for s in surfaces:
        mat = scene.materials[s.material]
        other = scene.materials[mat.checker.material] if mat.checker else mat
        through = int(mat.transmittance > 0 or other.transmittance > 0)
        s.rank = (through << 50) | (KIND_ORDER[s.kind] << 48) | count[s.kind]
        count[s.kind] += 1


def _coplanar(surfaces: list[Surface]) -> None:
    """Flat surfaces of different objects in one plane, with meeting boxes, joined into groups; a surface in a
    pair whose verdict is within the noise of the thresholds is marked unsure."""
    flat = [k for k, s in enumerate(surfaces) if s.kind != "sphere"]
    if len(flat) < 2:
        return
    f = [surfaces[k] for k in flat]
    normal = np.stack([s.normal for s in f])
    corners = np.stack([s.v if s.v is not None else np.stack([s.point] * 3) for s in f])
    plane = np.array([s.kind == "plane" for s in f])
    extent = np.where(plane, np.inf, np.max(np.ptp(corners, axis=1), axis=1))
    lo = np.where(plane[:, None], -np.inf, corners.min(axis=1))
    hi = np.where(plane[:, None], np.inf, corners.max(axis=1))
    mag, obj = np.array([s.mag for s in f]), np.array([s.obj for s in f])
    label = list(range(len(f)))

    def root(i: int) -> int:
        while label[i] != i:
            i = label[i]
        return i

    # a surface is paired only with those of later objects: two of one object (faces of a mesh) are never joined
    # nor made unsure, and surfaces come in object order, so the later objects' are those past its object's last
    after = np.searchsorted(obj, obj, side="right")
    for i in range(len(f) - 1):
        j = np.arange(after[i], len(f))
        if not len(j):
            continue
        sine = _norm(np.cross(normal[i], normal[j]))
        scale = mag[i] + mag[j]
        big_i = (extent[i] > extent[j]) | (extent[i] == extent[j])  # the larger holds the smaller's corners
        dist = np.zeros(len(j))
        for c in range(3):
            to_i = np.abs(_dot(corners[j, c] - f[i].point, normal[i]))
            to_j = np.abs(_dot(corners[i, c][None] - corners[j, 0], normal[j]))
            dist = np.maximum(dist, np.where(big_i, to_i, to_j))
        both = plane[i] & plane[j]
        dist = np.where(both, np.maximum(dist, np.abs(_dot(f[i].point - corners[j, 0], normal[j]))), dist) / scale
        slack = (BOX_SLACK * scale)[:, None]
        meet = np.all((lo[i] <= hi[j] + slack) & (lo[j] <= hi[i][None] + slack), axis=1) & (obj[j] != obj[i])
        yes = meet & (sine <= SINE_IN) & (dist <= PLANE_IN)
        unsure = meet & ~yes & (sine <= SINE_OUT) & (dist <= PLANE_OUT)
        for k in j[yes]:
            a, b = root(i), root(int(k))
            label[max(a, b)] = min(a, b)
        for k in j[unsure]:
            f[i].sure = f[int(k)].sure = False
    members: dict[int, list[int]] = {}
    for i in range(len(f)):
        members.setdefault(root(i), []).append(i)
    groups = [m for m in members.values() if len(m) > 1]
    for g, m in enumerate(groups):
        first = min(m, key=lambda i: f[i].rank & ((1 << 50) - 1))  # planes first, then by index
        for i in m:
            f[i].group, f[i].plane = g, (f[first].point, f[first].normal)


# -- one surface against many rays -------------------------------------------------------------------------------


@dataclass
class Test:
    """One surface against N rays: the hit ``t`` (inf for none), whether that answer is unclear, and where an
    unclear answer might put a hit instead (``maybe``: t itself for a hit, inf when no hit is possible)."""

    t: np.ndarray
    unclear: np.ndarray
    sigma: np.ndarray  # how far t may be off, for ties
    maybe: np.ndarray
    u: np.ndarray | None = None
    w: np.ndarray | None = None


def _distance(s: Surface, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance of points p (N, 3) from the surface (its plane, for a triangle), and the magnitude that
    scales its rounding."""
    if s.kind == "sphere":
        return _norm(p - s.center) - s.radius, _mag(p) + s.mag
    return _dot(p - s.point, s.normal), _mag(p) + s.mag


def _on(s: Surface, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(on, unclear) for points p: lies on the surface, or lies too near to say."""
    dist, scale = _distance(s, p)
    on = np.abs(dist) <= ON * scale
    return on, ~on & (np.abs(dist) <= OFF * scale)


def intersect(s: Surface, o: np.ndarray, d: np.ndarray, leaving: np.ndarray) -> Test:
    """The first hit t > 0 of rays o + t d (unit d) with the surface; ``leaving`` marks rays that start on it."""
    on, near = _on(s, o)
    on |= leaving
    near &= ~leaving
    scale = _mag(o) + s.mag
    err = ERR * scale  # how far a computed distance may be off, in world units
    if s.kind == "sphere":
        oc = o - s.center
        b = _dot(oc, d)
        perp = oc - b[:, None] * d
        h = _norm(perp)
        disc = (s.radius - h) * (s.radius + h)
        root = np.sqrt(np.maximum(disc, 0.0))
        dist = _norm(oc)
        c = (dist - s.radius) * (dist + s.radius)
        q = -b - np.where(b >= 0, root, -root)
        with np.errstate(divide="ignore", invalid="ignore"):
            t2 = np.where(q != 0, c / q, 0.0)
        lo, hi = np.minimum(q, t2), np.maximum(q, t2)
        t = np.where(lo > 0, lo, np.where(hi > 0, hi, np.inf))
        t = np.where(disc >= 0, t, np.inf)
        t = np.where(on, np.where(b < 0, -2.0 * b, np.inf), t)  # from the surface: only the far root, inward
        t = np.where(t > 0, t, np.inf)
        grazing = np.abs(s.radius - h) <= GRAY * s.radius + err
        turning = on & (np.abs(b) <= GRAY * s.radius + err)  # leaving along the tangent
        with np.errstate(divide="ignore", invalid="ignore"):
            sigma = err * (1.0 + h / root)  # an error err in h moves the roots by h·err/root
        maybe = np.where(np.isfinite(t), t, np.where(grazing & (b < 0), -b, np.inf))
        maybe = np.where(near | turning, 0.0, maybe)
        return Test(t, near | turning | (grazing & np.isfinite(maybe)), sigma, maybe)
    return flat_tests([s], o, d, leaving[None])


def flat_tests(flat: list[Surface], o: np.ndarray, d: np.ndarray, leaving: np.ndarray) -> Test:
    """Planes and triangles ``flat`` (F of them) against N rays at once: a :class:`Test` of (F, N) arrays.
    ``leaving (F, N)`` marks the rays that start on each surface."""
    normal = np.stack([s.normal for s in flat])[:, None, :]  # (F, 1, 3)
    point = np.stack([s.point for s in flat])[:, None, :]
    mag = np.array([s.mag for s in flat])[:, None]
    dist = _dot(o[None] - point, normal)  # (F, N)
    scale = _mag(o)[None] + mag
    on = (np.abs(dist) <= ON * scale) | leaving
    near = ~on & (np.abs(dist) <= OFF * scale)
    err = ERR * scale
    denom = _dot(d[None], normal)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -dist / denom
        sigma = err / np.abs(denom)
    crossing = (denom != 0) & (t > 0) & np.isfinite(t)
    ok = ~on & crossing
    maybe = np.where(near, 0.0, np.inf)
    unclear = near.copy()
    u = np.zeros(t.shape)
    w = np.zeros(t.shape)
    tri = np.array([s.kind == "triangle" for s in flat])
    if tri.any():
        v = np.stack([s.v for s in flat if s.kind == "triangle"])  # (T, 3, 3)
        rows = np.flatnonzero(tri)
        tt, cr = t[rows], crossing[rows]
        p = o[None] + np.where(cr, tt, 0.0)[..., None] * d[None]  # (T, N, 3) the crossings
        e1, e2 = (v[:, 1] - v[:, 0])[:, None], (v[:, 2] - v[:, 0])[:, None]
        rel = p - v[:, None, 0]
        # barycentrics of the crossing, from the two edges (least squares in the plane)
        g11, g12, g22 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2)
        r1, r2 = _dot(rel, e1), _dot(rel, e2)
        det = g11 * g22 - g12 * g12
        uu = (g22 * r1 - g12 * r2) / det
        ww = (g11 * r2 - g12 * r1) / det
        edge = np.minimum(np.minimum(uu, ww), 1.0 - uu - ww)
        size = np.sqrt(np.maximum(g11, g22))
        with np.errstate(invalid="ignore"):
            slack = GRAY + (err[rows] + np.where(np.isfinite(sigma[rows]), sigma[rows], 0.0)) / size
        at_edge = ok[rows] & (np.abs(edge) <= slack)
        unclear[rows] |= at_edge
        maybe[rows] = np.where(at_edge, tt, maybe[rows])
        ok[rows] &= edge >= 0
        u[rows], w[rows] = uu, ww
    t = np.where(ok, t, np.inf)
    maybe = np.where(ok, t, maybe)
    return Test(t, unclear, sigma, maybe, u, w)


def tests_of(surfaces: list[Surface], o: np.ndarray, d: np.ndarray, start: np.ndarray) -> Test:
    """Every surface against every ray: a :class:`Test` of (S, N) arrays, in the order of ``surfaces``."""
    n, count = len(o), len(surfaces)
    out = Test(
        np.full((count, n), np.inf),
        np.zeros((count, n), bool),
        np.zeros((count, n)),
        np.full((count, n), np.inf),
        np.zeros((count, n)),
        np.zeros((count, n)),
    )
    flat = [k for k, s in enumerate(surfaces) if s.kind != "sphere"]
    leaves = _leaving(surfaces, start)
    for k, s in enumerate(surfaces):
        if s.kind == "sphere":
            x = intersect(s, o, d, start == k)
            out.t[k], out.unclear[k], out.sigma[k], out.maybe[k] = x.t, x.unclear, x.sigma, x.maybe
    step = max(1, (1 << 21) // max(n, 1))  # bounded temporaries: (surfaces, rays, 3) at a time
    for a in range(0, len(flat), step):
        rows = np.array(flat[a : a + step])
        x = flat_tests([surfaces[k] for k in rows], o, d, leaves(rows))
        assert x.u is not None and x.w is not None
        out.t[rows], out.unclear[rows], out.sigma[rows], out.maybe[rows] = x.t, x.unclear, x.sigma, x.maybe
        out.u[rows], out.w[rows] = x.u, x.w  # type: ignore[index]
    return out


def _leaving(surfaces: list[Surface], start: np.ndarray):  # noqa: ANN202
    """``rows (F,)`` → ``(F, N)``: which rays leave each of those surfaces (start on it or on a member of its
    coplanar group)."""
    group = np.array([s.group for s in surfaces] + [-1])
    from_group = group[np.where((start >= 0) & (start < len(surfaces)), start, -1)]

    def leaves(rows: np.ndarray) -> np.ndarray:
        mine = group[rows][:, None]
        return (start[None] == rows[:, None]) | ((mine >= 0) & (from_group[None] == mine))

    return leaves


# -- rays through the scene ------------------------------------------------------------------------------------


@dataclass
class Hits:
    t: np.ndarray  # (N,)
    surface: np.ndarray  # (N,) index into the surface list, -1 for a miss
    unclear: np.ndarray  # (N,)
    u: np.ndarray = field(default_factory=lambda: np.zeros(0))
    w: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: (N,) the ray met, at its t, members of its hit's coplanar group of two objects: a tie left open
    open: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))


def _timed_on_groups(surfaces: list[Surface], x: Test, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The hits ``x.t`` (S, N), those of coplanar groups' members on their group's plane (where it has one)."""
    t = x.t.copy()
    for k, s in enumerate(surfaces):
        if s.plane is None:
            continue
        point, normal = s.plane
        with np.errstate(divide="ignore", invalid="ignore"):
            shared = -_dot(o - point, normal) / _dot(d, normal)
        ok = np.isfinite(t[k]) & np.isfinite(shared) & (shared > 0)
        t[k] = np.where(ok, shared, t[k])
        x.maybe[k] = np.where(ok, shared, x.maybe[k])
    return t


def closest(surfaces: list[Surface], o: np.ndarray, d: np.ndarray, start: np.ndarray) -> Hits:
    """First hits of rays that leave surfaces ``start`` (index, −1 for none)."""
    n = len(o)
    if not surfaces:
        return Hits(np.full(n, np.inf), np.full(n, -1), np.zeros(n, bool), np.zeros(n), np.zeros(n), np.zeros(n, bool))
    x = tests_of(surfaces, o, d, start)
    t = _timed_on_groups(surfaces, x, o, d)  # (S, N)
    rank = np.array([s.rank for s in surfaces])
    bt = np.min(t, axis=0)
    best = np.argmin(np.where(t == bt[None], rank[:, None], np.iinfo(np.int64).max), axis=0)  # ties by rank
    cols = np.arange(n)
    sig = np.where(np.isfinite(x.sigma), x.sigma, np.inf)
    maybe, unclear = x.maybe, x.unclear
    reach = np.where(np.isfinite(bt), bt + sig[best, cols] + GRAY * bt, np.inf)
    # a rival: another surface whose hit, or possible hit, lies within noise of the best (or before it); but a
    # member of the best's group (both surely grouped) that it meets too, or that would lose the tie, is none
    rival = (maybe <= reach[None] + np.where(np.isfinite(maybe), sig, 0.0)) & np.isfinite(maybe)
    rival &= np.arange(len(surfaces))[:, None] != best[None]
    rival &= unclear | np.isfinite(t)
    group = np.array([s.group for s in surfaces])
    sure = np.array([s.sure for s in surfaces])
    obj = np.array([s.obj for s in surfaces])
    mates = (group[:, None] == group[best][None]) & ((group[best] >= 0) & np.isfinite(bt))[None]
    mates &= sure[:, None] & sure[best][None]
    rival &= ~(mates & (np.isfinite(t) | (rank[:, None] > rank[best][None])))
    tied = mates & (obj[:, None] != obj[best][None]) & (np.arange(len(surfaces))[:, None] != best[None])
    opened = np.any(tied & (t == bt[None]), axis=0) & np.isfinite(bt)
    maybe_open = np.any(tied & unclear & np.isfinite(maybe), axis=0)  # a member that may be met as well
    amb = (unclear[best, cols] & np.isfinite(bt)) | np.any(rival, axis=0) | maybe_open
    assert x.u is not None and x.w is not None
    us, ws = x.u, x.w
    surface = np.where(np.isfinite(bt), best, -1)
    return Hits(bt, surface, amb, us[best, cols], ws[best, cols], opened)


def blocked(
    surfaces: list[Surface],
    p: np.ndarray,
    to: np.ndarray,
    reach: np.ndarray,
    start: np.ndarray,
    light: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Shadow decisions from points p towards unit directions ``to`` over distances ``reach`` (inf for a
    directional light), towards the light position ``light`` (3,) or None: (blocked, unclear)."""
    n = len(p)
    if not surfaces:
        return np.zeros(n, bool), np.zeros(n, bool)
    x = tests_of(surfaces, p, to, start)
    t, unclear, maybe, sigma = x.t, x.unclear, x.maybe, x.sigma
    leaves = _leaving(surfaces, start)
    for k, s in enumerate(surfaces if light is not None else []):
        assert light is not None
        on_l, near_l = (a[0] for a in _on(s, light[None]))
        if s.kind == "sphere" and (on_l or near_l):
            # the light is a root; only the other one (their product is c) may block
            oc = p - s.center
            c = (_norm(oc) - s.radius) * (_norm(oc) + s.radius)
            with np.errstate(divide="ignore", invalid="ignore"):
                other = np.where(reach > 0, c / reach, np.inf)
            other = np.where(start == k, np.inf, other)  # from the sphere to a light on it: nothing between
            other = np.where(other > 0, other, np.inf)
            near_end = np.abs(other - reach) <= GRAY * reach + sigma[k]
            if on_l:
                t[k] = np.where(near_end, np.inf, other)
                unclear[k] |= near_end
                maybe[k] = np.where(near_end, reach, t[k])
            else:
                unclear[k] |= np.isfinite(t[k])
        elif on_l:  # a plane through the light meets the segment only there (or holds all of it)
            t[k] = np.inf
            unclear[k] = _on(s, p)[1] & ~leaves(np.array([k]))[0]  # unless the origin is too near the plane to say
            maybe[k] = np.where(unclear[k], 0.0, np.inf)
        elif near_l:
            unclear[k] |= np.isfinite(t[k])
    with np.errstate(invalid="ignore"):
        at_end = np.isfinite(t) & np.isfinite(reach)[None] & (np.abs(t - reach[None]) <= GRAY * reach[None] + sigma)
        sure = np.any((t < reach[None]) & ~unclear & ~at_end, axis=0)
        amb = np.any((unclear & (maybe < reach[None] + sigma)) | at_end, axis=0)
    return sure, amb & ~sure


# -- lights -----------------------------------------------------------------------------------------------------


@dataclass
class Emitter:
    kind: str  # "directional" or "point"
    color: np.ndarray
    position: np.ndarray | None
    direction: np.ndarray | None  # the way light travels (directional, spot)
    attenuation: tuple[float, float, float]
    cos_outer: float | None = None
    cos_inner: float | None = None
    exponent: float = 0.0


def emitters_of(scene) -> tuple[np.ndarray, list[Emitter]]:  # noqa: ANN001
    ambient = np.zeros(3)
    out: list[Emitter] = []
    for light in scene.lights:
        c = _v(light.color)
        if light.type == "ambient":
            ambient += c
        elif light.type == "directional":
            out.append(Emitter("directional", c, None, _unit(_v(light.direction)), (1.0, 0.0, 0.0)))
        elif light.type == "point":
            out.append(Emitter("point", c, _v(light.position), None, tuple(light.attenuation)))
        elif light.type == "spot":
            inner = light.cutoff if light.inner_cutoff is None else light.inner_cutoff
            out.append(
                Emitter(
                    "point",
                    c,
                    _v(light.position),
                    _unit(_v(light.direction)),
                    tuple(light.attenuation),
                    math.cos(math.radians(light.cutoff)),
                    math.cos(math.radians(inner)),
                    light.exponent,
                )
            )
        else:
            nu, nv = light.samples
            corner, eu, ev = _v(light.corner), _v(light.edge_u), _v(light.edge_v)
            for i in range(nu):
                for j in range(nv):
                    pos = corner + ((i + 0.5) / nu) * eu + ((j + 0.5) / nv) * ev
                    out.append(Emitter("point", c / (nu * nv), pos, None, tuple(light.attenuation)))
    return ambient, out


def illuminate(e: Emitter, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Towards-light L, distance d, intensity factor f (times colour) and whether f is unclear, at points p."""
    n = len(p)
    if e.kind == "directional":
        assert e.direction is not None
        return np.broadcast_to(-e.direction, (n, 3)), np.full(n, np.inf), np.ones(n), np.zeros(n, bool)
    assert e.position is not None
    v = e.position - p
    dist = _norm(v)
    with np.errstate(divide="ignore", invalid="ignore"):
        L = v / np.where(dist > 0, dist, 1.0)[:, None]
    c, lin, q = e.attenuation
    denom = c + lin * dist + q * dist * dist
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where((dist > 0) & (denom > 0), 1.0 / np.where(denom > 0, denom, 1.0), 0.0)
    unclear = np.zeros(n, bool)
    if e.cos_outer is not None:
        assert e.direction is not None and e.cos_inner is not None
        s = _dot(-L, e.direction)
        span = e.cos_inner - e.cos_outer
        with np.errstate(divide="ignore", invalid="ignore"):
            ramp = np.where(s >= e.cos_inner, 1.0, (s - e.cos_outer) / (span if span > 0 else 1.0))
            powered = np.where(s > 0, np.power(np.maximum(s, 0.0), e.exponent), 0.0 if e.exponent > 0 else 1.0)
        f = f * np.where(s < e.cos_outer, 0.0, powered * ramp)
        if span <= 0:  # a hard edge: the factor jumps there
            unclear |= np.abs(s - e.cos_outer) <= GRAY
        if e.exponent == 0:
            unclear |= np.abs(s) <= GRAY
    return L, dist, f, unclear


def in_plane(s: Surface, e: Emitter) -> tuple[bool, bool]:
    """Whether the light lies in a flat surface's plane (N·L is then 0 there), and whether that is unclear."""
    if not s.flat:
        return False, False
    if e.kind == "directional":
        assert e.direction is not None and s.normal is not None
        cos = abs(float(np.dot(e.direction, s.normal)))
        return cos <= ON, ON < cos <= GRAY
    assert e.position is not None
    on, unclear = _on(s, e.position[None])
    return bool(on[0]), bool(unclear[0])


def n_dot_l(
    surfaces: list[Surface], which: np.ndarray, e: Emitter, normal: np.ndarray, L: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """N·L at points on the surfaces ``which`` (index per point) for their facing shading normals: 0 where the
    light lies in a flat surface's plane; and whether it is unclear."""
    nl = _dot(normal, L)
    flags = np.array([in_plane(surfaces[k], e) for k in range(len(surfaces))], dtype=bool).reshape(-1, 2)
    planar, near = flags[which, 0], flags[which, 1]
    return np.where(planar, 0.0, nl), ~planar & (near | (np.abs(nl) <= GRAY))


# -- the image --------------------------------------------------------------------------------------------------


def camera_rays(scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # noqa: ANN001
    """Origins, directions and pixel index of every sub-sample, pixel-major, sub-sample (a, b) at b·n + a."""
    cam, img = scene.camera, scene.image
    eye = _v(cam.position)
    f = _unit(_v(cam.look_at) - eye)
    r = _unit(np.cross(f, _unit(_v(cam.up))))
    u = np.cross(r, f)
    W, H, n = img.width, img.height, img.samples
    j, i, b, a = np.meshgrid(np.arange(H), np.arange(W), np.arange(n), np.arange(n), indexing="ij")
    i, j, a, b = (np.transpose(x, (0, 1, 2, 3)).reshape(-1) for x in (i, j, a, b))
    sx = (i + (a + 0.5) / n) / W
    sy = (j + (b + 0.5) / n) / H
    if cam.type == "orthographic":
        h = cam.height / 2.0
    else:
        h = math.tan(math.radians(cam.fov) / 2.0)
    x = (2.0 * sx - 1.0) * (W / H) * h
    y = (1.0 - 2.0 * sy) * h
    plane = x[:, None] * r + y[:, None] * u
    if cam.type == "orthographic":
        o = eye + plane
        d = np.broadcast_to(f, o.shape).copy()
    else:
        o = np.broadcast_to(eye, plane.shape).copy()
        d = _unit(f + plane)
    return o, d, j * W + i


@dataclass
class Frame:
    """What the brute force rendered: linear colour per pixel before clamping, and which pixels are unclear."""

    colour: np.ndarray  # (H, W, 3)
    unclear: np.ndarray  # (H, W) bool
    open: np.ndarray  # (H, W) bool: a ray of the pixel's tree met a tie left open (:attr:`Hits.open`)

    def pixels(self) -> np.ndarray:
        v = np.clip(np.nan_to_num(self.colour, nan=0.0), 0.0, 1.0)
        return np.floor(255.0 * v + 0.5).astype(np.uint8)


def _checker_material(scene, s: Surface, p: np.ndarray, index=np.floor) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """Per hit point: whether the checker's other material applies, and whether that is unclear.  ``index`` takes
    a coordinate in cells to its cell's index (``np.trunc``: a student's ``int()``, for tests/student.py)."""
    mat = scene.materials[s.material]
    n = len(p)
    if mat.checker is None:
        return np.zeros(n, bool), np.zeros(n, bool)
    size = mat.checker.size
    q = p
    if s.kind != "sphere":
        q = p - _dot(p - s.point, s.normal)[:, None] * s.normal
    cell = q / size
    idx = index(cell)
    odd = np.mod(np.sum(idx, axis=1), 2.0) == 1.0
    frac = np.abs(cell - np.round(cell))
    exact_axis = np.zeros((n, 3), bool)
    if s.kind != "sphere":
        for k in range(3):  # a flat surface facing an axis lies exactly on its coordinate
            if abs(s.normal[k]) == 1.0:
                exact_axis[:, k] = True
    near = (frac <= GRAY * (np.abs(cell) + 1.0) + OFF * _mag(p)[:, None] / size) & ~exact_axis
    return odd, np.any(near, axis=1)


def surface_point(
    s: Surface, o: np.ndarray, d: np.ndarray, t: np.ndarray, u: np.ndarray, w: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hit points on the surface (moved onto it), geometric normals, and shading normals facing the rays."""
    if s.kind == "sphere":
        assert s.center is not None
        geo = _unit(o + t[:, None] * d - s.center)
        p = s.center + s.radius * geo
    elif s.kind == "plane":
        assert s.point is not None and s.normal is not None
        raw = o + t[:, None] * d
        p = raw - _dot(raw - s.point, s.normal)[:, None] * s.normal
        geo = np.broadcast_to(s.normal, p.shape)
    else:
        assert s.v is not None and s.normal is not None
        p = s.v[0] + u[:, None] * (s.v[1] - s.v[0]) + w[:, None] * (s.v[2] - s.v[0])
        geo = np.broadcast_to(s.normal, p.shape)
    shading = np.array(geo, dtype=np.float64)
    if s.vn is not None:
        blend = _unit((1 - u - w)[:, None] * s.vn[0] + u[:, None] * s.vn[1] + w[:, None] * s.vn[2])
        zero = ~np.any(blend != 0, axis=1)
        shading = np.where(zero[:, None], geo, blend)
    flip = _dot(shading, d) > 0
    shading[flip] *= -1.0
    return p, np.array(geo), shading


def render(scene) -> Frame:  # noqa: ANN001
    """The scene's image by brute force, with the pixels that met something unclear marked."""
    img = scene.image
    surfaces = surfaces_of(scene)
    ambient, emitters = emitters_of(scene)
    o, d, pixel = camera_rays(scene)
    n_px = img.width * img.height
    spp = img.samples * img.samples
    colour = np.zeros((n_px, 3))
    unclear_px = np.zeros(n_px, bool)
    open_px = np.zeros(n_px, bool)
    weight = np.ones(len(o))
    start = np.full(len(o), -1)
    background = _v(img.background)
    for depth in range(img.max_depth + 1):
        if len(o) == 0:
            break
        hits = closest(surfaces, o, d, start)
        live = weight > 2.0**-24
        np.logical_or.at(unclear_px, pixel[hits.unclear & live], True)
        np.logical_or.at(open_px, pixel[hits.open], True)
        miss = hits.surface < 0
        np.add.at(colour, pixel[miss], weight[miss, None] * background)
        rows = np.flatnonzero(~miss)
        if len(rows) == 0:
            break
        which = hits.surface[rows]
        rd, rw, rp = d[rows], weight[rows], pixel[rows]
        p, geo, shading = np.zeros((len(rows), 3)), np.zeros((len(rows), 3)), np.zeros((len(rows), 3))
        mats = {name: np.zeros((len(rows), 3)) for name in ("ambient", "diffuse", "specular")}
        mats.update({name: np.zeros(len(rows)) for name in ("shininess", "reflectance", "transmittance", "ior")})
        unclear = np.zeros(len(rows), bool)
        for k in np.unique(which):  # the geometry and the material of each surface's hits
            sel = np.flatnonzero(which == k)
            s = surfaces[k]
            r = rows[sel]
            p[sel], geo[sel], shading[sel] = surface_point(s, o[r], d[r], hits.t[r], hits.u[r], hits.w[r])
            other, unclear_mat = _checker_material(scene, s, p[sel])
            unclear[sel] |= unclear_mat
            main = scene.materials[s.material]
            alt = scene.materials[main.checker.material] if main.checker else main
            for name, a in mats.items():
                a[sel] = np.where(
                    other[:, None] if a.ndim == 2 else other, _v(getattr(alt, name)), _v(getattr(main, name))
                )
        c = mats["ambient"] * ambient
        view = -rd
        for e in emitters:  # every hit point's shadow ray to one light at once
            L, dist, f, unclear_f = illuminate(e, p)
            nl, unclear_nl = n_dot_l(surfaces, which, e, shading, L)
            unclear |= (unclear_nl & (f > 0)) | unclear_f
            sel = np.flatnonzero((nl > 0) & (f > 0))
            if len(sel) == 0:
                continue
            blk, unclear_b = blocked(surfaces, p[sel], L[sel], dist[sel], which[sel], e.position)
            unclear[sel] |= unclear_b
            lit = np.zeros(len(rows), bool)
            lit[sel] = ~blk
            rv = _dot(2.0 * nl[:, None] * shading - L, view)  # R·V, R = 2(N·L)N − L
            with np.errstate(over="ignore", invalid="ignore"):
                spec = np.where(rv > 0, np.power(np.where(rv > 0, rv, 1.0), mats["shininess"]), 0.0)
            term = mats["diffuse"] * nl[:, None] + mats["specular"] * spec[:, None]
            c += np.where(lit[:, None], e.color * f[:, None] * term, 0.0)
        np.add.at(colour, rp, rw[:, None] * c)
        np.logical_or.at(unclear_px, rp[unclear & (rw > 2.0**-24)], True)
        if depth == img.max_depth:
            break
        kr, kt, ior = mats["reflectance"], mats["transmittance"], mats["ior"]
        refl = np.flatnonzero(rw * kr > 0)
        dd, nn = rd[refl], shading[refl]
        mirror = _unit(dd - 2.0 * _dot(dd, nn)[:, None] * nn)
        trans = np.flatnonzero(rw * kt > 0)
        dd, g = rd[trans], geo[trans]
        entering = _dot(dd, g) < 0
        eta = np.where(entering, 1.0 / ior[trans], ior[trans])
        wn = np.where(entering[:, None], g, -g)
        cc = -_dot(dd, wn)
        kk = 1.0 - eta * eta * (1.0 - cc * cc)
        through = eta[:, None] * dd + (eta * cc - np.sqrt(np.maximum(kk, 0.0)))[:, None] * wn
        bounce = dd - 2.0 * _dot(dd, wn)[:, None] * wn
        refracted = _unit(np.where((kk < 0)[:, None], bounce, through))
        np.logical_or.at(unclear_px, rp[trans][(np.abs(kk) <= GRAY) & (rw[trans] > 2.0**-24)], True)
        o = np.concatenate([p[refl], p[trans]])
        d = np.concatenate([mirror, refracted])
        weight = np.concatenate([rw[refl] * kr[refl], rw[trans] * kt[trans]])
        pixel = np.concatenate([rp[refl], rp[trans]])
        start = np.concatenate([which[refl], which[trans]])
    colour /= spp
    shape = (img.height, img.width)
    return Frame(colour.reshape(*shape, 3), unclear_px.reshape(shape), open_px.reshape(shape))
