"""The renders a diagnosis needs, made from a scene when first asked for (:func:`renders_of`), and kept for the
last few scenes diagnosed (:class:`Cached`)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from tracer.passes import ADDITIVE, LIGHT_TERMS
from tracer.variants import BOUNDS, REFERENCE, VARIANTS, Options, unchanged

from .fit import FIT_BLOCK_PIXELS
from .renders import Renders

if TYPE_CHECKING:
    from tracer import Renderer
    from tracer.render import Fold


#: the variants made from the reference's own linear colour, with no render of their own
DERIVED = ("gamma", "image-flipped")
#: the whole image's passes (every light's terms included) are kept for the scene's later diagnoses when they
#: take at most this; a larger scene's fit and lights are rendered again for each, folded as they come
WHOLE_PASSES_BYTES = 64 << 20


def renders_of(scene: Any, threads: int | None = None) -> Renders:
    """:class:`Renders` of a validated scene, rendered here when first asked for; its ``cancel()`` true stops a
    render with :class:`tracer.RenderCancelled`.

    One render gives every pass, every light's terms and the image's linear colour
    (:meth:`tracer.Renderer.diagnosis_passes`); from that colour come, exactly as their own renders would make
    them, the gamma variant (each pixel's colour to the power 1/2.2, then stored) and the flipped image, and
    the reference itself stands for every variant the scene cannot show (:func:`tracer.variants.unchanged`).
    Only the other variants are rendered, each once.

    That render is made only when something needs the whole image's passes (a fit of the terms, a variant
    made from the colour).  Until then the passes of the failing pixels come alone (``at``), at most the
    image's worth of them in all, and the gamma and flipped variants are rendered, first a few rows of
    them, like any other: the same pixels either way."""
    from tracer import Renderer
    from tracer.image import quantize

    variants: dict[str, np.ndarray] = {}
    bounds: dict[str, np.ndarray] = {}
    made: dict[str, dict[str, np.ndarray]] = {}
    last = threading.local()  # per thread, the last scene prepared and its options
    asked = threading.local()  # per thread, the cancel of the diagnosis it runs (these renders may be shared)

    def polled() -> Callable[[], bool] | None:
        mine: Callable[[], bool] | None = getattr(asked, "cancel", None)
        return mine if mine is not None else out.cancel

    def cancel_in_thread(cancel: Callable[[], bool] | None) -> None:
        asked.cancel = cancel

    def done() -> None:
        last.__dict__.clear()
        asked.__dict__.clear()

    def prepared(options: Options) -> Renderer:
        # a variant's first look, its second and its whole render come one after another: one preparation of
        # the scene (its world, its Embree scene) serves them all.  One per thread, and only the last: threads
        # share no renderer; and none is held once a diagnosis is over, cancelled or not (``done``)
        if getattr(last, "options", None) != options:
            last.__dict__.clear()  # (the last one let go of before the next is built)
            last.renderer = Renderer(scene, options)
            last.options = options
        renderer: Renderer = last.renderer
        return renderer

    height, width, total = scene.image.height, scene.image.width, scene.image.width * scene.image.height
    shining = sum(light.type != "ambient" for light in scene.lights)
    #: whether the whole image's passes, every light's terms included, are small enough to keep (then one render
    #: serves every later fit of the scene); else each fit renders them again, folded as they come
    whole = total * 3 * 8 * (len(ADDITIVE) + 2 + 2 * shining) <= WHOLE_PASSES_BYTES

    def passes() -> dict[str, np.ndarray]:  # the whole image's passes, held (a scene small enough, or no blocks)
        if "all" not in made:
            out.check()
            made["all"] = prepared(REFERENCE).diagnosis_passes(threads=threads, cancel=polled())
        return made["all"]

    def images() -> dict[str, np.ndarray]:
        """The reference's pixels from its linear colour, and its gamma variant: from the passes held, or from a
        render folded as it comes (all it keeps are these)."""
        if "images" not in made:
            if whole or "all" in made:
                colour = passes()["colour"]
                made["images"] = {"reference": quantize(colour),
                                  "gamma": quantize(np.clip(colour, 0.0, None) ** (1.0 / 2.2))}
            else:
                folded(None)
        return made["images"]

    def folded(fold: Fold | None) -> None:
        """A render of the whole image's passes, each chunk to ``fold`` and to the reference's images."""
        out.check()
        mine = "images" not in made
        reference, gamma = (np.empty((total, 3), dtype=np.uint8) for _ in range(2))

        def each(first: int, part: dict[str, np.ndarray]) -> None:
            if mine:  # as Renderer.pixels stores each chunk's colour (and a gamma variant's)
                reference[first:first + len(part["colour"])] = quantize(part["colour"])
                gamma[first:first + len(part["colour"])] = quantize(np.clip(part["colour"], 0.0, None) ** (1.0 / 2.2))
            if fold is not None:
                fold(first, part)

        prepared(REFERENCE).diagnosis_passes(threads=threads, cancel=polled(), fold=each)
        if mine:
            made["images"] = {"reference": reference.reshape(height, width, 3),
                              "gamma": gamma.reshape(height, width, 3)}

    def blocks(fold: Fold) -> None:
        if not whole:
            folded(fold)
            return
        every = passes()
        for first in range(0, total, FIT_BLOCK_PIXELS):
            fold(first, {name: plane.reshape(total, -1)[first:first + FIT_BLOCK_PIXELS]
                         for name, plane in every.items() if name not in ("object", "colour")})

    def made_whole() -> bool:  # the reference's images are at hand, without a render
        return "images" in made or "all" in made

    def variant(name: str) -> np.ndarray:
        if name not in variants:
            if name == "gamma" and made_whole():  # as Renderer.pixels stores a gamma variant's chunk colour
                variants[name] = images()["gamma"]
                kept.pop(name, None)
            elif name == "image-flipped" and made_whole():  # the reference's rows, bottom to top
                variants[name] = images()["reference"][::-1]
                kept.pop(name, None)
            elif unchanged(name, scene):
                variants[name] = images()["reference"]
            elif name in kept:  # the rows not yet rendered
                rows(name, np.arange(height))
            else:
                variants[name] = prepared(VARIANTS[name][0]).pixels(threads=threads, cancel=polled())
        return variants[name]

    #: per variant (and per far end), its rows rendered so far, until it is whole
    kept: dict[str, dict[int, np.ndarray]] = {}
    guard = threading.Lock()

    def kept_rows(key: str, name: str, options: Options, whole: dict[str, np.ndarray],
                  numbers: np.ndarray) -> np.ndarray:
        # a render's rows are kept as they come (first looks, bands), under ``key``, and are not rendered again:
        # once every row has come, they are its whole image, ``whole[name]``
        with guard:
            if name in whole:
                return whole[name][numbers]
            have = dict(kept.get(key, {}))
        todo = np.array(sorted(set(numbers.tolist()) - set(have)), dtype=np.int64)
        if len(todo):
            fresh = prepared(options).pixels_of_rows(todo, threads=threads, cancel=polled())
            with guard:
                if name in whole:  # (made whole meanwhile, in another thread)
                    return whole[name][numbers]
                mine = kept.setdefault(key, {})
                mine.update(zip(todo.tolist(), fresh))
                have = dict(mine)
                if len(mine) == height:
                    whole[name] = np.stack([mine[r] for r in range(height)])
                    kept.pop(key)
        return np.stack([have[r] for r in numbers.tolist()])

    def rows(name: str, numbers: np.ndarray) -> np.ndarray:
        if name in variants or (name in DERIVED and made_whole()) or unchanged(name, scene):
            return variant(name)[numbers]
        return kept_rows(name, name, VARIANTS[name][0], variants, numbers)

    def bound(name: str) -> np.ndarray:
        if name not in bounds:
            if unchanged(name, scene):
                bounds[name] = images()["reference"]
            elif "bound:" + name in kept:  # the rows not yet rendered
                bound_rows(name, np.arange(height))
            else:
                bounds[name] = prepared(BOUNDS[name]).pixels(threads=threads, cancel=polled())
        return bounds[name]

    def bound_rows(name: str, numbers: np.ndarray) -> np.ndarray:
        if name in bounds or unchanged(name, scene):
            return bound(name)[numbers]
        return kept_rows("bound:" + name, name, BOUNDS[name], bounds, numbers)

    spent = [0]  # pixels whose passes were rendered alone so far

    def at(pixels: np.ndarray, fold: Fold) -> np.ndarray:
        # pixels alone while they add up to at most the image (a scene diagnosed once renders only its failing
        # pixels); past that, the whole image once, and kept, when it is small enough to keep
        if "all" in made or (whole and spent[0] + len(pixels) > total):
            rows, cols = np.divmod(pixels, width)
            there = {name: plane[rows, cols] for name, plane in passes().items() if name != "colour"}
            fold(0, there)
            return there["object"]
        spent[0] += len(pixels)
        found = np.empty(len(pixels), dtype=np.int64)

        def each(first: int, part: dict[str, np.ndarray]) -> None:
            found[first:first + len(part["object"])] = part["object"]
            fold(first, part)

        prepared(REFERENCE).diagnosis_passes(threads=threads, cancel=polled(), pixels=pixels, first_hits=True,
                                             fold=each)
        return found

    def of(names: list[str], light: int | None) -> dict[str, np.ndarray]:
        every = passes()
        return {name: every[name if light is None or name not in LIGHT_TERMS else f"{name}:{light}"]
                for name in names}

    def nbytes() -> int:
        return held_bytes([*list(variants.values()), *list(bounds.values()),
                           *(r for rows in list(kept.values()) for r in list(rows.values())),
                           *(a for planes in list(made.values()) for a in list(planes.values()))])

    out = Renders(variant, of, [light.type for light in scene.lights], [obj.type for obj in scene.objects], bound,
                  rows=rows, bound_rows=bound_rows, at=at, unchanged=lambda name: unchanged(name, scene),
                  done=done, cancel_in_thread=cancel_in_thread, blocks=blocks, nbytes=nbytes, polled=polled)
    return out


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
        return sum(r.nbytes() for r in held if r.nbytes is not None)

    def trim(self) -> None:
        """Let go of the oldest scenes until what is held fits in ``room()`` (after a diagnosis, whose renders
        have grown)."""
        if self.room is None:
            return
        while True:
            with self._lock:
                sizes = [(key, r.nbytes() if r.nbytes is not None else 0) for key, r in self.held.items()]
                if not sizes or sum(size for _, size in sizes) <= max(self.room(), 0):
                    return
                self.held.pop(sizes[0][0], None)

    def __len__(self) -> int:
        return len(self.held)


#: this process's renders for diagnosis (the CLI, each class worker; each service worker has its own, counted)
CACHE = Cached()
