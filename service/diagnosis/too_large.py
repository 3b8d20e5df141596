"""An offset too large, and how large: ``offset-too-large`` scored against a ladder of amounts beyond those
accepted, with its size estimated in the scene's units.

A student whose shadow and secondary rays start too far off the surface detaches shadows from what casts them
and shifts what glass shows.  Their amount is their own (0.05, 0.1...), so one render of one amount matches
few of them.  The reference is rendered instead at a ladder of amounts (:mod:`.offsets`), from the largest
offset accepted (:data:`tracer.scene.variants.ACCEPTED_DEFAULT`) up to :data:`TOP` of the visible size; the rung
nearest the submission and its two neighbours bracket the student's amount, which is looked for on either
side of it (:func:`.offsets.narrowed`), and the submission is graded against the range of the amounts found: any
amount between them lies in their range.  That range names the mistake, with the amount of it the submission comes
closest to as its size: "shadow and secondary rays offset too far from the surface: about 0.1 in the scene's
units".
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from tracer.scene.variants import ACCEPTED_DEFAULT

from ..images.grading import Counts, Grade, grade, passes, range_counts
from ..images.nearby import rows_distance
from .looks import sampled_rows, telling_middles
from .offsets import amount_words, narrowed, round_amounts
from .records import Cause
from .rendered import options_of
from .renders import Renders
from .settled import FIRST_ROWS, unsettled, windows

NAME = "offset-too-large"
#: the ladder of offsets too large goes up to this × the visible size (an offset that large hides most shadows,
#: and reads as no shadows at all)
TOP = 5e-2


def amounts(size: float, along: str = "normal") -> list[float]:
    """The ladder's amounts in a scene of visible size ``size``, ascending: the largest accepted offset along the
    normal (along ``"direction"``: the largest accepted t_min), the round amounts above it (none within a tenth of
    either end: a rung next to an end is the same look twice, and where the look changes at once above the lowest
    rung, as a shadow ray that passes its light reaches a ceiling, the side of two rungs that alike would leave
    the student's amount out of every range), and :data:`TOP` × ``size``."""
    low, high = ACCEPTED_DEFAULT[_ACCEPTED_AS[along]] * size, TOP * size
    return [low, *(a for a in round_amounts(low, high) if 1.1 * low < a < high / 1.1), high]


#: the ways a ladder's offsets are taken: along the shading normal; in a scene with a mesh, along its faces' own
#: (geometric) normal too, which many a student's tracer offsets along (where a mesh's normals are interpolated,
#: the two part, and a shadow an offset detaches moves with the normal it was offset along); and along the ray
#: itself (``"direction"``: ``p + ε·d``, a shadow ray still as long as from the hit point to the light, so that it
#: passes the light by ε), the other way a textbook keeps rays off the surface they leave.  (A true t_min, whose
#: shadow ray ends at the light, hides only what lies within it of a surface, and a large one rarely shows.)
ALONG = ("normal", "geometric", "direction")
#: the accepted variant (:data:`tracer.scene.variants.ACCEPTED_DEFAULT`) each way's ladder starts above
_ACCEPTED_AS = {"normal": "normal-offset", "geometric": "normal-offset", "direction": "t-min"}


def rung_name(amount: float, along: str = "normal") -> str:
    """The name a rung renders under (:func:`service.diagnosis.rendered.options_of`): ``offset-too-large@0.05``,
    along the geometric normal ``offset-too-large@geometric@0.05``."""
    return f"{NAME}@{amount!r}" if along == "normal" else f"{NAME}@{along}@{amount!r}"


def words(amount: float, size: float, along: str = "normal") -> str:
    accepted = amount_words(ACCEPTED_DEFAULT[_ACCEPTED_AS[along]] * size)
    if along == "direction":
        return (
            f"shadow and secondary rays started too far along their own direction: about {amount_words(amount)} in "
            f"the scene's units, a t_min or an offset along the ray too large (at most {accepted} is accepted)"
        )
    return (
        f"shadow and secondary rays offset too far from the surface: about {amount_words(amount)} in the scene's "
        f"units (at most {accepted} is accepted)"
    )


class Scoring(Protocol):
    """What scoring the ladder needs of a diagnosis's scoring (:class:`service.diagnosis.causes._Scoring`)."""

    reference: np.ndarray
    submitted: np.ndarray
    verdict: Grade
    renders: Renders
    pixels: int
    counts: np.ndarray  # per row, the submission's pixels off even nearby against the reference
    scored: list[Cause]


def score(scoring: Scoring, beyond: Callable[[int], bool]) -> bool:
    """Scores ``offset-too-large`` along the shading normal (:func:`along`); where nothing is passed against yet,
    along its faces' geometric normal too in a scene with a mesh, then along the ray itself (each way's ladder
    the cost of a few renders: none is climbed for an image already explained); of those scored, the one that
    leaves fewest pixels off is kept.  False when none is scored."""
    ways = [way for way in ALONG if way != "geometric" or "mesh" in scoring.renders.objects]
    scored = False
    for way in ways:
        if any(c.passes for c in scoring.scored):
            break
        scored = along(scoring, beyond, way) or scored
    mine = [c for c in scoring.scored if c.variant == NAME]
    if len(mine) > 1:
        best = min(mine, key=lambda c: (not c.passes, c.fraction_off_nearby))
        scoring.scored[:] = [c for c in scoring.scored if c.variant != NAME or c is best]
    return scored


def along(scoring: Scoring, beyond: Callable[[int], bool], normal: str) -> bool:
    """Scores ``offset-too-large`` along ``normal`` (of :data:`ALONG`) against the range of a few amounts: on
    either side of the rung that leaves the fewest of the submission's pixels off on the sampled rows, each side
    narrowed (:func:`.offsets.narrowed`) to the amounts that leave fewer, the side whose range leaves fewer kept,
    then rendered whole.  False, as :meth:`_Scoring.score` says, when the rows alone (an exact lower bound, as
    :func:`service.diagnosis.looks.off_at_least` counts) or the whole count are off by a count ``beyond`` says is
    too many; else adds the cause, its words the amount of the range the submission comes closer to.  The ladder is
    given up before any of that when its rungs' rows alone show that no range of them, nor a narrower one, can
    come under ``beyond`` (:mod:`.settled`: the same False, sooner)."""
    renders, submitted, verdict = scoring.renders, scoring.submitted, scoring.verdict
    size = renders.size()
    ladder = amounts(size, normal)
    sampled = _Told(scoring, normal)
    told = telling_middles(scoring.counts, FIRST_ROWS * verdict.max_fraction * scoring.pixels)
    first = _Sampled(scoring, told, normal)
    if _settled(scoring, [first, sampled.first], ladder, beyond):
        return False  # (no range of its rungs, nor any narrower one, can leave few enough off: as narrowing finds)
    # (on either side of the rung nearest the submission: a range of two rungs may leave a pixel fewer off than
    # the range that holds the student's amount, where a larger offset hides what a smaller one shows)
    best = min(range(len(ladder)), key=lambda k: sampled.off((ladder[k],)))
    sides = [pair for pair in zip(ladder, ladder[1:]) if ladder[best] in pair]
    found = [narrowed(lambda a: sampled.off((a,)), low, high) for low, high in sides]
    chosen = min(found, key=lambda amounts: sampled.off(tuple(amounts)))
    if beyond(sampled.off(tuple(chosen))[0]):
        return False
    counts = None
    if sampled.off((ladder[best],)) <= sampled.off(tuple(chosen)):  # (the rows tell the rung alone no worse)
        counts = _rung_alone(scoring, ladder[best], normal)
    if counts is not None:
        chosen = [ladder[best]]
    images = [renders.variant(rung_name(a, normal)) for a in chosen]
    counts = counts or range_counts(images, submitted, verdict.tolerance, renders.open)
    if beyond(counts.off_nearby):
        return False
    alone = [
        grade(image, submitted, "", verdict.tolerance, open_pixels=renders.open).fraction_off_nearby for image in images
    ]
    amount = chosen[int(np.argmin(alone))]
    fraction = counts.off_nearby / scoring.pixels
    scoring.scored.append(
        Cause(NAME, words(amount, size, normal), fraction, passes(counts, scoring.pixels, verdict.max_fraction))
    )
    return True


def _rung_alone(scoring: Scoring, rung: float, normal: str) -> Counts | None:
    """The whole count against the rung nearest the submission alone, where it passes (None where not): a
    student's round amount (0.1) is a rung, and where the sampled rows leave every amount near it alike,
    narrowing walks away from it (the first of equals) to a range that leaves more off elsewhere."""
    renders, verdict = scoring.renders, scoring.verdict
    image = renders.variant(rung_name(rung, normal))
    counts = range_counts([image], scoring.submitted, verdict.tolerance, renders.open)
    return counts if passes(counts, scoring.pixels, verdict.max_fraction) else None


def _settled(scoring: Scoring, looks: list[_Sampled], ladder: list[float], beyond: Callable[[int], bool]) -> bool:
    """Whether the ladder is given up (:mod:`.settled`) on the rows of ``looks`` (each holding the rows of the one
    before), then on every row the submission is off on: each look from the pair of rungs the one before left open
    (:func:`.settled.unsettled`).  The last look costs two rungs' pixels near every pixel off (often fewer than the
    dozen amounts narrowing renders on the sampled rows); it is taken only when it has more rows than the others."""
    left = 1
    for look in looks:
        open_from = look.unsettled(ladder, beyond, left)
        if open_from is None:
            return True
        left = open_from
    every = np.flatnonzero(scoring.counts > 0)
    if len(every) <= len(looks[-1].middles):
        return False
    return _Sampled(scoring, every, looks[-1].along).unsettled(ladder, beyond, left) is None


class _Sampled:
    """The submission's pixels off even nearby against the range of renders of a few amounts, on a few rows (those
    most off against the reference, as many as :func:`service.diagnosis.looks.sampled_rows` takes, each with the
    rows either side): an exact lower bound of the whole count."""

    def __init__(self, scoring: Scoring, middles: np.ndarray | None = None, along: str = "normal"):
        self.renders, self.along = scoring.renders, along
        self.tolerance = scoring.verdict.tolerance
        h, self.w, _ = scoring.submitted.shape
        self.h = h
        self.middles = telling_middles(scoring.counts, np.inf) if middles is None else middles
        if not len(self.middles):
            self.middles = sampled_rows(h)[0]
        self.rows = (self.middles[:, None] + np.arange(-1, 2)[None, :]).ravel()
        self.submitted = scoring.submitted[self.rows].reshape(len(self.middles), 3, self.w, 3)
        self.shut = None if scoring.renders.open is None else scoring.renders.open[self.middles]
        self.reference = scoring.reference[self.rows].reshape(len(self.middles), 3, self.w, 3)
        self.counted: dict[tuple[float, ...], tuple[int, int]] = {}

    def bands(self, amount: float) -> np.ndarray:
        name, renders = rung_name(amount, self.along), self.renders
        return renders.rows(name, self.rows).reshape(len(self.middles), 3, self.w, 3)

    def off(self, amounts: tuple[float, ...]) -> tuple[int, int]:
        """The pixels off on the sampled rows against the range of the renders of ``amounts``, and the sum of
        their nearby distances."""
        if amounts not in self.counted:
            if not len(self.middles):
                self.counted[amounts] = (0, 0)
                return self.counted[amounts]
            self.renders.check()
            bands = [self.bands(a) for a in amounts]
            near = rows_distance(np.min(bands, axis=0), np.max(bands, axis=0), self.submitted)
            if self.shut is not None:
                near = np.where(self.shut, 0, near)
            self.counted[amounts] = (int(np.count_nonzero(near > self.tolerance)), int(near.sum(dtype=np.int64)))
        return self.counted[amounts]

    def unsettled(self, ladder: list[float], beyond: Callable[[int], bool], start: int) -> int | None:
        """None when, on these rows, no range of two neighbouring amounts of ``ladder`` nor any narrower range
        between two of them can leave a count of pixels off that ``beyond`` lets by (:func:`.settled.unsettled`,
        from pair ``start`` on, those before it settled on some of these rows), else the first pair that leaves it
        open; counted where the submission is off against the reference (a lower bound): the rungs are rendered
        near there alone (:func:`.settled.windows`)."""
        if not len(self.middles):
            return start
        self.renders.check()
        shut = rows_distance(self.reference, self.reference, self.submitted) <= self.tolerance
        if self.shut is not None:
            shut |= self.shut
        wanted = windows(~shut, self.middles, self.h)

        def near(k: int) -> np.ndarray:
            return self.near(ladder[k], wanted)

        return unsettled(near, len(ladder), self.submitted, self.tolerance, shut, beyond, start)

    def near(self, amount: float, wanted: np.ndarray) -> np.ndarray:
        """:meth:`bands` right where ``wanted`` says (:meth:`.renders.Renders.with_pixels`)."""
        options = options_of(rung_name(amount, self.along), self.renders.size)
        image = self.renders.with_pixels(options, wanted)
        return image[self.rows].reshape(len(self.middles), 3, self.w, 3)


class _Told:
    """The pixels off on the rows most off against the reference (:class:`_Sampled`), and where those leave none
    off, then on every row :func:`service.diagnosis.looks.sampled_rows` takes besides: the rows most off may
    tell only that an offset is larger than some amount (a light just below a ceiling that every larger offset
    puts out of reach), and all larger amounts alike; the other rows tell them apart.  Rendered only for the
    amounts that leave the first rows as the submission has them."""

    def __init__(self, scoring: Scoring, along: str = "normal"):
        self.first = _Sampled(scoring, None, along)
        spread = np.setdiff1d(sampled_rows(scoring.submitted.shape[0])[0], self.first.middles)
        self.spread = _Sampled(scoring, spread, along) if len(spread) else None

    def off(self, amounts: tuple[float, ...]) -> tuple[int, ...]:
        """:meth:`_Sampled.off` on the first rows, followed where it is nothing by that on the other rows (the
        first count is an exact lower bound of the whole image's, as :meth:`_Sampled.off` says)."""
        told = self.first.off(amounts)
        if told != (0, 0) or self.spread is None:
            return told
        return told + self.spread.off(amounts)
