"""Named options of a render: the classic mistakes of a student's tracer, for telling which one a student made.

A :class:`Options` with every field at its default is the reference render
(the renderer takes exactly the reference path then, byte for byte).  Each
entry of :data:`VARIANTS` changes one thing the way a student's tracer often
gets it wrong; a grader renders the reference with it and compares.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from .rays import Rays


@dataclass(frozen=True)
class Options:
    """How a render departs from the format (every field off: it does not)."""

    shadows: bool = True  # cast shadow rays
    acne: bool = False  # shadow rays start on the surface without leaving it, so it shadows itself in speckles
    acne_everywhere: bool = False  # with acne: every point a hair below its surface (acne's far end, a bound)
    blinn: bool = False  # the Blinn–Phong half vector (N·H)^n instead of (R·V)^n
    specular_behind: bool = False  # specular light also where N·L ≤ 0
    gamma: bool = False  # each channel raised to 1/2.2 before it is stored
    attenuation: bool = True  # point, spot and area lights fall off with distance
    ambient: bool = True  # the ambient term
    specular: bool = True  # the specular term
    flip_normals: bool = True  # normals turned to face the ray
    flip_image: bool = False  # rows stored bottom to top
    half_pixel: bool = True  # sub-sample centres at +0.5
    vertical_fov: bool = True  # fov spans the image's height (False: its width)
    area_divided: bool = True  # an area light's colour split among its nu·nv samples
    spot_degrees: bool = True  # a spot's cutoff read in degrees (False: radians, as a mix-up does)
    depth_offset: int = 0  # max_depth read as max_depth + this
    ior_inverted: bool = False  # η = ior entering and 1/ior leaving
    offset: float = 0.0  # shadow and secondary rays start this far off the hit point, × the scene's size
    offset_along: str = "normal"  # "normal": along the surface's normal; "ray": along the ray (a t_min)

    @property
    def reference(self) -> bool:
        return self == REFERENCE

    def spawn(self, scene: Any) -> Spawn | None:
        """Where this render's shadow and secondary rays start (None: at the hit point, as the format says)."""
        return Spawn(self.offset * scene_size(scene), self.offset_along) if self.offset else None

    def changes(self) -> list[str]:
        """The fields this departs from the reference in."""
        return [f.name for f in fields(self) if getattr(self, f.name) != getattr(REFERENCE, f.name)]


REFERENCE = Options()


def scene_size(scene: Any) -> float:
    """The largest side of the box around the scene's spheres and triangles (planes are unbounded and not
    counted); 1 for a scene of planes alone.  A ray offset of a student's tracer is measured against it."""
    lows, highs = [], []
    for obj in scene.objects:
        if obj.type == "sphere":
            centre = np.array(obj.center, dtype=np.float64)
            lows.append(centre - obj.radius)
            highs.append(centre + obj.radius)
        elif obj.type in ("triangle", "mesh"):
            corners = obj.rows("vertices") if obj.type == "mesh" else np.array(obj.vertices, dtype=np.float64)
            if len(corners):
                lows.append(corners.min(axis=0))
                highs.append(corners.max(axis=0))
    if not lows:
        return 1.0
    side = float(np.max(np.max(highs, axis=0) - np.min(lows, axis=0)))
    return side if 0 < side < np.inf else 1.0


@dataclass(frozen=True)
class Spawn:
    """A student's way of starting shadow and secondary rays off the surface: ``amount`` (local units) along the
    geometric normal, to the side the ray leaves by (``along="normal"``), or along the ray itself
    (``along="ray"``: the same as ignoring hits nearer than ``amount``, a t_min, since the ray starts on the
    surface).  As a student's rays do, the moved rays carry no identity of the surface they leave: the offset
    alone keeps them off it, and they are traced as rays from anywhere are (a camera inside the scene's).

    Guarantee: each origin moves by exactly ``amount`` and never to the other side of the surface it leaves
    than the one its direction points to (the normal's sign is taken from the direction)."""

    amount: float
    along: str

    def leaving(self, rays: Rays, geometric: np.ndarray) -> Rays:
        """``rays`` (from hit points, leaving surfaces of normals ``geometric``, (N, 3)) moved off them."""
        points, dirs = rays.origins, rays.dirs
        if self.along == "ray":
            moved = points + self.amount * dirs
        else:
            side = np.where(np.einsum("ij,ij->i", dirs, geometric) < 0, -self.amount, self.amount)
            moved = points + side[:, None] * geometric
        return Rays.leaving(moved, dirs, 0.0, mag=rays.mag)

