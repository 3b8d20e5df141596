"""Light sources: direction towards the light, distance and intensity at surface points.

Every non-ambient light becomes one or more :class:`Emitter` records: a
directional light, a point light, a spot, or one sample of an area light
(a point light of ``color / (nu·nv)``).  Ambient light is summed separately.
:data:`LIGHT_TYPES` is the one list of the light types: what each becomes,
how many emitters, and where its shadow rays run (:mod:`tracer.proofs.sightlines`);
:func:`light_groups` gives each light of a scene as its span of emitters.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from schemas.scene import AmbientLight, AreaLight, DirectionalLight, PointLight, Scene, SpotLight

from .variants import REFERENCE, Options
from .vec import columns, dot_into

F64 = np.float64


@dataclass(frozen=True)
class Emitter:
    kind: str  # "directional" or "point" (point lights, spots and area samples)
    color: np.ndarray  # (3,)
    position: np.ndarray  # (3,) local; unused for directional
    direction: np.ndarray  # (3,) unit: the way light travels (directional, spot)
    attenuation: np.ndarray  # (3,) c, l, q
    cos_outer: float = -2.0  # spot: cos(cutoff); -2 means "no cone"
    cos_inner: float = -2.0
    exponent: float = 0.0
    ramp_in_angle: bool = False  # spot: the ramp linear in the angle off the axis (a variant's), not its cosine

    @property
    def is_spot(self) -> bool:
        return self.cos_outer > -2.0


Emitters = list[Emitter]


def _unit3(v: Sequence[float]) -> np.ndarray:
    a = np.asarray(v, dtype=F64)
    a = a / np.max(np.abs(a))
    return a / np.linalg.norm(a)


# -- the light types, in one list: what each becomes and where its shadow rays go ---------------------------


def _directional(light: DirectionalLight, origin: np.ndarray, options: Options) -> Emitters:
    return [
        Emitter("directional", np.array(light.color, F64), np.zeros(3), _unit3(light.direction), np.array([1.0, 0, 0]))
    ]


def _attenuation(light: PointLight | SpotLight | AreaLight, options: Options) -> np.ndarray:
    """``c, l, q``: the light's, or as a variant's student reads them: none, or q·d for q·d² (``c + (l + q)·d``)."""
    if not options.attenuation:
        return np.array((1.0, 0.0, 0.0), F64)
    c, lin, q = light.attenuation
    return np.array((c, lin, q) if options.attenuation_squared else (c, lin + q, 0.0), F64)


def _point(light: PointLight | SpotLight, origin: np.ndarray, options: Options) -> Emitters:
    return [
        Emitter(
            "point",
            np.array(light.color, F64),
            np.array(light.position, F64) - origin,
            np.zeros(3),
            _attenuation(light, options),
        )
    ]


def _spot(light: SpotLight, origin: np.ndarray, options: Options) -> Emitters:
    if not options.spot_cone:  # (a variant's student lights a spot as a point light: no cone, no exponent)
        return _point(light, origin, options)
    angle = math.radians if options.spot_degrees else float  # (a variant reads the cutoffs as radians)
    return [
        Emitter(
            "point",
            np.array(light.color, F64),
            np.array(light.position, F64) - origin,
            _unit3(light.direction),
            _attenuation(light, options),
            cos_outer=math.cos(angle(light.cutoff)),
            cos_inner=math.cos(angle(light.inner)),
            exponent=light.exponent,
            ramp_in_angle=options.spot_ramp_angle,
        )
    ]


def _area(light: AreaLight, origin: np.ndarray, options: Options) -> Emitters:
    nu, nv = light.samples
    color = np.array(light.color, F64) / (nu * nv if options.area_divided else 1)
    half = 0.5 if options.area_centres else 0.0  # (a variant's samples at the cells' corners: still on the light)
    corner = np.array(light.corner, F64)
    eu, ev = np.array(light.edge_u, F64), np.array(light.edge_v, F64)
    return [
        Emitter(
            "point",
            color,
            corner + ((i + half) / nu) * eu + ((j + half) / nv) * ev - origin,
            np.zeros(3),
            _attenuation(light, options),
        )
        for i in range(nu)
        for j in range(nv)
    ]


def _position_hull(light: PointLight | SpotLight, origin: np.ndarray) -> np.ndarray:
    return np.asarray(light.position, dtype=F64)[None] - origin


def area_corners(light: AreaLight, origin: np.ndarray) -> np.ndarray:
    """An area light's parallelogram: its four local corners ``(4, 3)``, in order round it (the order the
    proofs of :mod:`tracer.proofs.culling` need; as a hull of its shadow rays' ends, any order serves)."""
    c = np.asarray(light.corner, dtype=F64) - origin
    u, v = np.asarray(light.edge_u, dtype=F64), np.asarray(light.edge_v, dtype=F64)
    return np.stack([c, c + u, c + u + v, c + v])


@dataclass(frozen=True)
class LightType:
    """What one type of light becomes: its emitters (none for ambient light, summed apart), how many, and the
    points (a hull: every shadow ray passes through a point of it) or the direction its shadow rays run on."""

    emitters: Callable[[Any, np.ndarray, Options], Emitters]
    count: Callable[[Any], int]
    hull: Callable[[Any, np.ndarray], np.ndarray] | None = None
    direction: Callable[[Any], np.ndarray] | None = None


