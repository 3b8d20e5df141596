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


def shown(n: int) -> str:
    """An integer for a message: in full up to 15 digits, else its order of magnitude (Python refuses
    to format integers of more than 4300 digits, and nobody wants to read them)."""
    if abs(n) < 10**15:
        return str(n)
    return f"about 10^{int(abs(n).bit_length() * math.log10(2))}"


def check_body(body: bytes | str, settings: Settings) -> None:
    """Before parsing: every object, material and light is a JSON object and every face, vertex and
    normal a JSON array, so a body with far more ``{`` or ``[`` than a scene within the limits can hold
    is refused without the cost of parsing it (a count of brackets, so strings holding them count too)."""
    raw = body.encode("utf-8", "surrogatepass") if isinstance(body, str) else body
    braces = raw.count(b"{")
    allowed = settings.max_objects + 2 * settings.max_materials + settings.max_lights + 16
    if braces > allowed:
        raise LimitError(f"scene: {braces} JSON objects ('{{'), more than a scene within max_objects = "
                         f"{settings.max_objects}, max_materials = {settings.max_materials} and max_lights = "
                         f"{settings.max_lights} can have", 413)
    arrays = raw.count(b"[")
    allowed = (settings.max_triangles + 2 * settings.max_vertices + 16 * settings.max_objects
               + 8 * settings.max_lights + 1024)
    if arrays > allowed:
        raise LimitError(f"scene: {arrays} JSON arrays ('['), more than a scene within max_triangles = "
                         f"{settings.max_triangles}, max_vertices = {settings.max_vertices} and max_objects = "
                         f"{settings.max_objects} can have", 413)


def check_raw(data: Any, settings: Settings) -> None:
    """Counts on the parsed JSON, before validation spends time on a huge scene."""
    if not isinstance(data, dict):
        return
    for name, limit in (("objects", "max_objects"), ("lights", "max_lights"), ("materials", "max_materials")):
        part = data.get(name)
        if isinstance(part, (list, dict)) and len(part) > getattr(settings, limit):
            raise LimitError(f"{name}: {len(part)} entries exceed the limit {limit} = {getattr(settings, limit)}")
    objects = data.get("objects")
    if not isinstance(objects, list):
        return
    meshes = [o for o in objects if isinstance(o, dict)]
    for key, limit in (("faces", "max_triangles"), ("vertices", "max_vertices"), ("normals", "max_vertices")):
        count = sum(len(o[key]) for o in meshes if isinstance(o.get(key), list))
        if count > getattr(settings, limit):
            raise LimitError(f"objects: {count} {key} in all exceed the limit {limit} = "
                             f"{getattr(settings, limit)}")


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
        raise LimitError(f"image: {shown(img.width)}×{shown(img.height)} = {shown(pixels)} pixels exceed the limit "
                         f"max_pixels = {settings.max_pixels}")
    if img.samples > settings.max_samples:
        raise LimitError(f"image.samples: {shown(img.samples)} exceeds the limit max_samples = {settings.max_samples}")
    if img.max_depth > settings.max_depth:
        raise LimitError(f"image.max_depth: {shown(img.max_depth)} exceeds the limit max_depth = {settings.max_depth}")
    triangles = triangle_count(scene)
    if triangles > settings.max_triangles:
        raise LimitError(f"objects: {triangles} triangles exceed the limit max_triangles = {settings.max_triangles}")
    samples = light_samples(scene)
    if samples > settings.max_light_samples:
        raise LimitError(f"lights: {shown(samples)} light samples exceed the limit "
                         f"max_light_samples = {settings.max_light_samples}")
    cost = estimated_cost(scene)
    if cost > settings.max_cost:
        raise LimitError(f"scene: estimated cost {cost:.3g} (pixels × samples² × worst-case ray tree × "
                         f"(1 + light samples) × per-ray factor) "
                         f"exceeds the limit max_cost = {settings.max_cost:.3g}")
