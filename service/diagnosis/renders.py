"""What a diagnosis needs rendered from the reference scene: the :class:`Renders` protocol, which the scene's own
renders (:class:`.rendered.SceneRenders`) implement, and :class:`WholeImages`, the same renders seen as whole
images only (rows, far ends' rows and failing pixels taken from them: the slow path a shortcut is checked by)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from tracer.render import Fold
    from tracer.scene.variants import Options

    from .words import Names


class Renders(Protocol):
    """What a diagnosis needs rendered from the reference scene: each call may come from a cache."""

    #: the current diagnosis's: true stops its renders (every thread's; see :meth:`cancel_in_thread`)
    cancel: Callable[[], bool] | None

    @property
    def lights(self) -> list[str]:
        """The scene's light types, in order."""

    @property
    def objects(self) -> list[str]:
        """The scene's object types, in order."""

    @property
    def samples(self) -> int:
        """The scene's sub-samples per pixel side (``image.samples``: each pixel the mean of n × n)."""

    @property
    def names(self) -> Names:
        """How a student is told of the scene's objects and lights (:mod:`.words`)."""

    @property
    def open(self) -> np.ndarray | None:
        """``(H, W)`` bool, True where a pixel is not counted against a submission: the format leaves it open, or
        an honest student's offset, fitted as a nuisance (:mod:`.nuisance`), may move it; None: every pixel
        counts."""

    def variant(self, name: str) -> np.ndarray:
        """``(H, W, 3)`` uint8 pixels of the reference with mistake ``name``."""

    def rows(self, name: str, numbers: np.ndarray) -> np.ndarray:
        """Rows ``numbers`` of variant ``name``'s pixels (a first look, :func:`.looks.off_at_least`, or a band
        of its whole image, :func:`.looks.whole_unless_off`): the rows of its whole image, exactly."""

    def bound(self, name: str) -> np.ndarray:
        """Pixels of the far end of a mistake of :data:`tracer.scene.variants.BOUNDS`."""

    def bound_rows(self, name: str, numbers: np.ndarray) -> np.ndarray:
        """Rows ``numbers`` of that far end (:func:`.looks.outside_at_least`)."""

    def passes(self, names: list[str], light: int | None) -> dict[str, np.ndarray]:
        """The reference's tracer passes ``names``, of light ``light`` for a light's terms."""

    def at(self, pixels: np.ndarray, fold: Fold) -> np.ndarray:
        """The first hits' ``object`` at pixel numbers ``pixels``; their ``diffuse:K`` and ``specular:K`` go to
        ``fold``, a block at a time (:data:`tracer.render.Fold`)."""

    def blocks(self, fold: Fold) -> None:
        """Hands the columns of the term fit (``background``, ``ambient``, ``reflection``, ``refraction``,
        ``diffuse:K``, ``specular:K``, each ``(pixels, 3)``) to ``fold``, a block of pixels at a time, in order:
        the whole image's passes are never needed at once."""

    def render(self, options: Options) -> np.ndarray:
        """The whole image rendered with ``options`` (mistakes made together, :mod:`.compose`)."""

    def with_rows(self, options: Options, numbers: np.ndarray) -> np.ndarray:
        """Rows ``numbers`` of the image rendered with ``options`` (a rung of a ladder of offsets), kept under the
        options: the accepted offsets' ladder and an offset too large's render a rung they share once."""

    def with_options(self, options: Options) -> np.ndarray:
        """The whole image rendered with ``options``, kept as :meth:`with_rows` keeps its rows."""

    def with_pixels(self, options: Options, wanted: np.ndarray) -> np.ndarray:
        """The image rendered with ``options`` where ``wanted`` (``(H, W)`` bool) is True, as ``(H, W, 3)`` (the other
        pixels unset): the pixels of its whole image, exactly, kept as :meth:`with_rows` keeps its rows."""

    def holds(self, options: Options) -> bool:
        """Whether the whole image with ``options`` is at hand, without a render."""

    def unchanged(self, name: str) -> bool:
        """Whether the scene cannot show mistake ``name`` (its render is the reference's, bit for bit)."""

    def size(self) -> float:
        """The scene's visible size (:mod:`tracer.exact.visible`): an offset too large is rendered at a ladder of
        amounts (``offset-too-large@0.05``, in the scene's units)."""

    def check(self) -> None:
        """Raises :class:`tracer.RenderCancelled` once the current diagnosis's cancel says to stop (its deadline,
        or its client gone): polled between the stages that render nothing (grading, the fit)."""

    def cancel_in_thread(self, cancel: Callable[[], bool] | None) -> None:
        """Sets the cancel of the diagnosis this thread runs (``cancel`` is every thread's): two diagnoses of one
        cached scene, in two threads, each stop on their own."""

    def done(self) -> None:
        """Called when a diagnosis is over, in its thread: lets go of what was prepared only for its renders."""

    def nbytes(self) -> int:
        """The bytes of the arrays these renders hold (what a cache of them counts)."""


class WholeImages:
    """``renders`` seen as whole images only: a variant's rows and a far end's rows are the rows of its whole
    image, the failing pixels' passes those of the whole image's passes, and every mistake is scored (none is
    known unchanged).  The same answers, exactly, by the slow path: what the shortcuts are checked against."""

    def __init__(self, renders: Renders):
        self.inner = renders
        self.lights, self.objects, self.names, self.open = renders.lights, renders.objects, renders.names, renders.open
        self.samples = renders.samples
        self.variant, self.bound, self.passes = renders.variant, renders.bound, renders.passes
        self.blocks, self.render, self.size, self.check = renders.blocks, renders.render, renders.size, renders.check
        self.cancel_in_thread, self.done, self.nbytes = renders.cancel_in_thread, renders.done, renders.nbytes
        self.with_options, self.holds = renders.with_options, renders.holds

    @property
    def cancel(self) -> Callable[[], bool] | None:
        return self.inner.cancel

    @cancel.setter
    def cancel(self, cancel: Callable[[], bool] | None) -> None:
        self.inner.cancel = cancel

    def rows(self, name: str, numbers: np.ndarray) -> np.ndarray:
        return self.variant(name)[numbers]

    def bound_rows(self, name: str, numbers: np.ndarray) -> np.ndarray:
        return self.bound(name)[numbers]

    def with_rows(self, options: Options, numbers: np.ndarray) -> np.ndarray:
        return self.with_options(options)[numbers]

    def with_pixels(self, options: Options, wanted: np.ndarray) -> np.ndarray:
        return self.with_options(options)

    def at(self, pixels: np.ndarray, fold: Fold) -> np.ndarray:
        found: np.ndarray = self.passes(["object"], None)["object"].reshape(-1)[pixels]
        there: dict[str, np.ndarray] = {}
        for k, kind in enumerate(self.lights):
            if kind != "ambient":
                own = self.passes(["diffuse", "specular"], k)
                there |= {f"{term}:{k}": own[term].reshape(-1, 3)[pixels] for term in ("diffuse", "specular")}
        fold(0, there)
        return found

    def unchanged(self, name: str) -> bool:
        return False
