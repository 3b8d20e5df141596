"""What one request may ask of the service, checked before any work is done."""

from __future__ import annotations

import math
from typing import Any

from schemas import AreaLight, Mesh, Plane, Scene, Sphere, Triangle
from tracer.budget import Budget, OverBudget
from tracer.sizes import shown

from ..settings import Settings
from .estimate import ray_tree


class LimitError(ValueError):
    """A request beyond a configured limit; ``status`` is 413 or 422."""

    def __init__(self, message: str, status: int = 422):
        super().__init__(message)
        self.status = status


def check_body(body: bytes | str, settings: Settings) -> None:
    """Before parsing: every object, material and light is a JSON object and every face, vertex and
    normal a JSON array, so a body with far more ``{`` or ``[`` than a scene within the limits can hold
    is refused without the cost of parsing it (a count of brackets, so strings holding them count too)."""
    raw = body.encode("utf-8", "surrogatepass") if isinstance(body, str) else body
    braces = raw.count(b"{")
    allowed = settings.max_objects + 2 * settings.max_materials + settings.max_lights + 16
    if braces > allowed:
        raise LimitError(
            f"scene: {braces} JSON objects ('{{'), more than a scene within max_objects = "
            f"{settings.max_objects}, max_materials = {settings.max_materials} and max_lights = "
            f"{settings.max_lights} can have",
            413,
        )
    arrays = raw.count(b"[")
    allowed = (
        settings.max_triangles + 2 * settings.max_vertices + 16 * settings.max_objects + 8 * settings.max_lights + 1024
    )
    if arrays > allowed:
        raise LimitError(
            f"scene: {arrays} JSON arrays ('['), more than a scene within max_triangles = "
            f"{settings.max_triangles}, max_vertices = {settings.max_vertices} and max_objects = "
            f"{settings.max_objects} can have",
            413,
        )


def check_raw(data: Any, settings: Settings) -> None:
    """Counts on the parsed JSON, before validation spends time on a huge scene."""
    if not isinstance(data, dict):
        return
    for name, limit in (("objects", "max_objects"), ("lights", "max_lights"), ("materials", "max_materials")):
        part = data.get(name)
        if isinstance(part, (list, dict)) and len(part) > getattr(settings, limit):
            raise LimitError(
                f"{name}: {len(part)} entries exceed the limit {limit} = {getattr(settings, limit)} "
                f"(PHONGRAY_{limit.upper()})"
            )
    objects = data.get("objects")
    if not isinstance(objects, list):
        return
    meshes = [o for o in objects if isinstance(o, dict)]
    for key, limit in (("faces", "max_triangles"), ("vertices", "max_vertices"), ("normals", "max_vertices")):
        count = sum(len(o[key]) for o in meshes if isinstance(o.get(key), list))
        if count > getattr(settings, limit):
            raise LimitError(
                f"objects: {count} {key} in all exceed the limit {limit} = "
                f"{getattr(settings, limit)} (PHONGRAY_{limit.upper()})"
            )


def shadow_rays_per_point(scene: Scene) -> int:
    """Shadow rays per shading point: one per light, nu·nv per area light, none for ambient."""
    return sum(
        light.samples[0] * light.samples[1] if isinstance(light, AreaLight) else 1
        for light in scene.lights
        if light.type != "ambient"
    )


def triangle_count(scene: Scene) -> int:
    return sum(1 if isinstance(o, Triangle) else len(o.faces) if isinstance(o, Mesh) else 0 for o in scene.objects)


def per_ray_factor(scene: Scene) -> float:
    """Relative cost of one ray from what it is tested against: planes (and spheres that would be tested
    directly) cost per ray, BVH candidates about log n, and every sphere around the eye is crossed."""
    spheres = [o for o in scene.objects if isinstance(o, Sphere)]
    planes = sum(isinstance(o, Plane) for o in scene.objects)
    bvh = len(spheres) + triangle_count(scene)
    eye = scene.camera.position
    around = sum(1 for o in spheres if math.dist(eye, o.center) < o.radius)  # (hypot: no overflow at 1e300)
    return 1.0 + planes / 4.0 + math.log2(1.0 + bvh) / 8.0 + around / 2.0


def camera_rays(scene: Scene) -> float:
    """The rays a render certainly casts: one per pixel and sub-sample."""
    img = scene.image
    return float(img.width) * img.height * img.samples**2


def estimated_cost(scene: Scene) -> float:
    """Ray work of a render, estimated before it starts: camera rays × (rays of the tree each spawns + their
    hits × light samples) × per-ray factor (:func:`service.admission.estimate.ray_tree`)."""
    tree = ray_tree(scene)
    return camera_rays(scene) * (tree.rays + tree.hits * shadow_rays_per_point(scene)) * per_ray_factor(scene)


