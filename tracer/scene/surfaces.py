"""The surfaces of a world as flat float64 arrays, one record a kind, and the two row helpers every stage uses.

Positions are local (:mod:`tracer.scene.world`: world position minus the eye's); each surface carries its world
magnitude, the rounding of its numbers (:func:`tracer.scene.shapes.on_tolerance`).  Shapes: S spheres, Q planes,
T triangles (lone triangles and mesh faces of non-zero area), M materials.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .vec import divided, dot, most


def max_abs(v: np.ndarray) -> np.ndarray:
    """Largest absolute component of each row of ``v (N, 3)``. Shape (N,)."""
    return most(np.abs(v))


def magnitude(points: np.ndarray, origin_mag: float) -> np.ndarray:
    """The world magnitude of local ``points (N, 3)``: each one's largest absolute coordinate plus the local
    origin's world magnitude (:mod:`tracer.scene.world`).  What scales the rounding that decides whether a point lies
    on a surface (:func:`tracer.scene.shapes.on_tolerance`): the one place it is computed. Shape (N,)."""
    out = np.maximum(np.maximum(np.abs(points[:, 0]), np.abs(points[:, 1])), np.abs(points[:, 2]))
    out += origin_mag
    return out


def unit(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` scaled to length 1 (zero rows stay zero), computed without overflow."""
    v = np.asarray(v, dtype=np.float64)
    if v.ndim == 2:
        squared = dot(v, v)
        if np.all((squared > 1e-280) & (squared < 1e280)):  # the usual case: no overflow or underflow possible
            return divided(v, np.sqrt(squared))
    scale = np.max(np.abs(v), axis=-1, keepdims=True)
    scale = np.where(scale > 0, scale, 1.0)
    w = v / scale
    length = np.sqrt(np.sum(w * w, axis=-1, keepdims=True))
    return np.where(length > 0, w / np.where(length > 0, length, 1.0), 0.0)


@dataclass(frozen=True)
class Materials:
    """Material parameters as arrays indexed by material id."""

    ambient: np.ndarray  # (M, 3)
    diffuse: np.ndarray  # (M, 3)
    specular: np.ndarray  # (M, 3)
    shininess: np.ndarray  # (M,)
    reflectance: np.ndarray  # (M,)
    transmittance: np.ndarray  # (M,)
    ior: np.ndarray  # (M,)
    checker_size: np.ndarray  # (M,), 0 where the material has no checker
    checker_other: np.ndarray  # (M,) int, the material of odd cells (itself if none)


@dataclass(frozen=True)
class Spheres:
    center: np.ndarray  # (S, 3) local
    radius: np.ndarray  # (S,)
    material: np.ndarray  # (S,) int
    mag: np.ndarray  # (S,) world magnitude: max |centre| + radius
    object: np.ndarray  # (S,) int: the index in ``scene.objects``


@dataclass(frozen=True)
class Planes:
    point: np.ndarray  # (Q, 3) local
    normal: np.ndarray  # (Q, 3) unit
    material: np.ndarray  # (Q,) int
    point_world: np.ndarray  # (Q, 3) as given, for the checker projection
    mag: np.ndarray  # (Q,) world magnitude of the plane's point
    object: np.ndarray  # (Q,) int: the index in ``scene.objects``


@dataclass(frozen=True)
class Triangles:
    v0: np.ndarray  # (T, 3) local
    e1: np.ndarray  # (T, 3) v1 - v0
    e2: np.ndarray  # (T, 3) v2 - v0
    normal: np.ndarray  # (T, 3) unit face normal
    material: np.ndarray  # (T,) int
    v0_world: np.ndarray  # (T, 3) first vertex as given, for the checker projection
    vertex_normals: np.ndarray  # (T, 3, 3) per-corner shading normals (face normal where none)
    smooth: np.ndarray  # (T,) bool: has per-vertex normals
    mag: np.ndarray  # (T,) world magnitude: largest absolute corner coordinate
    corner_ids: np.ndarray  # (T, 3) int: the corner's index among its mesh's vertices (unique across meshes)
    object: np.ndarray  # (T,) int: the index in ``scene.objects``
    face: np.ndarray  # (T,) int: the face's index in its mesh (0 for a lone triangle)
