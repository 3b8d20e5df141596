"""Rules of the scene format that relate values to each other.

Each check yields ``(path, message)`` pairs, with paths written the way users
see them: ``objects[3].material``.  They run only on a structurally valid
:class:`~schemas.scene.Scene`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import numpy as np

from .errors import suggestion
from .scene import (
    AreaLight,
    DirectionalLight,
    Mesh,
    Plane,
    PointLight,
    Scene,
    SpotLight,
    Triangle,
)

Problem = tuple[str, str]
#: at most this many index errors are listed for one mesh
MAX_LISTED = 10
#: the largest magnitude of a coordinate or a length (a radius, an area light's edge, an orthographic view's
#: height) phongray renders: beyond about 1e77 the squares and products of the tracer's bounds and tests overflow
#: (a mesh's cell grid, a sphere's lighting past 1e150), so a scene there would render wrong, not be refused
MOST = 1e60
#: the least the largest of them may be (a whole scene this small underflows the same way below about 1e-100);
#: one tiny coordinate or object in a scene of ordinary size is no problem.  The format asks for every scale
#: from 1e-30 to 1e30 times a scene's; these bounds leave thirty orders of ten beyond that either way
LEAST = 1e-60


def parallel(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> bool:
    """The contract's test: ``|a × b| ≤ 1e-12 |a| |b|``; a zero vector is parallel to all.

    Both vectors are scaled to a largest component of 1 first, which changes
    nothing in the test but keeps huge inputs from overflowing.
    """
    va, vb = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    sa, sb = np.abs(va).max(), np.abs(vb).max()
    if sa == 0 or sb == 0:
        return True
    if not (np.isfinite(sa) and np.isfinite(sb)):  # callers reject overflowing vectors before asking
        return False
    va, vb = va / sa, vb / sb
    cross = float(np.linalg.norm(np.cross(va, vb)))
    return cross <= 1e-12 * float(np.linalg.norm(va)) * float(np.linalg.norm(vb))


def is_zero(v: Sequence[float] | np.ndarray) -> bool:
    return all(c == 0 for c in v)


def _sub(a: Sequence[float], b: Sequence[float]) -> list[float]:
    return [x - y for x, y in zip(a, b)]  # Python floats overflow to inf quietly


def check_scene(scene: Scene) -> list[Problem]:
    return [
        *_camera(scene),
        *_materials(scene),
        *_objects(scene),
        *_lights(scene),
        *_names(scene.objects, "objects"),
        *_names(scene.lights, "lights"),
        *_scale(scene),
    ]


def _scale(scene: Scene) -> Iterator[Problem]:
    """The scene's largest coordinate or length, where it lies beyond :data:`MOST` or below :data:`LEAST`."""
    largest, where = 0.0, ""
    for path, values in _lengths(scene):
        if values.size:
            k = int(np.argmax(np.abs(values)))
            if abs(float(values.flat[k])) > largest:
                largest, where = abs(float(values.flat[k])), _at(path, values.shape, k)
    if largest > MOST:
        yield (
            where,
            f"{largest:.3g} is too large: phongray renders coordinates and sizes of at most 1e{math.log10(MOST):.0f} "
            "(scale the scene down)",
        )
    elif 0 < largest < LEAST:
        yield (
            where,
            (
                f"the scene's largest coordinate or size is {largest:.3g}: phongray renders scenes whose largest "
                f"is at least 1e{math.log10(LEAST):.0f} (scale the scene up)"
            ),
        )


def _at(path: str, shape: tuple[int, ...], k: int) -> str:
    """The path of element ``k`` (flat) of values of ``shape`` at ``path``: ``objects[2].vertices[5][0]``."""
    return path + "".join(f"[{i}]" for i in np.unravel_index(k, shape)) if len(shape) else path


def _lengths(scene: Scene) -> Iterator[tuple[str, np.ndarray]]:
    """Each coordinate and length of the scene with its path (directions, whose length is not read, are not)."""
    cam = scene.camera
    yield "camera.position", np.asarray(cam.position, dtype=np.float64)
    yield "camera.look_at", np.asarray(cam.look_at, dtype=np.float64)
    if cam.type == "orthographic":
        yield "camera.height", np.asarray(cam.height, dtype=np.float64)
    for i, obj in enumerate(scene.objects):
        where = f"objects[{i}]"
        if isinstance(obj, Mesh):
            yield f"{where}.vertices", obj.rows("vertices")
        elif isinstance(obj, Triangle):
            yield f"{where}.vertices", np.asarray(obj.vertices, dtype=np.float64)
        elif isinstance(obj, Plane):
            yield f"{where}.point", np.asarray(obj.point, dtype=np.float64)
        else:
            yield f"{where}.center", np.asarray(obj.center, dtype=np.float64)
            yield f"{where}.radius", np.asarray(obj.radius, dtype=np.float64)
    for i, light in enumerate(scene.lights):
        for name in ("position", "corner", "edge_u", "edge_v"):
            if hasattr(light, name):
                yield f"lights[{i}].{name}", np.asarray(getattr(light, name), dtype=np.float64)


