"""How many rays a scene can really spawn: the ray tree estimated from where its mirrors and glass are.

A camera sub-sample casts one ray; a ray that hits a surface whose material reflects casts a mirror ray, one
that transmits a refracted ray, up to ``max_depth``.  The worst case doubles at every depth, but a mirror ray
only goes on if it meets another mirror or glass: the tree is as large as the chance that a ray leaving one
reflecting or transmitting body meets another.  This module estimates that chance from the bodies' bounding
spheres (planes as themselves), with no tracing:

* a camera ray: a grid of :data:`GRID`² camera rays (the scene's own camera) against the bounds, nearest first;
* a ray leaving body *i*: going out of it, it meets body *j* with the share of directions *j* fills seen from
  *i* (every direction when *j* holds *i*; half of them for a plane); going in (glass, or a closed mirror
  seen from inside), it meets *i* again, or a body inside *i* by its share of *i*'s area.

Opaque bodies in the way are ignored (the estimate errs high), and so are weights: the tracer follows every
ray whose weight is not zero.  ``python -m bench.calibrate`` compares the estimate with the rays counted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from schemas import Image, Mesh, Plane, Scene, Sphere, Triangle
from tracer.scene.camera import CameraRays

#: camera rays per side of the grid that estimates what the camera sees
GRID = 24
#: bounding spheres tested against the grid at a time
BLOCK = 512
#: the most mirror and glass bodies followed one by one (the largest): the chain between them is a matrix
MAX_CASTING = 256
#: depths followed one by one; deeper ones grow as the last did
DEEPEST = 64


@dataclass(frozen=True)
class Body:
    """A surface as the estimate sees it: a bounding sphere (``radius`` inf for a plane, then ``center`` is a
    point of it and ``normal`` its normal), the rays a hit on it casts, and whether it is closed."""

    center: np.ndarray
    radius: float
    children: int  # mirror and refracted rays a hit casts: 0, 1 or 2
    closed: bool  # a sphere or a mesh: a ray can go into it
    transmits: bool  # a hit casts a refracted ray
    normal: np.ndarray | None = None


@dataclass(frozen=True)
class Tree:
    """Rays per camera sub-sample: ``rays`` in all (camera, mirror and refracted), of which ``hits`` meet a
    surface (each casts one shadow ray per light sample)."""

    rays: float
    hits: float


def _casts(scene: Scene, name: str) -> tuple[bool, bool]:
    """Whether a hit on material ``name`` (or its checker's other material) casts a mirror ray, a refracted one."""
    mats = scene.materials
    both = [mats[name]] if name in mats else []
    if both and both[0].checker is not None and both[0].checker.material in mats:
        both.append(mats[both[0].checker.material])
    return any(m.reflectance > 0 for m in both), any(m.transmittance > 0 for m in both)


def _bound(points: np.ndarray) -> tuple[np.ndarray, float]:
    centre = (points.min(axis=0) + points.max(axis=0)) / 2.0
    return centre, float(np.sqrt(((points - centre) ** 2).sum(axis=1).max()))


def bodies(scene: Scene) -> list[Body]:
    """Every object of the scene as a :class:`Body`."""
    out = []
    for obj in scene.objects:
        mirror, glass = _casts(scene, obj.material)
        casts = int(mirror) + int(glass)
        if isinstance(obj, Sphere):
            out.append(Body(np.asarray(obj.center, dtype=float), obj.radius, casts, True, glass))
        elif isinstance(obj, Plane):
            normal = np.asarray(obj.normal, dtype=float)
            out.append(
                Body(
                    np.asarray(obj.point, dtype=float),
                    math.inf,
                    casts,
                    False,
                    glass,
                    normal / (np.linalg.norm(normal) or 1.0),
                )
            )
        elif isinstance(obj, (Triangle, Mesh)) and len(obj.vertices):
            centre, radius = _bound(np.asarray(obj.vertices, dtype=float))
            out.append(Body(centre, radius, casts, isinstance(obj, Mesh), glass))
    return out


def _ball_t(origins: np.ndarray, dirs: np.ndarray, centre: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Where each ray's line first meets each bounding sphere ahead of it (its exit when inside). (rays, balls)."""
    rel = centre[None, :, :] - origins[:, None, :]
    along = np.einsum("rbk,rk->rb", rel, dirs)
    gap = np.einsum("rbk,rbk->rb", rel, rel) - along**2
    half = np.sqrt(np.maximum(radius**2 - gap, 0.0))
    return np.where(gap <= radius**2, np.where(along - half > 0, along - half, along + half), np.inf)


def _nearest(origins: np.ndarray, dirs: np.ndarray, found: list[Body]) -> np.ndarray:
    """Which body each ray's line meets first ahead of its origin (bounds only), −1 for none. Shape (N,).
    Bounding spheres a block of :data:`BLOCK` at a time, planes one by one."""
    best = np.full(len(dirs), np.inf)
    which = np.full(len(dirs), -1)

    def offer(t: np.ndarray, ks: np.ndarray) -> None:
        t = np.where(np.isfinite(t) & (t > 0), t, np.inf)
        pick = np.argmin(t, axis=1)
        near = t[np.arange(len(t)), pick]
        better = near < best
        best[better], which[better] = near[better], ks[pick[better]]

    balls = np.array([k for k, b in enumerate(found) if b.normal is None], dtype=int)
    for at in range(0, len(balls), BLOCK):
        ks = balls[at : at + BLOCK]
        offer(
            _ball_t(origins, dirs, np.array([found[k].center for k in ks]), np.array([found[k].radius for k in ks])), ks
        )
    for k, body in enumerate(found):
        if body.normal is not None:
            offer((((body.center - origins) @ body.normal) / (dirs @ body.normal))[:, None], np.array([k]))
    return which


def _grid(image: Image) -> Image:
    """The estimate's grid of camera rays: at most :data:`GRID` a side, the image's own aspect."""
    w, h = image.width, image.height
    if w >= h:
        side = min(GRID, w)
        return Image(width=side, height=max(1, min(side, round(side * h / w))))
    side = min(GRID, h)
    return Image(width=max(1, min(side, round(side * w / h))), height=side)


def _camera(scene: Scene, found: list[Body]) -> tuple[np.ndarray, float]:
    """The share of camera rays that first meet each body, and the share that meet any."""
    grid = _grid(scene.image)
    with np.errstate(all="ignore"):
        origins, dirs = CameraRays(scene.camera, grid, np.zeros(3)).rays(0, grid.width * grid.height)
        which = _nearest(np.asarray(origins, dtype=float), dirs, found)
    share = np.bincount(which[which >= 0], minlength=len(found)) / len(which)
    return share, float(np.mean(which >= 0))


def _inside(a: Body, b: Body) -> bool:
    """Body ``a`` lies within the bound of closed body ``b``."""
    return b.closed and a is not b and bool(np.linalg.norm(a.center - b.center) + a.radius <= b.radius)


def _seen(a: Body, b: Body) -> float:
    """The share of directions leaving ``a`` outwards that meet ``b`` (its solid angle over a hemisphere)."""
    if b.normal is not None:
        return 0.5
    if a.normal is not None:  # from a plane: as seen from the plane's point nearest to b
        d = abs(float((b.center - a.center) @ a.normal))
    else:
        d = float(np.linalg.norm(b.center - a.center))
    if d <= b.radius:
        return 1.0
    return 1.0 - math.sqrt(1.0 - (b.radius / d) ** 2)


def _shares(i: int, found: list[Body]) -> np.ndarray:
    """Where one ray cast by a hit on body ``i`` goes next: the chance it meets each body (at most 1 in all)."""
    a = found[i]
    out = np.zeros(len(found))
    inward = 0.5 if a.closed and a.transmits else 0.0  # glass: one ray in, one out; a mirror's goes out
    holders = [j for j, b in enumerate(found) if _inside(a, b)]
    if holders:  # going out, it meets the closest body holding it
        out[min(holders, key=lambda j: found[j].radius)] += 1.0 - inward
    else:
        for j, b in enumerate(found):
            if j != i:
                out[j] += (1.0 - inward) * _seen(a, b)
    held = [j for j, b in enumerate(found) if _inside(b, a)]
    area = np.array([min(1.0, (found[j].radius / a.radius) ** 2) for j in held])
    inner = float(area.sum())
    out[held] += inward * area / max(1.0, inner)
    out[i] += inward * max(0.0, 1.0 - inner)
    total = float(out.sum())
    return out / total if total > 1.0 else out


def transitions(found: list[Body]) -> np.ndarray:
    """``M[i, j]``: how many of the rays a hit on body ``i`` casts meet body ``j`` next."""
    m = np.zeros((len(found), len(found)))
    for i, a in enumerate(found):
        if a.children:
            m[i] = _shares(i, found) * a.children
    return m


def ray_tree(scene: Scene) -> Tree:
    """Rays per camera sub-sample the scene can really spawn (:class:`Tree`): each depth's rays are those the
    hits of the depth before cast, and they meet the bodies that cast as :func:`transitions` says (rays that
    meet none are assumed to meet something that casts nothing, as often as camera rays do)."""
    found = bodies(scene)
    share, hit = _camera(scene, found) if found else (np.zeros(0), 0.0)
    every = [k for k, b in enumerate(found) if b.children]
    if not every:
        return Tree(1.0, hit)
    # beyond MAX_CASTING bodies, those the camera sees most stand for the rest (their share scaled up to all's)
    keep = sorted(every, key=lambda k: (-share[k], -found[k].radius))[:MAX_CASTING]
    casting = [found[k] for k in keep]
    level = share[keep] * (share[every].sum() / max(share[keep].sum(), 1e-300))  # per body, rays meeting it
    step = np.nan_to_num(transitions(casting), nan=0.0)
    children = np.array([float(b.children) for b in casting])
    rays, hits, spawned, grew = 1.0, hit, 0.0, 0.0
    depth = scene.image.max_depth
    for d in range(min(depth, DEEPEST)):
        before, spawned = spawned, float(level @ children)
        if not spawned >= 1e-12:
            return Tree(rays, hits)
        level = level @ step
        met = float(level.sum())
        rays += spawned
        hits += met + (spawned - met) * hit
        grew = spawned / before if d else 0.0
    if depth > DEEPEST:
        more = _beyond(spawned, grew, depth - DEEPEST)
        rays, hits = rays + more, hits + more
    return Tree(rays, hits)


def _beyond(spawned: float, grew: float, k: int) -> float:
    """The rays of ``k`` more depths, each growing ``grew`` times the one before, the last having ``spawned``
    (a hall of mirrors: as many at every depth): spawned · (grew + grew² + … + grewᵏ), inf past a float."""
    if abs(grew - 1.0) < 1e-9:
        return spawned * k
    if grew < 1.0:
        return spawned * grew * (1.0 - grew**k) / (1.0 - grew)
    if k * math.log(grew) > 700.0:
        return math.inf
    return spawned * grew * (grew**k - 1.0) / (grew - 1.0)
