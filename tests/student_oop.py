"""A second student's ray tracer: object-oriented, recursive, one ray at a time, each mistake a switch.

It is written from the scene format alone (docs/scene-format.md), the way a
student writes a first tracer: a class per shape and per light, its own
intersection code, a camera, and a recursive ``trace(ray, depth)``.  Nothing
comes from ``tracer/`` or from :mod:`student` (tests/student.py, vectorised
NumPy with the brute force's hits): two students, two styles.  Rays leave a
surface by a small offset along the normal (:data:`EPS`), as most students'
do.  It is slow (pure Python per ray) and meant for small images, 64×48 or so.

The switches are the classic mistakes (named as :data:`tracer.scene.variants.VARIANTS`
names them) and those of :data:`tracer.scene.variants.MORE_VARIANTS`; any of them
compose (a student with two bugs).  A mistake is made as a student makes it,
not as the tracer's variants imitate it: the ray offset far too large is this
student's own amount (:data:`TOO_LARGE`, not the variant's), shadow acne is a
shadow ray with no offset at all.

**Its images must not be used to tune the diagnosis** (thresholds, which
variants to try, how they are scored): they are the held-out check that the
diagnosis names mistakes of a tracer it was not shaped on.
"""

from __future__ import annotations

import math

import numpy as np
from PIL import Image as PILImage
from student_oop_world import (
    BLACK,
    LIGHTS,
    Hit,
    LightSample,
    Ray,
    Vec,
    add,
    clamp,
    cross,
    dot,
    mul,
    normalize,
    shapes_of,
    sub,
    times,
    vec,
)

CLASSIC = (
    "no-shadows",
    "shadow-acne",
    "blinn-phong",
    "specular-behind",
    "gamma",
    "no-attenuation",
    "no-ambient",
    "no-specular",
    "normals-not-flipped",
    "normals-not-normalised",
    "image-flipped",
    "no-half-pixel",
    "horizontal-fov",
    "aspect-inverted",
    "camera-up-as-given",
    "area-not-divided",
    "area-samples-at-corners",
    "spot-radians",
    "depth-plus-one",
    "depth-minus-one",
    "ior-inverted",
    "offset-too-large",
    "reflect-sign",
    "checker-ignored",
    "checker-truncated",
    "colours-not-clamped",
    "ambient-from-diffuse",
    "spot-ramp-angle",
    "transparent-no-shadows",
    "no-reflection",
    "bounce-miss-black",
    "no-refraction",
    "spot-cone-ignored",
    "attenuation-not-squared",
    "shadow-past-light",
    "specular-in-shadow",
)
NEW = (
    "reflection-blended",
    "camera-left-handed",
    "samples-ignored",
    "grayscale",
    "spot-exponent-ignored",
    "light-colour-ignored",
    "channels-swapped",
    "clamped-per-term",
    "exit-normal-not-flipped",
)
MISTAKES = CLASSIC + NEW

#: how far this student moves a shadow or secondary ray's origin off the surface, along the normal (world units;
#: the examples' objects are about 1 across, so it is 1e-4 of them: within what the grader accepts)
EPS = 1e-4
#: the offset of the "offset-too-large" mistake: 5 % of a unit scene (the student's own, not the variant's)
TOO_LARGE = 5e-2


# -- camera -----------------------------------------------------------------------------------------------------


class Camera:
    def __init__(self, scene, wrong: set[str]):  # noqa: ANN001
        cam, img = scene.camera, scene.image
        self.eye = vec(cam.position)
        self.f = normalize(sub(vec(cam.look_at), self.eye))
        up = vec(cam.up)
        if "camera-left-handed" in wrong:
            self.r = normalize(cross(up, self.f))
            self.u = cross(self.f, self.r)
        else:
            self.r = normalize(cross(self.f, up))
            self.u = normalize(up) if "camera-up-as-given" in wrong else cross(self.r, self.f)
        self.ortho = cam.type == "orthographic"
        h = cam.height / 2 if self.ortho else math.tan(math.radians(cam.fov) / 2)
        self.w, self.h = img.width, img.height
        self.half_w, self.half_h = (h, h * self.h / self.w) if "horizontal-fov" in wrong else (h * self.w / self.h, h)
        if "aspect-inverted" in wrong:
            self.half_w = h * self.h / self.w
        self.centre = 0.0 if "no-half-pixel" in wrong else 0.5

    def ray(self, i: int, j: int, a: int, b: int, n: int) -> Ray:
        sx = (i + (a + self.centre) / n) / self.w
        sy = (j + (b + self.centre) / n) / self.h
        x, y = (2 * sx - 1) * self.half_w, (1 - 2 * sy) * self.half_h
        side = add(mul(self.r, x), mul(self.u, y))
        if self.ortho:
            return Ray(add(self.eye, side), self.f)
        return Ray(self.eye, normalize(add(self.f, side)))


