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
from typing import TypeVar

import numpy as np

from schemas import Scene

from .budget import UNLIMITED, Budget, Growth, OverBudget, RayCount, RenderCancelled, Stop
from .camera import CameraRays
from .direct import DirectLight, light_groups
from .image import quantize
from .intersect import PLANE, SPHERE, TRIANGLE, Hits, Intersector
from .lights import LIGHT_TYPES, emitter_count
from .passes import ADDITIVE, BRANCH_PASS, LIGHT_TERMS, REFLECTED, REFRACTED, Tally, check_passes
from .planner import plan_proofs, scene_sightlines
from .rays import Among, Rays, Work
from .shading import mirror, refract, resolve_material, shading_normal
from .variants import REFERENCE, Options
from .vec import rows_of, scaled
from .walk import NO_HIT
from .world import World, build_world, max_abs

#: rays per chunk on several threads: large enough for NumPy to be efficient (and for its long loops, which let
#: go of the GIL, to outweigh the interpreter's share), small enough to bound memory.  Measured on two threads:
#: 2^16 is 12-25 % faster than 2^15 on the bench scenes, 2^17 no faster; a 4096² render then peaks at 221 MiB
#: (168 MiB at 2^15)
CHUNK_RAYS = 1 << 16
#: rays per chunk on one thread, where no other thread waits for the GIL and a chunk's arrays had better stay in
#: the cache: measured on one core, 2^15 is 8-20 % faster than 2^16 (three spheres at 320×240 and at 1080p, the
#: antialiased and the soft-shadow examples), 2^14 no faster
ONE_THREAD_CHUNK_RAYS = 1 << 15


def _chunking(threads: int | None, chunk_rays: int | None) -> tuple[int, int]:
    """The threads a render runs on (every core by default) and the rays of its chunks."""
    workers = threads or os.cpu_count() or 1
    return workers, chunk_rays or (CHUNK_RAYS if workers > 1 else ONE_THREAD_CHUNK_RAYS)

Progress = Callable[[int, int], None]

__all__ = ["Budget", "ImageTooLarge", "OverBudget", "RenderCancelled", "Renderer", "render"]


#: the largest image the renderer will make (16384 × 16384): its pixels alone take 768 MiB
MAX_PIXELS = 1 << 28
#: the most primary rays (pixels × sub-samples) one render will cast
MAX_PRIMARY_RAYS = 1 << 32


#: the most point lights (lights plus area-light samples) one render will shade with
MAX_LIGHT_SAMPLES = 1 << 20
#: the most bytes a chunk's tally of diagnosis passes holds (:meth:`Renderer.diagnosis_passes`): every light's
#: terms per sub-sample, so a scene of many lights takes fewer pixels per chunk
TALLY_BYTES = 8 << 20
#: what :meth:`Renderer.diagnosis_passes` hands each chunk's passes to: the chunk's first position, its passes
Fold = Callable[[int, dict[str, np.ndarray]], None]


class ImageTooLarge(ValueError):
    """The render asked for is beyond what phongray does: too many pixels, rays or light samples."""


T = TypeVar("T")
R = TypeVar("R")


