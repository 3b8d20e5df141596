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

from schemas import Scene, parse_json, validate_scene
from tracer import OverBudget, RenderCancelled, encode_png
from tracer.memory import release_if_grown, resident, tune_allocator

from .cache import RenderCache
from .diagnosis import unavailable
from .limits import budget, check_body, check_raw, check_scene, outgrown
from .passes import Format
from .pipeline import Graded, explain, with_overrides
from .rendering import render_pixels
from .scenekey import scene_key
from .settings import Settings


class Busy(Exception):
    """Every render slot is taken."""


class TooSlow(Exception):
    """The render ran past the time limit."""


class ClusterDown(Exception):
    """The Dask cluster the renders go to cannot be reached."""


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
        self.cache = RenderCache(settings.cache_bytes)
        self.slots = threading.BoundedSemaphore(settings.max_concurrent_renders)
        self.threads = settings.render_threads or os.cpu_count() or 1
        self.grading = anyio.CapacityLimiter(settings.max_concurrent_renders)  # decoding and comparing images
        # parsing and validating: a thread per core at most, so that a burst of requests never has dozens of
        # threads queueing for the interpreter in front of the event loop (the others wait without a thread)
        self.parsing = anyio.CapacityLimiter(os.cpu_count() or 1)
        self.renders = 0
        self._dask: Any = None
        self._client_lock = threading.Lock()

    @contextlib.contextmanager
    def _slot(self) -> Iterator[Callable[[], bool]]:
        """One of this worker's render slots (Busy when none is free) for at most ``render_timeout``: yields the
        deadline's test, and hands what the work freed back to the OS afterwards."""
        if not self.slots.acquire(blocking=False):
            raise Busy()
        before = resident()
        deadline = time.monotonic() + self.settings.render_timeout
        try:
            yield lambda: time.monotonic() > deadline
        finally:
            self.slots.release()
            release_if_grown(before)  # a large render gives what it freed back to the OS: memory returns to baseline

    def png(self, job: Job, cancelled: Callable[[], bool] = lambda: False) -> bytes:
        """The PNG of a job, from the cache or rendered. Raises Busy, TooSlow, RenderCancelled, or LimitError when
        the render outgrows its budget (:func:`service.limits.budget`).

        Concurrent requests for one scene are joined before they get here (one flight per scene in
        :mod:`service.routes`), so each scene is rendered once."""
        cached = self.cache.get(job.key)
        if cached is not None:
            return cached
        with self._slot() as late:
            client = self._client() if self.settings.cluster else None
            try:
                pixels = render_pixels(job.scene, client, threads=self.threads, cancel=lambda: cancelled() or late(),
                                       budget=budget(job.scene, self.settings))
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

    def pass_file(self, job: Job, name: str, light: int | None, fmt: Format) -> bytes:
        """Render pass ``name`` of a job (of light ``light``) as a PNG or ``.npy`` file (:mod:`service.passes`),
        from the cache or rendered in a render slot within ``render_timeout``.  Raises Busy, TooSlow, LimitError
        when it outgrows its budget, or ValueError for a light the scene does not have."""
        from . import passes

        key = f"{job.key}/pass={name}/light={light}.{fmt}"
        cached = self.cache.get(key)
        if cached is not None:
            return cached
        with self._slot() as late:
            try:
                data = passes.encoded(name, passes.values(job.scene, name, light, self.threads, cancel=late,
                                                          budget=budget(job.scene, self.settings)), fmt)
            except RenderCancelled:
                raise TooSlow() from None
            except OverBudget as exc:
                raise outgrown(exc, self.settings) from None
        self.cache.put(key, data)
        return data

    def explain(self, job: Job, graded: Graded, reference: np.ndarray, submitted: np.ndarray) -> Graded:
        """``graded`` with the diagnosis of a failing grade, rendered in one of this worker's render slots
        within ``render_timeout``; when no slot is free or time runs out, a diagnosis that says so."""
        if graded.grade.passed:
            return graded
        try:
            with self._slot() as late:
                return explain(job.scene, graded, reference, submitted, self.threads, cancel=late)
        except Busy:
            return replace(graded, diagnosis=unavailable("every render slot is busy; grade again for one"))
        except RenderCancelled:
            return replace(graded, diagnosis=unavailable(
                f"its renders ran past the limit render_timeout = {self.settings.render_timeout:g} s"))

    def _client(self) -> Any:
        """The one Dask client of this process, made on first use (``settings.cluster``); ClusterDown when the
        scheduler cannot be reached or has no workers (the render would wait for one forever)."""
        from .cluster import ClusterError, client, workers

        try:
            with self._client_lock:
                if self._dask is None:
                    self._dask = client(self.settings.cluster)
            if not workers(self._dask):
                raise ClusterDown(f"the Dask scheduler at {self.settings.cluster} has no workers")
        except ClusterError as exc:
            raise ClusterDown(str(exc)) from None
        return self._dask

    def status(self) -> dict[str, Any]:
        return {"worker": os.getpid(), "cache_entries": len(self.cache), "cache_bytes": self.cache.size,
                "cache_hits": self.cache.hits,
                "renders": self.renders}
