"""What one request may ask of the service, checked before any work is done."""

from __future__ import annotations

import math
from typing import Any

from schemas import AreaLight, Mesh, Plane, Scene, Sphere, Triangle

from .settings import Settings


class LimitError(ValueError):
    """A request beyond a configured limit; ``status`` is 413 or 422."""

    def __init__(self, message: str, status: int = 422):
        super().__init__(message)
        self.status = status


def check_body(body: bytes | str, settings: Settings) -> None:
    """Before parsing: every face, vertex and normal is a JSON array, so a body with far more
    ``[`` than a scene within the limits can hold is refused without the cost of parsing it."""
    raw = body.encode() if isinstance(body, str) else body
    arrays = raw.count(b"[")
    allowed = 2 * settings.max_triangles + 16 * settings.max_objects + 4 * settings.max_light_samples + 1024
    if arrays > allowed:
        raise LimitError(f"scene: {arrays} JSON arrays, more than a scene within max_triangles = "
                         f"{settings.max_triangles} and max_objects = {settings.max_objects} can have")


def check_raw(data: Any, settings: Settings) -> None:
    """Cheap counts on the parsed JSON, before validation spends time on a huge scene."""
    if not isinstance(data, dict):
        return
    objects = data.get("objects")
    if isinstance(objects, list):
        if len(objects) > settings.max_objects:
            raise LimitError(f"objects: {len(objects)} objects exceed the limit max_objects = {settings.max_objects}")
        faces = sum(len(o["faces"]) for o in objects
                    if isinstance(o, dict) and isinstance(o.get("faces"), list))
        if faces > settings.max_triangles:
            raise LimitError(f"objects: {faces} faces exceed the limit max_triangles = {settings.max_triangles}")


def light_samples(scene: Scene) -> int:
    """Shadow rays per shading point: one per light, nu·nv per area light, none for ambient."""
    return sum(light.samples[0] * light.samples[1] if isinstance(light, AreaLight) else 1
               for light in scene.lights if light.type != "ambient")


def triangle_count(scene: Scene) -> int:
    return sum(1 if isinstance(o, Triangle) else len(o.faces) if isinstance(o, Mesh) else 0 for o in scene.objects)


def ray_tree_nodes(scene: Scene) -> float:
    """Rays per sub-sample in the worst case: the ray tree doubles at every depth where a material both
    reflects and transmits, grows by one where materials only reflect or only transmit."""
    mats = scene.materials.values()
    depth = scene.image.max_depth
    if any(m.reflectance > 0 and m.transmittance > 0 for m in mats):
        return 2.0 ** (depth + 1) - 1.0
    if any(m.reflectance > 0 or m.transmittance > 0 for m in mats):
        return depth + 1.0
    return 1.0


def per_ray_factor(scene: Scene) -> float:
    """Relative cost of one ray from what it is tested against: planes (and spheres that would be tested
    directly) cost per ray, BVH candidates about log n, and every sphere around the eye is crossed."""
    spheres = [o for o in scene.objects if isinstance(o, Sphere)]
    planes = sum(isinstance(o, Plane) for o in scene.objects)
    bvh = len(spheres) + triangle_count(scene)
    eye = scene.camera.position
    around = sum(1 for o in spheres if math.dist(eye, o.center) < o.radius)  # (hypot: no overflow at 1e300)
    return 1.0 + planes / 4.0 + math.log2(1.0 + bvh) / 8.0 + around / 2.0


def estimated_cost(scene: Scene) -> float:
    """Ray work of a render: pixels × samples² × worst-case ray tree × (1 + light samples) × per-ray factor."""
    img = scene.image
    return (float(img.width) * img.height * img.samples**2 * ray_tree_nodes(scene) * (1 + light_samples(scene))
            * per_ray_factor(scene))


def check_scene(scene: Scene, settings: Settings) -> None:
    img = scene.image
    pixels = img.width * img.height
    if pixels > settings.max_pixels:
        raise LimitError(f"image: {img.width}×{img.height} = {pixels} pixels exceed the limit "
                         f"max_pixels = {settings.max_pixels}")
    if img.samples > settings.max_samples:
        raise LimitError(f"image.samples: {img.samples} exceeds the limit max_samples = {settings.max_samples}")
    if img.max_depth > settings.max_depth:
        raise LimitError(f"image.max_depth: {img.max_depth} exceeds the limit max_depth = {settings.max_depth}")
    triangles = triangle_count(scene)
    if triangles > settings.max_triangles:
        raise LimitError(f"objects: {triangles} triangles exceed the limit max_triangles = {settings.max_triangles}")
    samples = light_samples(scene)
    if samples > settings.max_light_samples:
        raise LimitError(f"lights: {samples} light samples exceed the limit "
                         f"max_light_samples = {settings.max_light_samples}")
    cost = estimated_cost(scene)
    if cost > settings.max_cost:
        raise LimitError(f"scene: estimated cost {cost:.3g} (pixels × samples² × worst-case ray tree × "
                         f"(1 + light samples) × per-ray factor) "
                         f"exceeds the limit max_cost = {settings.max_cost:.3g}")
