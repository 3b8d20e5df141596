"""A renderer: a scene prepared for tracing (:mod:`tracer.stages`), and every entry point over one driver.

The entry points (the image or a band of its rows, rows in any order, render
passes, a diagnosis's passes) each cut their pixels into chunks; the driver
runs the chunks on a thread pool (Embree and the large NumPy operations
release the GIL) and hands their results on in order.  Each chunk writes only
its own pixels, so the result does not depend on the thread count or the chunk
size, and a call's chunk and slice sizes are its own: one renderer may serve
calls on several threads at once, each with the bytes of a render alone.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from schemas import Scene

from .budget import UNLIMITED, Budget, Calls, OverBudget, RenderCancelled
from .chunks import CHUNK_RAYS, ONE_THREAD_CHUNK_RAYS, Pixels, Run, chunking, ordered, parts_of
from .film import stored
from .memory import tune_once
from .scene.variants import REFERENCE, Options
from .shade.passes import ADDITIVE, LIGHT_TERMS, Tally, check_passes
from .sizes import ImageTooLarge, check_size
from .stages import Stages

Progress = Callable[[int, int], None]

__all__ = [
    "CHUNK_RAYS",
    "ONE_THREAD_CHUNK_RAYS",
    "Budget",
    "ImageTooLarge",
    "OverBudget",
    "RenderCancelled",
    "Renderer",
    "render",
]


#: the most bytes a chunk's tally of diagnosis passes holds (:meth:`Renderer.diagnosis_passes`): every light's
#: terms per sub-sample, so a scene of many lights takes fewer pixels per chunk.  A diagnosis holds a few chunks
#: at once (a tally at work on each thread, the results waiting their turn, the one being folded): at 8 MiB those
#: came to 72–86 MiB for 96 lights at 160×120, as much as the lights' planes themselves; at 4 MiB, 58
TALLY_BYTES = 4 << 20
#: what :meth:`Renderer.diagnosis_passes` hands each chunk's passes to: the chunk's first position, its passes
Fold = Callable[[int, dict[str, np.ndarray]], None]

R = TypeVar("R")


@dataclass(frozen=True)
class Picture:
    """A render's stored pixels, and which of them the format leaves open: their ray tree met, at some depth, a
    tie between overlapping coplanar surfaces of two objects (:mod:`tracer.exact.ties`), which a grade does not count
    against a submission.  Found as the render goes, at no cost but in scenes with such surfaces."""

    pixels: np.ndarray  # (H, W, 3) uint8
    open: np.ndarray  # (H, W) bool


class Renderer:
    """A scene prepared for tracing; :meth:`pixels` renders it.

    ``counts`` tallies the rays cast so far by kind (primary, shadow, secondary), over every render.  One renderer
    may render on several threads at once: each call has its own chunks, slices and films, and its own count,
    ``cancel`` and budget (:class:`tracer.budget.Calls`), so its bytes, and when it stops, are those of a render
    alone; :attr:`spent` and :attr:`tests` are those of the call begun last.
    """

    def __init__(self, scene: Scene, options: Options = REFERENCE):
        scene = options.read(scene)  # (the scene itself, but in a variant that misreads it)
        check_size(scene)
        tune_once()  # (the first render of a process tunes its allocator, unless the process did)
        self.scene = scene
        #: the render calls under way, each with its own count and stop (one renderer may serve several at once)
        self._calls = Calls()
        self.counts = self._calls.counts
        #: how this render departs from the format (a variant, :mod:`tracer.scene.variants`); the reference by default
        self.options = options
        #: the scene's stages, in the order they are built and run (:mod:`tracer.stages`)
        self.stages = Stages(scene, options, self._calls)
        self.max_depth, self.emitter_light = self.stages.max_depth, self.stages.emitter_light
        self.world, self.camera, self.intersector = self.stages.world, self.stages.camera, self.stages.intersector
        self.spawner, self.plan, self.shadows = self.stages.spawner, self.stages.plan, self.stages.shadows
        self.shading = self.stages.shading

    def visible_size(self) -> float:
        """The size of what the camera sees (:func:`tracer.exact.visible.visible_size`): what an offset is measured
        against."""
        return self.stages.visible_size()

    @property
    def spent(self) -> int:
        """What the budget counted of the last render (:class:`tracer.budget.RayCount`)."""
        return self._calls.last.count.total

    @property
    def tests(self) -> int:
        """The exact tests of rays against spheres and triangles the last render made (its budget's ``tests``)."""
        return self._calls.last.count.tests

    # -- the entry points: each a list of chunks for the driver (_begin, _drive) -----------------------------
    def pixels(
        self,
        threads: int | None = None,
        chunk_rays: int | None = None,
        progress: Progress | None = None,
        cancel: Callable[[], bool] | None = None,
        rows: tuple[int, int] | None = None,
        budget: Budget = UNLIMITED,
    ) -> np.ndarray:
        """The image as ``(H, W, 3) uint8``, or only its rows ``top..bottom`` with ``rows``.

        Every pixel is computed alone (its sums are exact integers), so a band of
        rows is byte for byte the same rows of the whole image.  ``cancel`` is
        polled before every chunk and between slices of rays; once it returns True
        :class:`RenderCancelled` is raised.  A render that outgrows its ``budget``
        stops with :class:`OverBudget`, polled where ``cancel`` is.
        """
        return self._picture(threads, chunk_rays, progress, cancel, rows, budget, False).pixels

    def picture(
        self,
        threads: int | None = None,
        chunk_rays: int | None = None,
        progress: Progress | None = None,
        cancel: Callable[[], bool] | None = None,
        rows: tuple[int, int] | None = None,
        budget: Budget = UNLIMITED,
    ) -> Picture:
        """:meth:`pixels`, with the pixels the format leaves open (:class:`Picture`) found in the same render."""
        return self._picture(threads, chunk_rays, progress, cancel, rows, budget, True)

    def _picture(
        self,
        threads: int | None,
        chunk_rays: int | None,
        progress: Progress | None,
        cancel: Callable[[], bool] | None,
        rows: tuple[int, int] | None,
        budget: Budget,
        with_open: bool,
    ) -> Picture:
        img = self.scene.image
        top, bottom = rows if rows is not None else (0, img.height)
        if not 0 <= top <= bottom <= img.height:
            raise ValueError(f"rows {top}..{bottom} are not within 0..{img.height}")
        run = self._begin(threads, chunk_rays, cancel, budget)
        pixel = range(top * img.width, bottom * img.width)
        run.call.count.plan(len(pixel) * img.samples * img.samples)
        out = np.empty((len(pixel), 3), dtype=np.uint8)
        opened = np.zeros(len(pixel) if with_open else 0, dtype=bool)
        done = 0

        def each(first: int, part: tuple[np.ndarray, np.ndarray]) -> None:
            nonlocal done
            out[first : first + len(part[0])] = part[0]
            if with_open:
                opened[first : first + len(part[0])] = part[1]
            done += len(part[0])
            if progress:
                progress(done, len(pixel))

        self._drive(parts_of(pixel, run.per_chunk), lambda part: self._stored(part, run.slice_rays), run, each)
        image = out.reshape(bottom - top, img.width, 3)
        mask = opened.reshape(bottom - top, img.width if with_open else 0)
        return Picture(image[::-1], mask[::-1]) if self.options.flip_image else Picture(image, mask)

    def pixels_of_rows(
        self,
        rows: np.ndarray,
        threads: int | None = None,
        chunk_rays: int | None = None,
        cancel: Callable[[], bool] | None = None,
    ) -> np.ndarray:
        """The image's rows ``rows`` (row numbers, any order) as ``(len(rows), W, 3) uint8``, in one go: byte for
        byte those rows of :meth:`pixels` (every pixel is computed alone)."""
        width = self.scene.image.width
        shown = np.asarray(rows, dtype=np.int64)
        pixel = (shown[:, None] * width + np.arange(width)[None, :]).ravel()
        return self.pixels_at(pixel, threads, chunk_rays, cancel).reshape(len(shown), width, 3)

    def pixels_at(
        self,
        pixels: np.ndarray,
        threads: int | None = None,
        chunk_rays: int | None = None,
        cancel: Callable[[], bool] | None = None,
    ) -> np.ndarray:
        """The image's pixels ``pixels`` (pixel numbers, row by row from the top left, any order) as
        ``(len(pixels), 3) uint8``, in one go: byte for byte those pixels of :meth:`pixels` (every pixel is
        computed alone, its sub-samples' sums exact integers on its own film), at the price of those pixels
        alone."""
        img = self.scene.image
        run = self._begin(threads, chunk_rays, cancel, UNLIMITED)
        pixel = np.asarray(pixels, dtype=np.int64)
        if self.options.flip_image:  # (stored bottom to top: row r of the image is row H − 1 − r of the render)
            shown, column = np.divmod(pixel, img.width)
            pixel = (img.height - 1 - shown) * img.width + column
        if not len(pixel):
            return np.empty((0, 3), dtype=np.uint8)
        out = self._drive(parts_of(pixel, run.per_chunk), lambda part: self._stored(part, run.slice_rays), run)
        return np.concatenate([part for part, _ in out])

    def passes(
        self,
        names: list[str],
        light: int | None = None,
        threads: int | None = None,
        chunk_rays: int | None = None,
        cancel: Callable[[], bool] | None = None,
        budget: Budget = UNLIMITED,
    ) -> dict[str, np.ndarray]:
        """Render passes (:mod:`tracer.shade.passes`) by name: ``(H, W, 3)`` float64 for the additive ones and the
        normal, ``(H, W)`` for shadow and depth, ``(H, W)`` int64 for object.  ``cancel`` is polled, and the
        ``budget`` held, as :meth:`pixels` polls and holds them."""
        check_passes(names, light, len(self.scene.lights))
        img = self.scene.image
        run = self._begin(threads, chunk_rays, cancel, budget)
        total = img.width * img.height
        run.call.count.plan(total * img.samples * img.samples)
        counted = int(np.count_nonzero(self.emitter_light == light)) if light is not None else len(self.emitter_light)
        s = img.samples * img.samples
        whole: dict[str, np.ndarray] = {}

        def work(part: Pixels) -> dict[str, np.ndarray]:
            tally = Tally(tuple(names), len(part) * s, s, light, self.emitter_light)
            self.chunk(0, len(part), tally, pixels=part, slice_rays=run.slice_rays)
            return tally.result((len(part), s), counted)

        def each(first: int, result: dict[str, np.ndarray]) -> None:  # each chunk into its place: no copies
            for name, part in result.items():
                if name not in whole:
                    whole[name] = np.empty((total, *part.shape[1:]), dtype=part.dtype)
                whole[name][first : first + len(part)] = part

        self._drive(parts_of(range(total), run.per_chunk), work, run, each)
        return {name: whole[name].reshape(img.height, img.width, *whole[name].shape[1:]) for name in names}

    def diagnosis_passes(
        self,
        threads: int | None = None,
        chunk_rays: int | None = None,
        cancel: Callable[[], bool] | None = None,
        pixels: np.ndarray | None = None,
        first_hits: bool = False,
        fold: Fold | None = None,
    ) -> dict[str, np.ndarray]:
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
            colour = self.chunk(0, len(part), tally, part, 0 if first_hits else None, run.slice_rays)
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
    def _begin(
        self, threads: int | None, chunk_rays: int | None, cancel: Callable[[], bool] | None, budget: Budget
    ) -> Run:
        """A render call begins: its own stop polls ``cancel`` and holds ``budget`` from here
        (:class:`tracer.budget.Stop`: the one way every entry point is cancelled), on the threads and chunks asked
        for."""
        call = self._calls.begin(cancel, budget)
        workers, rays = chunking(threads, chunk_rays)
        return Run(workers, max(1, rays // (self.scene.image.samples**2)), rays, call)

    def _stored(self, part: Pixels, slice_rays: int) -> tuple[np.ndarray, np.ndarray]:
        """The stored bytes of the pixels ``part`` (len(part), 3) uint8, and which are open (len(part),) bool."""
        film = self.stages.film(0, len(part), pixels=part, slice_rays=slice_rays)
        return stored(film.colour(), self.options), film.open_pixels()

    def _drive(
        self, parts: list[Pixels], work: Callable[[Pixels], R], run: Run, each: Callable[[int, R], None] | None = None
    ) -> list[R]:
        """``work`` of every chunk of pixels, on up to ``run.workers`` threads, at most that many chunks ahead of
        the one handed on; each result goes to ``each(first, result)`` in order (``first``: the position of the
        chunk's first pixel), or, without ``each``, all are returned in order.  Every chunk works for the call of
        ``run`` (its thread's polls and counts go to it) and polls its stop first, which raises
        :class:`RenderCancelled` or :class:`OverBudget`, and the render ends there."""

        def polled(part: Pixels) -> R:
            with self._calls.working(run.call):
                run.call.stop()
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
    def chunk(
        self,
        start: int,
        stop: int,
        tally: Tally | None = None,
        pixels: Pixels | None = None,
        depth: int | None = None,
        slice_rays: int = CHUNK_RAYS,
    ) -> np.ndarray:
        """Linear colour of pixels ``start..stop`` (mean of their sub-samples), or of the pixels ``pixels`` (then
        ``stop − start`` of them). Shape (stop − start, 3): the colour of :meth:`tracer.stages.Stages.film`'s
        film, which says how the ray tree is traced and why the bytes do not depend on the order of the work.
        """
        return self.stages.film(start, stop, tally, pixels, depth, slice_rays).colour()


def render(
    scene: Scene,
    threads: int | None = None,
    chunk_rays: int | None = None,
    progress: Progress | None = None,
    cancel: Callable[[], bool] | None = None,
    budget: Budget = UNLIMITED,
) -> np.ndarray:
    """Render a validated scene to ``(H, W, 3) uint8`` pixels (:class:`OverBudget` past its ``budget``)."""
    return Renderer(scene).pixels(
        threads=threads, chunk_rays=chunk_rays, progress=progress, cancel=cancel, budget=budget
    )
