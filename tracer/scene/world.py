"""A validated scene turned into flat float64 arrays, re-centred on the eye.

Every position the tracer works with is *local*: world position minus
``World.origin``, the camera's position (never ``look_at``, which only sets a
direction; never the scene's bounds, which a far light or a planet would
stretch).  Moving a whole scene (camera and lights with it) therefore changes
no local coordinate beyond the rounding of the input, so a scene far from the
world origin is exactly as precise as one near it.  Each surface also carries its
world *magnitude* (largest absolute coordinate it was given with): the
rounding of its numbers, which decides when a point lies on it
(:func:`tracer.scene.shapes.on_tolerance`).

Array shapes: S spheres, Q planes, T triangles (lone triangles and mesh faces
of non-zero area), M materials.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from schemas import Mesh, Plane, Scene, Sphere, Triangle

from .coplanar import Groups, coplanar_groups
from .lights import Emitters, build_emitters
from .surfaces import Materials, Planes, Spheres, Triangles, magnitude, unit
from .variants import REFERENCE, Options
from .vec import cross, most, rows_of

F64 = np.float64


@dataclass(frozen=True)
class World:
    origin: np.ndarray  # (3,) world position of the local origin
    origin_mag: float  # its largest absolute coordinate (adds to every local point's magnitude)
    materials: Materials
    spheres: Spheres
    planes: Planes
    triangles: Triangles
    ambient: np.ndarray  # (3,) sum of ambient light colours
    emitters: Emitters
    #: flat surfaces of different objects in one plane, grouped (:mod:`tracer.scene.coplanar`); None: no such surfaces
    coplanar: Groups | None = None

    def magnitude(self, points: np.ndarray) -> np.ndarray:
        """The world magnitude of local ``points (N, 3)`` (:func:`tracer.scene.surfaces.magnitude`). Shape (N,)."""
        return magnitude(points, self.origin_mag)

    @property
    def flat_mag(self) -> float:
        """The largest world magnitude of a plane or a triangle (0 without any)."""
        return float(max(np.max(self.planes.mag, initial=0.0), np.max(self.triangles.mag, initial=0.0)))


def scene_centre(scene: Scene) -> np.ndarray:
    """The local origin: the eye.

    Precision then follows the viewer: every camera ray starts exactly at the origin (a perspective camera)
    or in its view window, and the local coordinates of what it sees are as small as their distance from
    it.  Something far away (a sun 10⁸ away, the centre of a planet) moves nothing here, where a centre of
    the scene's bounds would move every local coordinate near the eye by that much and round it with it.
    """
    return np.asarray(scene.camera.position, dtype=F64).copy()


def build_world(scene: Scene, options: Options = REFERENCE) -> World:
    origin = scene_centre(scene)
    names = {name: k for k, name in enumerate(scene.materials)}
    planes, triangles = _planes(scene, names, origin), _triangles(scene, names, origin)
    return World(
        origin=origin,
        origin_mag=float(np.max(np.abs(origin))),
        materials=_materials(scene, names),
        spheres=_spheres(scene, names, origin),
        planes=planes,
        triangles=triangles,
        ambient=np.sum(
            np.array([light.color for light in scene.lights if light.type == "ambient"], dtype=F64).reshape(-1, 3),
            axis=0,
        ),
        emitters=build_emitters(scene.lights, origin, options),
        coplanar=coplanar_groups(planes, triangles),
    )


def _materials(scene: Scene, names: dict[str, int]) -> Materials:
    mats = list(scene.materials.values())

    def col(attr: str) -> np.ndarray:
        return np.array([getattr(m, attr) for m in mats], dtype=F64).reshape(-1, 3)

    def num(attr: str) -> np.ndarray:
        return np.array([getattr(m, attr) for m in mats], dtype=F64).reshape(-1)

    return Materials(
        ambient=col("ambient"),
        diffuse=col("diffuse"),
        specular=col("specular"),
        shininess=num("shininess"),
        reflectance=num("reflectance"),
        transmittance=num("transmittance"),
        ior=num("ior"),
        checker_size=np.array([m.checker.size if m.checker else 0.0 for m in mats], dtype=F64),
        checker_other=np.array(
            [names[m.checker.material] if m.checker else k for k, m in enumerate(mats)], dtype=np.int64
        ),
    )


def _spheres(scene: Scene, names: dict[str, int], origin: np.ndarray) -> Spheres:
    index = [k for k, o in enumerate(scene.objects) if isinstance(o, Sphere)]
    objs = [o for o in scene.objects if isinstance(o, Sphere)]
    center = np.array([o.center for o in objs], dtype=F64).reshape(-1, 3) - origin
    radius = np.array([o.radius for o in objs], dtype=F64)
    return Spheres(
        center=center,
        radius=radius,
        material=np.array([names[o.material] for o in objs], dtype=np.int64),
        mag=np.max(np.abs(center + origin), axis=1, initial=0.0) + radius,
        object=np.array(index, dtype=np.int64),
    )


def _planes(scene: Scene, names: dict[str, int], origin: np.ndarray) -> Planes:
    index = [k for k, o in enumerate(scene.objects) if isinstance(o, Plane)]
    objs = [o for o in scene.objects if isinstance(o, Plane)]
    point_world = np.array([o.point for o in objs], dtype=F64).reshape(-1, 3)
    return Planes(
        point=point_world - origin,
        normal=unit(np.array([o.normal for o in objs], dtype=F64).reshape(-1, 3)),
        material=np.array([names[o.material] for o in objs], dtype=np.int64),
        point_world=point_world,
        mag=np.max(np.abs(point_world), axis=1, initial=0.0),
        object=np.array(index, dtype=np.int64),
    )


def _triangles(scene: Scene, names: dict[str, int], origin: np.ndarray) -> Triangles:
    corners, materials, normals, smooth, ids, owners, faces_of = [], [], [], [], [], [], []
    count = 0  # corners numbered so far
    for k, obj in enumerate(scene.objects):
        if isinstance(obj, Triangle):
            owners.append(np.full(1, k))
            faces_of.append(np.zeros(1, dtype=np.int64))
            ids.append(np.arange(count, count + 3).reshape(1, 3))
            count += 3
            corners.append(np.array(obj.vertices, dtype=F64).reshape(1, 3, 3))
            materials.append(np.full(1, names[obj.material]))
            normals.append(np.zeros((1, 3, 3)))
            smooth.append(np.zeros(1, dtype=bool))
        elif isinstance(obj, Mesh) and obj.faces:
            verts, faces = obj.rows("vertices"), obj.rows("faces")
            owners.append(np.full(len(faces), k))
            faces_of.append(np.arange(len(faces)))
            ids.append(faces + count)
            count += len(verts)
            corners.append(rows_of(verts, faces))
            materials.append(np.full(len(faces), names[obj.material]))
            if obj.normals is not None:
                normals.append(rows_of(obj.rows("normals"), faces))
                smooth.append(np.ones(len(faces), dtype=bool))
            else:
                normals.append(np.zeros((len(faces), 3, 3)))
                smooth.append(np.zeros(len(faces), dtype=bool))
    world = np.concatenate(corners) if corners else np.zeros((0, 3, 3))
    local = world - origin
    e1, e2 = local[:, 1] - local[:, 0], local[:, 2] - local[:, 0]
    normal = unit(cross(unit(e1), unit(e2)))
    keep = np.any(normal != 0, axis=1) & np.all(np.isfinite(local), axis=(1, 2))  # zero-area faces are never hit
    vertex_normals = np.concatenate(normals) if normals else np.zeros((0, 3, 3))
    smooth_mask = np.concatenate(smooth) if smooth else np.zeros(0, dtype=bool)
    if not smooth_mask.all():
        vertex_normals = np.where(smooth_mask[:, None, None], vertex_normals, normal[:, None, :])
    material = np.concatenate(materials).astype(np.int64) if materials else np.zeros(0, dtype=np.int64)
    corner_ids = np.concatenate(ids) if ids else np.zeros((0, 3), dtype=np.int64)
    owner = np.concatenate(owners).astype(np.int64) if owners else np.zeros(0, dtype=np.int64)
    face = np.concatenate(faces_of).astype(np.int64) if faces_of else np.zeros(0, dtype=np.int64)
    if not keep.all():  # (when every face is kept, as usual, no copies)
        local, world, e1, e2, normal = local[keep], world[keep], e1[keep], e2[keep], normal[keep]
        material, vertex_normals, smooth_mask = material[keep], vertex_normals[keep], smooth_mask[keep]
        corner_ids, owner, face = corner_ids[keep], owner[keep], face[keep]
    return Triangles(
        v0=np.ascontiguousarray(local[:, 0]),
        e1=e1,
        e2=e2,
        normal=normal,
        material=material,
        v0_world=np.ascontiguousarray(world[:, 0]),
        vertex_normals=vertex_normals,
        smooth=smooth_mask,
        mag=most(np.abs(world).reshape(-1, 9)) if len(world) else np.zeros(0),
        corner_ids=corner_ids,
        object=owner,
        face=face,
    )
