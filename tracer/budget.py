"""A render's budget, counted while it runs: the rays it traces and the memory its batches of rays hold.

The renderer counts every ray it casts (:class:`RayCount`) and polls its stop (:class:`Stop`) between slices of
rays, walk passes and slices of exact tests, where it already polls its caller's ``cancel``; a render that
outgrows its :class:`Budget` there raises :class:`OverBudget`, naming what it outgrew.  The counting is one
addition under a lock per batch and one comparison per poll, nothing per ray.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

#: bytes one ray of the renderer's work stack holds: origin and direction (48), the surface it leaves (9), its
#: magnitude (8), its sample and weight (16), its branch (1)
RAY_BYTES = 82


@dataclass(frozen=True)
class Budget:
    """What one render may spend: ``rays`` traced in all (primary, secondary and shadow), and ``ray_bytes``, the
    memory its pending batches of rays may hold at once (every thread's together)."""

    rays: float = math.inf
    ray_bytes: float = math.inf


#: no limit: what a render on one's own machine gets
UNLIMITED = Budget()


class RenderCancelled(Exception):
    """Raised by :meth:`tracer.Renderer.pixels` when its ``cancel`` callback asked it to stop."""


class OverBudget(Exception):
    """A render stopped because it outgrew its budget: ``what`` is ``"rays"`` or ``"memory"``, ``spent`` what
    it had spent when stopped and ``limit`` the budget's value (rays, or bytes)."""

    def __init__(self, what: str, spent: float, limit: float):
        super().__init__(f"the render outgrew its budget of {what}: {spent:.3g} spent, {limit:.3g} allowed")
        self.what, self.spent, self.limit = what, spent, limit


class RayCount:
    """The rays cast so far, by kind (primary, shadow, secondary), counted from every thread, and the rays the
    work stacks hold now.  Apart from the renderer, so that the stages that count hold no reference back to it."""

    def __init__(self) -> None:
        self.counts = {"primary": 0, "shadow": 0, "secondary": 0}
        self.total = 0
        self._held: dict[int, int] = {}  # the rays of each thread's work stack
        self._lock = threading.Lock()

    def __call__(self, kind: str, n: int) -> None:
        with self._lock:
            self.counts[kind] += n
            self.total += n

    def hold(self, holder: int, n: int) -> None:
        """The work stack of ``holder`` (a thread) holds ``n`` rays now."""
        with self._lock:
            self._held[holder] = n

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
        self.count.total = 0

    def __call__(self) -> None:
        if self.cancel is not None and self.cancel():
            raise RenderCancelled("the render was cancelled")
        budget, count = self.budget, self.count
        if count.total > budget.rays:
            raise OverBudget("rays", count.total, budget.rays)
        held = count.held * RAY_BYTES if budget.ray_bytes < math.inf else 0
        if held > budget.ray_bytes:
            raise OverBudget("memory", held, budget.ray_bytes)
