"""Render passes: the image taken apart, term by term, for a student who debugs a tracer stage by stage.

The additive passes are linear colours, each the mean over a pixel's
sub-samples before any clamp, and they sum to the image's linear value:

* ``background``: camera rays that hit nothing;
* ``ambient``, ``diffuse``, ``specular``: the Phong terms at the first hit
  (with ``light=K``, diffuse and specular of the scene's light K alone);
* ``reflection``, ``refraction``: everything the mirror ray and the
  refracted ray of the first hit bring back, whole trees included.

The others are for debugging: ``shadow``, the fraction of a light's samples
(light K, or every light) that reach the first hit and face it; ``normal``,
the facing shading normal there (each component in −1..1); ``depth``, the
distance t along the camera ray (inf for a miss); ``object``, the index in
``scene.objects`` of what the sub-sample nearest the pixel's centre hits
(−1 for nothing).

Sums are fixed-point integers, as the image's are (:func:`tracer.render`), so
a pass does not depend on threads or chunks either; a pass saturates at
:data:`CEILING` per pixel.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..scene.rays import Hits, Work
from ..scene.vec import scaled

ADDITIVE = ("background", "ambient", "diffuse", "specular", "reflection", "refraction")
DEBUG = ("shadow", "normal", "depth", "object")
NAMES = ADDITIVE + DEBUG
#: the additive passes that belong to a light
LIGHT_TERMS = ("diffuse", "specular")
#: where an additive pass saturates, per pixel (the image itself saturates at 1)
CEILING = 1024.0
#: the ray-tree branches a contribution comes from: the first hit, its mirror ray, its refracted ray
FIRST, REFLECTED, REFRACTED = 0, 1, 2
BRANCH_PASS = {FIRST: None, REFLECTED: "reflection", REFRACTED: "refraction"}


#: an observer of how many emitters reach each point and face it: called per emitter with a
#: :class:`tracer.shade.kernel.Reach`'s ``weight`` (after the shadows) and ``facing``, and the rows among the points
#: shaded that they are of (None: all of them, in order)
Seen = Callable[[np.ndarray, np.ndarray, "np.ndarray | None"], None]


def unseen(weight: np.ndarray, facing: np.ndarray, rows: np.ndarray | None) -> None:
    """The observer that counts nothing."""


def check_passes(names: list[str], light: int | None, lights: int) -> None:
    """Raises ValueError naming what is wrong with asking for passes ``names`` of light ``light`` (None for
    every light) of a scene with ``lights`` lights."""
    for name in names:
        if name not in NAMES:
            raise ValueError(f"pass: unknown pass '{name}' (one of {', '.join(NAMES)})")
    if light is not None and not 0 <= light < lights:
        raise ValueError(f"light: the scene has {lights} lights (0..{lights - 1}), not {light}")


@dataclass
class Tally:
    """What one chunk adds up for the passes asked for: fixed-point sums per sub-sample."""

    names: tuple[str, ...]
    samples: int  # sub-samples in the chunk
    per_pixel: int  # sub-samples per pixel
    light: int | None  # the scene light the light-specific passes are of
    emitter_light: np.ndarray  # (E,) int: the scene light each emitter comes from
    fixed: float = 2.0**30
    #: keep diffuse and specular apart for every scene light, as ``diffuse:K`` and ``specular:K`` (one render
    #: for every light's terms, :meth:`tracer.render.Renderer.diagnosis_passes`)
    by_light: bool = False
    colour: np.ndarray | None = None  # (pixels, 3) the chunk's linear colour, when asked for (by_light)
    sums: dict[str, np.ndarray] = field(default_factory=dict)
    visible: np.ndarray | None = None  # (samples,) reached-and-facing samples of the light(s)
    normal: np.ndarray | None = None  # (samples, 3)
    depth: np.ndarray | None = None  # (samples,)
    object: np.ndarray | None = None  # (samples,) int

    def __post_init__(self) -> None:
        for name in self.names:
            if name in ADDITIVE and not (self.by_light and name in LIGHT_TERMS):
                self.sums[name] = np.zeros((3, self.samples), dtype=np.int64)
        if self.by_light:
            for k in sorted(set(self.emitter_light.tolist())):
                for name in LIGHT_TERMS:
                    if name in self.names:
                        self.sums[f"{name}:{k}"] = np.zeros((3, self.samples), dtype=np.int64)
        if "shadow" in self.names:
            self.visible = np.zeros(self.samples)
        if "normal" in self.names:
            self.normal = np.zeros((self.samples, 3))
        if "depth" in self.names:
            self.depth = np.full(self.samples, np.inf)
        if "object" in self.names:
            self.object = np.full(self.samples, -1, dtype=np.int64)

    def counts(self, emitter: int) -> bool:
        """Whether the light-specific passes count this emitter."""
        return self.light is None or int(self.emitter_light[emitter]) == self.light

    def term(self, name: str, emitter: int) -> str:
        """The pass a light-specific term of this emitter goes to: ``name``, or ``name:K`` by light."""
        return f"{name}:{int(self.emitter_light[emitter])}" if self.by_light else name

    def add(self, name: str, sample: np.ndarray, values: np.ndarray) -> None:
        """Add linear colours ``values (n, 3)`` to pass ``name`` at sub-samples ``sample`` (which may repeat).

        A value is clamped to 0..CEILING per sub-sample of a pixel (NaN as 0, +∞ as CEILING), then added as a
        fixed-point integer, a channel at a time (each channel's sums lie in one contiguous row): integer sums,
        the same in any order."""
        acc = self.sums.get(name)
        if acc is None or len(sample) == 0:
            return
        v = np.fmax(values, 0.0)  # (NaN and −∞ to 0)
        np.copyto(v, CEILING, where=v == np.inf)
        np.minimum(v, CEILING * self.per_pixel, out=v)
        v *= self.fixed
        units = np.rint(v, out=v).astype(np.int64)
        for k in range(3):
            np.add.at(acc[k], sample, units[:, k])

    def result(self, shape: tuple[int, int], samples_of_light: int) -> dict[str, np.ndarray]:
        """Per pixel, over ``shape = (pixels, sub-samples per pixel)``: every pass asked for."""
        n, s = shape
        out: dict[str, np.ndarray] = {}
        sums = dict(self.sums)
        for name in LIGHT_TERMS if self.by_light else ():  # every light's, from the exact sums of each
            parts = [acc for key, acc in self.sums.items() if key.startswith(name + ":")]
            if name in self.names:
                sums[name] = sum(parts[1:], parts[0].copy()) if parts else np.zeros((3, self.samples), np.int64)
        starts = np.arange(0, n * s, s)
        for name, acc in sums.items():
            # each pixel's sub-samples summed in integers (exact, in any order): reduceat over runs of ``s``
            per_pixel = (acc if s == 1 else np.add.reduceat(acc, starts, axis=1) if n else acc[:, :0]).T
            out[name] = np.minimum(per_pixel.astype(np.float64) / (self.fixed * s), CEILING)
        if self.colour is not None:
            out["colour"] = self.colour
        if self.visible is not None:
            out["shadow"] = self.visible.reshape(n, s).mean(axis=1) / max(samples_of_light, 1)
        if self.normal is not None:
            out["normal"] = self.normal.reshape(n, s, 3).mean(axis=1)
        if self.depth is not None:
            out["depth"] = self.depth.reshape(n, s).mean(axis=1)
        if self.object is not None:
            side = int(round(s**0.5))
            out["object"] = self.object.reshape(n, s)[:, (side // 2) * side + side // 2]
        return out


class Observer:
    """What the stages of a render tell the passes; this one notes nothing (a render without passes).  Every
    stage calls it unconditionally: the passes are an observer of the render, not a branch of its stages."""

    def missed(self, missed: np.ndarray, background: np.ndarray) -> None:
        """The rays ``missed`` (bool, of the work batch) bring back the ``background``."""

    def first_hits(self, hit: Hits, owners: dict[int, np.ndarray], normal: np.ndarray) -> None:
        """The camera rays' first hits (only the rays that hit), with the shading ``normal`` there; ``owners``:
        the object of each surface, by kind."""

    def ambient(self, colour: np.ndarray) -> None:
        """The ambient term of the hit points (only the rays that hit)."""

    def seen(self, emitter: int) -> Seen:
        """The observer of how many of this light's emitters (its first: ``emitter``) reach each point."""
        return unseen

    def light(
        self,
        emitter: int,
        color: np.ndarray,
        diffuse: np.ndarray,
        specular: np.ndarray,
        terms: tuple[np.ndarray, np.ndarray],
    ) -> None:
        """A light's (its first emitter: ``emitter``) terms ``Σwd, Σws``, of colour ``color``, at points of
        ``k_d = diffuse`` and ``k_s = specular``."""

    def shaded(self, colour: np.ndarray) -> None:
        """The direct light of the hit points, whole."""


#: the observer that notes nothing
UNOBSERVED = Observer()


class PassObserver(Observer):
    """The passes of one work batch of a chunk (:class:`tracer.scene.rays.Work`): each stage's contributions to the
    ``tally``, at the batch's sub-samples and weights; the light's terms only at the first hit."""

    def __init__(self, tally: Tally, work: Work):
        self.tally, self.work = tally, work
        self.first = work.depth == 0

    def missed(self, missed: np.ndarray, background: np.ndarray) -> None:
        work, tally = self.work, self.tally
        rows = np.flatnonzero(missed)
        if len(rows) == 0:
            return
        if self.first:
            tally.add("background", work.sample[rows], work.weight[rows, None] * background)
            return
        assert work.branch is not None
        for branch, name in BRANCH_PASS.items():
            sel = rows[work.branch[rows] == branch]
            if name is not None:
                tally.add(name, work.sample[sel], work.weight[sel, None] * background)

    def first_hits(self, hit: Hits, owners: dict[int, np.ndarray], normal: np.ndarray) -> None:
        tally, sample = self.tally, self.work.sample
        if tally.normal is not None:
            tally.normal[sample] = normal
        if tally.depth is not None:
            tally.depth[sample] = hit.t
        if tally.object is not None:
            for kind, owner in owners.items():
                sel = np.flatnonzero(hit.kind == kind)
                tally.object[sample[sel]] = owner[hit.index[sel]]

    def ambient(self, colour: np.ndarray) -> None:
        if self.first:
            self.tally.add("ambient", self.work.sample, scaled(colour, self.work.weight))

    def seen(self, emitter: int) -> Seen:
        visible = self.tally.visible
        if not self.first or visible is None or not self.tally.counts(emitter):
            return unseen
        sample = self.work.sample

        def count(weight: np.ndarray, facing: np.ndarray, rows: np.ndarray | None) -> None:
            assert visible is not None
            np.add.at(visible, sample if rows is None else sample[rows], (weight > 0) & facing)

        return count

    def light(
        self,
        emitter: int,
        color: np.ndarray,
        diffuse: np.ndarray,
        specular: np.ndarray,
        terms: tuple[np.ndarray, np.ndarray],
    ) -> None:
        tally, work = self.tally, self.work
        if not self.first or not tally.counts(emitter):
            return
        wd, ws = terms
        tally.add(tally.term("diffuse", emitter), work.sample, scaled(color * scaled(diffuse, wd), work.weight))
        tally.add(tally.term("specular", emitter), work.sample, scaled(color * scaled(specular, ws), work.weight))

    def shaded(self, colour: np.ndarray) -> None:
        work = self.work
        if work.branch is None or self.first:
            return
        for branch, name in BRANCH_PASS.items():
            sel = np.flatnonzero(work.branch == branch)
            if name is not None and len(sel):
                self.tally.add(name, work.sample[sel], scaled(colour[sel], work.weight[sel]))
