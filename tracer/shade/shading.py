"""Surface response: materials with checkers, shading normals, Phong, mirror and refraction.

Nothing here casts a ray; :mod:`tracer.render` decides which rays to cast.
"""

from __future__ import annotations

import numpy as np

from ..scene.kinds import PLANE, TRIANGLE
from ..scene.lights import Emitter
from ..scene.rays import Hits
from ..scene.shapes import PARALLEL, on_tolerance
from ..scene.surfaces import unit
from ..scene.vec import along, dot, rows_of
from ..scene.world import World


def resolve_material(world: World, hits: Hits, floor: bool = True) -> np.ndarray:
    """Material id after the checker, per hit. Shape (N,), int.

    The checker is evaluated in world coordinates; on flat surfaces the point
    is first projected onto the surface's plane, computed from the plane's
    point (or the face's first vertex) as given, so that a floor lying on a
    cell boundary such as y = 0 lands exactly on it.  A column at a time: the
    same operations, in the same order, as on ``(N, 3)`` rows (the cells' sum
    is ``(x + y) + z``, as ``np.sum`` over a row adds it).  ``floor`` False is a
    variant's: cell indices truncated toward 0, as a student's ``int(P/s)``.
    """
    mats = world.materials
    mat = hits.material
    size = mats.checker_size[mat]
    sel = np.flatnonzero(size > 0)
    if len(sel) == 0:
        return mat
    every = len(sel) == len(mat)  # (every hit checkered: no gathering)

    def pick(a: np.ndarray, rows: np.ndarray, all_of: bool) -> np.ndarray:
        return a.copy() if all_of else np.take(a, rows)

    p = [pick(hits.point[:, k], sel, every) + world.origin[k] for k in range(3)]
    kind, index = hits.kind[sel], hits.index[sel]
    for code, anchors, normals in (
        (PLANE, world.planes.point_world, world.planes.normal),
        (TRIANGLE, world.triangles.v0_world, world.triangles.normal),
    ):
        flat = np.flatnonzero(kind == code)
        if len(flat):  # projected onto the surface's plane: p − ((p − anchor)·n) n
            at = index[flat]
            whole = len(flat) == len(sel)
            pf = [pick(p[k], flat, whole) for k in range(3)]
            one = bool(at[0] == at[-1]) and bool(np.all(at == at[0]))  # one surface: its numbers shared
            if one:  # (a hit's normal is its flat surface's own, copied: the same numbers)
                anchor, nf = [anchors[at[0], k] for k in range(3)], [normals[at[0], k] for k in range(3)]
            else:
                anchor = [np.take(anchors[:, k], at) for k in range(3)]
                nf = [pick(hits.normal[:, k], sel[flat], every and whole) for k in range(3)]
            side = (pf[0] - anchor[0]) * nf[0] + (pf[1] - anchor[1]) * nf[1] + (pf[2] - anchor[2]) * nf[2]
            for k in range(3):
                if whole:
                    p[k] = pf[k] - side * nf[k]
                else:
                    p[k][flat] = pf[k] - side * nf[k]
    cell = size[sel]
    for k in range(3):
        p[k] /= cell
        (np.floor if floor else np.trunc)(p[k], out=p[k])
    cells = p[0] + p[1]
    cells += p[2]
    odd = sel[odd_cells(cells)]
    out = mat.copy()
    out[odd] = mats.checker_other[mat[odd]]
    return out


def odd_cells(cells: np.ndarray) -> np.ndarray:
    """``np.mod(cells, 2.0) == 1.0`` for sums of whole numbers, as ``cells − 2·floor(cells / 2) == 1``: exact for
    whole numbers (halving and doubling are), NaN where mod gives NaN (infinities, NaN), and a fifth of mod's
    time. Shape as ``cells``, bool."""
    with np.errstate(invalid="ignore"):
        half = cells * 0.5
        np.floor(half, out=half)
        half *= 2.0
        np.subtract(cells, half, out=half)
        return half == 1.0


def shading_normal(
    world: World, hits: Hits, dirs: np.ndarray, face_the_ray: bool = True, unit_blend: bool = True
) -> np.ndarray:
    """Unit shading normal turned to face the ray (N·D ≤ 0; unless not ``face_the_ray``, a variant's
    mistake). Shape (N, 3).  Without ``unit_blend`` (another), a mesh's interpolated normal is the blend of its
    vertex normals as it is, not made unit: shorter than 1 between normals that differ, and as long as the
    normals given are."""
    normal = hits.normal.copy(order="K")  # (its columns contiguous, as every later stage reads them)
    tris = np.flatnonzero(hits.kind == TRIANGLE)
    if len(tris):
        k = hits.index[tris]
        smooth = world.triangles.smooth[k]
        if np.any(smooth):
            rows, k = tris[smooth], k[smooth]
            u, v = hits.bary[rows, 0:1], hits.bary[rows, 1:2]
            vn = rows_of(world.triangles.vertex_normals, k)
            blend = (1.0 - u - v) * vn[:, 0] + u * vn[:, 1] + v * vn[:, 2]
            blend = unit(blend) if unit_blend else blend
            zero = ~np.any(blend != 0, axis=1)
            blend[zero] = normal[rows[zero]]
            normal[rows] = blend
    if face_the_ray:
        turned = np.flatnonzero(dot(normal, dirs) > 0)
        for c in range(3):  # (a column at a time)
            normal[turned, c] *= -1.0
    return normal


