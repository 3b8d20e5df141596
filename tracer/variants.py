"""Named options of a render: the classic mistakes of a student's tracer, for telling which one a student made.

A :class:`Options` with every field at its default is the reference render
(the renderer takes exactly the reference path then, byte for byte).  Each
entry of :data:`VARIANTS` changes one thing the way a student's tracer often
gets it wrong; a grader renders the reference with it and compares.
"""

from __future__ import annotations

from dataclasses import dataclass, fields


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
