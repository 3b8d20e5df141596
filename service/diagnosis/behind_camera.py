"""A mistake behind a camera mistake: the camera's mistake made the reference, so that the other keeps its name.

A student whose camera is wrong (the fov taken across the image's width, pixel centres without the +0.5) sees
every object from a little elsewhere: each pixel shows another point of the scene.  What a second mistake
changes (no shadow rays, say) then falls on other pixels than in the reference, so its difference, measured on
the reference's pixels, does not add to the camera's (:mod:`.compose`'s rows), and the diagnosis finds the
camera's mistake only as the closest ("fov taken as horizontal — comes closest, 11 % of pixels off").

So where the diagnosis names a camera mistake (:data:`CAMERA`) and nothing passes, the diagnosis is made again
with that mistake as the student's own way of rendering (the renders' ``base``, :func:`.rendered.on_base`): the
reference is the scene as that camera sees it, and each mistake is that mistake made by the same camera.  A
mistake the submission passes against there is named with the camera's, as mistakes made together, graded as
that whole diagnosis grades it: every reading it gives is kept.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from schemas import Scene
from tracer.scene.variants import VARIANTS

from ..images.grading import grade
from ..images.nearby import rows_distance
from .accepting import Failing
from .cache import Cached
from .causes import diagnose
from .combination import ALL, Combination, Member, compatible, merged
from .looks import sampled_rows
from .records import Diagnosis
from .rendered import renders_of
from .renders import Renders
from .together import together_causes

#: the mistakes of the camera: each moves what every pixel shows, so no other mistake's difference adds to theirs
CAMERA = ("horizontal-fov", "no-half-pixel")


#: a camera mistake the diagnosis does not name is tried when, made with the mistake it names first, it leaves at
#: most this share of the pixels off on a few rows that mistake alone leaves (a shift of every edge: far fewer)
HELPS = 0.5


def camera_named(found: Diagnosis) -> str | None:
    """The first camera mistake ``found`` names among its causes (closest, nearest or made with another), if any."""
    for cause in found.causes:
        for name in (cause.variant, *cause.together):
            if name in CAMERA:
                return name
    return None


def behind_camera(
    pair: Failing, found: Diagnosis, renders: Renders, made: Callable[[str], Renders]
) -> Diagnosis | None:
    """``found`` (a diagnosis that names no mistake the submission matches) with the mistakes it matches behind a
    camera mistake (:func:`bases`): diagnosed against the scene rendered with that mistake (``renders.variant``,
    the diagnosis's own render of it), with the renders ``made(name)`` gives (the scene's renders on that
    mistake's base).  None when no camera mistake is tried, or nothing passes behind one."""
    for name in bases(found, pair, renders):
        behind = _behind(name, pair, found, renders, made)
        if behind is not None:
            return behind
    return None


def bases(found: Diagnosis, pair: Failing, renders: Renders) -> list[str]:
    """The camera mistakes to diagnose behind: the one ``found`` names, else each that helps its first mistake
    on a few rows (:data:`HELPS`)."""
    named = camera_named(found)
    if named is not None:
        return [named]
    first = next((c.variant for c in found.causes if c.variant in ALL), None)
    if first is None or pair.submitted.shape[0] < 3:
        return []
    off = _RowsOff(pair)
    alone = off(renders.rows(first, off.rows))  # (its rows kept from the diagnosis's first looks)
    helped = [c for c in CAMERA if compatible((c, first))]
    return [c for c in helped if off(renders.with_rows(merged((c, first)), off.rows)) <= HELPS * alone]


class _RowsOff:
    """The submission's pixels off even nearby on the sampled rows (:func:`.looks.sampled_rows`) against a render
    of those rows."""

    def __init__(self, pair: Failing):
        h, self.w, _ = pair.submitted.shape
        self.middles, self.rows = sampled_rows(h)
        self.submitted = pair.submitted[self.rows].reshape(len(self.middles), 3, self.w, 3)
        self.shut = None if pair.open_pixels is None else pair.open_pixels[self.middles]
        self.tolerance = pair.failed.tolerance

    def __call__(self, rendered: np.ndarray) -> int:
        """The pixels off against ``rendered``, the rows :attr:`rows` of a render."""
        bands = rendered.reshape(len(self.middles), 3, self.w, 3)
        off = rows_distance(bands, bands, self.submitted) > self.tolerance
        return int(np.count_nonzero(off if self.shut is None else off & ~self.shut))


def _behind(
    name: str, pair: Failing, found: Diagnosis, renders: Renders, made: Callable[[str], Renders]
) -> Diagnosis | None:
    """What :func:`behind_camera` finds behind camera mistake ``name``."""
    base = renders.variant(name)
    failed = pair.failed
    verdict = grade(base, pair.submitted, "", failed.tolerance, failed.max_fraction, pair.open_pixels)
    if verdict.passed:  # (the camera mistake alone: the diagnosis has graded it already)
        return None
    behind = diagnose(base, pair.submitted, verdict, made(name))
    readings = [r for r in _readings(behind) if name not in r and compatible((name, *r))]
    if not readings:
        return None
    share = _share(failed.fraction_off_nearby, verdict.fraction_off_nearby)
    combos = [_combined(name, share, reading, behind) for reading in readings]
    first = combos[0]
    causes = together_causes(Combination(first.members, first.fraction_off_nearby, True, tuple(combos[1:])))
    return Diagnosis(closest=False, causes=causes, objects=found.objects, lights=found.lights, offset=found.offset)


def _readings(behind: Diagnosis) -> list[tuple[str, ...]]:
    """The mistakes ``behind`` passes against, by reading: each combination's names, or each single mistake."""
    if behind.together:
        return [tuple(c.variant for c in made) for made in behind.combinations if made[0].passes]
    return [(c.variant,) for c in behind.causes if c.passes and c.variant in ALL]


def _share(reference: float, base: float) -> float:
    """Of the pixels off against the reference, the share the camera's render no longer leaves off."""
    return float(np.clip((reference - base) / reference, 0.0, 1.0)) if reference > 0 else 0.0


def _combined(camera: str, share: float, reading: tuple[str, ...], behind: Diagnosis) -> Combination:
    """The camera mistake with the mistakes of one reading of ``behind``, graded as ``behind`` graded them."""
    by_name = {c.variant: c for c in behind.causes}
    fraction = min(by_name[n].fraction_off_nearby for n in reading if n in by_name)
    evidence = "the image shows the scene from where that camera sees it"
    members = [Member(camera, VARIANTS[camera][1], share, evidence)]
    rest = (1.0 - share) / len(reading)
    members += [
        Member(n, ALL[n][1], rest, "it matches the reference rendered with that camera and this mistake")
        for n in reading
    ]
    members.sort(key=lambda m: -m.share)
    return Combination(tuple(members), fraction, True)


def renders_behind(
    scene: Scene,
    key: str,
    run: tuple[int | None, Callable[[], bool] | None],
    held: Cached,
    open_pixels: np.ndarray | None,
) -> Callable[[str], Renders]:
    """What gives the scene's renders on a camera mistake's base, held with the scene's others (one budget; a
    class's students with the same camera mistake share them)."""
    threads, cancel = run

    def made(name: str) -> Renders:
        pixels = scene.image.width * scene.image.height
        renders = held.get(f"{key}@{name}", lambda: renders_of(scene, threads, VARIANTS[name][0], open_pixels), pixels)
        renders.cancel_in_thread(cancel)
        return renders

    return made
