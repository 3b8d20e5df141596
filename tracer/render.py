"""The one place that knows the order of the stages.

For each chunk of pixels, per depth: intersect → misses take the background →
direct light (ambient, then one shadow batch per light or area-light sample)
→ spawn mirror and refracted rays.  Chunks run on a thread pool: Embree and
the large NumPy operations release the GIL, and each chunk writes only its own
pixels, so the result does not depend on the thread count or the chunk size.
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from schemas import Scene

from .camera import CameraRays
from .image import quantize
from .intersect import MISS, Hits, Intersector
from .lights import illuminate, light_samples
from .rays import Rays, Shadows, Work
from .shading import light_in_plane, mirror, phong, refract, resolve_material, shading_normal
from .sightlines import scene_sightlines
from .vec import dot, rows_of, scaled
from .world import World, build_world, max_abs

#: rays per chunk: large enough for NumPy to be efficient (and for its long loops, which let go of the GIL, to
#: outweigh the interpreter's share), small enough to bound memory.  Measured on two threads: 2^16 is 12-25 %
#: faster than 2^15 on the bench scenes, 2^17 no faster; a 4096² render then peaks at 221 MiB (168 MiB at 2^15)
CHUNK_RAYS = 1 << 16

Progress = Callable[[int, int], None]


#: the largest image the renderer will make (16384 × 16384): its pixels alone take 768 MiB
MAX_PIXELS = 1 << 28
#: the most primary rays (pixels × sub-samples) one render will cast
MAX_PRIMARY_RAYS = 1 << 32


#: the most point lights (lights plus area-light samples) one render will shade with
MAX_LIGHT_SAMPLES = 1 << 20


class ImageTooLarge(ValueError):
    """The render asked for is beyond what phongray does: too many pixels, rays or light samples."""


class RenderCancelled(Exception):
    """Raised by :meth:`Renderer.pixels` when its ``cancel`` callback asked it to stop."""


class _Stop:
    """Raises :class:`RenderCancelled` when called once the caller's ``cancel`` returns True.  The renderer and
    its intersector both poll it; it holds no reference back to the renderer, so that a renderer dropped by
    its caller is freed at once (a cycle would keep its arrays and BVH until the garbage collector ran)."""

    def __init__(self) -> None:
        self.cancel: Callable[[], bool] | None = None

    def __call__(self) -> None:
        if self.cancel is not None and self.cancel():
            raise RenderCancelled("the render was cancelled")


class Renderer:
    """A scene prepared for tracing; :meth:`pixels` renders it.

    ``counts`` tallies the rays cast so far by kind: primary, shadow, secondary.
    """

    def __init__(self, scene: Scene):
        img = scene.image
        if img.width * img.height > MAX_PIXELS:
            raise ImageTooLarge(f"image: {img.width}×{img.height} pixels is more than phongray renders "
                                f"({MAX_PIXELS} pixels, 16384×16384)")
        if img.width * img.height * img.samples**2 > MAX_PRIMARY_RAYS:
            raise ImageTooLarge(f"image: {img.width}×{img.height} pixels × {img.samples}² sub-samples is more "
                                f"primary rays than phongray renders ({MAX_PRIMARY_RAYS})")
        lights = light_samples(scene.lights)
        if lights > MAX_LIGHT_SAMPLES:
            raise ImageTooLarge(f"lights: {lights} light samples are more than phongray renders "
                                f"({MAX_LIGHT_SAMPLES})")
        self.scene = scene
        self._stop = _Stop()
        self.slice_rays = CHUNK_RAYS
        self.counts = {"primary": 0, "shadow": 0, "secondary": 0}
        self._count_lock = threading.Lock()
        with np.errstate(all="ignore"):  # hostile magnitudes (1e300) overflow to inf here; the tracer copes
            self.world: World = build_world(scene)
            self.camera = CameraRays(scene.camera, scene.image, self.world.origin)
            self.intersector = Intersector(self.world, scene_sightlines(scene, self.world.origin, self.camera))
        self.intersector.check = self._stop

    # -- whole image -------------------------------------------------------
    def pixels(self, threads: int | None = None, chunk_rays: int = CHUNK_RAYS,
               progress: Progress | None = None, cancel: Callable[[], bool] | None = None,
               rows: tuple[int, int] | None = None) -> np.ndarray:
        """The image as ``(H, W, 3) uint8``, or only its rows ``top..bottom`` with ``rows``.

        Every pixel is computed alone (its sums are exact integers), so a band of
        rows is byte for byte the same rows of the whole image.  ``cancel`` is
        polled before every chunk; once it returns True the remaining chunks are
        skipped and :class:`RenderCancelled` is raised.
        """
        img = self.scene.image
        self._stop.cancel = cancel
        self.slice_rays = chunk_rays
        top, bottom = rows if rows is not None else (0, img.height)
        if not 0 <= top <= bottom <= img.height:
            raise ValueError(f"rows {top}..{bottom} are not within 0..{img.height}")
        first, end = top * img.width, bottom * img.width
        total = end - first
        per_chunk = max(1, chunk_rays // (img.samples * img.samples))
        bounds = [(a, min(a + per_chunk, end)) for a in range(first, end, per_chunk)]
        out = np.empty((total, 3), dtype=np.uint8)
        workers = threads or os.cpu_count() or 1

        stopped = False

        def work(bound: tuple[int, int]) -> int:
            nonlocal stopped
            a, b = bound
            if stopped or (cancel is not None and cancel()):
                stopped = True
                return 0
            out[a - first:b - first] = quantize(self.chunk(a, b))
            return b - a

        if workers == 1 or len(bounds) == 1:
            done = 0
            for bound in bounds:
                done += work(bound)
                if progress:
                    progress(done, total)
        else:
            with ThreadPoolExecutor(max_workers=workers) as pool:
                done = 0
                for count in pool.map(work, bounds):
                    done += count
                    if progress:
                        progress(done, total)
        if stopped:
            raise RenderCancelled("the render was cancelled")
        return out.reshape(bottom - top, img.width, 3)

    # -- one chunk ---------------------------------------------------------
    def chunk(self, start: int, stop: int) -> np.ndarray:
        """Linear colour of pixels ``start..stop`` (mean of their sub-samples). Shape (stop − start, 3).

        The ray tree is traced depth-first in slices of at most ``slice_rays``
        rays, so memory depends on the slice size and the depth, never on
        2^depth.  Every contribution is added as a fixed-point integer, so the
        sums, and the bytes of the image, do not depend on the order in which
        slices, chunks or threads deliver them.
        """
        img = self.scene.image
        s = img.samples * img.samples
        with np.errstate(all="ignore"):
            origins, dirs = self.camera.rays(start, stop)
            n = len(origins)
            self._count("primary", n)
            acc = np.zeros((n, 3), dtype=np.int64)
            ceiling = float(2 * s)  # a sub-sample this bright saturates its pixel: sums are clamped there
            # the fixed-point unit leaves room for a slice's worth of contributions on top of a clamped sum
            fixed = 2.0 ** (48 - math.ceil(math.log2(ceiling)) - max(0, math.ceil(math.log2(self.slice_rays)) - 14))
            background = np.asarray(img.background, dtype=np.float64)
            camera = Work(self.intersector.rays(origins, dirs), np.arange(n), np.ones(n), 0)
            stack: list[Work] = [camera]
            while stack:
                work = stack.pop()
                if len(work) > self.slice_rays:  # split; the first slice goes on top, so it is traced first
                    stack += reversed(work.slices(self.slice_rays))
                    continue
                self._stop()
                hits = self.intersector.closest(work.rays)
                missed = hits.kind == MISS
                once = work.depth == 0  # a primary ray is its sample's only ray of its depth; later, two may share
                _accumulate(acc, work.sample[missed], work.weight[missed, None] * background, ceiling, fixed, once)
                rows = np.flatnonzero(~missed)
                if len(rows) == 0:
                    continue
                hit, done = hits.take(rows), work.take(rows)
                dd = done.rays.dirs
                mat = resolve_material(self.world, hit)
                normal = shading_normal(self.world, hit, dd)
                _accumulate(acc, done.sample, scaled(self.direct(hit, mat, normal, dd), done.weight), ceiling, fixed,
                            once)
                if work.depth == img.max_depth:
                    continue
                children = self.secondary(hit, mat, normal, done)
                self._count("secondary", len(children))
                if len(children):
                    stack.append(children)
            per_pixel = acc.reshape(stop - start, s, 3).sum(axis=1)  # integers: exact in any order
            return per_pixel.astype(np.float64) / (fixed * s)

    def _count(self, kind: str, n: int) -> None:
        with self._count_lock:
            self.counts[kind] += n

    def direct(self, hit: Hits, mat: np.ndarray, normal: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Ambient plus every light's Phong term where the light reaches the hit points. Shape (N, 3).

        Per light: L, d and the intensity factor at every point; one batch of
        shadow rays for the points that face the light; then Phong over all
        points with the unreached ones weighted zero (cheaper than gathering).
        """
        m = self.world.materials
        colour = rows_of(m.ambient, mat) * self.world.ambient
        diffuse, specular, shininess = rows_of(m.diffuse, mat), rows_of(m.specular, mat), m.shininess[mat]
        nv = -dot(normal, dirs)  # N·V, the same for every light
        mag_points = max_abs(hit.point) + self.world.origin_mag  # every light's shadow rays start there
        for em in self.world.emitters:
            self._stop()  # a long chunk (many lights) stops early too
            mag_light = max_abs(em.position[None]) + self.world.origin_mag
            if not np.any(em.color > 0):
                continue
            to_light, dist, factor = illuminate(em, hit.point)
            nl = light_in_plane(self.world, hit, em, dot(normal, to_light), dist)
            rows = np.flatnonzero((nl > 0) & (factor > 0))
            if len(rows) == 0:
                continue
            every = len(rows) == len(nl)  # then no gathering: the rows are all of them, in order

            def pick(a: np.ndarray, every: bool = every, rows: np.ndarray = rows) -> np.ndarray:
                return a if every else rows_of(a, rows)

            shadow_dirs = np.ascontiguousarray(pick(to_light))
            # from the exact hit point, leaving its surface by identity, to the light itself
            rays = Rays(pick(hit.point), shadow_dirs, pick(hit.kind), pick(hit.index), pick(mag_points))
            if em.kind == "directional":
                shadows = Shadows(rays, np.full(len(rows), np.inf), None, None)
            else:
                shadows = Shadows(rays, pick(dist), em.position[None], mag_light)  # one light for every ray
            self._count("shadow", len(rows))
            blocked = self.intersector.occluded(shadows)
            if every:
                weight = np.where(blocked, 0.0, factor)
            else:
                weight = np.zeros(len(nl))
                weight[rows] = np.where(blocked, 0.0, factor[rows])
            rv = 2.0 * nl * nv + dot(to_light, dirs)  # R·V with R = 2(N·L)N − L, V = −D
            colour += em.color * phong(diffuse, specular, shininess, nl, rv, weight)
        return colour

    def secondary(self, hit: Hits, mat: np.ndarray, normal: np.ndarray, work: Work) -> Work:
        """Mirror and refracted rays of the hits whose material asks for them: the next depth's work."""
        m = self.world.materials
        kr, kt = m.reflectance[mat], m.transmittance[mat]
        dirs, weight = work.rays.dirs, work.weight
        r = np.flatnonzero(weight * kr > 0)  # a weight that underflowed to 0 would only add 0·∞ = NaN
        t = np.flatnonzero(weight * kt > 0)
        # secondary rays start at the exact hit point and leave its surface by identity
        out = np.concatenate([mirror(dirs[r], normal[r]), refract(dirs[t], hit.normal[t], m.ior[mat[t]])])
        both = np.concatenate([r, t])
        points = rows_of(hit.point, both)
        rays = Rays(points, out, hit.kind[both], hit.index[both], max_abs(points) + self.world.origin_mag)
        return Work(rays, work.sample[both], np.concatenate([weight[r] * kr[r], weight[t] * kt[t]]), work.depth + 1)


