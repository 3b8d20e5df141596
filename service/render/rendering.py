"""Rendering a validated scene here or on a Dask cluster: the one place that chooses, for the command line,
the service and class grading alike."""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from schemas import Scene
from tracer import Renderer, render
from tracer.budget import UNLIMITED, Budget

from .cluster import render as render_on


def die_with_parent(parent: int, prctl: bool) -> None:
    """Initializer of a process forked by :func:`render_forked`: it ends when its parent does, however that
    ends (SIGKILL, the OOM killer), never left running (class grading's pool, whose processes are not the
    grading process's children, watches a pipe instead: :mod:`service.classgrade.processes`).  On Linux the
    kernel kills it (PR_SET_PDEATHSIG; only when the pool was made by the main thread, as the signal comes when
    the creating thread ends); everywhere, a watchdog thread sees the parent gone."""
    if prctl and sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL, 0, 0, 0)  # 1: PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent died before the signal was asked for
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.25)
        os._exit(1)

    threading.Thread(target=watch, name="phongray-parent-watch", daemon=True).start()


#: the fewest primary rays (pixels × sub-samples) a render of the command line spreads over processes: below,
#: starting them costs more than the threads lose to the GIL
FORKED_RAYS = 1 << 18
#: the most triangles a render spread over processes may have: each process builds its own BVH, so a large
#: mesh's build, which is on several threads already, is made once per process (measured on the bench's 208k-face
#: torus: 1.34-1.46 s forked against 1.10-1.27 s on threads, 0.67 s of it the build)
FORKED_TRIANGLES = 1 << 12
#: bands of rows per process, handed out in turn, so that a process whose rows are cheap (sky) takes more of them
BANDS_PER_PROCESS = 8


def render_pixels(
    scene: Scene,
    client: Any = None,
    threads: int | None = None,
    cancel: Callable[[], bool] | None = None,
    progress: Callable[[int, int], None] | None = None,
    processes: bool = False,
    budget: Budget = UNLIMITED,
) -> np.ndarray:
    """``(H, W, 3) uint8`` pixels of ``scene``: on the cluster of the Dask ``client`` (in bands, the same bytes),
    else here on ``threads`` threads (every core by default), or, with ``processes`` (the command line, a
    process of its own), on as many forked processes when the render is large (:func:`render_forked`).
    ``cancel()`` true stops it with :class:`tracer.RenderCancelled`; an image beyond what phongray renders
    raises :class:`tracer.ImageTooLarge`; a render that outgrows its ``budget`` raises :class:`tracer.OverBudget`
    (on a cluster, each band is held to the whole budget; a budgeted render is not forked)."""
    if client is not None:
        return render_on(
            client,
            scene.model_dump_json().encode(),
            scene.image.width,
            scene.image.height,
            cancelled=cancel or (lambda: False),
            budget=None if budget == UNLIMITED else budget,
        )
    workers = threads or os.cpu_count() or 1
    img = scene.image
    if (
        processes
        and workers > 1
        and sys.platform.startswith("linux")
        and img.width * img.height * img.samples**2 >= FORKED_RAYS
        and img.height >= 2 * workers
        and _triangles(scene) <= FORKED_TRIANGLES
        and budget == UNLIMITED
    ):
        return render_forked(scene, workers, progress)
    return render(scene, threads=threads, progress=progress, cancel=cancel, budget=budget)


def _triangles(scene: Scene) -> int:
    """How many triangles the scene's meshes and triangles make."""
    return sum(len(obj.faces) if obj.type == "mesh" else 1 if obj.type == "triangle" else 0 for obj in scene.objects)


class BandLost(RuntimeError):
    """A forked process of :func:`render_forked` died before its bands were done (killed, out of memory)."""


#: the scene a forked process renders, and its renderer, made there once (set before the processes fork)
_FORKED: dict[str, Any] = {}


def _band(rows: tuple[int, int]) -> np.ndarray:
    if "renderer" not in _FORKED:
        _FORKED["renderer"] = Renderer(_FORKED["scene"])
    pixels: np.ndarray = _FORKED["renderer"].pixels(threads=1, rows=rows)
    return pixels


def render_forked(scene: Scene, workers: int, progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """``scene`` rendered in bands of rows on ``workers`` forked processes, one thread each: the same bytes
    as a render on threads (every pixel is computed alone), without the threads' contention for the
    interpreter lock (measured at 1080p on two cores: 0.39 s against 0.47 s on two threads).  Each process
    makes its own renderer, after the fork (no Embree scene crosses one); the parent makes none.  The processes
    die with the parent, whatever signal ends it; a process that dies raises :class:`BandLost`."""
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool
    from multiprocessing import get_context

    img = scene.image
    count = min(img.height, workers * BANDS_PER_PROCESS)
    edges = [round(k * img.height / count) for k in range(count + 1)]
    bands = [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]
    _FORKED.clear()
    _FORKED["scene"] = scene
    parts = []
    # each process dies with this one, however this one ends (a supervisor's SIGTERM or SIGKILL to it alone)
    pool = ProcessPoolExecutor(
        workers,
        mp_context=get_context("fork"),
        initializer=die_with_parent,
        initargs=(os.getpid(), threading.current_thread() is threading.main_thread()),
    )
    try:
        for part in pool.map(_band, bands):
            parts.append(part)
            if progress:
                progress(sum(len(q) for q in parts) * img.width, img.width * img.height)
    except BrokenProcessPool:  # a process was killed (the OOM killer, say): the others are ended with it
        pool.shutdown(wait=False, cancel_futures=True)
        raise BandLost("a process rendering part of the image died (killed, or out of memory)") from None
    except BaseException:  # (interrupted, say: the bands not begun are dropped, not waited for)
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    finally:
        _FORKED.clear()
    pool.shutdown()
    image = np.concatenate(parts)
    return image
