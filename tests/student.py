"""A student's ray tracer, for the diagnosis tests: written from the scene format, each classic mistake a switch.

It is what a course's student writes: a camera, the lights, the Phong model,
shadow rays and the ray tree, in float64, one depth at a time.  Finding what
a ray hits is taken from the brute force (:mod:`reference`), so that the
student's image differs from the reference only where a mistake is switched
on.  The switches are named as :data:`tracer.scene.variants.VARIANTS` names them,
but nothing here comes from ``tracer/``: the mistakes are made the way a
student makes them, not the way the tracer's variants imitate them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import reference as ref

MISTAKES = (
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


def _student_normal(
    surface: ref.Surface, uw: tuple[np.ndarray, np.ndarray], facing: np.ndarray, outward: np.ndarray, wrong: set[str]
) -> np.ndarray:
    """The shading normal as a student with the normal's mistakes among ``wrong`` has it: a mesh's blend of its
    vertex normals (at barycentric ``uw``) left as it is (``normals-not-normalised``), and any normal left on the
    side it was given on (``normals-not-flipped``: a sphere's, a plane's or a face's ``outward``, a mesh's
    blend); else as the format's ``facing`` (unit, turned to face the ray)."""
    if surface.vn is None:
        return outward if "normals-not-flipped" in wrong else facing
    u, w = uw
    blend = (1 - u - w)[:, None] * surface.vn[0] + u[:, None] * surface.vn[1] + w[:, None] * surface.vn[2]
    zero = ~np.any(blend != 0, axis=1)
    blend = np.where(zero[:, None], outward, blend if "normals-not-normalised" in wrong else _unit(blend))
    if "normals-not-flipped" in wrong:
        return blend
    return np.where((_dot(blend, facing) < 0)[:, None], -blend, blend)


@dataclass(frozen=True)
class Offset:
    """How the student starts shadow and secondary rays off the surface, ``amount`` in the scene's units, as the
    student wrote it (``1e-3``): along the normal, to the side the ray leaves by (``along="normal"``), or along the
    ray itself (``along="ray"``: ``p + amount·d``, a shadow ray still as long as from the hit point to the light,
    so that it passes the light by ``amount``; for the small amounts of an honest tracer, the same image as a
    t_min, the tracer's ``offset_along="ray"``; for a large one, the tracer's ``"direction"``).  The student's rays
    then carry no identity of the surface they leave: the offset is all that keeps them off it."""

    amount: float
    along: str = "normal"


#: the three offset styles of honest tracers the grade accepts, as a textbook writes them
STYLES = {"offset 1e-3": Offset(1e-3), "t_min 1e-3": Offset(1e-3, "ray"), "offset 1e-4": Offset(1e-4)}
#: the mistake of an offset far too large: a tenth of a unit, in scenes a few units across
TOO_LARGE = Offset(0.1)


def spawn(
    p: np.ndarray, to: np.ndarray, n: np.ndarray, start: np.ndarray, off: Offset | None
) -> tuple[np.ndarray, np.ndarray]:
    """Where rays from points p along ``to`` start, and the surface each leaves (−1: none), in the student's
    offset style (None: on the surface, leaving it by identity)."""
    if off is None:
        return p, start
    step = off.amount
    if off.along == "ray":
        return p + step * to, np.full(len(p), -1)
    side = np.where(_dot(to, n) < 0, -step, step)
    return p + side[:, None] * n, np.full(len(p), -1)


def _unit(a: np.ndarray) -> np.ndarray:
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


@dataclass
class Lamp:
    """One light the student loops over (an area light is nu·nv of them)."""

    color: np.ndarray
    position: np.ndarray | None  # None: directional
    direction: np.ndarray | None  # the way the light travels (directional, spot)
    attenuation: tuple[float, float, float] = (1.0, 0.0, 0.0)
    cone: tuple[float, float, float] | None = None  # spot: cos(outer), cos(inner), exponent
    angles: tuple[float, float] | None = None  # spot of a student who ramps in the angle: outer, inner (radians)
    unsquared: bool = False  # the attenuation's q·d for q·d², the distance not squared


