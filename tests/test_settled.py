"""A ladder of offsets given up on a few rows (service.diagnosis.settled): the count it rests on, exactly; the
stray pixels it allows for, on the glass example; and the verdicts, the full ladder's."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import student

from schemas import validate_scene
from service.diagnosis import accepting, diagnose, renders_of, settled, too_large
from service.diagnosis.offsets import POINTS, rung, visible_size
from service.images.grading import grade
from tracer import Renderer
from tracer.scene.variants import REFERENCE

WHITTED = Path(__file__).resolve().parent.parent / "examples" / "04_whitted.json"


def _bands(row: np.ndarray) -> np.ndarray:
    """One middle row of pixel values (W,) as bands (1, 3, W, 3): the rows above and below alike."""
    return np.repeat(np.repeat(row.astype(np.uint8)[None, None, :, None], 3, axis=1), 3, axis=3)


def test_the_count_is_the_pixels_off_where_both_rungs_agree_on_the_whole_neighbourhood():
    w = 20
    low = _bands(np.zeros(w))
    high = _bands(np.where(np.arange(w) == 10, 50, 0))  # the rungs disagree at column 10 alone
    submitted = _bands(np.where(np.isin(np.arange(w), [0, 3, 8, 12, 15, 19]), 255, 0))
    # columns 8..12 lie within REACH of the disagreement: 0, 3, 15 and 19 are counted
    assert settled.REACH == 2
    assert settled.kept_off((low, high), submitted, 2.0, None) == 4
    shut = np.isin(np.arange(w), [3])[None, :]
    assert settled.kept_off((low, high), submitted, 2.0, shut) == 3


def test_a_ladder_is_given_up_only_past_the_margin_and_on_every_pair_of_rungs():
    w = 20
    rungs = [_bands(np.zeros(w)), _bands(np.zeros(w)), _bands(np.zeros(w))]
    submitted = _bands(np.where(np.arange(w) % 4 == 0, 255, 0))  # 5 pixels off wherever the rungs agree
    assert settled.MARGIN == 3  # 5 // 3 = 1 counted against what is refused

    def given_up(allowed: int, ladder: list[np.ndarray] = rungs) -> bool:
        return settled.settled(lambda k: ladder[k], len(ladder), submitted, 2.0, None, lambda off: off > allowed)

    assert given_up(0) and not given_up(1)  # (off by one either way, the verdict would change)
    some = [rungs[0], rungs[1], _bands(np.full(w, 255))]  # the last two rungs agree nowhere: nothing counted there
    assert not given_up(0, some)
    assert not given_up(0, rungs[:1])  # (one rung: no range to rule out)


def test_a_look_on_more_rows_asks_only_for_the_rungs_from_the_pair_left_open():
    """The resumed look: pairs a look at fewer rows settled are not asked again (their count on more rows is at
    least theirs); the rungs from the pair left open are, and settle it or say which pair is open."""
    w = 20
    ladder = [_bands(np.zeros(w)), _bands(np.zeros(w)), _bands(np.zeros(w)), _bands(np.full(w, 255))]
    submitted = _bands(np.where(np.arange(w) % 4 == 0, 255, 0))
    asked: list[int] = []

    def bands(k: int) -> np.ndarray:
        asked.append(k)
        return ladder[k]

    def left(start: int) -> int | None:
        asked.clear()
        return settled.unsettled(bands, len(ladder), submitted, 2.0, None, lambda off: off > 0, start)

    assert left(1) == 3 and asked == [0, 1, 2, 3]  # (rungs 2 and 3 agree nowhere: that pair is left open)
    assert left(3) == 3 and asked == [2, 3]  # (resumed there: rungs 0 and 1 are not rendered again)
    assert settled.unsettled(lambda k: ladder[k], 3, submitted, 2.0, None, lambda off: off > 0, 2) is None


def test_a_count_near_the_pixels_counted_reads_the_rungs_there_alone():
    """:func:`settled.windows`: rungs right only within REACH columns of the pixels counted (on the middle row and
    the rows either side) give the count of a whole render, there; elsewhere they may be anything."""
    rng = np.random.default_rng(5505)
    h, w, middles = 12, 30, np.array([2, 6, 9])
    rows = (middles[:, None] + np.arange(-1, 2)[None, :]).ravel()
    low = rng.choice([0, 10, 200], size=(h, w, 3)).astype(np.uint8)
    high = low.copy()
    high[rng.random((h, w)) < 0.05] = 100  # (the two rungs disagree here and there)
    whole = [low, high]
    submitted = rng.choice([0, 10, 200], size=(h, w, 3)).astype(np.uint8)[rows].reshape(3, 3, w, 3)
    counted = rng.random((3, w)) < 0.3
    wanted = settled.windows(counted, middles, h)
    assert wanted[middles].sum() < wanted[middles].size  # (some pixels are not read)
    garbled = [np.where(wanted[..., None], image, rng.integers(0, 256, image.shape, dtype=np.uint8)) for image in whole]
    ends = [tuple(image[rows].reshape(3, 3, w, 3) for image in pair) for pair in (whole, garbled)]
    counts = [settled.kept_off(pair, submitted, 2.0, ~counted) for pair in ends]  # type: ignore[arg-type]
    assert counts[0] == counts[1] > 0


@pytest.fixture(scope="module")
def glass():  # noqa: ANN201
    data = json.loads(WHITTED.read_text())
    data["image"].update(width=120, height=90)
    return validate_scene(data)


def test_amounts_between_two_rungs_stray_from_both_in_fewer_pixels_than_the_margin_covers(glass):
    """What the margin covers: at the amounts narrowing renders between two neighbouring rungs of the accepted
    ladder, the pixels counted where both rungs agree (:func:`settled.agreed`) whose neighbourhood the amount
    between renders otherwise, every middle row of the image looked at: fewer than the margin lets by (a ladder
    given up holds more than MARGIN times what is allowed, so strays would have to make up MARGIN − 1 times it)."""
    h, w = glass.image.height, glass.image.width
    middles = np.arange(1, h - 1)
    rows = (middles[:, None] + np.arange(-1, 2)[None, :]).ravel()

    def bands(options) -> np.ndarray:  # noqa: ANN001
        return Renderer(glass, options).pixels()[rows].reshape(len(middles), 3, w, 3)

    def alike(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # the 3×3 neighbourhood alike, (k, W)
        same = np.pad(np.all(a == b, axis=(1, 3)), ((0, 0), (1, 1)), mode="edge")
        return same[:, :-2] & same[:, 1:-1] & same[:, 2:]

    rungs = next(r for r in accepting.accepted_ladders(glass, None) if r[0].kind == "normal-offset")
    made = [bands(REFERENCE), *(bands(r.options) for r in rungs)]
    amounts, size = [0.0, *(r.amount for r in rungs)], visible_size(glass)
    strays = []
    for k in range(len(rungs)):
        low, high = amounts[k], amounts[k + 1]
        agree = settled.agreed(made[k], made[k + 1])
        for j in (1, 2, 3, 4):  # (narrowing's first round: the amounts between the two ends)
            between = low * (high / low) ** (j / (POINTS - 1)) if low else high * j / (POINTS - 1)
            there = bands(rung("normal-offset", between, size).options)
            strays.append(int(np.count_nonzero(agree & ~alike(there, made[k]))))
    allowed = 0.001 * h * w
    assert max(strays) <= (settled.MARGIN - 1) * allowed, strays


def _accepted(scene, image: np.ndarray, reference: np.ndarray, full: bool, monkeypatch) -> tuple:  # noqa: ANN001
    """``accept``'s verdict, early stop or the full ladder (``full``), cold; and whether it narrowed."""
    narrowed = []
    monkeypatch.setattr(accepting, "KEPT_RENDERS", accepting._Kept())
    original = accepting._narrowed
    monkeypatch.setattr(accepting, "_narrowed", lambda *a: narrowed.append(1) or original(*a))
    if full:
        monkeypatch.setattr(accepting, "_unsettled", lambda *a: a[-1])
    found = accepting.accept(scene, accepting.Failing(reference, image, grade(reference, image, "")))
    monkeypatch.undo()
    said = None if found is None else (found.words, found.grade.passed, found.grade.fraction_off_nearby)
    return said, bool(narrowed)