LIGHT_TYPES: dict[type, LightType] = {
    AmbientLight: LightType(lambda light, origin, options: [], lambda light: 0),
    DirectionalLight: LightType(_directional, lambda light: 1, direction=lambda light: _unit3(light.direction)),
    PointLight: LightType(_point, lambda light: 1, hull=_position_hull),
    SpotLight: LightType(_spot, lambda light: 1, hull=_position_hull),
    AreaLight: LightType(_area, lambda light: light.samples[0] * light.samples[1], hull=area_corners),
}


def emitter_count(lights: Sequence[object]) -> int:
    """How many emitters (point lights, spots, directional lights and area-light samples) ``lights`` make."""
    return sum(LIGHT_TYPES[type(light)].count(light) for light in lights)


def build_emitters(lights: Sequence[object], origin: np.ndarray, options: Options = REFERENCE) -> Emitters:
    return [em for light in lights for em in LIGHT_TYPES[type(light)].emitters(light, origin, options)]


def illuminate(em: Emitter, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Towards-light unit vectors L (N, 3), distances d (N,) and factors f (N,): the intensity is ``f·color``.

    f is zero wherever the light gives nothing: a point at the light's own
    position, a zero attenuation denominator, or outside a spot's cone.
    (:func:`illuminate_into`, into arrays of their own.)
    """
    n = len(points)
    to_light, dist, safe = columns(n), np.empty(n), np.empty(n)
    factor = illuminate_into(em, points, to_light, dist, safe)
    return to_light, dist, np.broadcast_to(factor, (n,)).astype(F64)


def illuminate_into(
    em: Emitter, points: np.ndarray, to_light: np.ndarray, dist: np.ndarray, safe: np.ndarray
) -> np.ndarray | float:
    """L into ``to_light (N, 3)`` (its columns contiguous) and d into ``dist (N,)``, a column at a time, with
    ``safe (N,)`` as scratch; returns the factor f, one number when it is the same at every point (a light
    without attenuation and cone, or a directional light).  L is ``(P − p) / d`` (divided by 1 where d = 0),
    d is ``√((P − p)·(P − p))`` summed x, y, z; for a directional light L is −direction and d is ∞."""
    if em.kind == "directional":
        for k in range(3):
            to_light[:, k] = -em.direction[k]
        dist.fill(np.inf)
        return 1.0
    for k in range(3):
        np.subtract(em.position[k], points[:, k], out=to_light[:, k])
    dot_into(dist, to_light, to_light, safe)
    np.sqrt(dist, out=dist)
    factor = attenuation(em, dist, safe)
    for k in range(3):
        to_light[:, k] /= safe
    if em.is_spot:
        factor = factor * spot_factor(em, -to_light)
    return factor


def attenuation(em: Emitter, dist: np.ndarray, safe: np.ndarray) -> np.ndarray | float:
    """An emitter's intensity factor ``1 / (c + l·d + q·d²)`` at distances ``dist`` (a point light's, before any
    cone; 0 at d = 0 and where the denominator is not positive), and the distances to divide ``L`` by into
    ``safe`` (1 where d = 0).  One number when every distance is positive and finite and ``l = q = 0``."""
    np.copyto(safe, dist)
    shortest = float(dist.min(initial=np.inf))
    if not shortest > 0:
        safe[~(dist > 0)] = 1.0
    c, lin, q = em.attenuation
    if lin == 0 and q == 0:  # c + 0·d + (0·d)·d is c wherever d is finite (at d = ∞, NaN: no light)
        if shortest > 0 and float(dist.max(initial=0.0)) < np.inf:
            return 1.0 / c if c > 0 else 0.0
        return np.where((dist > 0) & (dist < np.inf), 1.0 / c if c > 0 else 0.0, 0.0)
    denom = c + lin * dist + q * dist * dist
    return np.where((dist > 0) & (denom > 0), 1.0 / np.where(denom > 0, denom, 1.0), 0.0)


def spot_factor(em: Emitter, from_light: np.ndarray) -> np.ndarray:
    """S for unit vectors from the spot towards the points, shape (N,)."""
    s = from_light @ em.direction
    with np.errstate(invalid="ignore", divide="ignore"):
        span = em.cos_inner - em.cos_outer
        if em.ramp_in_angle:  # a variant's F = (θ_out − θ) / (θ_out − θ_in), θ the angle off the axis
            outer = math.acos(max(-1.0, min(1.0, em.cos_outer)))
            wide = outer - math.acos(max(-1.0, min(1.0, em.cos_inner)))
            into = (outer - np.arccos(np.clip(s, -1.0, 1.0))) / (wide if wide > 0 else 1.0)
        else:
            into = (s - em.cos_outer) / (span if span > 0 else 1.0)
        ramp = np.where(s >= em.cos_inner, 1.0, into)
        powered = np.where(s > 0, np.power(np.maximum(s, 0.0), em.exponent), 0.0 if em.exponent > 0 else 1.0)
    return np.where(s < em.cos_outer, 0.0, powered * ramp)


@dataclass(frozen=True)
class LightGroup:
    """One light of the scene as the emitters ``first..end − 1`` it became (all of one colour)."""

    light: int  # its index in ``scene.lights``
    first: int
    end: int
    #: an area light's parallelogram: its four local corners, in order round it; None for the other lights
    corners: np.ndarray | None = None


def light_groups(scene: Scene, origin: np.ndarray) -> list[LightGroup]:
    """The scene's lights that emit (every type but ambient), in order, with their emitters' span."""
    groups, first = [], 0
    for k, light in enumerate(scene.lights):
        count = LIGHT_TYPES[type(light)].count(light)
        if count:
            corners = area_corners(light, origin) if isinstance(light, AreaLight) else None
            groups.append(LightGroup(k, first, first + count, corners))
        first += count
    return groups
