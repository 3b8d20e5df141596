"""The one place that knows the order of the stages.

For each chunk of pixels, per depth: intersect → misses take the background →
direct light (ambient, then one shadow batch per light or area-light sample)
→ spawn mirror and refracted rays.  Chunks run on a thread pool: Embree and
the large NumPy operations release the GIL, and each chunk writes only its own
pixels, so the result does not depend on the thread count or the chunk size.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TypeVar

import numpy as np

from schemas import Scene

from .area import area_terms
from .best import NO_HIT
from .budget import UNLIMITED, Budget, Growth, OverBudget, RayCount, RenderCancelled, Stop
from .camera import CameraRays
from .chunks import CHUNK_RAYS, ONE_THREAD_CHUNK_RAYS, Pixels, Run, chunking, ordered, parts_of, pixel_numbers
from .direct import DirectLight, Meter
from .film import Film, stored
from .intersect import PLANE, SPHERE, TRIANGLE, Intersector
from .lights import LIGHT_TYPES, emitter_count, light_groups
from .passes import ADDITIVE, LIGHT_TERMS, UNOBSERVED, PassObserver, Tally, check_passes
from .planner import plan_proofs, scene_sightlines
from .rays import Among, Rays, Work
from .shading import resolve_material, shading_normal
from .spawn import Spawner
from .variants import REFERENCE, Options, scene_size
from .vec import scaled
from .visible import visible_size
from .world import World, build_world

Progress = Callable[[int, int], None]

__all__ = ["CHUNK_RAYS", "ONE_THREAD_CHUNK_RAYS", "Budget", "ImageTooLarge", "OverBudget", "RenderCancelled",
           "Renderer", "render"]


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


R = TypeVar("R")


def _check_size(scene: Scene) -> None:
    """Raises :class:`ImageTooLarge` for a render beyond what phongray does."""
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


class Renderer:
    """A scene prepared for tracing; :meth:`pixels` renders it.

    ``counts`` tallies the rays cast so far by kind: primary, shadow, secondary.
    """

    def __init__(self, scene: Scene, options: Options = REFERENCE):
        scene = options.read(scene)  # (the scene itself, but in a variant that misreads it)
        _check_size(scene)
        img = scene.image
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
            self.shading = self._direct_light()
        #: the index in ``scene.objects`` of each surface, by kind (the passes' ``object``)
        self._owners = {SPHERE: self.world.spheres.object, PLANE: self.world.planes.object,
                        TRIANGLE: self.world.triangles.object}
        self.intersector.check = self._stop
        self.intersector.tested = self._count.tested

    def _direct_light(self) -> DirectLight:
        """The direct-light stage, with the proofs that spare shadow rays (:mod:`tracer.planner`)."""
        world, options = self.world, self.options
        #: where shadow and secondary rays are born: off the surface in a variant of a student's offset
        self.spawner = Spawner(world, options, options.spawn(self.visible_size))
        #: which proofs spare which rays (:mod:`tracer.planner`)
        self.plan = plan_proofs(world, options, self.spawner.offset)
        shading = DirectLight(world, options, self.intersector, light_groups(self.scene, world.origin), self.plan,
                              Meter(self._stop, self._count), area_terms)
        shading.spawner = self.spawner
        return shading

    def visible_size(self) -> float:
        """The size of what the camera sees (:func:`tracer.visible.visible_size`): what an offset is measured
        against."""
        return visible_size(self.scene, self.world, self.intersector, scene_size(self.scene))

    @property
    def spent(self) -> int:
        """What the budget counted of the last render (:class:`tracer.budget.RayCount`)."""
        return self._count.total

    @property
    def tests(self) -> int:
        """The exact tests of rays against spheres and triangles the last render made (its budget's ``tests``)."""
        return self._count.tests

    # -- the entry points: each a list of chunks for the driver (_begin, _drive) -----------------------------
    def pixels(self, threads: int | None = None, chunk_rays: int | None = None,
               progress: Progress | None = None, cancel: Callable[[], bool] | None = None,
               rows: tuple[int, int] | None = None, budget: Budget = UNLIMITED) -> np.ndarray:
        """The image as ``(H, W, 3) uint8``, or only its rows ``top..bottom`` with ``rows``.

        Every pixel is computed alone (its sums are exact integers), so a band of
        rows is byte for byte the same rows of the whole image.  ``cancel`` is
        polled before every chunk and between slices of rays; once it returns True
        :class:`RenderCancelled` is raised.  A render that outgrows its ``budget``
        stops with :class:`OverBudget`, polled where ``cancel`` is.
        """
        img = self.scene.image
        top, bottom = rows if rows is not None else (0, img.height)
        if not 0 <= top <= bottom <= img.height:
            raise ValueError(f"rows {top}..{bottom} are not within 0..{img.height}")
        run = self._begin(threads, chunk_rays, cancel, budget)
        pixel = range(top * img.width, bottom * img.width)
        self._count.plan(len(pixel) * img.samples * img.samples)
        out = np.empty((len(pixel), 3), dtype=np.uint8)
        done = 0

        def each(first: int, part: np.ndarray) -> None:
            nonlocal done
            out[first:first + len(part)] = part
            done += len(part)
            if progress:
                progress(done, len(pixel))

        self._drive(parts_of(pixel, run.per_chunk), self._stored, run, each)
        image = out.reshape(bottom - top, img.width, 3)
        return image[::-1] if self.options.flip_image else image

    def pixels_of_rows(self, rows: np.ndarray, threads: int | None = None, chunk_rays: int | None = None,
                       cancel: Callable[[], bool] | None = None) -> np.ndarray:
        """The image's rows ``rows`` (row numbers, any order) as ``(len(rows), W, 3) uint8``, in one go: byte for
        byte those rows of :meth:`pixels` (every pixel is computed alone)."""
        img = self.scene.image
        run = self._begin(threads, chunk_rays, cancel, UNLIMITED)
        shown = np.asarray(rows, dtype=np.int64)
        if self.options.flip_image:  # (stored bottom to top: row r of the image is row H − 1 − r of the render)
            shown = img.height - 1 - shown
        pixel = (shown[:, None] * img.width + np.arange(img.width)[None, :]).ravel()
        out = self._drive(parts_of(pixel, run.per_chunk), self._stored, run)
        return np.concatenate(out).reshape(len(shown), img.width, 3)

    def passes(self, names: list[str], light: int | None = None, threads: int | None = None,
               chunk_rays: int | None = None, cancel: Callable[[], bool] | None = None,
               budget: Budget = UNLIMITED) -> dict[str, np.ndarray]:
        """Render passes (:mod:`tracer.passes`) by name: ``(H, W, 3)`` float64 for the additive ones and the
        normal, ``(H, W)`` for shadow and depth, ``(H, W)`` int64 for object.  ``cancel`` is polled, and the
        ``budget`` held, as :meth:`pixels` polls and holds them."""
        check_passes(names, light, len(self.scene.lights))
        img = self.scene.image
        run = self._begin(threads, chunk_rays, cancel, budget)
        total = img.width * img.height
        self._count.plan(total * img.samples * img.samples)
        counted = int(np.count_nonzero(self.emitter_light == light)) if light is not None else len(self.emitter_light)
        s = img.samples * img.samples
        whole: dict[str, np.ndarray] = {}

        def work(part: Pixels) -> dict[str, np.ndarray]:
            tally = Tally(tuple(names), len(part) * s, s, light, self.emitter_light)
            self.chunk(0, len(part), tally, pixels=part)
            return tally.result((len(part), s), counted)

        def each(first: int, result: dict[str, np.ndarray]) -> None:  # each chunk into its place: no copies
            for name, part in result.items():
                if name not in whole:
                    whole[name] = np.empty((total, *part.shape[1:]), dtype=part.dtype)
                whole[name][first:first + len(part)] = part

        self._drive(parts_of(range(total), run.per_chunk), work, run, each)
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
        run = self._begin(threads, chunk_rays, cancel, UNLIMITED)
        s = img.samples * img.samples
        terms = len(ADDITIVE) + 2 + 2 * len(set(self.emitter_light.tolist()))  # planes of a chunk's tally
        per_chunk = max(1, min(run.per_chunk, TALLY_BYTES // (terms * 3 * 8 * s)))
        picked: Pixels = range(img.width * img.height) if pixels is None else np.asarray(pixels, dtype=np.int64)
        names = ("object", *LIGHT_TERMS) if first_hits else (*ADDITIVE, "object")

        def work(part: Pixels) -> dict[str, np.ndarray]:
            tally = Tally(names, len(part) * s, s, None, self.emitter_light, by_light=True)
            colour = self.chunk(0, len(part), tally, pixels=part, depth=0 if first_hits else None)
            if not first_hits:  # (with the camera rays alone, not the image's colour)
                tally.colour = colour
            return tally.result((len(part), s), len(self.emitter_light))

        parts = parts_of(picked, per_chunk) or [picked]
        if fold is not None:
            self._drive(parts, work, run, fold)
            return {}
        done = self._drive(parts, work, run)
        out = {}
        for name in done[0]:
            whole = np.concatenate([p[name] for p in done])
            out[name] = whole if pixels is not None else whole.reshape(img.height, img.width, *whole.shape[1:])
        return out

    # -- the driver: one for every entry point ----------------------------------------------------------------
    def _begin(self, threads: int | None, chunk_rays: int | None, cancel: Callable[[], bool] | None,
               budget: Budget) -> Run:
        """A render begins: its stop polls ``cancel`` and holds ``budget`` from here (:class:`tracer.budget.Stop`:
        the one way every entry point is cancelled), on the threads and chunks asked for."""
        self._stop.start(cancel, budget)
        workers, rays = chunking(threads, chunk_rays)
        self.slice_rays = rays
        return Run(workers, max(1, rays // (self.scene.image.samples ** 2)))

    def _stored(self, part: Pixels) -> np.ndarray:
        """The stored bytes of the pixels ``part``. Shape (len(part), 3), uint8."""
        return stored(self.chunk(0, len(part), pixels=part), self.options)

    def _drive(self, parts: list[Pixels], work: Callable[[Pixels], R], run: Run,
               each: Callable[[int, R], None] | None = None) -> list[R]:
        """``work`` of every chunk of pixels, on up to ``run.workers`` threads, at most that many chunks ahead of
        the one handed on; each result goes to ``each(first, result)`` in order (``first``: the position of the
        chunk's first pixel), or, without ``each``, all are returned in order.  Every chunk polls the render's
        stop first, which raises :class:`RenderCancelled` or :class:`OverBudget`, and the render ends there."""

        def polled(part: Pixels) -> R:
            self._stop()
            return work(part)

        firsts = np.cumsum([0] + [len(p) for p in parts]).tolist()
        kept: list[R] = []
        for k, result in enumerate(ordered(polled, parts, run.workers)):
            if each is None:
                kept.append(result)
            else:
                each(firsts[k], result)
        return kept

    # -- one chunk: the stage order ----------------------------------------------------------------------------
    def chunk(self, start: int, stop: int, tally: Tally | None = None, pixels: Pixels | None = None,
              depth: int | None = None) -> np.ndarray:
        """Linear colour of pixels ``start..stop`` (mean of their sub-samples), or of the pixels ``pixels`` (then
        ``stop − start`` of them). Shape (stop − start, 3).

        The ray tree is traced depth-first in slices of at most ``slice_rays``
        rays, so memory depends on the slice size and the depth, never on
        2^depth.  Every contribution goes to the chunk's :class:`tracer.film.Film`
        as a fixed-point integer, so the sums, and the bytes of the image, do not
        depend on the order in which slices, chunks or threads deliver them.  With
        a ``tally``, the passes it asks for are added up too (each ray then carries
        the branch of the ray tree it belongs to).  With ``depth``, the tree stops
        there (0: the camera rays' hits alone), if not before.
        """
        s = self.scene.image.samples ** 2
        deepest = self.max_depth if depth is None else min(depth, self.max_depth)
        with np.errstate(all="ignore"):
            origins, dirs = self.camera.rays(start, stop) if pixels is None else \
                self.camera.rays_of(pixel_numbers(pixels))
            n = len(origins)
            self._count("primary", n)
            film = Film(stop - start, s, self.slice_rays, not self.options.clamp_colour)
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
                children = self._trace(work, film, tally, deepest)
                if children is None:
                    continue
                self._count("secondary", len(children))
                growth.add(work.depth, 0, len(children))
                self._count.foresee(holder, growth.ahead())
                if len(children):
                    stack.append(children)
            self._count.hold(holder, 0)
            self._count.foresee(holder, 0.0)
            return film.colour()

    def _trace(self, work: Work, film: Film, tally: Tally | None, deepest: int) -> Work | None:
        """One slice of one depth, stage by stage: intersect → misses take the background → direct light → the
        next depth's mirror and refracted rays, returned (None: no hit, or the deepest depth)."""
        background = np.asarray(self.scene.image.background, dtype=np.float64)
        best = self.intersector.nearest(work.rays, self._camera_among(work.rays) if work.depth == 0 else
                                        self._mirror_among(work.rays))
        missed = best.key == NO_HIT
        once = work.depth == 0  # a primary ray is its sample's only ray of its depth; later, two may share
        film.add(work.sample[missed], scaled(background, work.weight[missed]), once)
        (UNOBSERVED if tally is None else PassObserver(tally, work)).missed(missed, background)
        rows = np.flatnonzero(~missed)
        if len(rows) == 0:
            return None
        hit, done = self.intersector.describe(work.rays, best, rows), work.take(rows)  # (the hits alone)
        dd = done.rays.dirs
        mat = resolve_material(self.world, hit)
        normal = shading_normal(self.world, hit, dd, self.options.flip_normals)
        observer = UNOBSERVED if tally is None else PassObserver(tally, done)
        if work.depth == 0:
            observer.first_hits(hit, self._owners, normal)
        colour = self.shading.shade(hit, mat, normal, dd, observer)
        colour = self.options.blended(colour, self.world.materials.reflectance[mat])  # (a variant's)
        self._count.lit(len(rows) * len(self.emitter_light))
        film.add(done.sample, scaled(colour, done.weight), once)
        if work.depth >= deepest:
            return None
        return self.spawner.bounce(hit, mat, normal, done)

    def _mirror_among(self, rays: Rays) -> Among | None:
        """The surfaces each mirror or refracted ray may meet (:func:`tracer.cones.on_lines`), when the scene has
        few enough and walks them (with no walk, every surface is tested against every ray already)."""
        return self.plan.mirror_pairs(rays, self.intersector.walker is not None)

    def _camera_among(self, rays: Rays) -> Among | None:
        """The surfaces each camera ray may meet (:mod:`tracer.cones`), when the scene has few enough: from the
        eye (every perspective ray starts there, exactly), or along the view (orthographic)."""
        return self.plan.camera_pairs(self.camera, rays)


def render(scene: Scene, threads: int | None = None, chunk_rays: int | None = None,
           progress: Progress | None = None, cancel: Callable[[], bool] | None = None,
           budget: Budget = UNLIMITED) -> np.ndarray:
    """Render a validated scene to ``(H, W, 3) uint8`` pixels (:class:`OverBudget` past its ``budget``)."""
    return Renderer(scene).pixels(threads=threads, chunk_rays=chunk_rays, progress=progress, cancel=cancel,
                                  budget=budget)