def lamps(scene, wrong: set[str]) -> tuple[np.ndarray, list[Lamp]]:  # noqa: ANN001
    ambient, out = np.zeros(3), []
    for light in scene.lights:
        color = np.array(light.color, dtype=np.float64)
        atten = (1.0, 0.0, 0.0) if "no-attenuation" in wrong else tuple(getattr(light, "attenuation", (1, 0, 0)))
        if light.type == "ambient":
            ambient += color
        elif light.type == "directional":
            out.append(Lamp(color, None, _unit(np.array(light.direction, dtype=np.float64))))
        elif light.type == "spot" and "spot-cone-ignored" not in wrong:
            angle = float if "spot-radians" in wrong else math.radians
            inner = light.cutoff if light.inner_cutoff is None else light.inner_cutoff
            out.append(
                Lamp(
                    color,
                    np.array(light.position, dtype=np.float64),
                    _unit(np.array(light.direction, dtype=np.float64)),
                    atten,
                    (math.cos(angle(light.cutoff)), math.cos(angle(inner)), light.exponent),
                    (angle(light.cutoff), angle(inner)) if "spot-ramp-angle" in wrong else None,
                )
            )
        elif light.type in ("point", "spot"):  # (a spot whose cone is ignored: a point light)
            out.append(Lamp(color, np.array(light.position, dtype=np.float64), None, atten))
        else:
            nu, nv = light.samples
            corner, eu, ev = (np.array(v, dtype=np.float64) for v in (light.corner, light.edge_u, light.edge_v))
            share = color if "area-not-divided" in wrong else color / (nu * nv)
            half = 0.0 if "area-samples-at-corners" in wrong else 0.5  # (a cell's corner, not its centre)
            out += [
                Lamp(share, corner + (i + half) / nu * eu + (j + half) / nv * ev, None, atten)
                for i in range(nu)
                for j in range(nv)
            ]
    for lamp in out:
        lamp.unsquared = "attenuation-not-squared" in wrong
    return ambient, out


