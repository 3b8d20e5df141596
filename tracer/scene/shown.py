"""Variants a scene cannot show (:data:`UNCHANGED`): for those, the variant's render is the reference's, bit for bit,
and no render is needed to know it.  Each rule follows the one place the variant's option is read."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .camera import up_perpendicular


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
    "no-ambient": lambda scene: (
        not (
            any(light.type == "ambient" and any(v != 0 for v in light.color) for light in scene.lights)
            and _materials(scene, lambda m: any(v != 0 for v in m.ambient))
        )
    ),
    # every point, spot and area light already falls off as (1, 0, 0)
    "no-attenuation": lambda scene: all(
        tuple(light.attenuation) == (1.0, 0.0, 0.0) for light in scene.lights if light.type in ("point", "spot", "area")
    ),
    # only a mesh with vertex normals interpolates one (elsewhere the normal is a sphere's, a plane's or a face's)
    "normals-not-normalised": lambda scene: (
        not any(obj.type == "mesh" and obj.normals is not None for obj in scene.objects)
    ),
    # an up perpendicular to the view is u, as given (the variant reads it only where it is not)
    "camera-up-as-given": lambda scene: up_perpendicular(scene.camera),
    # a square image: the view window's half-sizes are (1, 1) either way
    "horizontal-fov": lambda scene: scene.image.width == scene.image.height,
    # a square image: its aspect is 1 either way up
    "aspect-inverted": lambda scene: scene.image.width == scene.image.height,
    # an area light of one sample is divided by 1 either way
    "area-not-divided": lambda scene: all(
        light.samples[0] * light.samples[1] == 1 for light in scene.lights if light.type == "area"
    ),
    # the samples are read only of an area light
    "area-samples-at-corners": lambda scene: not any(light.type == "area" for light in scene.lights),
    "spot-radians": lambda scene: not any(light.type == "spot" for light in scene.lights),
    # with no mirror or glass, no hit spawns a ray, so how deep the tree may go changes nothing
    "depth-plus-one": lambda scene: not _bounces(scene),
    "depth-minus-one": lambda scene: scene.image.max_depth == 0 or not _bounces(scene),
    # η is read only where a refracted ray is spawned: no glass, no bounce, or ior 1 (1/1 is 1)
    "ior-inverted": lambda scene: (
        scene.image.max_depth == 0 or not _materials(scene, lambda m: m.transmittance > 0 and m.ior != 1.0)
    ),
    # an offset moves only shadow rays (of a light that is not ambient) and mirror or refracted rays
    "offset-too-large": lambda scene: not _lit(scene) and (scene.image.max_depth == 0 or not _bounces(scene)),
    # -- of MORE_VARIANTS --
    # the local colour is multiplied by 1 − k_r = 1 exactly where k_r = 0
    "reflection-blended": lambda scene: not _materials(scene, lambda m: m.reflectance > 0),
    # the scene read with samples 1 is the scene
    "samples-ignored": lambda scene: scene.image.samples == 1,
    # exponent 0 read for an exponent of 0
    "spot-exponent-ignored": lambda scene: all(light.exponent == 0 for light in scene.lights if light.type == "spot"),
    # white read for white
    "light-colour-ignored": lambda scene: all(
        tuple(light.color) == (1.0, 1.0, 1.0) for light in scene.lights if light.type != "ambient"
    ),
    # the normal is read only where a refracted ray is spawned
    "exit-normal-not-flipped": lambda scene: (
        scene.image.max_depth == 0 or not _materials(scene, lambda m: m.transmittance > 0)
    ),
    # -- of the mistakes an image may not tell from another --
    # −R·V is read only where R·V is: in the specular term
    "reflect-sign": lambda scene: not _specular(scene),
    # a checker is read only of an object's own material (the other cell's has none)
    "checker-ignored": lambda scene: not any(scene.materials[o.material].checker for o in scene.objects),
    # int() and floor() agree on every cell index ≥ 0: a scene whose checkered objects lie where every coordinate is
    # ≥ 0 shows no difference, but that takes the geometry to know; with no checker at all, nothing is read
    "checker-truncated": lambda scene: not any(scene.materials[o.material].checker for o in scene.objects),
    # k_d read for k_a: the same where they are equal, and times 0 without ambient light
    "ambient-from-diffuse": lambda scene: (
        not any(light.type == "ambient" and any(v != 0 for v in light.color) for light in scene.lights)
        or not _materials(scene, lambda m: m.ambient != m.diffuse)
    ),
    # with inner_cutoff = cutoff there is no ramp to be linear: S is s^exponent inside the cone, 0 outside
    "spot-ramp-angle": lambda scene: (
        not any(light.type == "spot" and light.inner < light.cutoff for light in scene.lights)
    ),
    # with no transparent object (or no light to cast shadows), every surface blocks either way
    "transparent-no-shadows": lambda scene: (
        not _lit(scene) or not any(scene.materials[o.material].transmittance > 0 for o in scene.objects)
    ),
    # a mirror or refracted ray is spawned only below max_depth, at a material with k_r (k_t) > 0
    # a black background is black either way; only a mirror or refracted ray, spawned below max_depth, reads it
    "bounce-miss-black": lambda scene: (
        tuple(scene.image.background) == (0.0, 0.0, 0.0) or scene.image.max_depth == 0 or not _bounces(scene)
    ),
    "no-reflection": lambda scene: scene.image.max_depth == 0 or not _materials(scene, lambda m: m.reflectance > 0),
    "no-refraction": lambda scene: scene.image.max_depth == 0 or not _materials(scene, lambda m: m.transmittance > 0),
    # a spot is lit as a point light only in the variant: no spot, nothing to read otherwise
    "spot-cone-ignored": lambda scene: not any(light.type == "spot" for light in scene.lights),
    # q·d for q·d² is the same where q is 0 (lights lit with the attenuation are point, spot and area lights)
    "attenuation-not-squared": lambda scene: all(
        light.attenuation[2] == 0 for light in scene.lights if light.type in ("point", "spot", "area")
    ),
    # a directional light's shadow rays have no end to stop at: only point, spot and area lights show it
    "shadow-past-light": lambda scene: not any(light.type in ("point", "spot", "area") for light in scene.lights),
    # the specular term is k_s times a finite number: with every k_s zero, what a shadow leaves of it is 0 either way
    "specular-in-shadow": lambda scene: not _specular(scene),
}


def unchanged(name: str, scene: Any) -> bool:
    """Whether variant ``name`` (of :data:`tracer.scene.variants.VARIANTS` or ``MORE_VARIANTS``, or a far end in
    ``BOUNDS``) renders ``scene`` exactly as the reference does, by the rules of :data:`UNCHANGED` (a variant without
    a rule: False)."""
    rule = UNCHANGED.get(name)
    return bool(rule is not None and rule(scene))
