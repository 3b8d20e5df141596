"""The renders of one scene its diagnoses ask for, made when first asked for and kept as they come
(:func:`renders_of`, a :class:`SceneRenders`: the :class:`.renders.Renders` of a scene)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from tracer import RenderCancelled, Renderer
from tracer.image import quantize
from tracer.scene.shown import unchanged
from tracer.scene.variants import BOUNDS, MORE_VARIANTS, REFERENCE, VARIANTS, Options
from tracer.shade.passes import ADDITIVE, LIGHT_TERMS

from .combination import on_base
from .fit import FIT_BLOCK_PIXELS
from .offsets import visible_size
from .spots import Spots
from .words import names_of

if TYPE_CHECKING:
    from tracer import Renderer
    from tracer.render import Fold


#: the variants made from the reference's own linear colour, with no render of their own
DERIVED = ("gamma", "image-flipped")
#: the whole image's passes (every light's terms included) are kept for the scene's later diagnoses when they
#: take at most this; a larger scene's fit and lights are rendered again for each, folded as they come
WHOLE_PASSES_BYTES = 64 << 20


def renders_of(
    scene: Any, threads: int | None = None, base: Options = REFERENCE, open_pixels: np.ndarray | None = None
) -> SceneRenders:
    """The :class:`.renders.Renders` of a validated scene, rendered here when first asked for; its ``cancel()``
    true stops a render with :class:`tracer.RenderCancelled`.

    One render gives every pass, every light's terms and the image's linear colour
    (:meth:`tracer.Renderer.diagnosis_passes`); from that colour come, exactly as their own renders would make
    them, the gamma variant (each pixel's colour to the power 1/2.2, then stored) and the flipped image, and
    the reference itself stands for every variant the scene cannot show (:func:`tracer.scene.shown.unchanged`).
    Only the other variants are rendered, each once.

    That render is made only when something needs the whole image's passes (a fit of the terms, a variant
    made from the colour).  Until then the passes of the failing pixels come alone (``at``), at most the
    image's worth of them in all, and the gamma and flipped variants are rendered, first a few rows of
    them, like any other: the same pixels either way.

    With ``base`` (an honest student's offset, :mod:`.nuisance`), every render is made with its offset: the
    reference is the reference as that student renders it, and each mistake is that mistake made by them; the
    pixels of ``open_pixels`` (True) are not counted against a submission."""
    return SceneRenders(scene, threads, base, open_pixels)


def options_of(name: str, size: Callable[[], float] | None = None) -> Options:
    """The options of a classic mistake (:data:`VARIANTS`) or a new one (:data:`MORE_VARIANTS`), or of a rung of an
    offset too large (``offset-too-large@0.05``: that amount in the scene's units, ``size()`` its visible size;
    ``offset-too-large@geometric@0.05`` along the geometric normal)."""
    if "@" in name:  # (``offset-too-large@geometric@0.05``: along the geometric normal)
        along, _, amount = name.split("@", 1)[1].rpartition("@")
        return Options(offset=float(amount) / (size() if size is not None else 1.0), offset_along=along or "normal")
    return VARIANTS[name][0] if name in VARIANTS else MORE_VARIANTS[name][0]


def by_options(options: Options) -> str:
    """The name a render made with ``options`` is kept under (:meth:`SceneRenders.with_rows`)."""
    return f"options:{options!r}"


class SceneRenders:
    """What :func:`renders_of` renders of one scene, and keeps: the variants and far ends whole, the rows of
    those not yet whole, and the reference's passes and images (``made``).  The :class:`.renders.Renders` of
    the scene: its methods are those the protocol describes."""

    def __init__(self, scene: Any, threads: int | None, base: Options = REFERENCE, open: np.ndarray | None = None):
        self.scene, self.threads, self.base, self.open = scene, threads, base, open
        self.cancel: Callable[[], bool] | None = None
        self.lights = [light.type for light in scene.lights]
        self.objects = [obj.type for obj in scene.objects]
        self.names = names_of(scene)
        self.samples: int = scene.image.samples
        self.visible: float | None = None
        self.variants: dict[str, np.ndarray] = {}
        self.bounds: dict[str, np.ndarray] = {}
        #: the reference's passes (``all``) and images (``images``: ``reference``, ``gamma``), once made
        self.made: dict[str, dict[str, np.ndarray]] = {}
        #: per variant (and per far end), its rows rendered so far, until it is whole
        self.kept: dict[str, dict[int, np.ndarray]] = {}
        self.spots = Spots(scene.image.height, scene.image.width)  # (rungs' pixels rendered alone, near a look's)
        self.guard = threading.Lock()
        self.last = threading.local()  # per thread, the last scene prepared and its options
        self.asked = threading.local()  # per thread, the cancel of the diagnosis it runs (these may be shared)
        self.spent = 0  # pixels whose passes were rendered alone so far
        self.height, self.width = scene.image.height, scene.image.width
        self.total = self.height * self.width
        shining = sum(light.type != "ambient" for light in scene.lights)
        #: whether the whole image's passes, every light's terms included, are small enough to keep (then one
        #: render serves every later fit of the scene); else each fit renders them again, folded as they come
        self.whole = self.total * 3 * 8 * (len(ADDITIVE) + 2 + 2 * shining) <= WHOLE_PASSES_BYTES

    # -- the diagnosis this thread runs ------------------------------------------------------------------------

    def polled(self) -> Callable[[], bool] | None:
        """The current thread's cancel (set by :meth:`cancel_in_thread`), else ``cancel``."""
        mine: Callable[[], bool] | None = getattr(self.asked, "cancel", None)
        return mine if mine is not None else self.cancel

    def check(self) -> None:
        cancel = self.polled()
        if cancel is not None and cancel():
            raise RenderCancelled("diagnosis cancelled")

    def cancel_in_thread(self, cancel: Callable[[], bool] | None) -> None:
        self.asked.cancel = cancel

    def done(self) -> None:
        self.last.__dict__.clear()
        self.asked.__dict__.clear()

    def prepared(self, options: Options) -> Renderer:
        """The scene prepared with ``options``.  A variant's first look, its second and its whole render come one
        after another: one preparation of the scene (its world, its Embree scene) serves them all.  One per
        thread, and only the last: threads share no renderer; and none is held once a diagnosis is over,
        cancelled or not (:meth:`done`)."""
        options = on_base(options, self.base)
        if getattr(self.last, "options", None) != options:
            self.last.__dict__.clear()  # (the last one let go of before the next is built)
            self.last.renderer = Renderer(self.scene, options)
            self.last.options = options
        renderer: Renderer = self.last.renderer
        return renderer

    def unchanged(self, name: str) -> bool:
        return unchanged(name.split("@", 1)[0], self.scene)

    def size(self) -> float:
        """The scene's visible size (:mod:`tracer.exact.visible`), what an offset is measured against."""
        if self.visible is None:
            self.visible = visible_size(self.scene)
        return self.visible

    # -- the reference's passes and images ---------------------------------------------------------------------

    def whole_passes(self) -> dict[str, np.ndarray]:
        """The whole image's passes, held (a scene small enough, or no blocks)."""
        if "all" not in self.made:
            self.check()
            self.made["all"] = self.prepared(REFERENCE).diagnosis_passes(threads=self.threads, cancel=self.polled())
        return self.made["all"]

    def images(self) -> dict[str, np.ndarray]:
        """The reference's pixels from its linear colour, and its gamma variant: from the passes held, or from a
        render folded as it comes (all it keeps are these)."""
        if "images" not in self.made:
            if self.whole or "all" in self.made:
                colour = self.whole_passes()["colour"]
                self.made["images"] = {
                    "reference": quantize(colour),
                    "gamma": quantize(np.clip(colour, 0.0, None) ** (1.0 / 2.2)),
                }
            else:
                self.folded(None)
        return self.made["images"]

    def folded(self, fold: Fold | None) -> None:
        """A render of the whole image's passes, each chunk to ``fold`` and to the reference's images."""
        self.check()
        mine = "images" not in self.made
        reference, gamma = (np.empty((self.total, 3), dtype=np.uint8) for _ in range(2))

        def each(first: int, part: dict[str, np.ndarray]) -> None:
            if mine:  # as Renderer.pixels stores each chunk's colour (and a gamma variant's)
                reference[first : first + len(part["colour"])] = quantize(part["colour"])
                gamma[first : first + len(part["colour"])] = quantize(np.clip(part["colour"], 0.0, None) ** (1.0 / 2.2))
            if fold is not None:
                fold(first, part)

        self.prepared(REFERENCE).diagnosis_passes(threads=self.threads, cancel=self.polled(), fold=each)
        if mine:
            self.made["images"] = {
                "reference": reference.reshape(self.height, self.width, 3),
                "gamma": gamma.reshape(self.height, self.width, 3),
            }

    def blocks(self, fold: Fold) -> None:
        if not self.whole:
            self.folded(fold)
            return
        every, total = self.whole_passes(), self.total
        for first in range(0, total, FIT_BLOCK_PIXELS):
            fold(
                first,
                {
                    name: plane.reshape(total, -1)[first : first + FIT_BLOCK_PIXELS]
                    for name, plane in every.items()
                    if name not in ("object", "colour")
                },
            )

    def made_whole(self) -> bool:
        """Whether the reference's images are at hand, without a render."""
        return "images" in self.made or "all" in self.made

    def at(self, pixels: np.ndarray, fold: Fold) -> np.ndarray:
        """Pixels alone while they add up to at most the image (a scene diagnosed once renders only its failing
        pixels); past that, the whole image once, and kept, when it is small enough to keep."""
        if "all" in self.made or (self.whole and self.spent + len(pixels) > self.total):
            rows, cols = np.divmod(pixels, self.width)
            there = {name: plane[rows, cols] for name, plane in self.whole_passes().items() if name != "colour"}
            fold(0, there)
            return there["object"]
        self.spent += len(pixels)
        found = np.empty(len(pixels), dtype=np.int64)

        def each(first: int, part: dict[str, np.ndarray]) -> None:
            found[first : first + len(part["object"])] = part["object"]
            fold(first, part)

        self.prepared(REFERENCE).diagnosis_passes(
            threads=self.threads, cancel=self.polled(), pixels=pixels, first_hits=True, fold=each
        )
        return found

    def passes(self, names: list[str], light: int | None) -> dict[str, np.ndarray]:
        every = self.whole_passes()
        return {name: every[name if light is None or name not in LIGHT_TERMS else f"{name}:{light}"] for name in names}

    # -- the variants and the far ends -------------------------------------------------------------------------

    def variant(self, name: str) -> np.ndarray:
        return self._variant(name)

    def _variant(self, name: str) -> np.ndarray:
        """Variant ``name`` whole (what :meth:`variant` gives, and :meth:`rows` once it is whole)."""
        variants = self.variants
        if name not in variants:
            if name == "gamma" and self.made_whole():  # as Renderer.pixels stores a gamma variant's chunk colour
                variants[name] = self.images()["gamma"]
                self.kept.pop(name, None)
            elif name == "image-flipped" and self.made_whole():  # the reference's rows, bottom to top
                variants[name] = self.images()["reference"][::-1]
                self.kept.pop(name, None)
            elif self.unchanged(name):
                variants[name] = self.images()["reference"]
            elif "@" in name:  # (a rung of an offset too large, under its options)
                variants[name] = self.with_options(options_of(name, self.size))
            elif name in self.kept:  # the rows not yet rendered
                self.rows(name, np.arange(self.height))
            else:
                variants[name] = self.prepared(options_of(name, self.size)).pixels(
                    threads=self.threads, cancel=self.polled()
                )
        return variants[name]

    def kept_rows(
        self, key: str, name: str, options: Options, wholes: dict[str, np.ndarray], numbers: np.ndarray
    ) -> np.ndarray:
        """Rows ``numbers`` of a render: its rows are kept as they come (first looks, bands), under ``key``, and
        are not rendered again (nor its pixels rendered alone, :meth:`with_pixels`); once every row has come, they
        are its whole image, ``wholes[name]``."""
        with self.guard:
            if name in wholes:
                return wholes[name][numbers]
            have = dict(self.kept.get(key, {}))
        todo = np.array(sorted(set(numbers.tolist()) - set(have)), dtype=np.int64)
        if len(todo):
            fresh = self.spots.rows(key, todo, self.renderer_of(options)) if self.spots.has(key) else None
            if fresh is None:
                fresh = self.prepared(options).pixels_of_rows(todo, threads=self.threads, cancel=self.polled())
            with self.guard:
                if name in wholes:  # (made whole meanwhile, in another thread)
                    return wholes[name][numbers]
                mine = self.kept.setdefault(key, {})
                mine.update(zip(todo.tolist(), fresh))
                have = dict(mine)
                if len(mine) == self.height:
                    wholes[name] = np.stack([mine[r] for r in range(self.height)])
                    self.kept.pop(key)
                    self.spots.drop(key)
        return np.stack([have[r] for r in numbers.tolist()])

    def renderer_of(self, options: Options) -> Callable[[np.ndarray], np.ndarray]:
        """What renders pixel numbers with ``options`` (:meth:`tracer.Renderer.pixels_at`)."""
        return lambda pixels: self.prepared(options).pixels_at(pixels, threads=self.threads, cancel=self.polled())

    def rows(self, name: str, numbers: np.ndarray) -> np.ndarray:
        """Rows of a classic mistake's render (:data:`VARIANTS`), or of a new one's (:data:`MORE_VARIANTS`), kept; a
        rung of an offset too large's under its options (:meth:`with_rows`)."""
        if name in self.variants or (name in DERIVED and self.made_whole()) or self.unchanged(name):
            return self._variant(name)[numbers]
        if "@" in name:
            return self.with_rows(options_of(name, self.size), numbers)
        return self.kept_rows(name, name, options_of(name, self.size), self.variants, numbers)

    # -- renders by their options: the rungs of the ladders of offsets --------------------------------------------

    def with_rows(self, options: Options, numbers: np.ndarray) -> np.ndarray:
        """Rows ``numbers`` of the scene rendered with ``options`` (a rung of an accepted offset's ladder, or of an
        offset too large's: :mod:`.accepting` and :mod:`.too_large` ask for the same rung under its options, and it
        is rendered once), kept with the scene's other renders, in its budget."""
        key = by_options(options)
        with self.guard:
            if key in self.variants:
                return self.variants[key][numbers]
        return self.kept_rows(key, key, options, self.variants, numbers)

    def with_options(self, options: Options) -> np.ndarray:
        """The whole image rendered with ``options``, kept as :meth:`with_rows` keeps its rows (those rendered
        already are not rendered again)."""
        key = by_options(options)
        if key not in self.variants:
            if key in self.kept or self.spots.has(key):
                self.with_rows(options, np.arange(self.height))
            else:
                self.variants[key] = self.prepared(options).pixels(threads=self.threads, cancel=self.polled())
        return self.variants[key]

    def with_pixels(self, options: Options, wanted: np.ndarray) -> np.ndarray:
        """The scene rendered with ``options`` where ``wanted`` (``(H, W)`` bool) is True, as ``(H, W, 3)`` (the
        other pixels unset): those pixels alone are rendered (:meth:`tracer.Renderer.pixels_at`, the very bytes
        of the whole image's), and kept for its rows and whole image (:class:`.spots.Spots`)."""
        key = by_options(options)
        with self.guard:
            if key in self.variants:
                return self.variants[key]
            rows = dict(self.kept.get(key, {}))
        return self.spots.pixels(key, wanted, self.renderer_of(options), rows)

    def holds(self, options: Options) -> bool:
        """Whether the whole image with ``options`` is at hand, without a render."""
        return by_options(options) in self.variants

    def render(self, options: Options) -> np.ndarray:
        """The whole image with ``options`` (mistakes made together): rendered each time it is asked for (a
        combination is confirmed once per diagnosis, and rarely the same twice)."""
        return self.prepared(options).pixels(threads=self.threads, cancel=self.polled())

    def bound(self, name: str) -> np.ndarray:
        return self._bound(name)

    def _bound(self, name: str) -> np.ndarray:
        """The far end ``name`` whole (what :meth:`bound` gives, and :meth:`bound_rows` once it is whole)."""
        if name not in self.bounds:
            if self.unchanged(name):
                self.bounds[name] = self.images()["reference"]
            elif "bound:" + name in self.kept:  # the rows not yet rendered
                self.bound_rows(name, np.arange(self.height))
            else:
                self.bounds[name] = self.prepared(BOUNDS[name]).pixels(threads=self.threads, cancel=self.polled())
        return self.bounds[name]

    def bound_rows(self, name: str, numbers: np.ndarray) -> np.ndarray:
        if name in self.bounds or self.unchanged(name):
            return self._bound(name)[numbers]
        return self.kept_rows("bound:" + name, name, BOUNDS[name], self.bounds, numbers)

    def nbytes(self) -> int:
        return held_bytes(
            [
                *list(self.variants.values()),
                *list(self.bounds.values()),
                *(r for rows in list(self.kept.values()) for r in list(rows.values())),
                *self.spots.arrays(),
                *(a for planes in list(self.made.values()) for a in list(planes.values())),
            ]
        )


#: the most renders a diagnosis may need: the variants the scene can show (gamma and the flipped image too, when
#: the pass render is not there to make them from), a speckled mistake's far end in place of the mistake itself,
#: the failing pixels' first hits, and one render for every pass.  Most diagnoses need far fewer: a first look at
#: a few rows of a variant (:func:`off_at_least`) or a band of it (:func:`whole_unless_off`) may spare the rest
def renders_needed(scene: Any) -> int:
    shown = [name for name in [*(v for v in VARIANTS if v not in BOUNDS), *BOUNDS] if not unchanged(name, scene)]
    return len(shown) + 2


def held_bytes(arrays: list[np.ndarray]) -> int:
    """The bytes of the memory ``arrays`` hold, each buffer once (a view counts as its base)."""
    roots: dict[int, int] = {}
    for a in arrays:
        while isinstance(a.base, np.ndarray):
            a = a.base
        roots[id(a)] = a.nbytes
    return sum(roots.values())
