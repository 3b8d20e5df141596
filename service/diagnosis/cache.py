"""The renders of the last few scenes diagnosed, kept for the next pair of the same scene (:class:`Cached`)."""

from __future__ import annotations

import threading
from collections.abc import Callable

from .renders import Renders

#: the largest image whose diagnosis renders are kept for the next pair of the same scene
CACHED_PIXELS = 640 * 480


class Cached:
    """The :class:`Renders` of the last few scenes diagnosed, by canonical scene key: a class's failing pairs
    of one task (or a student's resubmissions) share one set of variant renders.  With ``room``, the arrays
    they hold are counted (:attr:`Renders.nbytes`) and held to ``room()`` bytes, the oldest scenes let go
    first (:meth:`trim`): the service counts them in one budget with its cache of answers."""

    def __init__(self, scenes: int = 4, room: Callable[[], int] | None = None):
        self.scenes = scenes
        self.room = room
        self.held: dict[str, Renders] = {}
        self.made = 0  # Renders built (a miss each)
        self._lock = threading.Lock()

    def get(self, key: str, make: Callable[[], Renders], pixels: int = 0) -> Renders:
        """The renders of scene ``key``, made by ``make()`` unless held; a scene of more than
        :data:`CACHED_PIXELS` pixels is not held (its variants would crowd out everything else)."""
        with self._lock:
            if key in self.held:
                self.held[key] = self.held.pop(key)  # most recently used last
                return self.held[key]
            self.made += 1
        renders = make()
        if pixels > CACHED_PIXELS:
            return renders
        with self._lock:
            self.held[key] = renders
            while len(self.held) > self.scenes:
                self.held.pop(next(iter(self.held)))
        return renders

    @property
    def size(self) -> int:
        """The bytes the scenes held hold."""
        with self._lock:
            held = list(self.held.values())
        return sum(r.nbytes() for r in held)

    def trim(self) -> None:
        """Let go of the oldest scenes until what is held fits in ``room()`` (after a diagnosis, whose renders
        have grown)."""
        if self.room is None:
            return
        while True:
            with self._lock:
                sizes = [(key, r.nbytes()) for key, r in self.held.items()]
                if not sizes or sum(size for _, size in sizes) <= max(self.room(), 0):
                    return
                self.held.pop(sizes[0][0], None)

    def __len__(self) -> int:
        return len(self.held)


#: this process's renders for diagnosis (the CLI, each class worker; each service worker has its own, counted)
CACHE = Cached()
