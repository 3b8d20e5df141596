"""From request bytes to a validated scene, and from a scene to PNG bytes, with the
cache, the render slots and cancellation.  No HTTP here: the routes translate the
exceptions into status codes."""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from typing import Any

import anyio
import numpy as np

from schemas import Scene, load_scene, parse_json, validate_scene
from service.admission.limits import LimitError, budget, check_body, check_raw, check_scene, outgrown
from service.diagnosis import Cached, unavailable
from service.render import passes
from service.render.cluster import ClusterError, client, run, workers
from service.render.passes import Format, PassFile
from service.render.rendering import render_pixels
from service.render.scenekey import scene_key
from service.settings import Settings
from service.work.cache import RenderCache
from service.work.pipeline import Checking, Checks, Graded, explain, with_overrides
from service.work.slots import Busy, Slots
from tracer import OverBudget, RenderCancelled, encode_png
from tracer.memory import release_if_grown, resident, tune_allocator


class TooSlow(Exception):
    """The render ran past the time limit."""


class OutOfMemory(Busy):
    """The work ran out of memory as it ran (the worker's other work held it): stopped, its memory let go, and
    answered as a busy slot is, to be tried again."""


class ClusterDown(Exception):
    """The Dask cluster the renders go to cannot be reached."""


class AnswersFull(Busy):
    """The image answers this worker holds (renders, passes, heat-maps) leave no room for another now
    (``max_answer_bytes``)."""


class Answers:
    """The bytes of the answers one worker holds at once (made, or being sent), at most ``total``: each takes
    its price before it is made, and gives it back once sent, or dropped with its client."""

    def __init__(self, total: int):
        self.total = total
        self.held = 0
        self._lock = threading.Lock()

    def take(self, size: int) -> bool:
        with self._lock:
            if self.held + size > self.total:
                return False
            self.held += size
            return True

    def give(self, size: int) -> None:
        with self._lock:
            self.held -= size

    def hold(self, size: int, what: str) -> int:
        """Take ``size`` bytes for an answer (``what`` it is, in words): LimitError when it could never fit in
        ``total``, AnswersFull when it does not now; the bytes taken, to give back once it is sent."""
        if size > self.total:
            raise LimitError(f"{what} holds about {size} bytes, more than the limit max_answer_bytes = {self.total}")
        if not self.take(size):
            raise AnswersFull()
        return size


@dataclass(frozen=True)
class Job:
    scene: Scene
    key: str  # sha256 of the canonical scene

    @property
    def etag(self) -> str:
        return f'"{self.key}"'


def parse_counted(body: bytes | str, settings: Settings) -> Any:
    """Parse a body whose size in objects and arrays is within the limits. Raises SceneError or LimitError."""
    check_body(body, settings)
    data = parse_json(body)
    check_raw(data, settings)
    return data


def prepare(body: bytes | str, overrides: dict[str, int | None], settings: Settings) -> Job:
    """Parse, apply image overrides, validate and check limits. Raises SceneError or LimitError."""
    scene = with_overrides(validate_scene(parse_counted(body, settings)), overrides)
    check_scene(scene, settings)
    return Job(scene, scene_key(scene))