def shine(lamp: Lamp, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Towards the light, its distance and its strength (times its colour) at points p."""
    if lamp.position is None:
        assert lamp.direction is not None
        return np.broadcast_to(-lamp.direction, p.shape), np.full(len(p), np.inf), np.ones(len(p))
    v = lamp.position - p
    d = np.linalg.norm(v, axis=1)
    c, lin, q = lamp.attenuation
    strength = 1.0 / (c + lin * d + q * d * (1.0 if lamp.unsquared else d))
    to = v / d[:, None]
    if lamp.cone is not None:
        assert lamp.direction is not None
        outer, inner, exponent = lamp.cone
        s = _dot(-to, np.broadcast_to(lamp.direction, to.shape))
        ramp = np.clip((s - outer) / (inner - outer), 0.0, 1.0) if inner > outer else (s >= outer) * 1.0
        if lamp.angles is not None and inner > outer:  # the angle off the axis, ramped from the cutoff inwards
            wide, narrow = lamp.angles
            ramp = np.clip((wide - np.arccos(np.clip(s, -1.0, 1.0))) / (wide - narrow), 0.0, 1.0)
        strength = strength * np.where(s >= outer, ramp * np.maximum(s, 0.0) ** exponent, 0.0)
    return to, d, strength


def eye_rays(scene, wrong: set[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # noqa: ANN001
    cam, img = scene.camera, scene.image
    W, H, n = img.width, img.height, img.samples
    eye = np.array(cam.position, dtype=np.float64)
    forward = _unit(np.array(cam.look_at, dtype=np.float64) - eye)
    right = _unit(np.cross(forward, np.array(cam.up, dtype=np.float64)))
    up = _unit(np.array(cam.up, dtype=np.float64)) if "camera-up-as-given" in wrong else np.cross(right, forward)
    half = cam.height / 2 if cam.type == "orthographic" else math.tan(math.radians(cam.fov) / 2)
    across, down = (half, half * H / W) if "horizontal-fov" in wrong else (half * W / H, half)
    if "aspect-inverted" in wrong:
        across = half * H / W
    centre = 0.0 if "no-half-pixel" in wrong else 0.5
    rows, cols, sub_rows, sub_cols = np.meshgrid(np.arange(H), np.arange(W), np.arange(n), np.arange(n), indexing="ij")
    x = ((cols + (sub_cols + centre) / n) / W * 2 - 1).ravel() * across
    y = (1 - (rows + (sub_rows + centre) / n) / H * 2).ravel() * down
    offset = x[:, None] * right + y[:, None] * up
    if cam.type == "orthographic":
        return eye + offset, np.broadcast_to(forward, offset.shape).copy(), (rows * W + cols).ravel()
    return np.broadcast_to(eye, offset.shape).copy(), _unit(forward + offset), (rows * W + cols).ravel()


def render(
    scene,
    mistakes: tuple[str, ...] | list[str] = (),
    style: Offset | None = None,  # noqa: ANN001, C901
) -> np.ndarray:
    """The student's ``(H, W, 3) uint8`` image of a validated scene, with the named mistakes made, its shadow
    and secondary rays started in offset ``style`` (None: on the surface, leaving it by identity)."""
    wrong = set(mistakes)
    assert wrong <= set(MISTAKES), wrong - set(MISTAKES)
    if "offset-too-large" in wrong:
        style = TOO_LARGE
    img = scene.image
    surfaces = ref.surfaces_of(scene)
    see_through = [scene.materials[s.material].transmittance > 0 for s in surfaces]
    opaque = [s for s, clear in zip(surfaces, see_through) if not clear]
    renumber = np.append(np.cumsum(np.logical_not(see_through)) - 1, -1)  # (index −1 stays −1)
    renumber[:-1][np.array(see_through, dtype=bool)] = -1
    ambient, lights = lamps(scene, wrong)
    o, d, pixel = eye_rays(scene, wrong)
    weight, start = np.ones(len(o)), np.full(len(o), -1)
    total = np.zeros((img.width * img.height, 3))
    depth_limit = img.max_depth + ("depth-plus-one" in wrong) - ("depth-minus-one" in wrong)
    for depth in range(max(depth_limit, 0) + 1):
        hit = ref.closest(surfaces, o, d, start)
        missed = hit.surface < 0
        sky = np.zeros(3) if depth > 0 and "bounce-miss-black" in wrong else np.array(img.background, dtype=np.float64)
        np.add.at(total, pixel[missed], weight[missed, None] * sky)
        keep = np.flatnonzero(~missed)
        if len(keep) == 0:
            break
        o, d, weight, pixel, which = o[keep], d[keep], weight[keep], pixel[keep], hit.surface[keep]
        p, outward, n = np.zeros_like(o), np.zeros_like(o), np.zeros_like(o)
        ka, kd, ks = np.zeros_like(o), np.zeros_like(o), np.zeros_like(o)
        shininess, kr, kt, ior = (np.zeros(len(o)) for _ in range(4))
        for k in np.unique(which):
            at = which == k
            surface = surfaces[k]
            p[at], outward[at], n[at] = ref.surface_point(
                surface, o[at], d[at], hit.t[keep][at], hit.u[keep][at], hit.w[keep][at]
            )
            if wrong & {"normals-not-flipped", "normals-not-normalised"}:
                n[at] = _student_normal(surface, (hit.u[keep][at], hit.w[keep][at]), n[at], outward[at], wrong)
            cells = np.trunc if "checker-truncated" in wrong else np.floor  # (int(P/s) rounds toward 0)
            other, _ = ref._checker_material(scene, surface, p[at], cells)
            if "checker-ignored" in wrong:  # every point in the object's own material
                other = np.zeros_like(other)
            main = scene.materials[surface.material]
            alt = scene.materials[main.checker.material] if main.checker else main
            for array, name in ((ka, "ambient"), (kd, "diffuse"), (ks, "specular")):
                array[at] = np.where(other[:, None], np.array(getattr(alt, name)), np.array(getattr(main, name)))
            for array, name in ((shininess, "shininess"), (kr, "reflectance"), (kt, "transmittance"), (ior, "ior")):
                array[at] = np.where(other, getattr(alt, name), getattr(main, name))
        colour = (
            np.zeros_like(o) if "no-ambient" in wrong else (kd if "ambient-from-diffuse" in wrong else ka) * ambient
        )
        view = -d
        for lamp in lights:
            to, dist, strength = shine(lamp, p)
            nl = _dot(n, to)
            gets = (strength > 0) & ((nl > 0) | ("specular-behind" in wrong))
            shines = gets.copy()  # (where the specular is added: after the shadow test, unless it skips it)
            if "no-shadows" not in wrong and gets.any():
                rows = np.flatnonzero(gets)
                origin, leaving = spawn(p[rows], to[rows], n[rows], which[rows], style)
                if "shadow-acne" in wrong:  # the ray starts where the hit was computed, and may hit its surface
                    speck = (np.floor(np.abs(origin).sum(axis=1) * 977.0) % 2 == 1)[:, None]
                    origin = origin - np.where(speck, 1e-7, 0.0) * n[rows]
                    leaving = np.full(len(rows), -1)
                # (a student who does not stop the ray at the light: as far as a directional light's goes)
                reach, at = (
                    (np.full(len(rows), np.inf), None) if "shadow-past-light" in wrong else (dist[rows], lamp.position)
                )
                if "transparent-no-shadows" in wrong:  # the loop over the objects skips glass
                    shadowed, _ = ref.blocked(opaque, origin, to[rows], reach, renumber[leaving], at)
                else:
                    shadowed, _ = ref.blocked(surfaces, origin, to[rows], reach, leaving, at)
                gets[rows[shadowed]] = False
                if "specular-in-shadow" not in wrong:
                    shines = gets
            if "blinn-phong" in wrong:
                rv = _dot(n, _unit(to + view))
            elif "reflect-sign" in wrong:  # reflect(L, N) = L − 2(N·L)N where reflect(−L, N) was meant
                rv = _dot(to - 2 * nl[:, None] * n, view)
            else:
                rv = _dot(2 * nl[:, None] * n - to, view)
            spec = np.where(rv > 0, np.abs(rv) ** shininess, 0.0)
            diffuse = kd * np.maximum(nl, 0.0)[:, None]
            specular = np.zeros_like(ks) if "no-specular" in wrong else ks * spec[:, None]
            lit = np.where(gets[:, None], diffuse, 0.0) + np.where(shines[:, None], specular, 0.0)
            colour += lamp.color * strength[:, None] * lit
        np.add.at(total, pixel, weight[:, None] * colour)
        if depth == depth_limit:
            break
        r, t = np.flatnonzero(weight * kr > 0), np.flatnonzero(weight * kt > 0)
        if "no-reflection" in wrong:  # (the mirror ray forgotten, at every depth)
            r = r[:0]
        if "no-refraction" in wrong:  # (the refracted ray forgotten, at every depth)
            t = t[:0]
        mirror = _unit(d[r] - 2 * _dot(d[r], n[r])[:, None] * n[r])
        into = _dot(d[t], outward[t]) < 0
        eta = np.where(into != ("ior-inverted" in wrong), 1 / ior[t], ior[t])
        facing = np.where(into[:, None], outward[t], -outward[t])
        cos_in = -_dot(d[t], facing)
        k = 1 - eta * eta * (1 - cos_in * cos_in)
        bent = eta[:, None] * d[t] + (eta * cos_in - np.sqrt(np.maximum(k, 0)))[:, None] * facing
        bounced = d[t] - 2 * _dot(d[t], facing)[:, None] * facing
        d = np.concatenate([mirror, _unit(np.where((k < 0)[:, None], bounced, bent))])
        o, start = spawn(
            np.concatenate([p[r], p[t]]),
            d,
            np.concatenate([n[r], n[t]]),
            np.concatenate([which[r], which[t]]),
            style,
        )
        weight = np.concatenate([weight[r] * kr[r], weight[t] * kt[t]])
        pixel = np.concatenate([pixel[r], pixel[t]])
    linear = (total / img.samples**2).reshape(img.height, img.width, 3)
    if "colours-not-clamped" not in wrong:
        linear = np.clip(linear, 0.0, 1.0)
    if "gamma" in wrong:
        linear = linear ** (1 / 2.2)
    # (unclamped, 1.2 is 306: kept to 8 bits as an integer cast keeps it, 50)
    image = np.floor(255 * linear + 0.5).astype(np.int64).astype(np.uint8)
    return image[::-1].copy() if "image-flipped" in wrong else image