#: name → (options, what a student did)
VARIANTS: dict[str, tuple[Options, str]] = {
    "no-shadows": (Options(shadows=False), "no shadow rays"),
    "shadow-acne": (Options(acne=True), "shadow acne: shadow rays hit the surface they start from"),
    "blinn-phong": (Options(blinn=True), "the Blinn–Phong half vector instead of the reflected vector"),
    "specular-behind": (Options(specular_behind=True), "specular light where N·L ≤ 0"),
    "gamma": (Options(gamma=True), "gamma 1/2.2 applied to the output"),
    "no-attenuation": (Options(attenuation=False), "no attenuation of point, spot and area lights"),
    "no-ambient": (Options(ambient=False), "no ambient term"),
    "no-specular": (Options(specular=False), "no specular term"),
    "normals-not-flipped": (Options(flip_normals=False), "normals not turned to face the ray"),
    "image-flipped": (Options(flip_image=True), "the image flipped vertically"),
    "no-half-pixel": (Options(half_pixel=False), "pixel centres without the +0.5"),
    "horizontal-fov": (Options(vertical_fov=False), "fov taken as horizontal instead of vertical"),
    "area-not-divided": (Options(area_divided=False), "an area light not divided by nu·nv"),
    "spot-radians": (Options(spot_degrees=False), "a spot's cutoff compared in radians"),
    "depth-plus-one": (Options(depth_offset=1), "max_depth off by one (one bounce too many)"),
    "depth-minus-one": (Options(depth_offset=-1), "max_depth off by one (one bounce too few)"),
    "ior-inverted": (Options(ior_inverted=True), "the index of refraction inverted"),
    "offset-too-large": (Options(offset=2e-2), "shadow and secondary rays offset too far from the surface "
                                               "(2e-2 of the scene's size)"),
}

#: the ways of honest tracers a grade accepts besides the reference, by default: name → how far (× the scene's
#: size) at most.  A task may narrow or widen them (``accepted`` in a class's tasks file).
ACCEPTED_DEFAULT: dict[str, float] = {"normal-offset": 1e-3, "t-min": 1e-3}

#: accepted variant → (the option that sets its amount, what it is in words)
ACCEPTED_KINDS: dict[str, tuple[str, str]] = {"normal-offset": ("normal", "ray offset"),
                                              "t-min": ("ray", "t_min")}


def _short(x: float) -> str:
    """``1e-3`` for 0.001, ``2.5e-3`` for 0.0025: an amount as a course writes it."""
    mantissa, exponent = f"{x:.2e}".split("e")
    return f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"


#: each accepted variant is rendered at its largest amount and at each half of it down to this many rungs
RUNGS = 4


def accepted_options(accepted: dict[str, float]) -> list[list[tuple[str, Options]]]:
    """Per accepted variant of ``accepted`` (name → largest amount), the renders it makes, each with its words
    ("a 1e-3 ray offset"): its largest amount and halves of it, :data:`RUNGS` in all, largest first; an amount of
    0 is the reference alone and makes none."""
    out = []
    for name, amount in sorted(accepted.items()):
        along, words = ACCEPTED_KINDS[name]
        rungs = [amount / 2**k for k in range(RUNGS)] if amount > 0 else []
        out.append([(f"a {_short(a)} {words}", Options(offset=a, offset_along=along)) for a in rungs])
    return [rungs for rungs in out if rungs]


