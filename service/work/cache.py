"""A byte-bounded LRU cache of reference renders, keyed by the canonical scene."""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable


class RenderCache:
    """``others()``: the bytes other caches of the worker hold in the same budget of ``max_bytes`` (the
    diagnosis's renders): a new entry makes room among this cache's own."""

    def __init__(self, max_bytes: int, others: Callable[[], int] = lambda: 0):
        self.max_bytes = max_bytes
        self.others = others
        self._items: OrderedDict[str, bytes] = OrderedDict()
        self._size = 0
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    def get(self, key: str) -> bytes | None:
        with self._lock:
            value = self._items.get(key)
            if value is None:
                self.misses += 1
                return None
            self._items.move_to_end(key)
            self.hits += 1
            return value

    def __contains__(self, key: str) -> bool:
        """Whether ``key`` is held now (not counted as a hit or a miss, nor made recent)."""
        with self._lock:
            return key in self._items

    def put(self, key: str, value: bytes) -> None:
        room = self.max_bytes - self.others()
        if len(value) > room:
            return
        with self._lock:
            old = self._items.pop(key, None)
            if old is not None:
                self._size -= len(old)
            self._items[key] = value
            self._size += len(value)
            while self._size > room:
                _, evicted = self._items.popitem(last=False)
                self._size -= len(evicted)

    @property
    def size(self) -> int:
        return self._size

    def __len__(self) -> int:
        return len(self._items)
