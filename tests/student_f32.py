"""A third student's ray tracer: single precision, its own intersections, the textbook's epsilon.

Written from the scene format alone, as a student who learnt ray tracing from a GPU course writes it: every
number a float32, NumPy over all rays at once, one surface at a time, and the classic ways of keeping a ray
off the surface it leaves: the origin moved ``eps`` along the shading normal turned to face the ray (against
it for a refracted ray), or a t_min, hits nearer than ``eps`` ignored.  Nothing comes from ``tracer/`` or
from the other students (tests/student.py takes its hits from the brute force; tests/student_oop.py traces a
ray at a time in Python floats): its rounding is its own.  It has no mistakes: it is an honest student, whose
images the grade must pass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

F = np.float32
#: the textbook's epsilon, in the scene's units
EPS = 1e-3


@dataclass(frozen=True)
class Style:
    """How the student keeps rays off a surface: ``eps`` along the facing normal (``"normal"``) or a t_min
    (``"ray"``)."""

    eps: float = EPS
    along: str = "normal"


def _f(a) -> np.ndarray:  # noqa: ANN001
    return np.asarray(a, dtype=F)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _unit(a: np.ndarray) -> np.ndarray:
    return (a / np.sqrt(np.einsum("...i,...i->...", a, a))[..., None]).astype(F)


@dataclass
class Shapes:
    """Every surface: spheres, planes and triangles (meshes' faces among them), each with its object's index."""

    centres: np.ndarray
    radii: np.ndarray
    sphere_obj: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    plane_obj: np.ndarray
    corners: np.ndarray  # (T, 3, 3)
    face_normals: np.ndarray  # (T, 3)
    vertex_normals: np.ndarray  # (T, 3, 3): the face normal thrice where the mesh gives none
    tri_obj: np.ndarray


def shapes_of(scene) -> Shapes:  # noqa: ANN001
    centres, radii, sobj, points, normals, pobj, corners, vnormals, tobj = [], [], [], [], [], [], [], [], []
    for k, obj in enumerate(scene.objects):
        if obj.type == "sphere":
            centres.append(obj.center)
            radii.append(obj.radius)
            sobj.append(k)
        elif obj.type == "plane":
            points.append(obj.point)
            n = np.asarray(obj.normal, dtype=np.float64)
            normals.append(n / np.linalg.norm(n))
            pobj.append(k)
        else:
            verts = np.asarray(obj.vertices, dtype=np.float64)
            faces = np.asarray([[0, 1, 2]] if obj.type == "triangle" else obj.faces, dtype=np.int64).reshape(-1, 3)
            given = getattr(obj, "normals", None)
            for face in faces:
                tri = verts[face]
                cross = np.cross(tri[1] - tri[0], tri[2] - tri[0])
                if np.linalg.norm(cross) == 0:
                    continue  # a face of zero area is never hit
                corners.append(tri)
                vnormals.append(np.asarray(given, dtype=np.float64)[face] if given else np.repeat([cross], 3, 0))
                tobj.append(k)
    tris = _f(corners).reshape(-1, 3, 3)
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]) if len(tris) else np.zeros((0, 3), F)
    return Shapes(
        _f(centres).reshape(-1, 3),
        _f(radii),
        np.array(sobj, dtype=np.int64),
        _f(points).reshape(-1, 3),
        _f(normals).reshape(-1, 3),
        np.array(pobj, dtype=np.int64),
        tris,
        _unit(_f(cross)) if len(tris) else _f(cross),
        _f(vnormals).reshape(-1, 3, 3),
        np.array(tobj, dtype=np.int64),
    )


@dataclass
class Hit:
    t: np.ndarray
    kind: np.ndarray  # 0 none, 1 sphere, 2 plane, 3 triangle
    index: np.ndarray
    u: np.ndarray
    v: np.ndarray


def _sphere_t(c: np.ndarray, r: F, o: np.ndarray, d: np.ndarray, tmin: F) -> np.ndarray:
    oc = o - c
    b = _dot(oc, d)
    disc = b * b - (_dot(oc, oc) - r * r)
    root = np.sqrt(np.maximum(disc, F(0)))
    near, far = -b - root, -b + root
    t = np.where(near > tmin, near, np.where(far > tmin, far, np.inf)).astype(F)
    return np.where(disc >= 0, t, np.inf).astype(F)


def _triangles(shapes: Shapes, o: np.ndarray, d: np.ndarray, tmin: F, best: Hit, rays: int = 2048) -> None:
    """Möller–Trumbore, a block of rays at a time against blocks of triangles."""
    for start in range(0, len(o), rays):
        part = Hit(*(a[start : start + rays] for a in (best.t, best.kind, best.index, best.u, best.v)))
        _triangle_block(shapes, o[start : start + rays], d[start : start + rays], tmin, part)
        for mine, whole in zip(
            (part.t, part.kind, part.index, part.u, part.v), (best.t, best.kind, best.index, best.u, best.v)
        ):
            whole[start : start + rays] = mine


def _triangle_block(shapes: Shapes, o: np.ndarray, d: np.ndarray, tmin: F, best: Hit, block: int = 256) -> None:
    for first in range(0, len(shapes.corners), block):
        tri = shapes.corners[first : first + block]
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        p = np.cross(d[:, None, :], e2[None])
        det = np.einsum("rtk,tk->rt", p, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = F(1) / det
            s = o[:, None, :] - tri[None, :, 0]
            u = np.einsum("rtk,rtk->rt", s, p) * inv
            q = np.cross(s, e1[None])
            v = np.einsum("rk,rtk->rt", d, q) * inv
            t = np.einsum("tk,rtk->rt", e2, q) * inv
        ok = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > tmin)
        t = np.where(ok, t, np.inf).astype(F)
        k = np.argmin(t, axis=1)
        rows = np.arange(len(o))
        tk = t[rows, k]
        better = tk < best.t
        best.t[better], best.kind[better], best.index[better] = tk[better], 3, first + k[better]
        best.u[better], best.v[better] = u[rows, k][better], v[rows, k][better]


def closest(shapes: Shapes, o: np.ndarray, d: np.ndarray, tmin: F) -> Hit:
    n = len(o)
    best = Hit(np.full(n, np.inf, F), np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, F), np.zeros(n, F))
    for i in range(len(shapes.radii)):
        t = _sphere_t(shapes.centres[i], shapes.radii[i], o, d, tmin)
        better = t < best.t
        best.t[better], best.kind[better], best.index[better] = t[better], 1, i
    for i in range(len(shapes.points)):
        n_ = shapes.normals[i]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (_dot(np.broadcast_to(shapes.points[i], o.shape) - o, np.broadcast_to(n_, o.shape))) / (d @ n_)
        t = np.where(np.isfinite(t) & (t > tmin), t, np.inf).astype(F)
        better = t < best.t
        best.t[better], best.kind[better], best.index[better] = t[better], 2, i
    if len(shapes.corners):
        _triangles(shapes, o, d, tmin, best)
    return best


def blocked(shapes: Shapes, o: np.ndarray, to: np.ndarray, dist: np.ndarray, tmin: F) -> np.ndarray:
    hit = closest(shapes, o, to, tmin)
    return hit.t < dist


@dataclass
class Lamp:
    color: np.ndarray
    position: np.ndarray | None
    direction: np.ndarray | None
    attenuation: tuple[float, float, float]
    cone: tuple[float, float, float] | None  # cos outer, cos inner, exponent


def lamps_of(scene) -> tuple[np.ndarray, list[Lamp]]:  # noqa: ANN001
    ambient, out = np.zeros(3, F), []
    for light in scene.lights:
        color = _f(light.color)
        att = tuple(getattr(light, "attenuation", (1.0, 0.0, 0.0)))
        if light.type == "ambient":
            ambient = ambient + color
        elif light.type == "directional":
            out.append(Lamp(color, None, _unit(_f(light.direction)), att, None))
        elif light.type == "point":
            out.append(Lamp(color, _f(light.position), None, att, None))
        elif light.type == "spot":
            inner = light.cutoff if light.inner_cutoff is None else light.inner_cutoff
            cone = (math.cos(math.radians(light.cutoff)), math.cos(math.radians(inner)), light.exponent)
            out.append(Lamp(color, _f(light.position), _unit(_f(light.direction)), att, cone))
        else:
            nu, nv = light.samples
            corner, eu, ev = _f(light.corner), _f(light.edge_u), _f(light.edge_v)
            for i in range(nu):
                for j in range(nv):
                    at = corner + F((i + 0.5) / nu) * eu + F((j + 0.5) / nv) * ev
                    out.append(Lamp(color / F(nu * nv), at, None, att, None))
    return ambient, out


def shine(lamp: Lamp, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if lamp.position is None:
        assert lamp.direction is not None
        return np.broadcast_to(-lamp.direction, p.shape), np.full(len(p), np.inf, F), np.ones(len(p), F)
    v = lamp.position - p
    d = np.sqrt(_dot(v, v))
    c, lin, q = lamp.attenuation
    with np.errstate(divide="ignore", invalid="ignore"):
        strength = np.where(d > 0, F(1) / (F(c) + F(lin) * d + F(q) * d * d), F(0)).astype(F)
        to = (v / d[:, None]).astype(F)
    if lamp.cone is not None:
        assert lamp.direction is not None
        outer, inner, exponent = lamp.cone
        s = -to @ lamp.direction
        ramp = np.clip((s - F(outer)) / F(inner - outer), 0, 1) if inner > outer else np.ones_like(s)
        strength = strength * np.where(s >= F(outer), ramp * np.maximum(s, F(0)) ** F(exponent), F(0)).astype(F)
    return to, d.astype(F), strength


def camera_rays(scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # noqa: ANN001
    cam, img = scene.camera, scene.image
    w, h, n = img.width, img.height, img.samples
    eye = _f(cam.position)
    f = _unit(_f(cam.look_at) - eye)
    r = _unit(np.cross(f, _f(cam.up)))
    u = np.cross(r, f)
    half = F(cam.height / 2 if cam.type == "orthographic" else math.tan(math.radians(cam.fov) / 2))
    j, i, b, a = np.meshgrid(
        np.arange(h, dtype=F), np.arange(w, dtype=F), np.arange(n, dtype=F), np.arange(n, dtype=F), indexing="ij"
    )
    sx = ((i + (a + F(0.5)) / F(n)) / F(w)).ravel()
    sy = ((j + (b + F(0.5)) / F(n)) / F(h)).ravel()
    x = (F(2) * sx - F(1)) * F(w / h) * half
    y = (F(1) - F(2) * sy) * half
    across = x[:, None] * r + y[:, None] * u
    pixel = (j.astype(np.int64) * w + i.astype(np.int64)).ravel()
    if cam.type == "orthographic":
        return (eye + across).astype(F), np.broadcast_to(f, across.shape).astype(F), pixel
    return np.broadcast_to(eye, across.shape).astype(F), _unit(f + across), pixel


MATERIAL_KEYS = ("ambient", "diffuse", "specular", "shininess", "reflectance", "transmittance", "ior")


def surface(scene, shapes: Shapes, o: np.ndarray, d: np.ndarray, hit: Hit) -> tuple:  # noqa: ANN001
    """Hit points, geometric normals, shading normals and the object of each hit."""
    p = (o + hit.t[:, None] * d).astype(F)
    geo, shade, obj = np.zeros_like(p), np.zeros_like(p), np.zeros(len(p), np.int64)
    s = hit.kind == 1
    geo[s] = (p[s] - shapes.centres[hit.index[s]]) / shapes.radii[hit.index[s]][:, None]
    obj[s] = shapes.sphere_obj[hit.index[s]]
    pl = hit.kind == 2
    geo[pl] = shapes.normals[hit.index[pl]]
    obj[pl] = shapes.plane_obj[hit.index[pl]]
    shade[:] = geo
    tr = hit.kind == 3
    k = hit.index[tr]
    geo[tr] = shapes.face_normals[k]
    obj[tr] = shapes.tri_obj[k]
    uu, vv = hit.u[tr][:, None], hit.v[tr][:, None]
    vn = shapes.vertex_normals[k]
    blend = (F(1) - uu - vv) * vn[:, 0] + uu * vn[:, 1] + vv * vn[:, 2]
    length = np.sqrt(np.einsum("ij,ij->i", blend, blend))
    shade[tr] = np.where(length[:, None] > 0, blend / np.where(length > 0, length, 1)[:, None], geo[tr])
    return p, geo, shade, obj


def materials_at(scene, p: np.ndarray, geo: np.ndarray, obj: np.ndarray) -> dict[str, np.ndarray]:  # noqa: ANN001
    out = {
        key: np.zeros((len(p), 3) if key in ("ambient", "diffuse", "specular") else len(p), F) for key in MATERIAL_KEYS
    }
    for k in np.unique(obj):
        at = obj == k
        item = scene.objects[k]
        main = scene.materials[item.material]
        other = np.zeros(int(at.sum()), bool)
        if main.checker is not None:
            q = p[at]
            if item.type != "sphere":  # flat: projected onto its plane first
                base = _f(item.point if item.type == "plane" else np.asarray(item.vertices)[0])
                n = geo[at]
                q = q - _dot(q - base, n)[:, None] * n
            cells = np.floor(q / F(main.checker.size)).astype(np.int64).sum(axis=1)
            other = cells % 2 == 1
            alt = scene.materials[main.checker.material]
        else:
            alt = main
        for key in MATERIAL_KEYS:
            a, b = _f(getattr(main, key)), _f(getattr(alt, key))
            out[key][at] = np.where(other[:, None] if a.ndim else other, b, a)
    return out


def render(scene, style: Style = Style()) -> np.ndarray:  # noqa: ANN001, C901
    """The student's ``(H, W, 3) uint8`` image of a validated scene."""
    img = scene.image
    shapes = shapes_of(scene)
    ambient, lamps = lamps_of(scene)
    eps = F(style.eps)
    t_min = eps if style.along == "ray" else F(0)
    o, d, pixel = camera_rays(scene)
    weight = np.ones(len(o), F)
    total = np.zeros((img.width * img.height, 3), F)
    background = _f(img.background)
    for depth in range(img.max_depth + 1):
        hit = closest(shapes, o, d, t_min if depth else F(0))
        missed = hit.kind == 0
        np.add.at(total, pixel[missed], weight[missed, None] * background)
        keep = ~missed
        if not keep.any():
            break
        o, d, weight, pixel = o[keep], d[keep], weight[keep], pixel[keep]
        hit = Hit(hit.t[keep], hit.kind[keep], hit.index[keep], hit.u[keep], hit.v[keep])
        p, geo, shade, obj = surface(scene, shapes, o, d, hit)
        m = materials_at(scene, p, geo, obj)
        facing = np.where((_dot(shade, d) > 0)[:, None], -shade, shade)
        lifted = (p + eps * facing).astype(F) if style.along == "normal" else p
        colour = m["ambient"] * ambient
        for lamp in lamps:
            to, dist, strength = shine(lamp, p)
            nl = _dot(facing, to)
            lit = (nl > 0) & (strength > 0)
            if lit.any():
                rows = np.flatnonzero(lit)
                lit[rows[blocked(shapes, lifted[rows], to[rows].astype(F), dist[rows], t_min)]] = False
            refl = F(2) * nl[:, None] * facing - to
            rv = _dot(refl, -d)
            spec = np.where(rv > 0, np.abs(rv) ** m["shininess"], F(0))
            term = m["diffuse"] * np.maximum(nl, F(0))[:, None] + m["specular"] * spec[:, None]
            colour += np.where(lit[:, None], lamp.color * strength[:, None] * term, F(0)).astype(F)
        np.add.at(total, pixel, weight[:, None] * colour)
        if depth == img.max_depth:
            break
        r = np.flatnonzero(weight * m["reflectance"] > 0)
        t = np.flatnonzero(weight * m["transmittance"] > 0)
        mirror = _unit(d[r] - F(2) * _dot(d[r], facing[r])[:, None] * facing[r])
        entering = _dot(d[t], geo[t]) < 0
        ior = m["ior"][t]
        eta = np.where(entering, F(1) / ior, ior)
        w = np.where(entering[:, None], geo[t], -geo[t])
        c = -_dot(d[t], w)
        k = F(1) - eta * eta * (F(1) - c * c)
        bent = eta[:, None] * d[t] + (eta * c - np.sqrt(np.maximum(k, F(0))))[:, None] * w
        bounced = d[t] - F(2) * _dot(d[t], w)[:, None] * w
        through = _unit(np.where((k < 0)[:, None], bounced, bent))
        if style.along == "normal":
            starts = [
                lifted[r],
                (p[t] + eps * np.where((_dot(through, facing[t]) < 0)[:, None], -facing[t], facing[t])).astype(F),
            ]
        else:
            starts = [p[r], p[t]]
        o = np.concatenate(starts).astype(F)
        d = np.concatenate([mirror, through]).astype(F)
        weight = np.concatenate([weight[r] * m["reflectance"][r], weight[t] * m["transmittance"][t]]).astype(F)
        pixel = np.concatenate([pixel[r], pixel[t]])
    linear = np.clip(total / F(img.samples**2), 0, 1).reshape(img.height, img.width, 3)
    return np.floor(F(255) * linear + F(0.5)).astype(np.uint8)
