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

    @property
    def reference(self) -> bool:
        return self == REFERENCE

    def changes(self) -> list[str]:
        """The fields this departs from the reference in."""
        return [f.name for f in fields(self) if getattr(self, f.name) != getattr(REFERENCE, f.name)]


REFERENCE = Options()

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
}

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
}


def unchanged(name: str, scene: Any) -> bool:
    """Whether variant ``name`` (of :data:`VARIANTS`, or its far end in :data:`BOUNDS`) renders ``scene`` exactly
    as the reference does, by the rules of :data:`UNCHANGED` (a variant without a rule: False)."""
    rule = UNCHANGED.get(name)
    return bool(rule is not None and rule(scene))
