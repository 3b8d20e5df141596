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
    normals_unit: bool = True  # a mesh's interpolated normal made unit (False: the blend of its vertex normals as is)
    flip_image: bool = False  # rows stored bottom to top
    half_pixel: bool = True  # sub-sample centres at +0.5
    vertical_fov: bool = True  # fov spans the image's height (False: its width)
    aspect_inverted: bool = False  # the view window's half-width h·H/W instead of h·W/H (the aspect upside down)
    area_divided: bool = True  # an area light's colour split among its nu·nv samples
    spot_degrees: bool = True  # a spot's cutoff read in degrees (False: radians, as a mix-up does)
    depth_offset: int = 0  # max_depth read as max_depth + this
    ior_inverted: bool = False  # η = ior entering and 1/ior leaving
    offset: float = 0.0  # shadow and secondary rays start this far off the hit point, × the visible size
    # "normal": along the shading normal; "geometric": the face's; "ray": a t_min (a shadow ray still ends at the
    # light); "direction": along the ray itself, a shadow ray as long as from the hit point to the light (so that
    # it passes the light by the amount, as a student's p + ε·d with t < |light − p| does)
    offset_along: str = "normal"
    # -- the mistakes of MORE_VARIANTS (none of them in VARIANTS yet) --
    blend_reflection: bool = False  # local colour × (1 − k_r) before the mirror ray's k_r·colour is added
    left_handed: bool = False  # r = unit(up × f), u = f × r: the image mirrored left to right
    samples_read: bool = True  # image.samples read (False: one ray through each pixel's centre)
    spot_exponent: bool = True  # a spot's exponent read (False: S = F, as if exponent were 0)
    light_colour: bool = True  # each light's colour read (False: every light but ambient white, [1, 1, 1])
    clamp_terms: bool = False  # each light's diffuse and specular term clamped to [0, 1] before it is added
    exit_normal_flipped: bool = True  # a refracted ray leaving uses w = −n (False: the outward n, as entering)
    grayscale: bool = False  # the 8-bit image stored as grey, L = 0.299 R + 0.587 G + 0.114 B (Pillow's "L")
    channels_swapped: bool = False  # the 8-bit image stored as BGR
    # -- the mistakes that image alone may not tell from another --
    reflect_flipped: bool = False  # the specular's R = L − 2(N·L)N, the reflected vector with the wrong sign
    checker_read: bool = True  # a material's checker read (False: every hit shaded with its object's material)
    clamp_colour: bool = True  # pixels clamped to [0, 1] (False: floor(255·v + 0.5) stored modulo 256, wrapped)
    ambient_from_diffuse: bool = False  # the ambient term k_d ⊙ Σ ambient instead of k_a ⊙ Σ ambient
    spot_ramp_angle: bool = False  # a spot's ramp from inner_cutoff to cutoff linear in the angle, not its cosine
    transparent_shadows: bool = True  # objects with k_t > 0 block shadow rays (False: shadow rays pass them)
    reflections: bool = True  # mirror rays traced where k_r > 0 (False: never, at any depth)
    refractions: bool = True  # refracted rays traced where k_t > 0 (False: never, at any depth)
    spot_cone: bool = True  # a spot's cone read (False: the spot lit as a point light, its cone and exponent unread)
    attenuation_squared: bool = True  # attenuation's q·d² (False: q·d, the distance not squared)
    shadow_to_light: bool = True  # a shadow ray stops at its light (False: it goes on, and what lies beyond blocks)
    specular_shadowed: bool = True  # a blocked shadow ray takes the specular term too (False: only the diffuse)
    checker_floor: bool = True  # a checker's cell index floor(P/s) (False: int(P/s), truncated toward 0)
    area_centres: bool = True  # area-light samples at cell centres, (i + 0.5)/nu (False: at corners, i/nu)
    up_made: bool = True  # the camera's u = r × f (False: u = unit(up), as given, where up is not ⟂ the view)
    miss_background: bool = True  # a mirror or refracted ray that misses takes the background (False: black)

    @property
    def reference(self) -> bool:
        return self == REFERENCE

    def background(self, colour: np.ndarray, depth: int) -> np.ndarray:
        """What a ray of ``depth`` that hits nothing returns: the scene's background ``colour``, at any depth, as
        the format says; black past the camera's rays in a variant's (``miss_background`` False)."""
        return colour if depth == 0 or self.miss_background else np.zeros(3)

    def spawn(self, size: Callable[[], float]) -> Spawn | None:
        """Where this render's shadow and secondary rays start (None: at the hit point, as the format says): its
        offset × ``size()``, the scene's visible size (:mod:`tracer.exact.visible`), asked for only with an offset."""
        return Spawn(self.offset * size(), self.offset_along) if self.offset else None

    def read(self, scene: Any) -> Any:
        """``scene`` as this render's student reads it: one sample per pixel, spots without their exponent,
        lights without their colour, materials without their checker, as the options say; ``scene`` itself
        when they read it as it is (the reference's path).  The copy is not validated again: each change keeps
        it valid (samples 1, exponent 0, colour [1, 1, 1] are all in range; a material with no checker is one)."""
        if self.samples_read and self.spot_exponent and self.light_colour and self.checker_read:
            return scene
        image = scene.image if self.samples_read else scene.image.model_copy(update={"samples": 1})
        materials = (
            scene.materials
            if self.checker_read
            else {name: m.model_copy(update={"checker": None}) for name, m in scene.materials.items()}
        )
        lights = [self._light(light) for light in scene.lights]
        return scene.model_copy(update={"image": image, "lights": lights, "materials": materials})

    def _light(self, light: Any) -> Any:
        update: dict[str, Any] = {}
        if not self.light_colour and light.type != "ambient":
            update["color"] = (1.0, 1.0, 1.0)
        if not self.spot_exponent and light.type == "spot":
            update["exponent"] = 0.0
        return light.model_copy(update=update) if update else light

    def stored(self, rows: np.ndarray) -> np.ndarray:
        """8-bit RGB pixels ``(..., 3)`` as this render's student stores them: as grey (Pillow's ``convert("L")``,
        exactly: ``(19595 R + 38470 G + 7471 B + 2¹⁵) >> 16``, repeated in the three channels), with red and blue
        swapped, or (the reference) as they are."""
        if self.grayscale:
            wide = rows.astype(np.int64)
            grey = (19595 * wide[..., 0] + 38470 * wide[..., 1] + 7471 * wide[..., 2] + 0x8000) >> 16
            rows = np.repeat(grey[..., None], 3, axis=-1).astype(np.uint8)
        return rows[..., ::-1] if self.channels_swapped else rows

    def blended(self, colour: np.ndarray, reflectance: np.ndarray) -> np.ndarray:
        """The local colour ``(N, 3)`` of hits of mirror weights ``reflectance (N,)``: × (1 − k_r) when this
        render's student blends the mirror ray in instead of adding it, else itself."""
        return colour * (1.0 - reflectance)[:, None] if self.blend_reflection else colour

    def changes(self) -> list[str]:
        """The fields this departs from the reference in."""
        return [f.name for f in fields(self) if getattr(self, f.name) != getattr(REFERENCE, f.name)]


