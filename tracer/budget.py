"""A render's budget, counted while it runs: the rays it traces and the memory its batches of rays hold.

The renderer counts every ray it casts (:class:`RayCount`) and polls its stop (:class:`Stop`) between slices of
rays, walk passes and slices of exact tests, where it already polls its caller's ``cancel``; a render that
outgrows its :class:`Budget` there raises :class:`OverBudget`, naming what it outgrew.  The counting is one
addition under a lock per batch and one comparison per poll, nothing per ray.  Each render call has its own
count and stop (:class:`Call`), and the stages reach the call of the thread they run on (:class:`Calls`).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

#: bytes one ray of the renderer's work stack holds: origin and direction (48), the surface it leaves (9), its
#: magnitude (8), its sample and weight (16), its branch (1)
RAY_BYTES = 82


@dataclass(frozen=True)
class Budget:
    """What one render may spend: ``rays`` in all (camera, mirror and refracted rays, and a shadow ray per hit and
    light sample: :class:`RayCount`), and ``ray_bytes``, the memory its pending batches of rays may hold at once
    (every thread's together)."""

    rays: float = math.inf
    ray_bytes: float = math.inf
    #: exact (ray, sphere or triangle) tests in all: what a ray costs beyond its count when many surfaces lie
    #: along it (every sphere or triangle far larger than the rest is tested against every ray; spheres nested
    #: around a point share every cell that holds it), which the per-ray factor cannot foresee
    tests: float = math.inf


#: a render is stopped early once the rays it has spent and the rays its chunks' trees foresee (:class:`Growth`)
#: pass its budget this many times over: a foresight, not a count, so only when far over
FORESIGHT = 4.0


#: no limit: what a render on one's own machine gets
UNLIMITED = Budget()


class RenderCancelled(Exception):
    """Raised by :meth:`tracer.Renderer.pixels` when its ``cancel`` callback asked it to stop."""


class OverBudget(Exception):
    """A render stopped because it outgrew its budget: ``what`` is ``"rays"`` or ``"memory"``, ``spent`` what
    it had spent when stopped (or, ``foreseen``, what it would have spent by the rates of its trees so far) and
    ``limit`` the budget's value (rays, or bytes); ``"tests"``: its exact tests of rays against surfaces."""

    def __init__(self, what: str, spent: float, limit: float, foreseen: bool = False):
        super().__init__(
            f"the render outgrew its budget of {what}: {spent:.3g} {'foreseen' if foreseen else 'spent'}"
            f", {limit:.3g} allowed"
        )
        self.what, self.spent, self.limit, self.foreseen = what, spent, limit, foreseen

    def __reduce__(self) -> tuple[type[OverBudget], tuple[str, float, float, bool]]:
        """Pickled whole, so that it crosses from a Dask worker or a process as itself."""
        return OverBudget, (self.what, self.spent, self.limit, self.foreseen)


class RayCount:
    """The rays cast so far, by kind (primary, shadow, secondary), counted from every thread; their ``total``,
    what a budget counts: camera, mirror and refracted rays, and a shadow ray per hit and light sample (cast,
    or proven clear by :mod:`tracer.proofs.culling`, which costs work too); and the rays the work stacks hold now.
    Apart from the renderer, so that the stages that count hold no reference back to it."""

    def __init__(self, counts: dict[str, int] | None = None, counts_lock: threading.Lock | None = None) -> None:
        #: the rays by kind, which go on from render to render (the renderer's, shared by its calls' counts)
        self.counts = {"primary": 0, "shadow": 0, "secondary": 0} if counts is None else counts
        self._counts_lock = threading.Lock() if counts_lock is None else counts_lock
        self.total = 0
        self.traced = 0  # camera, mirror and refracted rays of this render (total counts their light samples too)
        self.tests = 0  # exact (ray, sphere or triangle) tests of this render
        self.camera = 0  # camera rays of this render cast so far
        self.planned = 0  # camera rays this render will cast in all (0: not said)
        self._held: dict[int, int] = {}  # the rays of each thread's work stack
        self._ahead: dict[int, float] = {}  # the rays each thread's chunk foresees it has still to trace
        self._lock = threading.Lock()

    def __call__(self, kind: str, n: int) -> None:
        with self._counts_lock:
            self.counts[kind] += n
        with self._lock:
            if kind == "primary":
                self.camera += n
            if kind != "shadow":  # (counted as the light samples of every hit, cast or proven clear: lit)
                self.total += n
                self.traced += n

    def restart(self) -> None:
        """A new render: its budget's count starts from nothing (the counts by kind go on)."""
        with self._lock:
            self.total = self.traced = self.tests = self.camera = self.planned = 0
            self._ahead.clear()
            self._held.clear()

    def plan(self, camera: int) -> None:
        """This render will cast ``camera`` camera rays in all: the foresight extends what the chunks begun
        spend per camera ray to those not begun (:attr:`ahead`)."""
        with self._lock:
            self.planned = camera

    def lit(self, n: int) -> None:
        """``n`` more (hit, light sample) pairs shaded: a shadow ray each, whether cast or proven clear."""
        with self._lock:
            self.total += n

    def tested(self, n: int) -> None:
        """``n`` more exact tests of a ray against a sphere or a triangle."""
        with self._lock:
            self.tests += n

    def hold(self, holder: int, n: int) -> None:
        """The work stack of ``holder`` (a thread) holds ``n`` rays now."""
        with self._lock:
            self._held[holder] = n

    def foresee(self, holder: int, rays: float) -> None:
        """The chunk of ``holder`` (a thread) foresees ``rays`` more rays of its tree (:class:`Growth`)."""
        with self._lock:
            self._ahead[holder] = rays

    @property
    def ahead(self) -> float:
        """The budget's count that the chunks being traced foresee beyond :attr:`total`: their rays to come, each
        counted as the rays traced so far were (with its light samples); and, once :meth:`plan` said how many
        camera rays the render casts and a 1/:data:`FORESIGHT` share of them has begun, the chunks not begun, at
        what the chunks begun spend (and foresee) per camera ray.  Without them a render of many chunks, each
        within the budget, was seen a chunk or two at a time: nested glass at depth 12 and 1024² ran into the
        render_timeout (503 after 120 s, on a loaded machine) instead of stopping with 422."""
        with self._lock:
            ahead = sum(self._ahead.values()) * (self.total / self.traced if self.traced else 1.0)
            rest = self.planned - self.camera
            # only once a 1/FORESIGHT share of them has begun: the chunks begun then foresee at most FORESIGHT
            # times what the whole render spends, even when all its work lies in them (a mirror ball in the top
            # rows), so that no render within its budget is stopped by this extension of the foresight
            if rest > 0 and self.camera * FORESIGHT >= self.planned:
                ahead += rest * (self.total + ahead) / self.camera
            return ahead

    @property
    def held(self) -> int:
        """The rays every work stack holds now."""
        with self._lock:
            return sum(self._held.values())


class Stop:
    """Raises :class:`RenderCancelled` once the caller's ``cancel`` returns True, and :class:`OverBudget` once the
    ``count`` outgrows the ``budget``.  The renderer and its intersector both poll it; it holds no reference
    back to the renderer, so that a renderer dropped by its caller is freed at once (a cycle would keep its
    arrays and BVH until the garbage collector ran)."""

    def __init__(self, count: RayCount) -> None:
        self.cancel: Callable[[], bool] | None = None
        self.budget = UNLIMITED
        self.count = count

    def start(self, cancel: Callable[[], bool] | None, budget: Budget) -> None:
        """A render begins with these: its rays are counted from here."""
        self.cancel, self.budget = cancel, budget
        self.count.restart()

    def __call__(self) -> None:
        if self.cancel is not None and self.cancel():
            raise RenderCancelled("the render was cancelled")
        budget, count = self.budget, self.count
        if count.total > budget.rays:
            raise OverBudget("rays", count.total, budget.rays)
        if budget.rays < math.inf:
            foreseen = count.total + count.ahead
            if foreseen > FORESIGHT * budget.rays:
                raise OverBudget("rays", foreseen, budget.rays, foreseen=True)
        if count.tests > budget.tests:
            raise OverBudget("tests", count.tests, budget.tests)
        held = count.held * RAY_BYTES if budget.ray_bytes < math.inf else 0
        if held > budget.ray_bytes:
            raise OverBudget("memory", held, budget.ray_bytes)


@dataclass(frozen=True)
class Call:
    """One render call's count and stop (:class:`Calls`)."""

    count: RayCount
    stop: Stop


class Calls:
    """The render call each thread works for, so that one renderer may serve several calls at once.

    The stages poll and count through this object, bound to them once (:meth:`stop`, :meth:`count` and the
    rest); each reaches the call of the thread it runs on, which the driver sets for the time of a chunk
    (:meth:`working`).  Work outside any call (a stage called by itself) reaches an idle call with no budget.
    The counts by kind are the renderer's, shared by its calls.  Like :class:`Stop`, it holds no reference back
    to the renderer."""

    def __init__(self) -> None:
        self.counts = {"primary": 0, "shadow": 0, "secondary": 0}
        self._counts_lock = threading.Lock()
        self._local = threading.local()
        self.idle = self.begin(None, UNLIMITED)
        #: the call begun last (what a renderer's ``spent`` and ``tests`` read)
        self.last = self.idle

    def begin(self, cancel: Callable[[], bool] | None, budget: Budget) -> Call:
        """A new call, its rays counted from nothing, stopped by its own ``cancel`` and ``budget``."""
        count = RayCount(self.counts, self._counts_lock)
        stop = Stop(count)
        stop.start(cancel, budget)
        self.last = Call(count, stop)
        return self.last

    @contextmanager
    def working(self, call: Call) -> Iterator[None]:
        """This thread works for ``call`` within the block."""
        before = getattr(self._local, "call", None)
        self._local.call = call
        try:
            yield
        finally:
            self._local.call = before

    def current(self) -> Call:
        """The call this thread works for (the idle call outside any)."""
        call: Call | None = getattr(self._local, "call", None)
        return self.idle if call is None else call

    def stop(self) -> None:
        self.current().stop()

    def count(self, kind: str, n: int) -> None:
        self.current().count(kind, n)

    def tested(self, n: int) -> None:
        self.current().count.tested(n)

    def lit(self, n: int) -> None:
        self.current().count.lit(n)

    def hold(self, holder: int, n: int) -> None:
        self.current().count.hold(holder, n)

    def foresee(self, holder: int, rays: float) -> None:
        self.current().count.foresee(holder, rays)


class Growth:
    """The ray tree of one chunk as it is traced depth-first, and how many rays it will trace in all, foreseen
    from how many rays each depth's rays have cast so far.  Depth-first, the first slice of every depth is traced
    long before the tree is done (at depth 16 the tree of nested glass is 2^17 times its camera rays): the
    foresight stops a render that is far over its budget in seconds, not once it has spent it."""

    def __init__(self, camera_rays: int, depth: int):
        self.camera_rays, self.depth = camera_rays, depth
        self.traced: list[int] = []  # per depth seen so far (grown as the tree goes deeper: max_depth may be huge)
        self.cast: list[int] = []
        self.done = 0

    def add(self, depth: int, traced: int, cast: int) -> None:
        """Rays of ``depth`` traced, and the mirror and refracted rays they cast."""
        while len(self.traced) <= depth:
            self.traced.append(0)
            self.cast.append(0)
        self.traced[depth] += traced
        self.cast[depth] += cast
        self.done += traced

    def ahead(self) -> float:
        """The rays still to trace, at the rates seen so far (0 until every depth that the tree reaches has
        been seen: no rate is guessed)."""
        level = total = float(self.camera_rays)
        for d in range(self.depth):  # the rays of depth d cast those of depth d + 1
            if level < 1.0:
                break
            if d >= len(self.traced) or self.traced[d] == 0:
                return 0.0
            level *= self.cast[d] / self.traced[d]
            total += level
        return max(0.0, total - self.done)