class Renderer:
    """A scene prepared for tracing; :meth:`pixels` renders it.

    ``counts`` tallies the rays cast so far by kind: primary, shadow, secondary.
    """

    def __init__(self, scene: Scene, options: Options = REFERENCE):
        scene = options.read(scene)  # (the scene itself, but in a variant that misreads it)
        img = scene.image
        if img.width * img.height > MAX_PIXELS:
            raise ImageTooLarge(f"image: {img.width}×{img.height} pixels is more than phongray renders "
                                f"({MAX_PIXELS} pixels, 16384×16384)")
        if img.width * img.height * img.samples**2 > MAX_PRIMARY_RAYS:
            raise ImageTooLarge(f"image: {img.width}×{img.height} pixels × {img.samples}² sub-samples is more "
                                f"primary rays than phongray renders ({MAX_PRIMARY_RAYS})")
        lights = emitter_count(scene.lights)
        if lights > MAX_LIGHT_SAMPLES:
            raise ImageTooLarge(f"lights: {lights} light samples are more than phongray renders "
                                f"({MAX_LIGHT_SAMPLES})")
        self.scene = scene
        self._count = RayCount()
        self._stop = Stop(self._count)
        self.slice_rays = CHUNK_RAYS
        self.counts = self._count.counts
        #: how this render departs from the format (a variant, :mod:`tracer.variants`); the reference by default
        self.options = options
        self.max_depth = max(0, img.max_depth + options.depth_offset)
        #: the index in ``scene.lights`` of each emitter
        self.emitter_light = np.repeat(np.arange(len(scene.lights)),
                                       [LIGHT_TYPES[type(light)].count(light) for light in scene.lights])
        with np.errstate(all="ignore"):  # hostile magnitudes (1e300) overflow to inf here; the tracer copes
            self.world: World = build_world(scene, options)
            self.camera = CameraRays(scene.camera, scene.image, self.world.origin, options.half_pixel,
                                     options.vertical_fov)
            if options.left_handed:  # a variant's r = up × f (u kept): the image mirrored left to right
                self.camera.right = -self.camera.right
            self.intersector = Intersector(self.world, scene_sightlines(scene, self.world.origin, self.camera))
            groups = light_groups(scene, self.world.origin)
            #: where shadow and secondary rays start: off the surface in a variant of a student's offset
            self.spawn = options.spawn(scene)
            #: which proofs spare which rays (:mod:`tracer.planner`)
            self.plan = plan_proofs(self.world, options, self.spawn)
            self.shading = DirectLight(self.world, options, self.intersector, groups, self.plan, self._stop,
                                       self._count)
            self.shading.spawn = self.spawn
        self.intersector.check = self._stop
        self.intersector.tested = self._count.tested

    @property
    def spent(self) -> int:
        """What the budget counted of the last render (:class:`tracer.budget.RayCount`)."""
        return self._count.total

    @property
    def tests(self) -> int:
        """The exact tests of rays against spheres and triangles the last render made (its budget's ``tests``)."""
        return self._count.tests

    # -- whole image -------------------------------------------------------
    def pixels(self, threads: int | None = None, chunk_rays: int | None = None,
               progress: Progress | None = None, cancel: Callable[[], bool] | None = None,
               rows: tuple[int, int] | None = None, budget: Budget = UNLIMITED) -> np.ndarray:
        """The image as ``(H, W, 3) uint8``, or only its rows ``top..bottom`` with ``rows``.

        Every pixel is computed alone (its sums are exact integers), so a band of
        rows is byte for byte the same rows of the whole image.  ``cancel`` is
        polled before every chunk; once it returns True the remaining chunks are
        skipped and :class:`RenderCancelled` is raised.  A render that outgrows
        its ``budget`` stops with :class:`OverBudget`, polled where ``cancel`` is.
        """
        img = self.scene.image
        self._stop.start(cancel, budget)
        workers, chunk_rays = _chunking(threads, chunk_rays)
        self.slice_rays = chunk_rays
        top, bottom = rows if rows is not None else (0, img.height)
        if not 0 <= top <= bottom <= img.height:
            raise ValueError(f"rows {top}..{bottom} are not within 0..{img.height}")
        first, end = top * img.width, bottom * img.width
        total = end - first
        per_chunk = max(1, chunk_rays // (img.samples * img.samples))
        bounds = [(a, min(a + per_chunk, end)) for a in range(first, end, per_chunk)]
        out = np.empty((total, 3), dtype=np.uint8)
        self._count.plan(total * img.samples * img.samples)

        stopped = False

        def work(bound: tuple[int, int]) -> int:
            nonlocal stopped
            a, b = bound
            if stopped:
                return 0
            try:
                self._stop()
            except RenderCancelled:
                stopped = True
                return 0
            colour = self.chunk(a, b)
            out[a - first:b - first] = self.options.stored(quantize(colour if not self.options.gamma else
                                                                    np.clip(colour, 0.0, None) ** (1.0 / 2.2)))
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
        image = out.reshape(bottom - top, img.width, 3)
        return image[::-1] if self.options.flip_image else image

    def passes(self, names: list[str], light: int | None = None, threads: int | None = None,
               chunk_rays: int | None = None, cancel: Callable[[], bool] | None = None,
               budget: Budget = UNLIMITED) -> dict[str, np.ndarray]:
        """Render passes (:mod:`tracer.passes`) by name: ``(H, W, 3)`` float64 for the additive ones and the
        normal, ``(H, W)`` for shadow and depth, ``(H, W)`` int64 for object.  ``cancel`` is polled, and the
        ``budget`` held, as :meth:`pixels` polls and holds them."""
        check_passes(names, light, len(self.scene.lights))
        self._stop.start(cancel, budget)
        img = self.scene.image
        workers, chunk_rays = _chunking(threads, chunk_rays)
        self.slice_rays = chunk_rays
        total = img.width * img.height
        per_chunk = max(1, chunk_rays // (img.samples * img.samples))
        bounds = [(a, min(a + per_chunk, total)) for a in range(0, total, per_chunk)]
        self._count.plan(total * img.samples * img.samples)
        counted = int(np.count_nonzero(self.emitter_light == light)) if light is not None else len(self.emitter_light)

        whole: dict[str, np.ndarray] = {}
        made = threading.Lock()

        def work(bound: tuple[int, int]) -> None:
            a, b = bound
            if cancel is not None and cancel():
                raise RenderCancelled("render cancelled")
            s = img.samples * img.samples
            tally = Tally(tuple(names), (b - a) * s, s, light, self.emitter_light)
            self.chunk(a, b, tally)
            for name, part in tally.result((b - a, s), counted).items():  # each chunk into its place: no copies
                with made:
                    if name not in whole:
                        whole[name] = np.empty((total, *part.shape[1:]), dtype=part.dtype)
                whole[name][a:b] = part

        _mapped(work, bounds, workers)
        return {name: whole[name].reshape(img.height, img.width, *whole[name].shape[1:]) for name in names}

    def diagnosis_passes(self, threads: int | None = None, chunk_rays: int | None = None,
                         cancel: Callable[[], bool] | None = None, pixels: np.ndarray | None = None,
                         first_hits: bool = False, fold: Fold | None = None) -> dict[str, np.ndarray]:
        """In one render, what a diagnosis needs of the reference scene: the additive passes, ``object``, every
        light's ``diffuse:K`` and ``specular:K`` (and their sums), and ``colour``, the image's linear colour
        per pixel ``(H, W, 3)``, the very values :meth:`pixels` quantizes (the passes change no colour).

        With ``pixels`` (pixel numbers, row by row from the top left), of those pixels alone, each pass
        ``(len(pixels), …)``: the very values of the whole render's (every pixel is computed alone).  With
        ``first_hits``, only what the camera rays' first hits give (``object`` and the lights' terms), their
        very values, from camera rays alone: no mirror or refracted ray is traced.

        With ``fold``, each chunk's passes go to ``fold(first, passes)`` in order as they come (``first``: the
        position of the chunk's first pixel among those rendered), none is kept, and the answer is empty: memory
        stays a few chunks' whatever the image and the lights.  A chunk's tally holds at most
        :data:`TALLY_BYTES` (fewer pixels per chunk for many lights; the same values)."""
        img = self.scene.image
        workers, chunk_rays = _chunking(threads, chunk_rays)
        self.slice_rays = chunk_rays
        total = img.width * img.height
        s = img.samples * img.samples
        terms = len(ADDITIVE) + 2 + 2 * len(set(self.emitter_light.tolist()))  # planes of a chunk's tally
        per_chunk = max(1, min(chunk_rays // s, TALLY_BYTES // (terms * 3 * 8 * s)))
        if pixels is None:
            parts: list[tuple[int, int, np.ndarray | None]] = [(a, min(a + per_chunk, total), None)
                                                               for a in range(0, total, per_chunk)]
        else:
            picked = np.asarray(pixels, dtype=np.int64)
            parts = [(0, len(picked[a:a + per_chunk]), picked[a:a + per_chunk])
                     for a in range(0, len(picked), per_chunk)]
        names = ("object", *LIGHT_TERMS) if first_hits else (*ADDITIVE, "object")

        def work(part: tuple[int, int, np.ndarray | None]) -> dict[str, np.ndarray]:
            a, b, some = part
            if cancel is not None and cancel():
                raise RenderCancelled("render cancelled")
            tally = Tally(names, (b - a) * s, s, None, self.emitter_light, by_light=True)
            colour = self.chunk(a, b, tally, pixels=some, depth=0 if first_hits else None)
            if not first_hits:  # (with the camera rays alone, not the image's colour)
                tally.colour = colour
            return tally.result((b - a, s), len(self.emitter_light))

        if not parts:
            parts = [(0, 0, np.zeros(0, dtype=np.int64))]
        if fold is not None:
            firsts = np.cumsum([0] + [b - a for a, b, _ in parts])
            for group in range(0, len(parts), workers):  # a group of chunks at a time, folded in order
                for first, part in zip(firsts[group:], _mapped(work, parts[group:group + workers], workers)):
                    fold(int(first), part)
            return {}
        done = _mapped(work, parts, workers)
        out = {}
        for name in done[0]:
            whole = np.concatenate([p[name] for p in done])
            out[name] = whole if pixels is not None else whole.reshape(img.height, img.width, *whole.shape[1:])
        return out

    # -- one chunk ---------------------------------------------------------
    def pixels_of_rows(self, rows: np.ndarray, threads: int | None = None, chunk_rays: int | None = None,
                       cancel: Callable[[], bool] | None = None) -> np.ndarray:
        """The image's rows ``rows`` (row numbers, any order) as ``(len(rows), W, 3) uint8``, in one go: byte for
        byte those rows of :meth:`pixels` (every pixel is computed alone)."""
        img = self.scene.image
        self._stop.start(cancel, UNLIMITED)
        workers, chunk_rays = _chunking(threads, chunk_rays)
        self.slice_rays = chunk_rays
        shown = np.asarray(rows, dtype=np.int64)
        if self.options.flip_image:  # (stored bottom to top: row r of the image is row H − 1 − r of the render)
            shown = img.height - 1 - shown
        pixel = (shown[:, None] * img.width + np.arange(img.width)[None, :]).ravel()
        per_chunk = max(1, chunk_rays // (img.samples * img.samples))
        parts = [pixel[a:a + per_chunk] for a in range(0, len(pixel), per_chunk)]

        def work(part: np.ndarray) -> np.ndarray:
            self._stop()
            colour = self.chunk(0, len(part), pixels=part)
            return self.options.stored(quantize(colour if not self.options.gamma else
                                                np.clip(colour, 0.0, None) ** (1.0 / 2.2)))

        out = _mapped(work, parts, workers)
        return np.concatenate(out).reshape(len(shown), img.width, 3)

    def chunk(self, start: int, stop: int, tally: Tally | None = None, pixels: np.ndarray | None = None,
              depth: int | None = None) -> np.ndarray:
        """Linear colour of pixels ``start..stop`` (mean of their sub-samples), or of the pixels ``pixels`` (then
        ``stop − start`` of them). Shape (stop − start, 3).

        The ray tree is traced depth-first in slices of at most ``slice_rays``
        rays, so memory depends on the slice size and the depth, never on
        2^depth.  Every contribution is added as a fixed-point integer, so the
        sums, and the bytes of the image, do not depend on the order in which
        slices, chunks or threads deliver them.  With a ``tally``, the passes
        it asks for are added up too (each ray then carries the branch of the
        ray tree it belongs to).  With ``depth``, the tree stops there (0: the
        camera rays' hits alone), if not before.
        """
        img = self.scene.image
        s = img.samples * img.samples
        deepest = self.max_depth if depth is None else min(depth, self.max_depth)
        with np.errstate(all="ignore"):
            origins, dirs = self.camera.rays(start, stop) if pixels is None else self.camera.rays_of(pixels)
            n = len(origins)
            self._count("primary", n)
            acc = np.zeros((3, n), dtype=np.int64).T  # (n, 3), its columns contiguous (_accumulate)
            ceiling = float(2 * s)  # a sub-sample this bright saturates its pixel: sums are clamped there
            # the fixed-point unit leaves room for a slice's worth of contributions on top of a clamped sum (for
            # slices of up to CHUNK_RAYS, one unit whatever the slice: the same sums, and bytes, for every size)
            room = math.ceil(math.log2(max(self.slice_rays, CHUNK_RAYS)))
            fixed = 2.0 ** (48 - math.ceil(math.log2(ceiling)) - max(0, room - 14))
            background = np.asarray(img.background, dtype=np.float64)
            camera = Work(self.intersector.rays(origins, dirs), np.arange(n), np.ones(n), 0,
                          None if tally is None else np.zeros(n, dtype=np.int8))
            stack: list[Work] = [camera]
            holder = threading.get_ident()  # (one chunk at a time per thread)
            growth = Growth(n, deepest)
            while stack:
                work = stack.pop()
                if len(work) > self.slice_rays:  # split; the first slice goes on top, so it is traced first
                    stack += reversed(work.slices(self.slice_rays))
                    continue
                self._count.hold(holder, len(work) + sum(len(w) for w in stack))
                self._stop()
                growth.add(work.depth, len(work), 0)
                best = self.intersector.nearest(work.rays, self._camera_among(work.rays) if work.depth == 0 else
                                                self._mirror_among(work.rays))
                missed = best.key == NO_HIT
                once = work.depth == 0  # a primary ray is its sample's only ray of its depth; later, two may share
                _accumulate(acc, work.sample[missed], scaled(background, work.weight[missed]), ceiling, fixed, once)
                if tally is not None:
                    _tally_misses(tally, work, missed, background)
                rows = np.flatnonzero(~missed)
                if len(rows) == 0:
                    continue
                hit, done = self.intersector.describe(work.rays, best, rows), work.take(rows)  # (the hits alone)
                dd = done.rays.dirs
                mat = resolve_material(self.world, hit)
                normal = shading_normal(self.world, hit, dd, self.options.flip_normals)
                if tally is not None and work.depth == 0:
                    _tally_first_hits(tally, self.world, hit, done, normal)
                colour = self.shading.shade(hit, mat, normal, dd, tally, done)
                colour = self.options.blended(colour, self.world.materials.reflectance[mat])  # (a variant's)
                self._count.lit(len(rows) * len(self.emitter_light))
                _accumulate(acc, done.sample, scaled(colour, done.weight), ceiling, fixed, once)
                if work.depth >= deepest:
                    continue
                children = self.secondary(hit, mat, normal, done)
                self._count("secondary", len(children))
                growth.add(work.depth, 0, len(children))
                self._count.foresee(holder, growth.ahead())
                if len(children):
                    stack.append(children)
            self._count.hold(holder, 0)
            self._count.foresee(holder, 0.0)
            per_pixel = acc.reshape(stop - start, s, 3).sum(axis=1)  # integers: exact in any order
            return per_pixel.astype(np.float64) / (fixed * s)

    def _mirror_among(self, rays: Rays) -> Among | None:
        """The surfaces each mirror or refracted ray may meet (:func:`tracer.cones.on_lines`), when the scene has
        few enough and walks them (with no walk, every surface is tested against every ray already)."""
        return self.plan.mirror_pairs(rays, self.intersector.walker is not None)

    def _camera_among(self, rays: Rays) -> Among | None:
        """The surfaces each camera ray may meet (:mod:`tracer.cones`), when the scene has few enough: from the
        eye (every perspective ray starts there, exactly), or along the view (orthographic)."""
        return self.plan.camera_pairs(self.camera, rays)

    def secondary(self, hit: Hits, mat: np.ndarray, normal: np.ndarray, work: Work) -> Work:
        """Mirror and refracted rays of the hits whose material asks for them: the next depth's work."""
        m = self.world.materials
        kr, kt = m.reflectance[mat], m.transmittance[mat]
        dirs, weight = work.rays.dirs, work.weight
        r = np.flatnonzero(weight * kr > 0)  # a weight that underflowed to 0 would only add 0·∞ = NaN
        t = np.flatnonzero(weight * kt > 0)
        # secondary rays start at the exact hit point and leave its surface by identity
        out = np.concatenate([mirror(dirs[r], normal[r]),
                              refract(dirs[t], hit.normal[t], m.ior[mat[t]], self.options.ior_inverted,
                                      self.options.exit_normal_flipped)])
        both = np.concatenate([r, t])
        points = rows_of(hit.point, both)
        rays = Rays(points, out, hit.kind[both], hit.index[both], max_abs(points) + self.world.origin_mag)
        if self.spawn is not None:  # a student's offset: off the surface
            rays = self.spawn.leaving(rays, rows_of(hit.normal, both))
        branch = None
        if work.branch is not None:  # the passes follow each branch of the tree from the first hit on
            branch = work.branch[both] if work.depth > 0 else \
                np.concatenate([np.full(len(r), REFLECTED), np.full(len(t), REFRACTED)]).astype(np.int8)
        return Work(rays, work.sample[both], np.concatenate([weight[r] * kr[r], weight[t] * kt[t]]), work.depth + 1,
                    branch)


def _mapped(work: Callable[[T], R], parts: list[T], workers: int) -> list[R]:
    """``work`` of every part, in order: on a pool of up to ``workers`` threads, or here when one would do."""
    if workers <= 1 or len(parts) <= 1:
        return [work(part) for part in parts]
    with ThreadPoolExecutor(max_workers=min(workers, len(parts))) as pool:
        return list(pool.map(work, parts))


def _tally_misses(tally: Tally, work: Work, missed: np.ndarray, background: np.ndarray) -> None:
    """The background that rays ``missed`` of ``work`` bring back, to its pass."""
    rows = np.flatnonzero(missed)
    if len(rows) == 0:
        return
    if work.depth == 0:
        tally.add("background", work.sample[rows], work.weight[rows, None] * background)
        return
    assert work.branch is not None
    for branch, name in BRANCH_PASS.items():
        sel = rows[work.branch[rows] == branch]
        if name is not None:
            tally.add(name, work.sample[sel], work.weight[sel, None] * background)


def _tally_first_hits(tally: Tally, world: World, hit: Hits, work: Work, normal: np.ndarray) -> None:
    """The geometry of the first hits (camera rays), to the debugging passes."""
    if tally.normal is not None:
        tally.normal[work.sample] = normal
    if tally.depth is not None:
        tally.depth[work.sample] = hit.t
    if tally.object is not None:
        owners = {SPHERE: world.spheres.object, PLANE: world.planes.object, TRIANGLE: world.triangles.object}
        for kind, owner in owners.items():
            sel = np.flatnonzero(hit.kind == kind)
            tally.object[work.sample[sel]] = owner[hit.index[sel]]


def _accumulate(acc: np.ndarray, index: np.ndarray, values: np.ndarray, ceiling: float, fixed: float,
                fresh: bool = False) -> None:
    """``acc[index] += values`` in fixed point (units of ``1/fixed``); repeated indices are summed.

    Contributions are never negative, so a sum at or above ``ceiling`` (twice
    the sub-samples of a pixel) already saturates its pixel and is clamped
    there; NaN counts as nothing.  Integer sums are exact, so their order
    never shows in the image.  ``fresh`` says that no index repeats and that
    ``acc`` holds nothing yet at ``index`` (a camera ray's contribution, its
    sample's first), so the sum is the value itself, at most ``ceiling``: a
    plain scatter instead of ``np.add.at``.
    """
    if len(index):
        cap = np.int64(ceiling * fixed)
        for k in range(3):  # a column at a time: 1-D gathers and scatters
            # clipped into 0..ceiling, NaN to 0 (fmax drops a NaN, as nan_to_num and then clip would), in place
            v = np.fmax(values[:, k], 0.0)
            np.fmin(v, ceiling, out=v)
            v *= fixed
            units = np.rint(v, out=v).astype(np.int64)
            column = acc[:, k]
            if fresh:
                column[index] = units
            else:
                np.add.at(column, index, units)
                np.minimum(column, cap, out=column)


def render(scene: Scene, threads: int | None = None, chunk_rays: int | None = None,
           progress: Progress | None = None, cancel: Callable[[], bool] | None = None,
           budget: Budget = UNLIMITED) -> np.ndarray:
    """Render a validated scene to ``(H, W, 3) uint8`` pixels (:class:`OverBudget` past its ``budget``)."""
    return Renderer(scene).pixels(threads=threads, chunk_rays=chunk_rays, progress=progress, cancel=cancel,
                                  budget=budget)