def _accumulate(acc: np.ndarray, index: np.ndarray, values: np.ndarray, ceiling: float, fixed: float,
                unique: bool = False) -> None:
    """``acc[index] += values`` in fixed point (units of ``1/fixed``); repeated indices are summed.

    Contributions are never negative, so a sum at or above ``ceiling`` (twice
    the sub-samples of a pixel) already saturates its pixel and is clamped
    there; NaN counts as nothing.  Integer sums are exact, so their order
    never shows in the image.  ``unique`` says that no index repeats: the
    sum is then a plain gather and scatter instead of ``np.add.at``.
    """
    if len(index):
        v = np.clip(np.nan_to_num(values, nan=0.0, posinf=ceiling), 0.0, ceiling)
        units = np.rint(v * fixed).astype(np.int64)
        cap = np.int64(ceiling * fixed)
        if unique:
            units += acc[index]
            np.minimum(units, cap, out=units)
            acc[index] = units
        else:
            np.add.at(acc, index, units)
            np.minimum(acc, cap, out=acc)


def render(scene: Scene, threads: int | None = None, chunk_rays: int = CHUNK_RAYS,
           progress: Progress | None = None, cancel: Callable[[], bool] | None = None) -> np.ndarray:
    """Render a validated scene to ``(H, W, 3) uint8`` pixels."""
    return Renderer(scene).pixels(threads=threads, chunk_rays=chunk_rays, progress=progress, cancel=cancel)
