"""A worker's render slots, handed out in the order they are asked for.

Every render, pass and diagnosis of a worker runs in one of its ``max_concurrent_renders`` slots.  Work that
finds them all taken waits its turn, first come first served, for at most ``queue_wait`` seconds (a slot freed
goes to the longest waiting, never to a newcomer); one whose client leaves meanwhile leaves the queue.  Work
that waited its time in vain is :class:`Busy`, answered 503 with a ``Retry-After`` that reflects the queue
(:meth:`Slots.retry_after`): the time the work waiting now would take, by the slots' recent holding times.  So a
rush is served in order, and a client told to come back is told when its turn is likely.

Waiting happens on the pool thread that would do the work (the work is already off the event loop); it looks
at whether its client is still there every :data:`POLL` seconds.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable

from tracer import RenderCancelled

#: seconds between two looks of a waiting thread at whether its client is still there
POLL = 0.25
#: the weight of the latest holding time in the slots' running mean
WEIGHT = 0.3
#: the most seconds a Retry-After asks a client to wait (a queue's estimate beyond it is no better a guess)
MOST = 600


class Busy(Exception):
    """Every render slot is taken (and stayed so for as long as the work could wait)."""


class Slots:
    """``count`` slots, taken in order of asking (waiting at most ``wait`` seconds) and given back."""

    def __init__(self, count: int, wait: float, clock: Callable[[], float] = time.monotonic):
        self.count, self.wait, self.clock = count, wait, clock
        self._free = count
        self._queue: deque[threading.Event] = deque()
        self._lock = threading.Lock()
        self._mean: float | None = None  # seconds a slot is held, a running mean

    @property
    def waiting(self) -> int:
        """How many wait for a slot now."""
        return len(self._queue)

    def take(self, cancelled: Callable[[], bool] = lambda: False) -> float:
        """A slot, at once when one is free and nobody waits, else in turn; the time it was taken (for
        :meth:`give`).  Raises :class:`Busy` when none came within ``wait`` seconds (at once with ``wait`` 0),
        :class:`tracer.RenderCancelled` once ``cancelled()`` (the client left) while waiting."""
        with self._lock:
            if self._free and not self._queue:
                self._free -= 1
                return self.clock()
            if self.wait <= 0 or self.count <= 0:
                raise Busy()
            turn = threading.Event()
            self._queue.append(turn)
        due = time.monotonic() + self.wait
        try:
            while not turn.wait(max(0.0, min(POLL, due - time.monotonic()))):
                if cancelled():
                    raise RenderCancelled("client closed the request")
                if time.monotonic() >= due:
                    raise Busy()
        except BaseException:
            with self._lock:
                if turn.is_set():  # (given to it as it gave up: passed on to the next)
                    self._pass_on()
                else:
                    self._queue.remove(turn)
            raise
        return self.clock()

    def give(self, taken: float) -> None:
        """Give back the slot taken at ``taken``: to the longest waiting, or to the free ones."""
        held = max(0.0, self.clock() - taken)
        with self._lock:
            self._mean = held if self._mean is None else (1 - WEIGHT) * self._mean + WEIGHT * held
            self._pass_on()

    def _pass_on(self) -> None:
        if self._queue:
            self._queue.popleft().set()
        else:
            self._free += 1

    def retry_after(self, least: int) -> int:
        """Whole seconds until a client that comes back is likely to find its turn: the work waiting now, and
        its own, at the slots' mean holding time, over the slots (at least ``least``, at most :data:`MOST`)."""
        with self._lock:
            mean, ahead = self._mean, len(self._queue)
        if mean is None or self.count <= 0:
            return least
        return max(least, min(MOST, math.ceil(mean * (ahead + 1) / self.count)))
