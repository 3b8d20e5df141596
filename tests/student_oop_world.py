"""The second student's world (tests/student_oop.py): vectors as tuples, rays, a class per shape with its own
intersection code, a class per light with its samples, as a student writes them from the scene format."""

from __future__ import annotations

import math
from dataclasses import dataclass

Vec = tuple[float, float, float]


def add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def mul(a: Vec, s: float) -> Vec:
    return (a[0] * s, a[1] * s, a[2] * s)


def times(a: Vec, b: Vec) -> Vec:
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


def dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def length(a: Vec) -> float:
    return math.sqrt(dot(a, a))


def normalize(a: Vec) -> Vec:
    n = length(a)
    return mul(a, 1.0 / n) if n > 0 else a


def vec(v) -> Vec:  # noqa: ANN001
    return (float(v[0]), float(v[1]), float(v[2]))


BLACK: Vec = (0.0, 0.0, 0.0)


@dataclass
class Ray:
    origin: Vec
    direction: Vec

    def at(self, t: float) -> Vec:
        return add(self.origin, mul(self.direction, t))


@dataclass
class Hit:
    t: float
    shape: Shape
    normal: Vec  # geometric, as the format defines it (outward for a sphere)
    shading: Vec  # the normal for lighting (a mesh's blended vertex normals)
    blend: Vec | None = None  # a mesh's blend of vertex normals before it is normalised (None: no blend, or zero)


# -- shapes -----------------------------------------------------------------------------------------------------


class Shape:
    material: str
    flat = False

    def intersect(self, ray: Ray) -> Hit | None:
        raise NotImplementedError


class Sphere(Shape):
    def __init__(self, center: Vec, radius: float, material: str):
        self.center, self.radius, self.material = center, radius, material

    def intersect(self, ray: Ray) -> Hit | None:
        oc = sub(ray.origin, self.center)
        b = dot(oc, ray.direction)
        c = dot(oc, oc) - self.radius * self.radius
        disc = b * b - c
        if disc < 0:
            return None
        root = math.sqrt(disc)
        for t in (-b - root, -b + root):
            if t > 0:
                n = mul(sub(ray.at(t), self.center), 1.0 / self.radius)
                return Hit(t, self, n, n)
        return None


class Plane(Shape):
    flat = True

    def __init__(self, point: Vec, normal: Vec, material: str):
        self.point, self.normal, self.material = point, normalize(normal), material

    def intersect(self, ray: Ray) -> Hit | None:
        denom = dot(ray.direction, self.normal)
        if denom == 0:
            return None
        t = dot(sub(self.point, ray.origin), self.normal) / denom
        return Hit(t, self, self.normal, self.normal) if t > 0 else None


class Triangle(Shape):
    flat = True

    def __init__(self, a: Vec, b: Vec, c: Vec, material: str, normals: tuple[Vec, Vec, Vec] | None = None):
        self.a, self.e1, self.e2, self.material = a, sub(b, a), sub(c, a), material
        self.point = a
        self.normal = normalize(cross(self.e1, self.e2))
        self.normals = normals

    def intersect(self, ray: Ray) -> Hit | None:  # Möller–Trumbore
        p = cross(ray.direction, self.e2)
        det = dot(self.e1, p)
        if abs(det) < 1e-300:
            return None
        inv = 1.0 / det
        s = sub(ray.origin, self.a)
        u = dot(s, p) * inv
        if u < 0 or u > 1:
            return None
        q = cross(s, self.e1)
        v = dot(ray.direction, q) * inv
        if v < 0 or u + v > 1:
            return None
        t = dot(self.e2, q) * inv
        if t <= 0:
            return None
        if self.normals is not None:
            na, nb, nc = self.normals
            blend = add(add(mul(na, 1 - u - v), mul(nb, u)), mul(nc, v))
            if length(blend) > 0:
                return Hit(t, self, self.normal, normalize(blend), blend)
        return Hit(t, self, self.normal, self.normal)


def shapes_of(obj) -> list[Shape]:  # noqa: ANN001
    """The shapes of one object of the scene (a mesh is its faces, each a triangle)."""
    if obj.type == "sphere":
        return [Sphere(vec(obj.center), obj.radius, obj.material)]
    if obj.type == "plane":
        return [Plane(vec(obj.point), vec(obj.normal), obj.material)]
    if obj.type == "triangle":
        return [Triangle(*(vec(v) for v in obj.vertices), obj.material)]
    vs = [vec(v) for v in obj.vertices]
    ns = [vec(n) for n in obj.normals] if obj.normals is not None else None
    out: list[Shape] = []
    for i, j, k in obj.faces:
        if length(cross(sub(vs[j], vs[i]), sub(vs[k], vs[i]))) > 0:  # a face of zero area is never hit
            out.append(Triangle(vs[i], vs[j], vs[k], obj.material, (ns[i], ns[j], ns[k]) if ns else None))
    return out