@pytest.mark.parametrize(
    "made",
    [
        {"mistakes": ("no-shadows",)},
        {"mistakes": ("gamma",)},
        {"mistakes": ("offset-too-large",), "narrows": True},  # (0.1: a t_min up to 0.06 comes near it)
        {"amount": 0.025, "narrows": True},
    ],
)
def test_the_early_stop_gives_the_full_ladders_verdict(glass, made, monkeypatch):
    """A mistake stops before any narrowing; an honest 0.025 (between the rungs 0.02 and 0.03, held by neither
    range) passes only once narrowed, and the stop lets it be."""
    reference = Renderer(glass).pixels()
    amount = made.get("amount")
    style = None if amount is None else student.Offset(amount)
    image = student.render(glass, made.get("mistakes", ()), style)
    early, narrowed_early = _accepted(glass, image, reference, False, monkeypatch)
    full, narrowed_full = _accepted(glass, image, reference, True, monkeypatch)
    assert early == full and narrowed_full and narrowed_early == made.get("narrows", False)
    assert (early is not None and early[1]) == (amount is not None)


@pytest.mark.parametrize("mistake", ["no-shadows", "offset-too-large"])
def test_the_early_stop_leaves_every_diagnosis_as_it_was(glass, mistake, monkeypatch):
    reference = Renderer(glass).pixels()
    image = student.render(glass, (mistake,))
    verdict = grade(reference, image, "")
    early = diagnose(reference, image, verdict, renders_of(glass)).as_dict()
    monkeypatch.setattr(too_large._Sampled, "unsettled", lambda *a: a[-1])
    assert diagnose(reference, image, verdict, renders_of(glass)).as_dict() == early