# -- the tracer -------------------------------------------------------------------------------------------------


class Tracer:
    def __init__(self, scene, wrong: set[str]):  # noqa: ANN001
        self.scene, self.wrong = scene, wrong
        self.shapes = [s for obj in scene.objects for s in shapes_of(obj)]
        self.lights = [LIGHTS[light.type](light, wrong) for light in scene.lights if light.type != "ambient"]
        self.ambient = BLACK
        for light in scene.lights:
            if light.type == "ambient":
                self.ambient = add(self.ambient, vec(light.color))
        self.background = vec(scene.image.background)
        self.max_depth = scene.image.max_depth + ("depth-plus-one" in wrong) - ("depth-minus-one" in wrong)
        self.eps = TOO_LARGE if "offset-too-large" in wrong else EPS

    def closest(self, ray: Ray) -> Hit | None:
        best = None
        for shape in self.shapes:
            hit = shape.intersect(ray)
            if hit is not None and (best is None or hit.t < best.t):
                best = hit
        return best

    def in_shadow(self, origin: Vec, s: LightSample) -> bool:
        ray = Ray(origin, s.to_light)
        for shape in self.shapes:
            if "transparent-no-shadows" in self.wrong and self.scene.materials[shape.material].transmittance > 0:
                continue  # glass lets the light through
            hit = shape.intersect(ray)  # (t > 0: with no offset, rounding puts half the points below)
            past = "shadow-past-light" in self.wrong  # (no check of the light's distance: anything on the line)
            if hit is not None and (past or hit.t < s.distance * (1 - 1e-9)):
                return True
        return False

    def material(self, hit: Hit, p: Vec):  # noqa: ANN201
        m = self.scene.materials[hit.shape.material]
        if m.checker is None or "checker-ignored" in self.wrong:
            return m
        q = p
        if hit.shape.flat:
            n = hit.shape.normal
            q = sub(p, mul(n, dot(sub(p, hit.shape.point), n)))
        size = m.checker.size
        index = int if "checker-truncated" in self.wrong else math.floor  # (int() rounds toward 0)
        cell = index(q[0] / size) + index(q[1] / size) + index(q[2] / size)
        return self.scene.materials[m.checker.material] if cell % 2 else m

    def off(self, p: Vec, n: Vec, towards: Vec, eps: float) -> Vec:
        """p moved ``eps`` along the geometric normal n, to the side of ``towards``."""
        return add(p, mul(n, eps if dot(n, towards) > 0 else -eps))

    def local(self, hit: Hit, m, p: Vec, n: Vec, v: Vec) -> Vec:  # noqa: ANN001
        ka = vec(m.diffuse) if "ambient-from-diffuse" in self.wrong else vec(m.ambient)
        colour = BLACK if "no-ambient" in self.wrong else times(ka, self.ambient)
        kd, ks = vec(m.diffuse), vec(m.specular)
        for light in self.lights:
            diffuse, specular = BLACK, BLACK
            for s in light.samples(p):
                nl = dot(n, s.to_light)
                if nl <= 0 and "specular-behind" not in self.wrong:
                    continue
                dark = False
                if "no-shadows" not in self.wrong:
                    eps = 0.0 if "shadow-acne" in self.wrong else self.eps
                    dark = self.in_shadow(self.off(p, hit.normal, s.to_light, eps), s)
                    if dark and "specular-in-shadow" not in self.wrong:
                        continue
                if not dark:  # (the student whose highlights shine in shadow skips only this)
                    diffuse = add(diffuse, mul(times(s.intensity, kd), max(nl, 0.0)))
                if "blinn-phong" in self.wrong:
                    rv = dot(n, normalize(add(s.to_light, v)))
                elif "reflect-sign" in self.wrong:
                    rv = dot(sub(s.to_light, mul(n, 2 * nl)), v)
                else:
                    rv = dot(sub(mul(n, 2 * nl), s.to_light), v)
                if rv > 0 and "no-specular" not in self.wrong:
                    specular = add(specular, mul(times(s.intensity, ks), rv**m.shininess))
            if "clamped-per-term" in self.wrong:
                diffuse, specular = clamp(diffuse), clamp(specular)
            colour = add(colour, add(diffuse, specular))
        return colour

    def trace(self, ray: Ray, depth: int) -> Vec:
        hit = self.closest(ray)
        if hit is None:
            return (0.0, 0.0, 0.0) if depth > 0 and "bounce-miss-black" in self.wrong else self.background
        p = ray.at(hit.t)
        d = ray.direction
        n = hit.blend if hit.blend is not None and "normals-not-normalised" in self.wrong else hit.shading
        if dot(n, d) > 0 and "normals-not-flipped" not in self.wrong:
            n = mul(n, -1.0)
        m = self.material(hit, p)
        colour = self.local(hit, m, p, n, mul(d, -1.0))
        if "reflection-blended" in self.wrong:
            colour = mul(colour, 1 - m.reflectance)
        if depth < self.max_depth:
            if m.reflectance > 0 and "no-reflection" not in self.wrong:
                r = normalize(sub(d, mul(n, 2 * dot(d, n))))
                colour = add(
                    colour, mul(self.trace(Ray(self.off(p, hit.normal, r, self.eps), r), depth + 1), m.reflectance)
                )
            if m.transmittance > 0 and "no-refraction" not in self.wrong:
                t = self.refract(d, hit.normal, m.ior)
                colour = add(
                    colour, mul(self.trace(Ray(self.off(p, hit.normal, t, self.eps), t), depth + 1), m.transmittance)
                )
        return colour

    def refract(self, d: Vec, n: Vec, ior: float) -> Vec:
        entering = dot(d, n) < 0
        eta = 1 / ior if entering else ior
        if "ior-inverted" in self.wrong:
            eta = 1 / eta
        w = n if entering or "exit-normal-not-flipped" in self.wrong else mul(n, -1.0)
        c = -dot(d, w)
        k = 1 - eta * eta * (1 - c * c)
        if k < 0:
            return normalize(sub(d, mul(w, 2 * dot(d, w))))
        return normalize(add(mul(d, eta), mul(w, eta * c - math.sqrt(k))))