# -- lights -----------------------------------------------------------------------------------------------------


@dataclass
class LightSample:
    to_light: Vec  # L, unit
    distance: float  # math.inf for a directional light
    intensity: Vec


class Light:
    def __init__(self, light, wrong: set[str]):  # noqa: ANN001
        self.color = (1.0, 1.0, 1.0) if "light-colour-ignored" in wrong else vec(light.color)
        self.wrong = wrong
        self.attenuation = (
            (1.0, 0.0, 0.0) if "no-attenuation" in wrong else vec(getattr(light, "attenuation", (1.0, 0.0, 0.0)))
        )

    def samples(self, p: Vec) -> list[LightSample]:
        raise NotImplementedError

    def point_sample(self, position: Vec, color: Vec, p: Vec) -> LightSample | None:
        v = sub(position, p)
        d = length(v)
        if d == 0:
            return None
        c, lin, q = self.attenuation
        denom = c + lin * d + q * (d if "attenuation-not-squared" in self.wrong else d * d)
        if denom == 0:
            return None
        return LightSample(mul(v, 1.0 / d), d, mul(color, 1.0 / denom))


class DirectionalLight(Light):
    def __init__(self, light, wrong: set[str]):  # noqa: ANN001
        super().__init__(light, wrong)
        self.to_light = mul(normalize(vec(light.direction)), -1.0)

    def samples(self, p: Vec) -> list[LightSample]:
        return [LightSample(self.to_light, math.inf, self.color)]


class PointLight(Light):
    def __init__(self, light, wrong: set[str]):  # noqa: ANN001
        super().__init__(light, wrong)
        self.position = vec(light.position)

    def samples(self, p: Vec) -> list[LightSample]:
        s = self.point_sample(self.position, self.color, p)
        return [s] if s else []


class SpotLight(PointLight):
    def __init__(self, light, wrong: set[str]):  # noqa: ANN001
        super().__init__(light, wrong)
        self.direction = normalize(vec(light.direction))
        angle = (lambda a: a) if "spot-radians" in wrong else math.radians
        inner = light.cutoff if light.inner_cutoff is None else light.inner_cutoff
        self.cos_outer, self.cos_inner = math.cos(angle(light.cutoff)), math.cos(angle(inner))
        self.outer, self.inner = angle(light.cutoff), angle(inner)
        self.in_angle = "spot-ramp-angle" in wrong
        self.exponent = 0.0 if "spot-exponent-ignored" in wrong else light.exponent

    def samples(self, p: Vec) -> list[LightSample]:
        out = super().samples(p)
        if not out or "spot-cone-ignored" in self.wrong:  # (lit as the point light it is also)
            return out
        s = dot(self.direction, mul(out[0].to_light, -1.0))
        if s < self.cos_outer:
            return []
        falloff = 1.0 if s >= self.cos_inner else (s - self.cos_outer) / (self.cos_inner - self.cos_outer)
        if self.in_angle and s < self.cos_inner:  # from the cutoff in, linear in the angle off the axis
            falloff = (self.outer - math.acos(min(s, 1.0))) / (self.outer - self.inner)
        out[0].intensity = mul(out[0].intensity, max(s, 0.0) ** self.exponent * falloff)
        return out


class AreaLight(Light):
    def __init__(self, light, wrong: set[str]):  # noqa: ANN001
        super().__init__(light, wrong)
        nu, nv = light.samples
        corner, eu, ev = vec(light.corner), vec(light.edge_u), vec(light.edge_v)
        h = 0.0 if "area-samples-at-corners" in wrong else 0.5  # (a cell's corner, not its centre)
        self.points = [
            add(corner, add(mul(eu, (i + h) / nu), mul(ev, (j + h) / nv))) for i in range(nu) for j in range(nv)
        ]
        self.share = self.color if "area-not-divided" in wrong else mul(self.color, 1.0 / (nu * nv))

    def samples(self, p: Vec) -> list[LightSample]:
        out = [self.point_sample(q, self.share, p) for q in self.points]
        return [s for s in out if s]


LIGHTS = {"directional": DirectionalLight, "point": PointLight, "spot": SpotLight, "area": AreaLight}


def clamp(c: Vec) -> Vec:
    return (min(max(c[0], 0.0), 1.0), min(max(c[1], 0.0), 1.0), min(max(c[2], 0.0), 1.0))
