"""Ray offsets as a student writes them: amounts in the scene's own units, the ladders of them rendered, words.

A student's tracer starts its shadow and secondary rays a little off the surface: along the normal (``p +
0.001·n``) or by a t_min (hits nearer than 0.001 ignored).  Which amounts leave an image as the format's is
measured against the scene's *visible size* (:mod:`tracer.exact.visible`: the view's height where the picture's
surfaces lie), never its bounding box, which a ground sphere of radius 1000 or a far sphere out of view makes
thousands of times too large.

An offset is rendered at a *ladder* of amounts: the round numbers a course writes (1, 2, 3 and 5 × 10ᵏ,
0.001, 0.003, 0.01...) from a fiftieth of the ladder's top up to the top itself.  An amount between two rungs
lies between their renders: an image within the range of two neighbouring rungs (or of the reference and the
lowest) is said as the amount of the one it comes closer to, in scene units ("a ray offset of 0.003 along
the normal").
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

from tracer import Renderer
from tracer.scene.variants import ACCEPTED_KINDS, Options

from ..render.scenekey import scene_key

#: the leading digits of the round amounts a ladder holds, by kind: a t_min changes an image far less than an
#: offset along the normal does (it only skips what lies nearer than it), so its ladder's rungs are further apart
ROUND = {"normal-offset": (1, 2, 3, 5), "t-min": (1, 3)}
#: a ladder goes down to its top over this; smaller amounts lie between its lowest rung and the reference
SPAN = 50


def round_amounts(low: float, high: float, digits: tuple[int, ...] = ROUND["normal-offset"]) -> list[float]:
    """The round amounts (``digits`` × 10ᵏ) in ``[low, high)``, ascending, each the nearest float to its decimal
    (``0.003``, not ``3 × 0.001``)."""
    if not 0 < low < high < math.inf:
        return []
    out = []
    for k in range(math.floor(math.log10(low)) - 1, math.ceil(math.log10(high)) + 1):
        for digit in digits:
            value = float(f"{digit}e{k}")
            if low <= value < high:
                out.append(value)
    return sorted(out)


def amount_words(amount: float) -> str:
    """An amount as a course writes it: ``0.003``, ``0.024``, ``1e-4``, ``2.5e-5`` (at most two significant
    digits, a power of ten below 10⁻³)."""
    text = f"{amount:.2g}"
    if "e" in text:
        mantissa, exponent = text.split("e")
        return f"{mantissa}e{int(exponent)}"
    return text


@dataclass(frozen=True)
class Rung:
    """One offset rendered: its amount in the scene's units, how it is applied, and the render's options."""

    kind: str  # a name of tracer.scene.variants.ACCEPTED_KINDS: "normal-offset" or "t-min"
    amount: float  # in the scene's units
    options: Options  # the render's (its offset relative to the visible size)

    @property
    def words(self) -> str:
        """``a ray offset of 0.003 along the normal``, ``a t_min of 0.01``."""
        return offset_words(self.kind, self.amount)


def offset_words(kind: str, amount: float) -> str:
    if kind == "t-min":
        return f"a t_min of {amount_words(amount)}"
    return f"a ray offset of {amount_words(amount)} along the normal"


def rung(kind: str, amount: float, size: float) -> Rung:
    """The render of ``amount`` (scene units) of offset ``kind`` in a scene of visible size ``size``."""
    along = ACCEPTED_KINDS[kind][0]
    return Rung(kind, amount, Options(offset=amount / size, offset_along=along))


def ladder(kind: str, top: float, size: float, low: float | None = None) -> list[Rung]:
    """The rungs of offset ``kind`` up to ``top`` (scene units), ascending: the round amounts from ``low``
    (default ``top`` / :data:`SPAN`) up to ``top`` (none within a tenth of it), and ``top`` itself; none for a top
    of 0."""
    if not top > 0:
        return []
    amounts = round_amounts(top / SPAN if low is None else low, top / 1.1, ROUND[kind])
    return [rung(kind, a, size) for a in [*amounts, top]]


#: a range of two neighbouring amounts that does not hold an image whole is looked into at this many amounts, on
#: a few rows, :data:`ROUNDS` times: an offset moves a glass ball's refractions from one amount to the next in
#: ways no range of two amounts a factor of two apart holds (a pixel goes from light to dark and back)
POINTS = 6
ROUNDS = 2


def narrowed(off: Callable[[float], tuple[int, ...]], low: float, high: float) -> list[float]:
    """Within the range ``(low, high)`` of amounts (``low`` 0: the reference), the amount of :data:`POINTS`, evenly
    spaced (in the logarithm, or from the reference in the amount), whose render leaves the fewest pixels off on
    a few rows, and among equals the nearest (``off``: the count, and the sum of the pixels' nearby distances),
    with the points either side of it; again within those, :data:`ROUNDS` times in all.  Ascending, the
    reference as 0."""
    chosen = [low, high]
    for _ in range(ROUNDS):
        low, high = chosen[0], chosen[-1]
        if low > 0:
            points = [low * (high / low) ** (k / (POINTS - 1)) for k in range(POINTS)]
        else:
            points = [high * k / (POINTS - 1) for k in range(POINTS)]
        best = min(range(POINTS), key=lambda k: off(points[k]))
        chosen = points[max(best - 1, 0) : best + 2]
    return chosen


class _Sizes:
    """The visible sizes of the last few scenes, by scene key (each costs a render's preparation)."""

    def __init__(self, kept: int = 16) -> None:
        self.kept = kept
        self.held: dict[str, float] = {}
        self.lock = threading.Lock()

    def of(self, scene: object, key: str) -> float:
        with self.lock:
            if key in self.held:
                return self.held[key]

        size = Renderer(scene).visible_size()  # type: ignore[arg-type]
        with self.lock:
            self.held[key] = size
            while len(self.held) > self.kept:
                self.held.pop(next(iter(self.held)))
        return size


SIZES = _Sizes()


def visible_size(scene: object, key: str | None = None) -> float:
    """The scene's visible size (:meth:`tracer.Renderer.visible_size`), kept by scene key."""
    if key is None:
        key = scene_key(scene)  # type: ignore[arg-type]
    return SIZES.of(scene, key)
