"""An offset too large made with another mistake: the other mistake found at the offset's own amount, the amount
a nuisance fitted on the way.

:mod:`.compose` models two mistakes made together by adding their differences from the reference, each rendered
alone, and confirms the pair by one render of both, the offset too large at the one amount its variant is rendered
at (2e-2 of the visible size).  Neither holds for an offset too large: its amount is the student's own (0.1 in a
scene 4.9 across is 2.03e-2 of it: a few pixels of a detached shadow apart), and its difference does not add to
another's: with no shadow rays there is no shadow left to detach, the pixels an offset detaches a shadow from are
those a transparent object's shadow left out lights already, and a detached shadow's edge moves with the camera's
rays as a whole shadow's does.  So when nothing else fits and the scene can show an offset too large, the pair is
looked for with both made in one render, on the rows a combination is chosen on (:func:`.compose.telling_rows`):

* the offset's rung, of the ladder of amounts :mod:`.too_large` grades an offset too large alone against, that
  comes nearest the submission on those rows;
* each other mistake the scene can show made with the offset at that rung, rows rendered; the two that come
  nearest (and nearer than the offset alone) are tried, in turn.  Where the offset alone explains those rows
  (what the other mistake changes lies elsewhere: a highlight missing, away from the detached shadows), the
  rows are chosen again where the submission departs most from the offset's render at its rung;
* for one, the rung with it made that comes nearest on the rows, then on the rows the submission is most off
  against it: the submission is graded against that rung's whole render, and against the range of it and each
  neighbour (:func:`service.images.grading.range_counts`: any amount between them lies in their range, as
  :mod:`.too_large` grades the offset alone).  Passed against, the two are named, the offset with its amount.

At most two whole renders a neighbour pair, one a rung, for each of the two mistakes tried: only where every other
round has left the image unexplained, and a pair's rows come within :data:`NEAR` of matching (an image no pair
explains, noise or a black one, costs the rows alone).  Pure (a :class:`Offsetting`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Protocol

import numpy as np

from tracer.scene.variants import Options

from ..images.grading import passes, range_counts
from .combination import ALL, Combination, Member, classic_first, merged
from .compose import ADD_LEVELS, _beyond, telling_rows
from .looks import off_rows
from .too_large import NAME, amounts, words

if TYPE_CHECKING:
    from ..images.grading import Grade

#: of the mistakes made with the offset at its rung, this many of the nearest are graded
TRIED = 2
#: a mistake made with the offset is graded on the whole image only when its rows are at most this part of the
#: reference's distance from the submission: a render's price is paid only for a pair the rows already nearly
#: match (Cornell at 64 px: pairs named at 0.00-0.23 of it; noise 0.80, a black image 0.59, a shifted one 1.04)
NEAR = 0.4


class Offsetting(Protocol):
    """What the search needs rendered (:class:`.renders.Renders` gives it)."""

    def with_rows(self, options: Options, numbers: np.ndarray) -> np.ndarray: ...

    def with_options(self, options: Options) -> np.ndarray: ...

    def size(self) -> float: ...

    def check(self) -> None: ...


def with_offset(
    reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Offsetting, tried: list[str]
) -> Combination | None:
    """An offset too large and one of the mistakes ``tried`` (those the scene can show) made together, that
    ``submitted`` (graded ``verdict``) passes against, found as the module says; None when none is.  A mistake of
    the stored image (the image flipped, gamma) is rendered as any other: made with the offset, no sum models it."""
    search = _Search(reference, submitted, verdict, renders)
    partners = [n for n in tried if n != NAME and n in ALL]
    return search.found(partners)


class _Search:
    """One search: the submission, its rows, the ladder of the offset's amounts, and the rows rendered so far."""

    def __init__(self, reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Offsetting):
        self.reference, self.submitted, self.verdict, self.renders = reference, submitted, verdict, renders
        self.open: np.ndarray | None = getattr(renders, "open", None)
        self.numbers = telling_rows(reference, submitted, verdict.tolerance)
        #: the reference's distance from the submission on the telling rows
        self.base = _beyond(reference[self.numbers], submitted[self.numbers], verdict.tolerance)
        self.size = renders.size()
        self.ladder = amounts(self.size)
        self.pixels = submitted.shape[0] * submitted.shape[1]
        #: per mistake and rung, the submission's pixels off against that rung's render alone (counted once)
        self.alone: dict[tuple[str, int], int] = {}

    def told_by(self, image: np.ndarray) -> None:
        """The rows a partner is chosen on made those where the submission departs most from ``image`` (the offset
        alone at its rung, which explains the rows it departs most from the reference on: a missing highlight
        lies elsewhere), and the reference's distance measured there."""
        self.numbers = telling_rows(image, self.submitted, self.verdict.tolerance)
        self.base = _beyond(self.reference[self.numbers], self.submitted[self.numbers], self.verdict.tolerance)

    def options(self, name: str | None, amount: float) -> Options:
        """The options of mistake ``name`` (None: none) made with an offset of ``amount`` in the scene's units."""
        made = merged((name,)) if name is not None else merged(())
        return replace(made, offset=amount / self.size, offset_along="normal") if amount else made

    def error(self, name: str | None, amount: float, numbers: np.ndarray | None = None) -> float:
        """How far the submission is, on rows ``numbers`` (None: the telling rows), from the render of ``name``
        made with the offset ``amount`` (0: none), as :class:`.compose.Rows` measures it."""
        numbers = self.numbers if numbers is None else numbers
        self.renders.check()
        rows = self.renders.with_rows(self.options(name, amount), numbers)
        return _beyond(rows, self.submitted[numbers], self.verdict.tolerance)

    def nearest(self, name: str | None, numbers: np.ndarray | None = None) -> int:
        """The rung of the ladder that comes nearest on ``numbers`` with ``name`` made (the first of equals)."""
        return min(range(len(self.ladder)), key=lambda k: self.error(name, self.ladder[k], numbers))

    def found(self, partners: list[str]) -> Combination | None:
        """The first of the :data:`TRIED` partners nearest on the rows (nearer than the offset alone, and within
        :data:`NEAR` of the reference's distance) that, made with the offset at some rung or between two, the
        submission passes against."""
        k = self.nearest(None)
        rung = self.ladder[k]
        alone = self.error(None, rung)
        if alone <= ADD_LEVELS:  # (the offset alone explains the rows: the other mistake shows elsewhere)
            self.told_by(self.whole(None, k))
            alone = self.error(None, rung)
        ranked = sorted(partners, key=lambda n: (self.error(n, rung), classic_first((n,))))
        for name in ranked[:TRIED]:
            if self.error(name, rung) > min(alone - ADD_LEVELS, NEAR * self.base):
                break
            made = self.graded(name)
            if made is not None:
                return made
        return None

    def graded(self, name: str) -> Combination | None:
        """``name`` with the offset at the rung nearest on the telling rows, then at the rung nearest on the rows
        the submission is most off against that one, alone and in a range with each neighbour: the first the
        submission passes against, of the ranges the one that leaves fewer off; None when none passes, or when the
        amount the submission comes nearest is the largest offset accepted (:meth:`above_accepted`)."""
        first = self.nearest(name)
        image = self.whole(name, first)
        if self.counted([image]) is not None:
            return self.named(name, [first]) if first > 0 else None
        counts = off_rows(image, self.submitted, self.verdict.tolerance, self.open)
        worst = np.sort(np.argsort(-counts, kind="stable")[: len(self.numbers)])
        k = self.nearest(name, worst[counts[worst] > 0]) if np.any(counts > 0) else first
        spans = [[k]] if k != first else []
        spans += [[j, j + 1] for j in (k - 1, k) if 0 <= j and j + 1 < len(self.ladder)]
        counted = [(self.counted([self.whole(name, j) for j in span]), span) for span in spans]
        passing = [(off, span) for off, span in counted if off is not None]
        passing = [(off, span) for off, span in passing if self.above_accepted(name, span)]
        return self.named(name, min(passing)[1]) if passing else None

    def above_accepted(self, name: str, span: list[int]) -> bool:
        """Whether the amount the submission comes nearest alone, of the rungs ``span``, is more than the largest
        offset accepted (the ladder's first rung): at that rung the offset is an honest student's, and the
        other mistake is looked for behind it (:mod:`.nuisance`), never named with an offset "too large"."""
        return span[self.nearest_of(name, span)] > 0

    def nearest_of(self, name: str, span: list[int]) -> int:
        """Which of the rungs ``span`` (made with ``name``) leaves the fewest of the submission's pixels off."""
        for j in span:
            if (name, j) not in self.alone:
                counts = range_counts([self.whole(name, j)], self.submitted, self.verdict.tolerance, self.open)
                self.alone[name, j] = counts.off_nearby
        return int(np.argmin([self.alone[name, j] for j in span]))

    def whole(self, name: str | None, rung: int) -> np.ndarray:
        self.renders.check()
        return self.renders.with_options(self.options(name, self.ladder[rung]))

    def counted(self, images: list[np.ndarray]) -> int | None:
        """The submission's pixels off against the range of ``images`` where it passes, else None."""
        counts = range_counts(images, self.submitted, self.verdict.tolerance, self.open)
        return counts.off_nearby if passes(counts, self.pixels, self.verdict.max_fraction) else None

    def named(self, name: str, span: list[int]) -> Combination:
        """The combination of ``name`` and the offset between the rungs ``span`` (the submission passes against
        their range), the offset's words the amount the submission comes nearest alone, each member's share of
        the difference on the telling rows."""
        images = [self.whole(name, j) for j in span]
        amount = self.ladder[span[self.nearest_of(name, span)]]
        counts = range_counts(images, self.submitted, self.verdict.tolerance, self.open)
        both = self.error(name, amount)
        share = {
            name: (self.error(None, amount) - both) / self.base if self.base > 0 else 0.0,
            NAME: (self.error(name, 0.0) - both) / self.base if self.base > 0 else 0.0,
        }
        members = [
            Member(name, ALL[name][1], max(0.0, share[name]), _evidence(share[name])),
            Member(NAME, words(amount, self.size), max(0.0, share[NAME]), _evidence(share[NAME], "at that amount; ")),
        ]
        members.sort(key=lambda m: -m.share)
        return Combination(tuple(members), counts.off_nearby / self.pixels, True)


def _evidence(share: float, how: str = "") -> str:
    accounts = round(100 * max(0.0, share))
    return f"made with the other mistake {how}the mistake accounts for {accounts} % of the difference"