class RenderService:
    def __init__(self, settings: Settings):
        tune_allocator(arenas=1)  # before any pool thread starts, so that release_if_grown hands back all it can
        self.settings = settings
        # one budget of cache_bytes for every cached array of the worker: answers and the diagnosis's renders
        self.diagnoses = Cached(room=lambda: settings.cache_bytes - self.cache.size)
        self.cache = RenderCache(settings.cache_bytes, others=lambda: self.diagnoses.size)
        self.answers = Answers(settings.max_answer_bytes)
        self.slots = Slots(settings.max_concurrent_renders, settings.queue_wait)
        self.threads = settings.render_threads or os.cpu_count() or 1
        self.grading = anyio.CapacityLimiter(settings.max_concurrent_renders)  # decoding and comparing images
        # parsing and validating: a thread per core at most, so that a burst of requests never has dozens of
        # threads queueing for the interpreter in front of the event loop (the others wait without a thread)
        self.parsing = anyio.CapacityLimiter(os.cpu_count() or 1)
        self.renders = 0
        self._dask: Any = None
        self._client_lock = threading.Lock()

    @contextlib.contextmanager
    def _slot(self, cancelled: Callable[[], bool] = lambda: False) -> Iterator[Callable[[], bool]]:
        """One of this worker's render slots, in turn (:class:`service.work.slots.Slots`: Busy when none came
        within ``queue_wait``, RenderCancelled once ``cancelled()`` while waiting) for at most
        ``render_timeout``: yields the deadline's test, and hands what the work freed back to the OS afterwards."""
        taken = self.slots.take(cancelled)
        before = resident()
        deadline = time.monotonic() + self.settings.render_timeout
        try:
            yield lambda: time.monotonic() > deadline
        finally:
            self.slots.give(taken)
            release_if_grown(before)  # a large render gives what it freed back to the OS: memory returns to baseline

    def png(self, job: Job, cancelled: Callable[[], bool] = lambda: False) -> bytes:
        """The PNG of a job, from the cache or rendered. Raises Busy, TooSlow, RenderCancelled, or LimitError when
        the render outgrows its budget (:func:`service.admission.limits.budget`).

        Concurrent requests for one scene are joined before they get here (one flight per scene in
        :mod:`service.http.waiting`), so each scene is rendered once."""
        cached = self.cache.get(job.key)
        if cached is not None:
            return cached
        with self._slot(cancelled) as late:
            client = self._client() if self.settings.cluster else None
            try:
                pixels = render_pixels(
                    job.scene,
                    client,
                    threads=self.threads,
                    cancel=lambda: cancelled() or late(),
                    budget=budget(job.scene, self.settings),
                )
            except RenderCancelled:
                if late():
                    raise TooSlow() from None
                raise
            except OverBudget as exc:
                raise outgrown(exc, self.settings) from None
            data = encode_png(pixels)
            del pixels  # before the slot's release, so that its pages go back too
            self.renders += 1
        self.cache.put(job.key, data)
        return data

    def pass_file(
        self, job: Job, name: str, light: int | None, fmt: Format, gone: Callable[[], bool] = lambda: False
    ) -> tuple[PassFile, int]:
        """Render pass ``name`` of a job (of light ``light``) as a PNG or ``.npy`` file (:mod:`service.render.passes`),
        from the cache, or rendered in a render slot within ``render_timeout`` (on the cluster when there is
        one), and the bytes of :attr:`answers` it holds: the caller gives them back once it is sent.  Priced up
        front (:func:`service.render.passes.price`): LimitError when it could never fit in ``max_answer_bytes``,
        AnswersFull when it does not now.  Raises Busy, TooSlow, ClusterDown, RenderCancelled once ``gone()``
        (its client left), LimitError when it outgrows its render budget (:func:`service.admission.limits.budget`), or
        ValueError for a light the scene does not have."""
        media = "application/x-npy" if fmt == "npy" else "image/png"
        key = f"{job.key}/pass={name}/light={light}.{fmt}"
        what = f"pass: {name} of {job.scene.image.width}×{job.scene.image.height} pixels as {fmt}"
        cached = self.cache.get(key)
        if cached is not None:  # (held as long as it is sent: the cache may let it go meanwhile)
            return passes.PassFile(b"", cached, media), self.answers.hold(len(cached), what)
        held = self.answers.hold(passes.price(job.scene, name, fmt), what)
        try:
            with self._slot(gone) as late:
                stop = lambda: late() or gone()  # noqa: E731
                try:
                    if self.settings.cluster:
                        data = run(
                            self._client(),
                            passes.pass_task,
                            job.scene.model_dump_json().encode(),
                            name,
                            light,
                            fmt,
                            self.settings.render_timeout,
                            cancelled=stop,
                        )
                        made = passes.PassFile(b"", data, media)
                    else:
                        made = passes.as_file(
                            name,
                            passes.values(
                                job.scene, name, light, self.threads, stop, budget=budget(job.scene, self.settings)
                            ),
                            fmt,
                        )
                except RenderCancelled:
                    if gone():
                        raise
                    raise TooSlow() from None
                except OverBudget as exc:
                    raise outgrown(exc, self.settings) from None
                except MemoryError:
                    raise OutOfMemory() from None
            self.answers.give(held - made.size)  # (what the making held beyond the file itself)
            held = made.size
            if made.size <= self.cache.max_bytes // 4:  # (a small answer is kept; a large one would crowd out all)
                self.cache.put(key, made.joined())
            return made, held
        except BaseException:
            self.answers.give(held)
            raise

    def explain(
        self,
        job: Job,
        graded: Graded,
        reference: np.ndarray,
        submitted: np.ndarray,
        gone: Callable[[], bool] = lambda: False,
    ) -> Graded:
        """``graded`` checked against the accepted variants and, when it fails them too, with its diagnosis
        (:func:`explained`), in one of this worker's render slots, in turn, within ``render_timeout`` (on the
        cluster when there is one).  The verdict never depends on the load: when no slot came within
        ``queue_wait`` (Busy), or the accepted variants' renders ran out of memory (OutOfMemory) or past the
        time (TooSlow), the grade is not answered now (503) rather than failed.  RenderCancelled once ``gone()``:
        its client left, no one reads the answer.  ClusterDown when the cluster has no worker, as for a render."""
        if graded.grade.passed:
            return graded
        with self._slot(gone) as late:
            stop = lambda: late() or gone()  # noqa: E731
            try:
                if self.settings.cluster:
                    return run(
                        self._client(),
                        explain_task,
                        job.scene.model_dump_json().encode(),
                        graded,
                        reference,
                        submitted,
                        self.settings.render_timeout,
                        cancelled=stop,
                    )
                here = Checking(self.threads, cancel=stop, cache=self.diagnoses)
                return explained(job.scene, graded, (reference, submitted), here, gone, self.settings.render_timeout)
            except RenderCancelled:
                if gone():
                    raise
                raise TooSlow() from None
            except MemoryError:
                raise OutOfMemory() from None

    def _client(self) -> Any:
        """The one Dask client of this process, made on first use (``settings.cluster``); ClusterDown when the
        scheduler cannot be reached or has no workers (the render would wait for one forever)."""
        try:
            with self._client_lock:
                if self._dask is None:
                    self._dask = client(self.settings.cluster)
            if not workers(self._dask):
                raise ClusterDown(f"the Dask scheduler at {self.settings.cluster} has no workers")
        except ClusterError as exc:
            raise ClusterDown(str(exc)) from None
        return self._dask

    def status(self) -> dict[str, Any]:  # (on the event loop: counters only, nothing that waits)
        return {
            "worker": os.getpid(),
            "cache_entries": len(self.cache),
            "cache_bytes": self.cache.size,
            "diagnosis_scenes": len(self.diagnoses),
            "answer_bytes": self.answers.held,
            "cache_hits": self.cache.hits,
            "renders": self.renders,
        }


