"""What one request may ask of the service, checked before any work is done."""

from __future__ import annotations

from typing import Any

from schemas import AreaLight, Mesh, Scene, Triangle

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


def estimated_cost(scene: Scene) -> float:
    """Rays a render may cast, roughly: pixels × sub-samples × (1 + light samples) × depth levels."""
    img = scene.image
    bounces = any(m.reflectance > 0 or m.transmittance > 0 for m in scene.materials.values())
    levels = 1 + img.max_depth if bounces else 1
    return float(img.width) * img.height * img.samples**2 * (1 + light_samples(scene)) * levels


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
    triangles = sum(1 if isinstance(o, Triangle) else len(o.faces) if isinstance(o, Mesh) else 0
                    for o in scene.objects)
    if triangles > settings.max_triangles:
        raise LimitError(f"objects: {triangles} triangles exceed the limit max_triangles = {settings.max_triangles}")
    samples = light_samples(scene)
    if samples > settings.max_light_samples:
        raise LimitError(f"lights: {samples} light samples exceed the limit "
                         f"max_light_samples = {settings.max_light_samples}")
    cost = estimated_cost(scene)
    if cost > settings.max_cost:
        raise LimitError(f"scene: estimated cost {cost:.3g} (pixels × samples² × (1 + light samples) × depth levels) "
                         f"exceeds the limit max_cost = {settings.max_cost:.3g}")