#: exact tests of a ray against a sphere or a triangle a render may make per unit of ``max_cost``: the examples, the
#: Cornell homework, the 10,000-sphere field and nested glass make at most 2.7 (``tests/test_limits.py``); a
#: scene whose rays each meet thousands of surfaces its per-ray factor does not see (huge spheres beside tiny
#: ones, tested against every ray; spheres nested around a point the camera looks at) makes over 1,000.  At the
#: slowest rate measured, 5·10⁶ tests a second, 4 × 10⁸ tests take 80 s, within the 120 s render_timeout
TESTS_PER_COST = 4.0


def budget(scene: Scene, settings: Settings) -> Budget:
    """What a render of ``scene`` may spend as it runs: its rays, counted, times its per-ray factor within
    ``max_cost``, its exact tests of rays against surfaces within :data:`TESTS_PER_COST` × ``max_cost``, and its
    rays in flight within ``max_ray_bytes``."""
    return Budget(
        rays=settings.max_cost / per_ray_factor(scene),
        ray_bytes=settings.max_ray_bytes,
        tests=settings.max_cost * TESTS_PER_COST,
    )


#: what to say of each budget a render may outgrow: the setting, and what the scene can do about it
OUTGROWN = {
    "rays": (
        "max_cost",
        "it needs more rays than the service traces for one image: lower image.max_depth "
        "(mirrors and glass that see each other multiply the rays at every bounce), "
        "image.samples, the image's size or the area lights' samples",
    ),
    "tests": (
        "max_cost",
        "its rays meet more surfaces than the service tests for one image (spheres or "
        "triangles far larger than the rest are tested against every ray, and so are "
        "surfaces nested around one another): lower the image's size, image.samples or "
        "the number of such surfaces",
    ),
    "memory": (
        "max_ray_bytes",
        "its rays in flight need more memory than the service allows for one "
        "image: lower image.max_depth or image.samples",
    ),
}


def outgrown(exc: OverBudget, settings: Settings) -> LimitError:
    """The refusal of a render stopped by its budget, in words a student can act on, naming the setting."""
    name, advice = OUTGROWN[exc.what]
    return LimitError(
        f"scene: the render was stopped: {advice}. The limit is {name} = {getattr(settings, name):.3g}, "
        f"set by PHONGRAY_{name.upper()}"
    )


def check_scene(scene: Scene, settings: Settings) -> None:
    """Refuse up front what is certain to exceed a limit: the image's size, samples and depth, the scene's
    triangles and light samples, and camera rays whose work alone is over ``max_cost``.  The rest of a
    render's work is counted as it runs (:func:`budget`)."""
    img = scene.image
    pixels = img.width * img.height
    if pixels > settings.max_pixels:
        raise LimitError(
            f"image: {shown(img.width)}×{shown(img.height)} = {shown(pixels)} pixels exceed the limit "
            f"max_pixels = {settings.max_pixels} (PHONGRAY_MAX_PIXELS)"
        )
    if img.samples > settings.max_samples:
        raise LimitError(
            f"image.samples: {shown(img.samples)} exceeds the limit max_samples = "
            f"{settings.max_samples} (PHONGRAY_MAX_SAMPLES)"
        )
    if img.max_depth > settings.max_depth:
        raise LimitError(
            f"image.max_depth: {shown(img.max_depth)} exceeds the limit max_depth = "
            f"{settings.max_depth} (PHONGRAY_MAX_DEPTH)"
        )
    triangles = triangle_count(scene)
    if triangles > settings.max_triangles:
        raise LimitError(
            f"objects: {triangles} triangles exceed the limit max_triangles = "
            f"{settings.max_triangles} (PHONGRAY_MAX_TRIANGLES)"
        )
    samples = shadow_rays_per_point(scene)
    if samples > settings.max_light_samples:
        raise LimitError(
            f"lights: {shown(samples)} light samples exceed the limit "
            f"max_light_samples = {settings.max_light_samples} (PHONGRAY_MAX_LIGHT_SAMPLES)"
        )
    certain = camera_rays(scene) * per_ray_factor(scene)
    if certain > settings.max_cost:
        raise LimitError(
            f"image: its camera rays alone (pixels × samples² × per-ray factor = {certain:.3g}) "
            f"exceed the limit max_cost = {settings.max_cost:.3g} (PHONGRAY_MAX_COST): lower "
            f"image.samples or the image's size"
        )


def beyond_limits(scene: Scene, settings: Settings) -> list[str]:
    """What a service with ``settings`` would refuse of ``scene`` up front, or most likely stop as it runs
    (its estimated cost over ``max_cost``): the warnings of ``phongray validate``."""
    try:
        check_scene(scene, settings)
    except LimitError as exc:
        return [str(exc)]
    cost = estimated_cost(scene)
    if cost <= settings.max_cost:
        return []
    return [
        f"scene: its estimated cost {cost:.3g} exceeds the limit max_cost = {settings.max_cost:.3g} "
        f"(PHONGRAY_MAX_COST): a service with that limit will likely stop its render"
    ]
