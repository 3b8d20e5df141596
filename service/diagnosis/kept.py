"""The renders of accepted variants kept for the next failing image of a scene (:data:`KEPT_RENDERS`: whole, or
the rows a first look rendered), and those rendered beforehand in a folder (:data:`STORED`, an autograder
bundle's): :mod:`.accepting` takes its rungs from here."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np

from tracer import decode_png
from tracer.scene.variants import Options

#: renders of accepted variants kept (by scene and variant, whole or a first look's rows), each of at most this
#: many pixels
KEPT = 40
KEPT_PIXELS = 640 * 480


class _Kept:
    """The last :data:`KEPT` accepted variants rendered, by canonical scene key and options."""

    def __init__(self) -> None:
        self.held: dict[tuple[object, ...], np.ndarray] = {}
        #: the rows of renders looked at so far, by scene key and options: row number → its pixels
        self.rows: dict[tuple[object, ...], dict[int, np.ndarray]] = {}
        self.lock = threading.Lock()

    def rows_of(
        self, key: tuple[object, ...], numbers: np.ndarray, make: Callable[[np.ndarray], np.ndarray]
    ) -> np.ndarray:
        """Rows ``numbers`` of the render ``key``: those not kept made by ``make`` (row numbers → their pixels),
        and kept (for the last :data:`KEPT` renders, each of at most :data:`KEPT_PIXELS`)."""
        with self.lock:
            have = dict(self.rows.get(key, {}))
        todo = np.array(sorted(set(numbers.tolist()) - set(have)), dtype=np.int64)
        if len(todo):
            fresh = make(todo)
            have.update(zip(todo.tolist(), fresh))
            with self.lock:
                mine = self.rows.setdefault(key, {})
                mine.update(zip(todo.tolist(), fresh))
                if sum(row.shape[0] for row in mine.values()) > KEPT_PIXELS:
                    self.rows.pop(key)
                while len(self.rows) > KEPT:
                    self.rows.pop(next(iter(self.rows)))
        return np.stack([have[r] for r in numbers.tolist()])

    def kept_rows(self, key: tuple[object, ...], numbers: np.ndarray) -> np.ndarray | None:
        """Rows ``numbers`` of the render ``key`` when every one of them is kept (else None: nothing rendered)."""
        with self.lock:
            have = self.rows.get(key, {})
            if not all(r in have for r in numbers.tolist()):
                return None
            return np.stack([have[r] for r in numbers.tolist()])

    def has(self, key: tuple[object, ...]) -> bool:
        with self.lock:
            return key in self.held or stored(key) is not None

    def get(self, key: tuple[object, ...], make: Callable[[], np.ndarray], pixels: int) -> np.ndarray:
        with self.lock:
            if key in self.held:
                return self.held[key]
        path = stored(key)
        image = make() if path is None else decode_png(path.read_bytes())
        if pixels <= KEPT_PIXELS:
            with self.lock:
                self.held[key] = image
                while len(self.held) > KEPT:
                    self.held.pop(next(iter(self.held)))
        return image


KEPT_RENDERS = _Kept()

#: a folder of accepted variants rendered beforehand (an autograder bundle's), ``<scene key>/<file_name>``
STORED = "PHONGRAY_ACCEPTED_RENDERS"


def file_name(options: Options) -> str:
    """The name of a whole render of an accepted variant in a folder of them: ``normal-0.0006.png`` (its offset
    relative to the visible size)."""
    return f"{options.offset_along}-{options.offset!r}.png"


def stored(key: tuple[object, ...]) -> Path | None:
    """The file of a whole render ``key`` = (scene key, options) in the folder :data:`STORED` names, if there is
    one (never a first look's rows)."""
    folder = os.environ.get(STORED)
    if not folder or len(key) != 2 or not isinstance(key[1], Options):
        return None
    path = Path(folder) / str(key[0]) / file_name(key[1])
    return path if path.is_file() else None
