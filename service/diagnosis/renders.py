"""What a diagnosis needs rendered from the reference scene, as callables: :class:`Renders`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from tracer import RenderCancelled

if TYPE_CHECKING:
    from tracer.render import Fold
    from tracer.variants import Options

    from .words import Names


@dataclass
class Renders:
    """What a diagnosis needs rendered from the reference scene: each call may come from a cache."""

    variant: Callable[[str], np.ndarray]  # name → (H, W, 3) uint8 pixels of the reference with that mistake
    passes: Callable[[list[str], int | None], dict[str, np.ndarray]]  # names, light → tracer passes
    lights: list[str]  # the scene's light types, in order
    objects: list[str]  # the scene's object types, in order
    bound: Callable[[str], np.ndarray] | None = None  # name of BOUNDS → pixels of the mistake's far end
    cancel: Callable[[], bool] | None = None  # the current diagnosis's: true stops its renders
    #: name, row numbers → those rows of the variant's pixels, rendered alone (a first look, :func:`off_at_least`,
    #: or a band of its whole image, :func:`whole_unless_off`)
    rows: Callable[[str, np.ndarray], np.ndarray] | None = None
    #: name of BOUNDS, row numbers → those rows of the mistake's far end, rendered alone (:func:`outside_at_least`)
    bound_rows: Callable[[str, np.ndarray], np.ndarray] | None = None
    #: pixel numbers, fold → the first hits' ``object`` at those pixels alone; their ``diffuse:K`` and
    #: ``specular:K`` go to the fold, a block at a time (:data:`tracer.render.Fold`)
    at: Callable[[np.ndarray, Fold], np.ndarray] | None = None
    #: name → whether the scene cannot show that mistake (its render is the reference's, bit for bit)
    unchanged: Callable[[str], bool] | None = None
    #: called when a diagnosis is over, in its thread: lets go of what was prepared only for its renders
    done: Callable[[], None] | None = None
    #: sets the cancel of the diagnosis this thread runs (``cancel`` is every thread's): two diagnoses of one
    #: cached scene, in two threads, each stop on their own
    cancel_in_thread: Callable[[Callable[[], bool] | None], None] | None = None
    #: hands the columns of the term fit (``background``, ``ambient``, ``reflection``, ``refraction``,
    #: ``diffuse:K``, ``specular:K``, each ``(pixels, 3)``) to a fold, a block of pixels at a time, in order
    #: (:data:`tracer.render.Fold`): the whole image's passes are never needed at once
    blocks: Callable[[Fold], None] | None = None
    #: the bytes of the arrays these renders hold (what a cache of them counts)
    nbytes: Callable[[], int] | None = None

    def check(self) -> None:
        """Raises :class:`tracer.RenderCancelled` once the current diagnosis's cancel says to stop (its deadline,
        or its client gone): polled between the stages that render nothing (grading, the fit)."""
        cancel = self.cancel if self.polled is None else self.polled()
        if cancel is not None and cancel():
            raise RenderCancelled("diagnosis cancelled")

    #: the current thread's cancel (set by ``cancel_in_thread``), else ``cancel``
    polled: Callable[[], Callable[[], bool] | None] | None = None
    #: options → the whole image rendered with them (mistakes made together, :mod:`.compose`); None: no
    #: combination is tried
    render: Callable[[Options], np.ndarray] | None = None
    #: how a student is told of the scene's objects and lights (:mod:`.words`); None: by index
    names: Names | None = None
    #: the scene's visible size (:mod:`tracer.visible`): an offset too large is rendered at a ladder of amounts
    #: (``offset-too-large@0.05``, in the scene's units) only when it is given; None: at its variant's alone
    size: Callable[[], float] | None = None
    #: ``(H, W)`` bool, True where a pixel is not counted against a submission: the format leaves it open, or an
    #: honest student's offset, fitted as a nuisance (:mod:`.nuisance`), may move it; None: every pixel counts
    open: np.ndarray | None = None
