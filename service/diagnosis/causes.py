""":func:`diagnose`, the one place that knows the order of a diagnosis's rounds: mistakes of the stored image
alone (no render), the classic mistakes scored on the rows most off, the terms out of scale, mistakes made
together (confirmed by one render), the closest mistake, and, when nothing fits, the nearest explanations
ranked by their share of the difference.  The evidence each round uses is described in the package's
docstring (:mod:`service.diagnosis`).

Everything here is pure: the renders come in through a :class:`Renders`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from tracer.scene.variants import ALIKE, BOUNDS, MORE_VARIANTS, VARIANTS

from ..images.grading import Grade, grade
from . import too_large, unclamped
from .combination import ALL
from .compose import stored_only
from .fit import fit_terms
from .looks import (
    bound_unless_outside,
    off_at_least,
    off_rows,
    outside_at_least,
    speckled,
    telling_middles,
    whole_unless_off,
)
from .records import Cause, Diagnosis
from .renders import Renders
from .speckled_with import speckled_with
from .together import beside_closest, closer, combined, nearest_causes, together_causes
from .where import where

#: a variant that is not passed against is still named when it leaves at most this share of the reference's
#: failing pixels
CLOSEST_SHARE = 0.25
#: the first look takes the rows where the submission is most off against the reference until they hold this many
#: times the off pixels that rule a variant out: a variant that changes only part of those rows is ruled out too
TELLING = 2.0


def diagnose(reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders) -> Diagnosis:
    """The likely causes of a failing grade ``verdict`` of ``submitted`` against ``reference`` (a passing
    grade gets no diagnosis: an empty one)."""
    try:
        return _diagnosed(reference, submitted, verdict, renders)
    finally:  # (cancelled or not)
        renders.done()


def _diagnosed(reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders) -> Diagnosis:
    out = Diagnosis()
    if verdict.passed:
        return out
    stored = stored_only(reference, submitted, verdict, renders.open)  # (grey, mirrored, BGR: found with no render)
    if stored is not None:
        out.causes = together_causes(stored)
    else:
        _named(out, reference, submitted, verdict, renders)
    renders.check()
    out.objects, out.lights = where(reference, submitted, verdict, renders)
    return out.worded(renders.names)


def _named(out: Diagnosis, reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders) -> None:
    """``out``'s causes (and terms): a single classic mistake passed against; else the terms out of scale, then
    mistakes made together (one render); else the closest; else the nearest explanations."""
    scoring = _Scoring(reference, submitted, verdict, renders)
    later, later_bounds = scoring.first_round()
    if any(c.passes for c in scoring.scored):
        scoring.alike_round()
        out.causes, out.closest = scoring.named()
        if out.causes[0].variant in BOUNDS:  # (acne's far end hides a mistake that only darkens: is one shown?)
            acne = speckled_with(reference, submitted, verdict, renders)
            out.causes = out.causes if acne is None else together_causes(acne)
            _wrapped_beats_acne(out, scoring.scored, submitted, verdict, renders)
        _wrapped(out, submitted, verdict, renders)
        return
    renders.check()
    out.terms = fit_terms(submitted, renders)
    together = combined(reference, submitted, verdict, renders, out.terms)
    if together is not None and together.passes:  # (mistakes that explain the image leave no term to fit)
        out.causes, out.terms = together_causes(together), []
        return
    acne = speckled_with(reference, submitted, verdict, renders)  # (acne is never one of a fitted combination)
    if acne is not None:
        out.causes, out.terms = together_causes(acne), []
        return
    scoring.closest_round(later, later_bounds)  # the closest is named: score what may come closest
    out.causes, out.closest = closer(together, *scoring.named(), verdict)
    _wrapped(out, submitted, verdict, renders)
    if out.closest and not out.together and out.causes[0].variant in ALL:  # (a second mistake on other rows?)
        beside = beside_closest(reference, submitted, verdict, renders, out.terms, out.causes[0].variant)
        if beside is not None:
            out.causes, out.closest, out.terms = together_causes(beside), False, []
    if not out.causes:
        out.causes = nearest_causes(reference, submitted, verdict, renders, out.terms)


def _wrapped(out: Diagnosis, submitted: np.ndarray, verdict: Grade, renders: Renders) -> None:
    """``out``'s causes made the mistake it names first with colours not clamped (:mod:`.unclamped`), where the
    submission passes against the two together with fewer pixels off than against that mistake alone."""
    first = out.causes[0] if out.causes else None
    if first is None or first.together or (first.passes and first.fraction_off_nearby == 0):
        return
    renders.check()
    found = unclamped.behind(first.variant, submitted, verdict, renders)
    if found is not None:
        out.causes, out.closest = together_causes(found), False


def _wrapped_beats_acne(
    out: Diagnosis, scored: list[Cause], submitted: np.ndarray, verdict: Grade, renders: Renders
) -> None:
    """``out``'s causes, acne's (alone or with another mistake), made the nearest mistake scored with colours
    not clamped (:mod:`.unclamped`) where the submission passes against those two rendered together with no
    more pixels off.  Acne's is a test between bounds (its speckles are one pattern of many), and the dark dots
    of colours that wrap lie between the reference and acne's far end too: an image that a render of two
    mistakes matches (no reflection with colours not clamped) is that render's, not acne's."""
    plain = [c for c in scored if c.variant not in BOUNDS]
    if not plain:
        return
    nearest = min(plain, key=lambda c: c.fraction_off_nearby)
    renders.check()
    found = unclamped.behind(nearest.variant, submitted, verdict, renders)
    if found is not None and found.fraction_off_nearby <= out.causes[0].fraction_off_nearby:
        out.causes = together_causes(found)


class _Scoring:
    """The classic mistakes of one diagnosis scored against the submission (``scored``), in two rounds: first
    every mistake that may pass, then, when none does, those that may come closest."""

    def __init__(self, reference: np.ndarray, submitted: np.ndarray, verdict: Grade, renders: Renders):
        self.reference, self.submitted, self.verdict, self.renders = reference, submitted, verdict, renders
        self.pixels = submitted.shape[0] * submitted.shape[1]
        self.scored: list[Cause] = []
        # where the submission is off against the reference, per row: the rows and bands looked at first (the
        # order of the looks only: every bound stays exact, every whole render the same image)
        self.counts = off_rows(reference, submitted, verdict.tolerance, renders.open)
        self.first = telling_middles(self.counts, TELLING * verdict.max_fraction * self.pixels)

    # whether a variant with at least ``off`` pixels off (even nearby) cannot pass, or cannot be named the
    # closest either: decided as the grade and the naming decide them, on the share of the pixels
    def cannot_pass(self, off: int) -> bool:
        return off / self.pixels > self.verdict.max_fraction

    def cannot_come_closest(self, off: int) -> bool:
        return self.cannot_pass(off) and off / self.pixels > CLOSEST_SHARE * self.verdict.fraction_off_nearby

    def shown(self, name: str) -> bool:  # a mistake the scene cannot show is no evidence of anything: not rendered
        return not self.renders.unchanged(name)

    def score(self, name: str, beyond: Callable[[int], bool]) -> bool:
        """Scores variant ``name``, unless its render shows on the way a count of off pixels ``beyond`` says
        is too many (then False: it cannot pass, or come closest, whichever ``beyond`` decides)."""
        image = whole_unless_off(name, self.submitted, self.verdict, self.renders, beyond, self.counts)
        if image is None:
            return False
        if np.array_equal(image, self.reference):  # the mistake changes nothing in this scene: no evidence
            return True
        g = grade(image, self.submitted, "", self.verdict.tolerance, self.verdict.max_fraction, self.renders.open)
        self.scored.append(Cause(name, _words(name), g.fraction_off_nearby, g.passed))
        return True

    def score_speckled(self, name: str, beyond: Callable[[int], bool]) -> bool:
        """Scores speckled mistake ``name``, unless its far end shows on the way a count of pixels outside that
        ``beyond`` says is too many (then False, as :meth:`score`)."""
        # the variant's own speckles are one pattern of many: only lying between the reference and the far
        # end, in speckles, is evidence of the mistake
        far = bound_unless_outside(
            name, self.reference, self.submitted, self.verdict, self.renders, beyond, self.counts
        )
        if far is None:
            return False
        outside = speckled(self.reference, far, self.submitted, self.verdict.tolerance, self.renders.samples)
        if outside is not None:
            self.scored.append(Cause(name, VARIANTS[name][1], outside, outside <= self.verdict.max_fraction))
        return True

    def first_round(self) -> tuple[list[str], list[str]]:
        """Scores every mistake that may pass; gives back those that cannot, but may come closest if none passes:
        the variants, and the speckled mistakes."""
        renders, later = self.renders, []
        for name in filter(self.shown, VARIANTS):
            renders.check()
            if name in BOUNDS or name == too_large.NAME:
                continue  # (a speckled mistake is scored against its far end below; an offset too large last)
            # a first look at a few rows (exact: a lower bound of the variant's off pixels): a variant that cannot
            # pass is scored only if none passes, and then only if it may come closest
            least = off_at_least(name, self.submitted, self.verdict, renders, self.cannot_pass, self.first)
            if (least is not None and self.cannot_pass(least)) or not self.score(name, self.cannot_pass):
                later.append(name)
        if self.shown(too_large.NAME) and not self._ladder_scored():
            later.append(too_large.NAME)
        later_bounds = []
        for name in filter(self.shown, BOUNDS):
            renders.check()
            least = outside_at_least(
                name, self.reference, self.submitted, self.verdict, renders, self.cannot_pass, self.first
            )
            if (least is not None and self.cannot_pass(least)) or not self.score_speckled(name, self.cannot_pass):
                later_bounds.append(name)
        return later, later_bounds

    def _ladder_scored(self) -> bool:
        """Scores ``offset-too-large`` against its ladder (:func:`.too_large.score`), unless a mistake scored before
        it passes already: its ladder is the costliest look of the round, and the image is explained without it.
        False where it is not scored (it is then scored later, if none passes)."""
        if any(c.passes for c in self.scored):
            return False
        return too_large.score(self, self.cannot_pass)

    def alike_round(self) -> None:
        """Scores the new mistakes that may render the image of a classic one passed against (:data:`ALIKE`), so
        that where the image cannot tell them apart, both readings are given."""
        passing = [c.variant for c in self.scored if c.passes]
        for name in [twin for variant in passing for twin in ALIKE.get(variant, ())]:
            self.renders.check()
            if self.shown(name) and all(c.variant != name for c in self.scored):
                self.score(name, self.cannot_pass)

    def closest_round(self, later: list[str], later_bounds: list[str]) -> None:
        """Scores those of the mistakes put off by :meth:`first_round` that may come closest."""
        renders, closest = self.renders, self.cannot_come_closest
        for name in later:
            renders.check()
            if name == too_large.NAME:
                too_large.score(self, closest)
                continue
            least = off_at_least(name, self.submitted, self.verdict, renders, closest, self.first)  # (every row)
            if least is None or not closest(least):
                self.score(name, closest)
        for name in later_bounds:
            renders.check()
            least = outside_at_least(name, self.reference, self.submitted, self.verdict, renders, closest, self.first)
            if least is None or not closest(least):
                self.score_speckled(name, closest)

    def named(self) -> tuple[list[Cause], bool]:
        """The causes named, best first, and whether the first is only the closest: those passed against, or
        else the one that comes far closer than the reference does, or none."""
        # (of two alike, the classic mistake first: the new one is a further reading of the same image)
        # (of two alike, a render matched before a speckled mistake's test between bounds: acne's far end darkens
        # every lit point, so a mistake that only adds shadow passes that test too, and a render that matches it
        # as well or better is that mistake's, not acne's)
        self.scored.sort(
            key=lambda c: (
                not c.passes,
                c.fraction_off_nearby,
                c.variant in BOUNDS,
                c.variant not in VARIANTS,
                c.variant,
            )
        )
        passing = [c for c in self.scored if c.passes]
        rendered = [c.fraction_off_nearby for c in passing if c.variant not in BOUNDS]
        if rendered:
            passing = [c for c in passing if c.variant not in BOUNDS or c.fraction_off_nearby < min(rendered)]
        if passing:
            return passing, False
        if self.scored and self.scored[0].fraction_off_nearby <= CLOSEST_SHARE * self.verdict.fraction_off_nearby:
            return self.scored[:1], True
        return [], False


def _words(name: str) -> str:
    """What a student did, in words: a classic mistake's or a new one's."""
    return VARIANTS[name][1] if name in VARIANTS else MORE_VARIANTS[name][1]