def explained(
    scene: Scene,
    graded: Graded,
    images: tuple[np.ndarray, np.ndarray],
    run: Checking,
    gone: Callable[[], bool],
    seconds: float,
) -> Graded:
    """``graded`` (failing) checked against the accepted variants, then, when it fails them too, diagnosed
    (:func:`service.work.pipeline.explain`) from the ``(reference, submitted)`` images.  Running out of time
    (:class:`tracer.RenderCancelled`) or memory while the accepted variants are checked is raised: the verdict
    is not known.  Once it is, a diagnosis cut short says why (``seconds``: the time it was given), unless
    ``gone()`` (its client left: RenderCancelled is raised)."""
    reference, submitted = images
    checked = explain(scene, graded, reference, submitted, Checks(diagnose=False), run)
    if checked.grade.passed:
        return checked
    try:  # (checked again first, from the renders kept of them: up to 640×480, at no cost)
        return explain(scene, graded, reference, submitted, run=run)
    except MemoryError:
        why = "its renders ran out of memory beside the worker's other work; grade again for one"
    except RenderCancelled:
        if gone():
            raise
        why = f"its renders ran past the limit render_timeout = {seconds:g} s"
    return replace(graded, diagnosis=unavailable(why))


def explain_task(scene: bytes, graded: Graded, reference: np.ndarray, submitted: np.ndarray, seconds: float) -> Graded:
    """A failing grade explained on a Dask worker (:func:`explained`), within ``seconds`` of its start there:
    RenderCancelled when the accepted variants could not be checked in them."""
    deadline = time.monotonic() + seconds
    run = Checking(1, cancel=lambda: time.monotonic() > deadline)
    return explained(load_scene(scene), graded, (reference, submitted), run, lambda: False, seconds)