def _names(items: Sequence[object], where: str) -> Iterator[Problem]:
    """A name used twice in one list: the second use, pointing at the first."""
    first: dict[str, int] = {}
    for i, item in enumerate(items):
        name = getattr(item, "name", None)
        if name is None:
            continue
        if name in first:
            yield f"{where}[{i}].name", f"'{name}' is already the name of {where}[{first[name]}] (names must be unique)"
        else:
            first[name] = i


def unknown_material(name: str, known: object) -> str:
    return f"unknown material '{name}'{suggestion(name, known)}"


def out_of_range(
    where: str, bad: Sequence[tuple[int, int, int]], n: int, total: int | None = None
) -> Iterator[Problem]:
    """The first face indices beyond a mesh's ``n`` vertices, as ``(face, corner, index)``; then how many more."""
    total = len(bad) if total is None else total
    for f, k, index in bad[:MAX_LISTED]:
        yield f"{where}.faces[{f}][{k}]", f"index {index} out of range (the mesh has {n} vertices)"
    if total > MAX_LISTED:
        yield f"{where}.faces", f"{total - MAX_LISTED} more indices out of range"


def _camera(scene: Scene) -> Iterator[Problem]:
    cam = scene.camera
    with np.errstate(over="ignore", invalid="ignore"):
        forward = np.subtract(cam.look_at, cam.position, dtype=np.float64)
    if not np.all(np.isfinite(forward)):
        yield "camera.look_at", "is too far from camera.position (look_at − position overflows)"
    elif is_zero(forward):
        yield "camera.look_at", "must differ from camera.position"
    elif parallel(forward, cam.up):
        yield "camera.up", "must not be parallel to look_at − position"


def _materials(scene: Scene) -> Iterator[Problem]:
    for name, mat in scene.materials.items():
        if mat.checker is None:
            continue
        other = scene.materials.get(mat.checker.material)
        where = f"materials.{name}.checker.material"
        if other is None:
            yield where, unknown_material(mat.checker.material, scene.materials)
        elif other.checker is not None:
            yield where, f"material '{mat.checker.material}' has a checker itself"


def _objects(scene: Scene) -> Iterator[Problem]:
    for i, obj in enumerate(scene.objects):
        where = f"objects[{i}]"
        if obj.material not in scene.materials:
            yield f"{where}.material", unknown_material(obj.material, scene.materials)
        if isinstance(obj, Plane) and is_zero(obj.normal):
            yield f"{where}.normal", "must be non-zero"
        elif isinstance(obj, Triangle):
            v0, v1, v2 = obj.vertices
            e1, e2 = _sub(v1, v0), _sub(v2, v0)
            if not all(math.isfinite(c) for c in (*e1, *e2)):
                yield f"{where}.vertices", "are too far apart (an edge, vertex minus vertex, overflows)"
            elif parallel(e1, e2):
                yield f"{where}.vertices", "must not be collinear (the triangle has zero area)"
        elif isinstance(obj, Mesh):
            yield from _mesh(obj, where)


def _mesh(mesh: Mesh, where: str) -> Iterator[Problem]:
    n = len(mesh.vertices)
    if mesh.faces:
        faces = mesh.rows("faces")
        yield from out_of_range(
            where,
            [(f, k, faces[f, k]) for f, k in np.argwhere(faces >= n)[: MAX_LISTED + 1]],
            n,
            int(np.count_nonzero(faces >= n)),
        )
    if mesh.normals is not None:
        if len(mesh.normals) != n:
            yield f"{where}.normals", f"must have one normal per vertex ({n}), got {len(mesh.normals)}"
        normals = mesh.rows("normals")
        zero = np.flatnonzero((normals[:, 0] == 0) & (normals[:, 1] == 0) & (normals[:, 2] == 0))
        for k in zero[:MAX_LISTED]:
            yield f"{where}.normals[{k}]", "must be non-zero"


def _lights(scene: Scene) -> Iterator[Problem]:
    for i, light in enumerate(scene.lights):
        where = f"lights[{i}]"
        if isinstance(light, (DirectionalLight, SpotLight)) and is_zero(light.direction):
            yield f"{where}.direction", "must be non-zero"
        if isinstance(light, (PointLight, SpotLight, AreaLight)) and is_zero(light.attenuation):
            yield f"{where}.attenuation", "coefficients must not all be zero"
        if isinstance(light, SpotLight) and light.inner > light.cutoff:
            yield f"{where}.inner_cutoff", f"must be ≤ cutoff ({light.cutoff:g})"
        if isinstance(light, AreaLight) and parallel(light.edge_u, light.edge_v):
            yield f"{where}.edge_v", "must not be parallel to edge_u"