def light_in_plane(world: World, hits: Hits, em: Emitter, nl: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """N·L as given (``nl``, with ``dist`` the distance to the light), but 0 where a hit lies on a flat
    surface (a plane, or a triangle without vertex normals) whose plane holds the light: its position within
    rounding (:func:`tracer.scene.shapes.on_tolerance`, the rule by which such a surface does not block it), or, for
    a directional light, its direction within :data:`tracer.scene.shapes.PARALLEL`.  Computed there, N·L would be
    rounding noise of either sign, and a positive one lets the specular term glint.  Shape (N,).

    Only hits whose light lies within twice that tolerance of their tangent plane (``|N·L|·d``, which every
    light in the plane meets) are looked at."""
    if em.kind == "directional":
        near = np.abs(nl) <= 2.0 * PARALLEL
    else:
        bound = on_tolerance(world.magnitude(em.position[None]), world.flat_mag)
        near = np.abs(nl) * dist <= 2.0 * bound
    if not near.any():
        return nl
    rows = np.flatnonzero(near)
    kind, index = hits.kind[rows], hits.index[rows]
    flat = kind == PLANE
    tri = np.flatnonzero(kind == TRIANGLE)
    flat[tri] = ~world.triangles.smooth[index[tri]]
    rows, kind, index = rows[flat], kind[flat], index[flat]
    normal = rows_of(hits.normal, rows)
    if em.kind == "directional":
        inside = np.abs(dot(normal, em.direction)) <= PARALLEL
    else:
        inside = np.zeros(len(rows), dtype=bool)
        position_mag = world.magnitude(em.position[None])
        for code, anchor, mag in (
            (PLANE, world.planes.point, world.planes.mag),
            (TRIANGLE, world.triangles.v0, world.triangles.mag),
        ):
            sel = np.flatnonzero(kind == code)
            if len(sel):
                k = index[sel]
                tol = on_tolerance(position_mag, mag[k])
                inside[sel] = np.abs(dot(em.position - rows_of(anchor, k), rows_of(normal, sel))) <= tol
    out = nl.copy()
    out[rows[inside]] = 0.0
    return out


#: the most (emitter, flat surface) pairs :func:`planes_holding` looks at (its temporaries are (E, F, 3)); past it,
#: every emitter may lie in one
HOLDING_PAIRS = 1 << 18


def planes_holding(world: World, emitters: list[Emitter]) -> np.ndarray:
    """Which emitters some flat surface's plane holds, by the rule of :func:`light_in_plane` (its ``inside``, for
    that surface's own anchor and normal: the same numbers a hit on it carries, so the same answer).  For an
    emitter no flat surface holds, :func:`light_in_plane` returns N·L as given, and need not be called.  Shape
    (E,), bool; every emitter when there are more pairs than :data:`HOLDING_PAIRS` to look at."""
    pl, tr = world.planes, world.triangles
    flat = np.flatnonzero(~tr.smooth)
    out = np.ones(len(emitters), dtype=bool)
    if len(emitters) * (len(pl.normal) + len(flat)) > HOLDING_PAIRS:
        return out
    points = [em for em in emitters if em.kind != "directional"]
    at = np.array([e for e, em in enumerate(emitters) if em.kind != "directional"], dtype=np.int64)
    directional = [e for e, em in enumerate(emitters) if em.kind == "directional"]
    out[:] = False
    for anchor, normal, mag in (
        (pl.point, pl.normal, pl.mag),
        (rows_of(tr.v0, flat), rows_of(tr.normal, flat), tr.mag[flat]),
    ):
        if len(mag) == 0:
            continue
        if len(at):  # (E, F) at once, each pair as light_in_plane computes it
            position = np.array([em.position for em in points])
            tol = on_tolerance(world.magnitude(position)[:, None], mag[None, :])
            out[at] |= np.any(np.abs(dot(position[:, None, :] - anchor[None, :, :], normal[None, :, :])) <= tol, axis=1)
        for e in directional:
            out[e] |= bool(np.any(np.abs(dot(normal, emitters[e].direction)) <= PARALLEL))
    return out


def add_phong(
    colour: np.ndarray, color: np.ndarray, diffuse: np.ndarray, specular: np.ndarray, wd: np.ndarray, ws: np.ndarray
) -> None:
    """``colour += color · (k_d · wd + k_s · ws)`` in place, a column at a time (a light's ``color (3,)``
    broadcast over the rows of ``(N, 3)`` arrays would loop three times per row), with ``wd, ws`` a light's
    terms (:class:`tracer.shade.kernel.Kernel`) and ``diffuse, specular (N, 3)`` the points' k_d and k_s."""
    for k in range(3):
        colour[:, k] += color[k] * (diffuse[:, k] * wd + specular[:, k] * ws)


def mirror(dirs: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``D − 2(D·N)N``. Shape (N, 3)."""
    return unit(along(dirs, -2.0 * dot(dirs, normal), normal))


def refract(
    dirs: np.ndarray, geometric: np.ndarray, ior: np.ndarray, inverted: bool = False, exit_flipped: bool = True
) -> np.ndarray:
    """Refracted unit directions by the contract's rule (mirror direction on total internal reflection); with
    ``inverted`` (a variant's mistake) η is ior entering and 1/ior leaving; without ``exit_flipped`` (another)
    a ray leaving uses the outward normal as w."""
    entering = dot(dirs, geometric) < 0
    eta = np.where(entering != inverted, 1.0 / ior, ior)
    w = np.where((entering | (not exit_flipped))[:, None], geometric, -geometric)
    c = -dot(dirs, w)
    k = 1.0 - eta * eta * (1.0 - c * c)
    root = np.sqrt(np.maximum(k, 0.0))
    through = eta[:, None] * dirs + (eta * c - root)[:, None] * w
    bounced = dirs - 2.0 * dot(dirs, w)[:, None] * w
    return unit(np.where((k < 0)[:, None], bounced, through))
