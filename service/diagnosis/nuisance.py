"""A mistake behind an honest offset: the student's offset fitted as a nuisance, so that the mistake keeps its name.

A student whose tracer offsets its rays honestly and who also makes a mistake fails the reference (the
mistake), every accepted variant (the mistake again) and the render of their mistake (the offset moves a glass
ball's refractions and the ends of shadows): the diagnosis finds their mistake only as the closest.  So for the
mistakes it came closest to (or found nearest), the offset is fitted with the mistake made: on a few rows,
the rung of the ladder of offsets along the normal (:mod:`.offsets`) whose render with the mistake leaves the
fewest of the submission's pixels off.  The mistake is then graded at that rung, the pixels its offset moves
between the rungs either side of it not counted: whatever amount the student wrote between them, only the
mistake is left, and a submission that matches it is said to ("matches the reference rendered with that
mistake and a ray offset of 0.01 along the normal"), with the mistake's deduction.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from schemas import Scene
from tracer.scene.variants import MORE_VARIANTS, VARIANTS, Options

from ..images.grading import Grade, grade
from ..images.nearby import rows_distance
from ..render.scenekey import scene_key
from .accepting import KEPT_RENDERS, Failing, Look, _render, accepted_ladders
from .combination import ALL, compatible, merged, on_base
from .looks import off_rows, sampled_rows, telling_middles
from .offsets import Rung
from .records import Cause, Diagnosis

#: the offset is fitted only when, with the mistake made, it explains more than this share of what the grade
#: allows off: less than that changes no verdict
MATTERS = 0.5
#: at most this many of the diagnosis's causes are tried
TRIED = 3


@dataclass(frozen=True)
class AtOffset:
    """A mistake (or mistakes made together) at an honest offset: the rung, and the grade against its render."""

    rung: Rung
    grade: Grade


@dataclass(frozen=True)
class Asked:
    """What the fit renders with: the scene, its key, the ladder of offsets along the normal, and how it renders."""

    scene: Scene
    look: Look
    rungs: list[Rung]


def behind_offset(
    scene: Scene,
    pair: Failing,
    found: Diagnosis,
    accepted: dict[str, float] | None = None,
    run: tuple[int | None, Callable[[], bool] | None] = (None, None),
) -> Diagnosis | None:
    """``found`` (a diagnosis that names no mistake the submission matches) with its first cause the submission
    matches at an honest offset (``accepted``, as :func:`.accepting.accept` takes them), fitted; None when the
    task accepts no offset along the normal or no cause matches at any."""
    key = scene_key(scene)
    ladders = [rungs for rungs in accepted_ladders(scene, accepted, key) if rungs[0].kind == "normal-offset"]
    if not ladders or pair.submitted.shape[0] < 3:
        return None
    asked = Asked(scene, Look(key, *run), ladders[0])
    for names in candidates(found):
        fitted = fit(asked, pair, merged(names))
        if fitted is not None and fitted.grade.passed:
            return _named(found, names, fitted)
    return None


def candidates(found: Diagnosis) -> list[tuple[str, ...]]:
    """The mistakes to fit an offset with: the diagnosis's mistakes made together, else each of its first causes
    that is a mistake (not a term), in order."""
    known = [c for c in found.causes if c.variant in VARIANTS or c.variant in MORE_VARIANTS]
    if found.together and known:  # (the combination named first: another reading of its image is no other fit)
        names = tuple(c.variant for c in found.combinations[0] if c in known)
        return [names] if compatible(names) else []
    return [(c.variant,) for c in known[:TRIED]]


def fit(asked: Asked, pair: Failing, mistake: Options) -> AtOffset | None:
    """The submission graded against ``mistake`` made at the rung of the ladder that leaves the fewest of its
    pixels off on a few rows, with the pixels the offset moves between the rungs either side not counted; None
    when no rung explains enough to matter (:data:`MATTERS`).

    The rows are first the sampled ones (:func:`.looks.sampled_rows`), a fair sample of the image; where the
    offset shows on few pixels (a glass ball's refractions, the mistake's own difference everywhere else) it
    may lie on none of them, so then on the rows where the submission departs most from the mistake's own
    render (as many as the sample, :func:`.looks.telling_middles`), which the offset's pixels fill.  Rows only
    choose the rung: the answer is the whole image's grade."""
    h, w, _ = pair.submitted.shape
    middles = sampled_rows(h)[0]
    best = _rung(asked, pair, mistake, middles, h / max(len(middles), 1))
    if best is None:
        counts = off_rows(_whole(asked, mistake, h * w), pair.submitted, pair.failed.tolerance, pair.open_pixels)
        middles = telling_middles(counts, float(counts.sum()))  # (as many as the sample has, most off first)
        best = _rung(asked, pair, mistake, middles, 1.0) if len(middles) else None
    if best is None:
        return None
    options = [on_base(mistake, r.options) for r in asked.rungs]
    near = [mistake] if best == 0 else []
    near += [options[k] for k in range(max(best - 1, 0), min(best + 2, len(options)))]
    images = {o: _whole(asked, o, h * w) for o in near}
    stack = np.stack(list(images.values()))
    moved = (stack.max(axis=0) - stack.min(axis=0)).max(axis=2) > pair.failed.tolerance
    if pair.open_pixels is not None:
        moved |= pair.open_pixels
    failed = pair.failed
    graded = grade(images[options[best]], pair.submitted, "", failed.tolerance, failed.max_fraction, moved)
    return AtOffset(asked.rungs[best], graded)


def _rung(asked: Asked, pair: Failing, mistake: Options, middles: np.ndarray, scale: float) -> int | None:
    """The rung whose render with ``mistake`` leaves the fewest of the submission's pixels off on the rows
    ``middles`` (each with its neighbours); None when it leaves fewer than the mistake alone by no more than
    :data:`MATTERS` of what the grade allows off, the rows' count × ``scale`` (their share of the image)."""
    h, w, _ = pair.submitted.shape
    rows = (middles[:, None] + np.arange(-1, 2)[None, :]).ravel()
    submitted = pair.submitted[rows].reshape(len(middles), 3, w, 3)
    shut = np.zeros((len(middles), w), bool) if pair.open_pixels is None else pair.open_pixels[middles]

    def off(options: Options) -> int:
        bands = asked.look.rows(asked.scene, options, rows).reshape(len(middles), 3, w, 3)
        return int(np.count_nonzero((rows_distance(bands, bands, submitted) > pair.failed.tolerance) & ~shut))

    counts = [off(on_base(mistake, r.options)) for r in asked.rungs]
    best = int(np.argmin(counts))
    if (off(mistake) - counts[best]) * scale <= MATTERS * pair.failed.max_fraction * h * w:
        return None
    return best


def _whole(asked: Asked, options: Options, pixels: int) -> np.ndarray:
    look = asked.look
    return KEPT_RENDERS.get(
        (look.key, options), partial(_render, asked.scene, options, look.threads, look.cancel), pixels
    )


def _named(found: Diagnosis, names: tuple[str, ...], fitted: AtOffset) -> Diagnosis:
    """``found`` with the mistakes ``names`` as its causes, matched at the fitted offset."""
    by_name = {c.variant: c for c in found.causes}
    fraction = fitted.grade.fraction_off_nearby
    if len(names) == 1:
        causes = [Cause(names[0], ALL[names[0]][1], fraction, True)]
    else:
        causes = [replace(by_name[n], fraction_off_nearby=fraction, passes=True) for n in names]
    return replace(found, causes=causes, closest=False, terms=[], offset=fitted.rung.words)