#: mistakes whose effect varies from point to point (a student's acne speckles in its own pattern): name →
#: the options of the mistake's far end.  An image with the mistake lies between the reference and that
#: render, pixel by pixel, and departs from the reference in speckles.
BOUNDS: dict[str, Options] = {"shadow-acne": Options(acne=True, acne_everywhere=True)}


# -- variants a scene cannot show: the reference, bit for bit, without a render -----------------------------------

def _lit(scene: Any) -> bool:
    return any(light.type != "ambient" for light in scene.lights)


def _materials(scene: Any, test: Callable[[Any], bool]) -> bool:
    return any(test(m) for m in scene.materials.values())


def _specular(scene: Any) -> bool:
    return _lit(scene) and _materials(scene, lambda m: any(v != 0 for v in m.specular))


def _bounces(scene: Any) -> bool:
    return _materials(scene, lambda m: m.reflectance > 0 or m.transmittance > 0)


#: per variant, whether a scene can show it: when not, the variant's render is the reference's, bit for bit.
#: Each rule follows the one place the variant's option is read (tracer/render.py, lights.py, camera.py):
UNCHANGED: dict[str, Callable[[Any], bool]] = {
    # shadow rays are cast only towards a light that is not ambient
    "no-shadows": lambda scene: not _lit(scene),
    "shadow-acne": lambda scene: not _lit(scene),
    # the specular term is k_s times a finite number: with every k_s zero (or no light to have one), another
    # R·V (Blinn's), or a term behind the surface, adds exactly 0; where N·L > 0 nothing else changes
    "blinn-phong": lambda scene: not _specular(scene),
    "specular-behind": lambda scene: not _specular(scene),
    "no-specular": lambda scene: not _specular(scene),
    # no ambient light (or every k_a zero): the ambient term is k_a times 0, exactly the 0 the variant starts at
    "no-ambient": lambda scene: not (any(light.type == "ambient" and any(v != 0 for v in light.color)
                                         for light in scene.lights)
                                     and _materials(scene, lambda m: any(v != 0 for v in m.ambient))),
    # every point, spot and area light already falls off as (1, 0, 0)
    "no-attenuation": lambda scene: all(tuple(light.attenuation) == (1.0, 0.0, 0.0) for light in scene.lights
                                        if light.type in ("point", "spot", "area")),
    # a square image: the view window's half-sizes are (1, 1) either way
    "horizontal-fov": lambda scene: scene.image.width == scene.image.height,
    # an area light of one sample is divided by 1 either way
    "area-not-divided": lambda scene: all(light.samples[0] * light.samples[1] == 1 for light in scene.lights
                                          if light.type == "area"),
    "spot-radians": lambda scene: not any(light.type == "spot" for light in scene.lights),
    # with no mirror or glass, no hit spawns a ray, so how deep the tree may go changes nothing
    "depth-plus-one": lambda scene: not _bounces(scene),
    "depth-minus-one": lambda scene: scene.image.max_depth == 0 or not _bounces(scene),
    # η is read only where a refracted ray is spawned: no glass, no bounce, or ior 1 (1/1 is 1)
    "ior-inverted": lambda scene: scene.image.max_depth == 0 or not _materials(
        scene, lambda m: m.transmittance > 0 and m.ior != 1.0),
    # an offset moves only shadow rays (of a light that is not ambient) and mirror or refracted rays
    "offset-too-large": lambda scene: not _lit(scene) and (scene.image.max_depth == 0 or not _bounces(scene)),
}


def unchanged(name: str, scene: Any) -> bool:
    """Whether variant ``name`` (of :data:`VARIANTS`, or its far end in :data:`BOUNDS`) renders ``scene`` exactly
    as the reference does, by the rules of :data:`UNCHANGED` (a variant without a rule: False)."""
    rule = UNCHANGED.get(name)
    return bool(rule is not None and rule(scene))
