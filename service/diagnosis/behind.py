"""A mistake behind another: the other mistake made the reference, so that the one behind it keeps its name.

The diagnosis finds two mistakes made together by adding their differences from the reference (:mod:`.compose`),
which holds where each changes its own term.  Some never add:

* a camera mistake (the fov taken across the image's width, pixel centres without the +0.5) sees every object
  from a little elsewhere: what a second mistake changes (no shadow rays) falls on other pixels than in the
  reference, and the camera's mistake is found only as the closest ("fov taken as horizontal — comes closest,
  11 % of pixels off");
* two mistakes of one term (a spot's falloff linear in the angle, under the Blinn–Phong half vector; normals not
  turned to face the ray, where no shadow rays light the back of a surface) change what the other changes.

So where nothing passes, the diagnosis is made again with a mistake as the student's own way of rendering (the
renders' ``base``, :func:`.combination.on_base`): the reference is the scene as that student renders it, and each
mistake is that mistake made by them too.  The mistakes tried (:func:`bases`): the camera mistake the diagnosis
names (closest, nearest, or made with another), else each camera mistake that, made with the mistake it names
first, leaves at most :data:`HELPS` of the pixels off on a few rows that mistake alone leaves (two renders of those
rows: a spot's cutoff in radians relights most of the image and hides the half-pixel shift); then the mistake it
names first (one made in the render: not one of :data:`NOT_BASES`), where it comes closest or is the nearest
explanation of at least :data:`LEADS` of the difference.  A mistake the submission passes against behind one is
named with it, as mistakes made together, graded as that whole diagnosis grades it: every reading it gives is
kept.  Each costs a diagnosis of its own, paid only for an image no mistake, nor any sum of them, explains.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from schemas import Scene
from tracer.scene.variants import BOUNDS

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
from .stored import OUTER, STORED
from .together import together_causes
from .too_large import NAME as TOO_LARGE

#: the mistakes of the camera: each moves what every pixel shows, so no other mistake's difference adds to theirs
CAMERA = ("horizontal-fov", "no-half-pixel")
#: the first nearest explanation is diagnosed behind when it is a mistake that accounts for at least this share of
#: the difference (most of it: the rest is likely another mistake's)
LEADS = 0.5
#: never a base: a speckled mistake (its render is one pattern of speckles of many, not the student's), an offset
#: too large (at the one amount its variant is rendered at: :mod:`.with_offset` finds it with another at the
#: student's own), and the mistakes of the stored image (:mod:`.compose` finds them with others exactly)
NOT_BASES = frozenset({*BOUNDS, TOO_LARGE, *OUTER, *STORED})

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


def behind_mistake(
    pair: Failing, found: Diagnosis, renders: Renders, made: Callable[[str], Renders]
) -> Diagnosis | None:
    """``found`` (a diagnosis that names no mistake the submission matches) with the mistakes it matches behind a
    mistake (:func:`bases`): diagnosed against the scene rendered with that mistake (``renders.variant``, the
    diagnosis's own render of it), with the renders ``made(name)`` gives (the scene's renders on that mistake's
    base).  None when no mistake is tried, or nothing passes behind one."""
    for name in bases(found, pair, renders):
        behind = _behind(name, pair, found, renders, made)
        if behind is not None:
            return behind
    return None


def bases(found: Diagnosis, pair: Failing, renders: Renders) -> list[str]:
    """The mistakes to diagnose behind, in order: the camera mistake ``found`` names, else each that helps its
    first mistake on a few rows (:data:`HELPS`); then that first mistake, where it comes closest or leads the
    nearest explanations (:data:`LEADS`)."""
    lead = found.causes[0] if found.causes else None
    first = lead.variant if lead is not None and lead.variant in ALL else None
    leads = first is not None and first not in NOT_BASES and (found.closest or (lead and (lead.share or 0.0) >= LEADS))
    out = [first] if leads and first is not None else []
    named = camera_named(found)
    if named is not None:
        return [named, *(n for n in out if n != named)]
    if first is None or pair.submitted.shape[0] < 3:
        return out
    off = _RowsOff(pair)
    alone = off(renders.rows(first, off.rows))  # (its rows kept from the diagnosis's first looks)
    helped = [c for c in CAMERA if c != first and compatible((c, first))]
    return [c for c in helped if off(renders.with_rows(merged((c, first)), off.rows)) <= HELPS * alone] + out


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
    """What :func:`behind_mistake` finds behind mistake ``name``."""
    base = renders.variant(name)
    failed = pair.failed
    verdict = grade(base, pair.submitted, "", failed.tolerance, failed.max_fraction, pair.open_pixels)
    if verdict.passed:  # (the mistake alone: the diagnosis has graded it already)
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
    """Of the pixels off against the reference, the share the render of the mistake behind no longer leaves off."""
    return float(np.clip((reference - base) / reference, 0.0, 1.0)) if reference > 0 else 0.0


def _combined(base: str, share: float, reading: tuple[str, ...], behind: Diagnosis) -> Combination:
    """Mistake ``base`` with the mistakes of one reading of ``behind``, graded as ``behind`` graded them."""
    by_name = {c.variant: c for c in behind.causes}
    fraction = min(by_name[n].fraction_off_nearby for n in reading if n in by_name)
    evidence = "the image matches it everywhere the other mistake leaves as it is"
    members = [Member(base, ALL[base][1], share, evidence)]
    rest = (1.0 - share) / len(reading)
    members += [
        Member(n, ALL[n][1], rest, "it matches the reference rendered with the other mistake and this one")
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
    """What gives the scene's renders on a mistake's base, held with the scene's others (one budget; a class's
    students with the same mistake share them)."""
    threads, cancel = run

    def made(name: str) -> Renders:
        pixels = scene.image.width * scene.image.height
        renders = held.get(f"{key}@{name}", lambda: renders_of(scene, threads, ALL[name][0], open_pixels), pixels)
        renders.cancel_in_thread(cancel)
        return renders

    return made
