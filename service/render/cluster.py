"""The one module that talks to Dask distributed (the optional ``phongray[cluster]`` extra).

Work goes to a cluster as ordinary tasks: a render is split into bands of rows
(:func:`band_task`), each band rendered alone on some worker and the bands
stacked in order.  Every pixel is computed on its own with exact integer sums,
so the stacked image is byte for byte the local one.  Dask reschedules the
tasks of a worker that dies; phongray adds nothing of its own on top.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from schemas import load_scene
from tracer import RenderCancelled
from tracer.budget import UNLIMITED
from tracer.render import Renderer

if TYPE_CHECKING:
    from tracer.budget import Budget

INSTALL = "--cluster needs Dask distributed: pip install 'phongray[cluster]'"
T = TypeVar("T")
#: pixels per band of a cluster render (a 3840×2160 image is 32 bands)
BAND_PIXELS = 1 << 18
#: seconds to wait for a cluster's first worker, unless ``--cluster-wait`` or ``PHONGRAY_CLUSTER_WAIT`` says
CLUSTER_WAIT = 30.0


class ClusterError(Exception):
    """Dask is not installed, or the scheduler cannot be reached."""


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise ClusterError(INSTALL) from None
    return distributed


#: the size of a task's graph past which Dask warns: above any student's folder a TA may allow
LARGE_GRAPH = "4GB"


def client(address: str, timeout: float = 10.0) -> Any:
    """A Dask client of the scheduler at ``address`` (``tcp://HOST:PORT``)."""
    distributed = _distributed()
    from distributed.comm import get_address_host_port

    try:  # before a Client is made: a half-made one hangs in its finaliser for 20 s
        get_address_host_port(address)
    except (ValueError, TypeError) as exc:  # "missing port number", an unknown protocol, ...
        raise ClusterError(
            f"--cluster {address}: not a Dask scheduler address ({exc}); expected tcp://HOST:PORT"
        ) from None
    # a student's folder goes to the worker inside its task, as bytes (:mod:`service.programs.pack`, at most
    # the folder limit): by design, so Dask's warning of a large graph (past 10 MB) would only alarm the TA
    import dask

    dask.config.set({"distributed.admin.large-graph-warning-threshold": LARGE_GRAPH})
    try:
        return distributed.Client(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise ClusterError(f"cannot reach the Dask scheduler at {address}: {exc}") from None


#: the shortest wait for a scheduler's answer, whatever --cluster-wait says (0 waits for no worker, not no answer)
MIN_CONNECT = 1.0


def connect_timeout(timeout: float, wait: float) -> float:
    """How long to wait for the scheduler to answer: within ``--cluster-wait`` (``wait``), so that an unreachable
    scheduler is told after about ``wait`` seconds, not after Dask's own ``timeout`` as well."""
    return min(timeout, max(wait, MIN_CONNECT))


def workers(client_: Any) -> int:
    """How many workers the client's scheduler has now."""
    return len(client_.scheduler_info().get("workers", {}))


def wait_for_workers(client_: Any, address: str, wait: float, spent: float = 0.0) -> None:
    """Return once the cluster has a worker; :class:`ClusterError` after ``wait`` seconds without one (work sent
    to a cluster with no workers would wait forever), ``spent`` of them already gone (on connecting)."""
    try:
        client_.wait_for_workers(1, timeout=max(wait - spent, 0.001))
    except (TimeoutError, OSError):
        raise ClusterError(
            f"the Dask scheduler at {address} has no workers (none joined within {wait:g} s; "
            f"start some with 'dask worker {address}', or wait longer with --cluster-wait)"
        ) from None


@contextlib.contextmanager
def connect(address: str, timeout: float = 10.0, wait: float | None = None) -> Iterator[Any]:
    """:func:`client`, closed afterwards; with ``wait``, once it has a worker (:func:`wait_for_workers`), the
    connection and the worker both within ``wait`` seconds."""
    started = time.monotonic()
    client_ = client(address, timeout if wait is None else connect_timeout(timeout, wait))
    try:
        if wait is not None:
            wait_for_workers(client_, address, wait, time.monotonic() - started)
        yield client_
    finally:
        client_.close()


def band_task(scene: bytes, top: int, bottom: int, budget: Budget | None = None) -> np.ndarray:
    """Rows ``top..bottom`` of a scene's image, ``(bottom − top, W, 3) uint8``, within ``budget`` when given (the
    whole render's: a band alone over it is a render over it; :class:`tracer.OverBudget` otherwise)."""
    return Renderer(load_scene(scene)).pixels(threads=1, rows=(top, bottom), budget=budget or UNLIMITED)


def bands(width: int, height: int) -> list[tuple[int, int]]:
    rows = max(1, BAND_PIXELS // max(width, 1))
    return [(top, min(top + rows, height)) for top in range(0, height, rows)]


def render(
    client: Any,
    scene: bytes,
    width: int,
    height: int,
    cancelled: Callable[[], bool] = lambda: False,
    poll: float = 0.05,
    budget: Budget | None = None,
) -> np.ndarray:
    """The image of a scene rendered band by band on the cluster; ``cancelled()`` is polled while waiting and,
    once true, the bands still to come are cancelled and :class:`tracer.RenderCancelled` is raised.  Each band is
    held to ``budget`` when given; one that outgrows it raises :class:`tracer.OverBudget` here (not retried), the
    others cancelled."""
    data = client.scatter(scene, broadcast=False, hash=False)
    parts = [
        client.submit(band_task, data, top, bottom, budget, pure=False, retries=2 if budget is None else 0)
        for top, bottom in bands(width, height)
    ]
    try:
        while not all(f.done() for f in parts) and not any(f.status == "error" for f in parts):
            if cancelled():
                client.cancel(parts)
                raise RenderCancelled("the render was cancelled")
            time.sleep(poll)
        return np.concatenate(client.gather(parts), axis=0)
    finally:
        client.cancel([f for f in parts if not f.done()])


def run(
    client: Any, task: Callable[..., T], *args: Any, cancelled: Callable[[], bool] = lambda: False, poll: float = 0.05
) -> T:
    """``task(*args)`` as one task on the cluster; ``cancelled()`` is polled while waiting and, once true, the
    task is cancelled and :class:`tracer.RenderCancelled` is raised (a task already running on a worker stops
    at the deadline it was given).  An exception of the task is raised here."""
    future = client.submit(task, *args, pure=False)
    try:
        while not future.done():
            if cancelled():
                raise RenderCancelled("the work was cancelled")
            time.sleep(poll)
        result: T = future.result()
        return result
    finally:
        if not future.done():
            client.cancel([future])