REFERENCE = Options()


def scene_size(scene: Any) -> float:
    """The largest side of the box around the scene's spheres and triangles (planes are unbounded and not
    counted); 1 for a scene of planes alone.  A ray offset is measured against the visible size
    (:mod:`tracer.exact.visible`), and against this only when the camera sees no surface."""
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
    shading normal, to the side the ray leaves by (``along="normal"``), along the surface's geometric normal
    (``along="geometric"``: a mesh's face's own, where its shading normal is interpolated), or along the ray itself
    (``along="ray"``: the same as ignoring hits nearer than ``amount``, a t_min, since the ray starts on the
    surface).  The rays are moved by :func:`tracer.shade.spawn.offset`."""

    amount: float
    along: str


#: name → (options, what a student did)
VARIANTS: dict[str, tuple[Options, str]] = {
    "no-shadows": (Options(shadows=False), "no shadow rays"),
    "shadow-acne": (Options(acne=True), "shadow acne: shadow rays hit the surface they start or end on"),
    "blinn-phong": (Options(blinn=True), "the Blinn–Phong half vector instead of the reflected vector"),
    "specular-behind": (Options(specular_behind=True), "specular light where N·L ≤ 0"),
    "gamma": (Options(gamma=True), "gamma 1/2.2 applied to the output"),
    "no-attenuation": (Options(attenuation=False), "no attenuation of point, spot and area lights"),
    "no-ambient": (Options(ambient=False), "no ambient term"),
    "no-specular": (Options(specular=False), "no specular term"),
    "normals-not-flipped": (Options(flip_normals=False), "normals not turned to face the ray"),
    "normals-not-normalised": (
        Options(normals_unit=False),
        "a mesh's interpolated normal not normalised: the blend of its vertex normals used as it is, not made unit",
    ),
    "image-flipped": (Options(flip_image=True), "the image flipped vertically"),
    "no-half-pixel": (Options(half_pixel=False), "pixel centres without the +0.5"),
    "horizontal-fov": (Options(vertical_fov=False), "fov taken as horizontal instead of vertical"),
    "aspect-inverted": (
        Options(aspect_inverted=True),
        "the aspect ratio inverted: the view's half-width tan(fov/2)·height/width, not ·width/height",
    ),
    "camera-up-as-given": (
        Options(up_made=False),
        "the camera's up vector used as given, not made perpendicular to the view (u = r × f)",
    ),
    "area-not-divided": (Options(area_divided=False), "an area light not divided by nu·nv"),
    "area-samples-at-corners": (
        Options(area_centres=False),
        "an area light's samples at its cells' corners, i/nu, without the + 0.5 of their centres",
    ),
    "spot-radians": (Options(spot_degrees=False), "a spot's cutoff compared in radians"),
    "depth-plus-one": (Options(depth_offset=1), "max_depth off by one (one bounce too many)"),
    "depth-minus-one": (Options(depth_offset=-1), "max_depth off by one (one bounce too few)"),
    "ior-inverted": (
        Options(ior_inverted=True),
        "the index of refraction inverted (or the surface normals pointing inward, which swaps entering and leaving)",
    ),
    # (rendered at 2e-2 of the visible size; the diagnosis scores it against a ladder of amounts, and says which)
    "offset-too-large": (Options(offset=2e-2), "shadow and secondary rays offset too far from the surface"),
    "reflect-sign": (Options(reflect_flipped=True), "the reflected vector R with the wrong sign (L − 2(N·L)N)"),
    "checker-ignored": (Options(checker_read=False), "the checkerboard ignored"),
    "checker-truncated": (
        Options(checker_floor=False),
        "the checker's cells counted with int() instead of floor(): the two cells either side of 0 count as one",
    ),
    "colours-not-clamped": (
        Options(clamp_colour=False),
        "colours not clamped: values above 1 wrap around in 8 bits instead of staying white",
    ),
    "ambient-from-diffuse": (Options(ambient_from_diffuse=True), "the ambient term scaled by k_d instead of k_a"),
    "spot-ramp-angle": (
        Options(spot_ramp_angle=True),
        "a spot's falloff from inner_cutoff to cutoff linear in the angle instead of in its cosine",
    ),
    "transparent-no-shadows": (
        Options(transparent_shadows=False),
        "transparent objects cast no shadows (shadow rays pass through objects with k_t > 0)",
    ),
    "no-reflection": (Options(reflections=False), "no reflection: mirror rays never traced"),
    "bounce-miss-black": (
        Options(miss_background=False),
        "a mirror or refracted ray that hits nothing returns black instead of the background",
    ),
    "no-refraction": (Options(refractions=False), "no refraction: refracted rays never traced"),
    "spot-cone-ignored": (Options(spot_cone=False), "a spot light lit as a point light: its cone ignored"),
    "attenuation-not-squared": (
        Options(attenuation_squared=False),
        "attenuation's quadratic term taken as q·d instead of q·d²",
    ),
    "shadow-past-light": (
        Options(shadow_to_light=False),
        "shadow rays not stopped at the light: what lies beyond a light casts shadows",
    ),
    "specular-in-shadow": (
        Options(specular_shadowed=False),
        "highlights not shadowed: the shadow test removes only the diffuse term",
    ),
}

#: more mistakes a student's tracer written from the format makes: name → (options, what a student
#: did).  Not in :data:`VARIANTS`, so that the diagnosis does not try them yet: trying them changes its cost and
#: its outcomes, which the wiring of the diagnosis decides.  A ray offset far too large is ``offset-too-large``.
MORE_VARIANTS: dict[str, tuple[Options, str]] = {
    "reflection-blended": (
        Options(blend_reflection=True),
        "reflection blended, (1 − k_r)·local + k_r·reflected, instead of added",
    ),
    "camera-left-handed": (
        Options(left_handed=True),
        "a left-handed camera basis (r = up × f): the image mirrored left to right",
    ),
    "samples-ignored": (Options(samples_read=False), "the scene's anti-aliasing samples ignored (one ray per pixel)"),
    "grayscale": (Options(grayscale=True), "the image saved in grayscale"),
    "spot-exponent-ignored": (Options(spot_exponent=False), "a spot's falloff exponent ignored"),
    "light-colour-ignored": (Options(light_colour=False), "the lights' colours ignored (every light white)"),
    "channels-swapped": (Options(channels_swapped=True), "red and blue swapped (the image stored as BGR)"),
    "clamped-per-term": (
        Options(clamp_terms=True),
        "each light's diffuse and specular term clamped on its own instead of the pixel once at the end",
    ),
    "exit-normal-not-flipped": (
        Options(exit_normal_flipped=False),
        "refraction leaving an object with the outward normal instead of the flipped one",
    ),
}

#: a classic mistake → the new ones (:data:`MORE_VARIANTS`) that may render the same image: light that never
#: leaves a glass object (a refracted ray leaving by the outward normal is turned back inside, every time) shows
#: as glass with no refracted ray at all.  Where a submission passes against the classic one, the diagnosis
#: scores these too, so that every reading of the image is given.
ALIKE: dict[str, tuple[str, ...]] = {"no-refraction": ("exit-normal-not-flipped",)}

#: per mistake of :data:`MORE_VARIANTS`, a sentence for the student who made it: what the image shows, what to fix
SENTENCES: dict[str, str] = {
    "reflection-blended": "Your mirror surfaces look too dark: the format adds k_r × the reflected colour to the "
    "surface's own colour; it does not mix the two by (1 − k_r).",
    "camera-left-handed": "Your image is mirrored left to right: the camera's right vector is f × up, not up × f.",
    "samples-ignored": "Your edges are jagged: the scene asks for n × n rays per pixel (image.samples), averaged.",
    "grayscale": "Your image has no colour: save it as RGB, not in grayscale.",
    "spot-exponent-ignored": "Your spot lights are too bright away from their axis: multiply by "
    "cos(angle)^exponent as well.",
    "light-colour-ignored": "Your lights are all white: multiply each light's term by the light's colour.",
    "channels-swapped": "Your red and blue are swapped: write the channels in the order R, G, B.",
    "clamped-per-term": "Your highlights are too dim where lights are bright: clamp each pixel once, after "
    "everything is added, not each light's diffuse or specular term.",
    "exit-normal-not-flipped": "Your glass looks wrong: when a refracted ray leaves an object, turn the normal "
    "inside (w = −n) and use η = ior.",
}


def add_clamped(
    colour: np.ndarray, color: np.ndarray, diffuse: np.ndarray, specular: np.ndarray, wd: np.ndarray, ws: np.ndarray
) -> None:
    """:func:`tracer.shade.shading.add_phong` of a student who clamps each term: ``colour += clip(I⊙k_d·wd) +
    clip(I⊙k_s·ws)``, each clipped to [0, 1] per channel (the ``clamp_terms`` mistake)."""
    for k in range(3):
        colour[:, k] += np.clip(color[k] * diffuse[:, k] * wd, 0.0, 1.0) + np.clip(
            color[k] * specular[:, k] * ws, 0.0, 1.0
        )


#: the ways of honest tracers a grade accepts besides the reference, by default: name → how far at most, × the
#: scene's visible size (:mod:`tracer.exact.visible`).  A task may narrow or widen them (``accepted`` in a class's
#: tasks file).  An offset along the normal moves a refracted ray sideways, and shows sooner than a t_min, which
#: only skips what lies nearer than it along the ray.
ACCEPTED_DEFAULT: dict[str, float] = {"normal-offset": 5e-3, "t-min": 1e-2}

#: accepted variant → (the option that sets its amount, what it is in words)
ACCEPTED_KINDS: dict[str, tuple[str, str]] = {"normal-offset": ("normal", "ray offset"), "t-min": ("ray", "t_min")}


#: mistakes whose effect varies from point to point (a student's acne speckles in its own pattern): name →
#: the options of the mistake's far end.  An image with the mistake lies between the reference and that
#: render, pixel by pixel, and departs from the reference in speckles.
BOUNDS: dict[str, Options] = {"shadow-acne": Options(acne=True, acne_everywhere=True)}