def render(scene, mistakes: tuple[str, ...] | list[str] = ()) -> np.ndarray:  # noqa: ANN001
    """The student's ``(H, W, 3) uint8`` image of a validated scene, with the named mistakes made (any of
    :data:`MISTAKES`, any number of them): the PNG it would save, as read back."""
    wrong = set(mistakes)
    assert wrong <= set(MISTAKES), wrong - set(MISTAKES)
    tracer, camera = Tracer(scene, wrong), Camera(scene, wrong)
    n = 1 if "samples-ignored" in wrong else scene.image.samples
    rows = []
    for j in range(camera.h):
        row = []
        for i in range(camera.w):
            total = BLACK
            for b in range(n):
                for a in range(n):
                    total = add(total, tracer.trace(camera.ray(i, j, a, b, n), 0))
            c = mul(total, 1.0 / (n * n))
            if "colours-not-clamped" not in wrong:
                c = clamp(c)
            if "gamma" in wrong:
                c = (c[0] ** (1 / 2.2), c[1] ** (1 / 2.2), c[2] ** (1 / 2.2))
            row.append([math.floor(255 * x + 0.5) for x in c])
        rows.append(row)
    return saved(np.array(rows).astype(np.uint8), wrong)  # (unclamped, 306 is kept as 50)


def saved(image: np.ndarray, wrong: set[str]) -> np.ndarray:
    """The image as the student writes it out (with Pillow) and a grader reads it back as RGB."""
    if "image-flipped" in wrong:
        image = image[::-1]
    if "channels-swapped" in wrong:
        image = image[..., ::-1]
    picture = PILImage.fromarray(np.ascontiguousarray(image), "RGB")
    if "grayscale" in wrong:
        picture = picture.convert("L")
    return np.asarray(picture.convert("RGB"))
