"""Where a ray meets two or more surfaces at one point: the order the tie goes by, and the ties the format leaves open.

**The rule.**  A ray that meets several surfaces at exactly the same ``t`` meets the first of them in this
order: a surface that lets no light through (its material, and its checker's other material, have
transmittance 0) before one that does; then spheres, planes, triangles (lone triangles and mesh faces); then the
earlier object in the scene (a mesh's faces in their order).  The same on every run, across a whole overlap and
at every scale: flat surfaces of different objects in one plane are met at bit for bit the same ``t`` where
they overlap (:mod:`tracer.scene.coplanar`), and :class:`tracer.exact.best.Best` keeps, of equal ``t``, the least key,
whatever order the candidates come in.

Why opaque first: a ray inside a glass box resting on a floor meets the box's bottom face and the floor at one
point.  Were it to meet the glass face, its refracted ray would leave from the floor's plane and meet the floor
nowhere (a ray never meets, at its own origin, a surface coincident with the one it leaves): the background
would show through an opaque floor.  Meeting the floor, it shows the floor, as a renderer that breaks such ties
towards the floor does, whatever order the box and the floor are listed in.

**Open pixels.**  Which of two overlapping coplanar surfaces shows is not the format's to say: a ray that meets,
at its nearest ``t``, surfaces of two objects, one of them a member of a coplanar group, is *open*
(:attr:`tracer.exact.best.Best.open`), and so is the pixel its ray tree serves (:meth:`tracer.render.Renderer.picture`),
which a grade does not count against a submission.

A key (:class:`tracer.exact.best.Best`'s) is ``see_through << 50 | kind << 48 | index``: least first.
"""

from __future__ import annotations

import numpy as np

from ..scene.coplanar import Groups
from ..scene.kinds import PLANE, SPHERE, TRIANGLE
from ..scene.surfaces import Materials

#: where a key holds the kind, and the flag of a surface that lets light through
KIND_SHIFT, SEE_THROUGH_SHIFT = 48, 50
#: a key's index bits
INDEX_MASK = (1 << KIND_SHIFT) - 1
#: a key without its see-through flag: the kind and the index, which name the surface
SURFACE_MASK = (1 << SEE_THROUGH_SHIFT) - 1


def surface_key(kind: int | np.ndarray, index: int | np.ndarray) -> np.ndarray | int:
    """A surface's key without the flag (:data:`SURFACE_MASK`): what names it."""
    if isinstance(kind, np.ndarray) or isinstance(index, np.ndarray):
        return (np.asarray(kind).astype(np.int64) << KIND_SHIFT) | np.asarray(index, dtype=np.int64)
    return (int(kind) << KIND_SHIFT) | int(index)


class Ties:
    """The tie order of a world's surfaces (each one's key), and which ties are open."""

    def __init__(
        self,
        materials: Materials,
        material: dict[int, np.ndarray],
        objects: dict[int, np.ndarray],
        groups: Groups | None,
    ):
        """``material`` and ``objects``: per kind, each surface's material and object."""
        through = materials.transmittance > 0
        through = through | through[materials.checker_other]
        #: per kind, the flag of each surface (1 where it lets light through), as it goes into a key
        self.flag = {k: through[m].astype(np.int64) << SEE_THROUGH_SHIFT for k, m in material.items()}
        self.any_flag = any(bool(f.any()) for f in self.flag.values())
        self.objects = objects
        self.groups = groups

    def key(self, kind: int | np.ndarray, index: np.ndarray) -> np.ndarray:
        """The keys of surfaces ``kind`` (one, or one each), ``index``. Shape (N,), int64."""
        key = np.asarray(surface_key(kind, index), dtype=np.int64)
        if not self.any_flag:
            return key
        if isinstance(kind, np.ndarray):
            flags = np.zeros(len(index), dtype=np.int64)
            for k, flag in self.flag.items():
                rows = np.flatnonzero(kind == k)
                flags[rows] = flag[index[rows]]
            return key | flags
        return key | self.flag[int(kind)][index]

    def key_of(self, kind: int, index: int) -> int:
        """The key of one surface."""
        return int(surface_key(kind, index)) | int(self.flag[kind][index])

    def objects_of(self, key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The object of each surface ``key`` (N,), and whether it is in a coplanar group. Each (N,)."""
        kind, index = (key >> KIND_SHIFT) & 3, key & INDEX_MASK
        obj = np.full(len(key), -1, dtype=np.int64)
        for k in (SPHERE, PLANE, TRIANGLE):
            rows = np.flatnonzero(kind == k)
            if len(rows):
                obj[rows] = self.objects[k][index[rows]]
        grouped = np.zeros(len(key), dtype=bool) if self.groups is None else self.groups.of(kind, index) >= 0
        return obj, grouped
