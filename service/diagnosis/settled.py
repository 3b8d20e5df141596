"""A ladder of offsets ruled out on a few rows before any of it is narrowed: the early stop of
:func:`.accepting.accept` and :func:`.too_large.score`.

A ladder decides an image in two steps (:mod:`.offsets`): the range of two neighbouring rungs holds it, or else a
narrower range of amounts between the two rungs that come closest does (:func:`.offsets.narrowed`: a dozen more
renders of a few rows each).  Each step first counts the submission's pixels off on a few rows and gives up when
they are too many (``beyond``); :func:`settled` gives up on both steps at once, from the rungs' own rows, before
either is taken:

* **the rungs' ranges**: a range of two rungs leaves at least as many pixels off, on any rows, as on the rows
  looked at here, and as on any of its pixels: exact (a pixel's count depends on its 3×3 neighbourhood alone,
  :mod:`service.images.nearby`), and
* **the narrowing**: a range of amounts between two neighbouring rungs leaves off at least the pixels that the two
  rungs leave off where they render the pixel's whole neighbourhood alike (:func:`kept_off`): an amount between
  two others changes a ray's start between theirs, and a pixel whose every ray two amounts trace alike is traced
  alike in between.

The second rests on how offsets act, not on arithmetic, and is checked rather than assumed: a t_min between
two others skips a hit only where one of them does (exact, ray by ray), but a ray moved along the normal that
grazes a glass ball's rim may miss at an amount between two that both hit.  Such stray pixels are rare:
tests/test_settled.py counts them on the glass example's accepted ladder, at the amounts narrowing renders, on
every middle row (a superset of any look's): at most 16 pixels counted here of 10,800 that such an amount
renders otherwise, where the rule lets 10.8 by.  So a pixel counts only where the two rungs agree on every
pixel within :data:`REACH` of it, and a ladder is given up only when what is counted is more than
:data:`MARGIN` times what ``beyond`` refuses: to turn the verdict, strays would have to make up (MARGIN − 1)
times what is allowed (that test's bound).  The verdict is then the full ladder's, and its price a few rows of
each rung (a mistake is off on the rows that tell it, at any offset).

Of those rows, a rung is rendered only near the pixels counted (:func:`windows`): the middle rows' pixels off even
nearby against the reference, and every pixel within :data:`REACH` columns of one of them on its three rows.  A
pixel's count reads the rungs at those pixels alone (its 3×3 neighbourhood, and :func:`agreed`'s 3 × (2·REACH + 1)),
so the count on them is exactly theirs, and a count on some of the middle rows' pixels is a lower bound of the count
on all of them: giving up stays the full ladder's verdict, at the price of the pixels where the submission is off.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..images.nearby import rows_distance

#: a pixel counts against a narrower range only when both rungs render every pixel this far from it alike (along
#: its row; the rows above and below as well)
REACH = 2
#: the ladder is given up only when the pixels counted are this many times what is refused: the stray pixels an
#: amount between two rungs renders otherwise cannot turn the verdict
MARGIN = 3
#: the rows looked at first are those most off against the reference until they hold this many times what is
#: refused (a mistake leaves most of them off at any offset); the rest of the rows only when those do not settle it
FIRST_ROWS = 2 * MARGIN


def agreed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per middle row's pixel of bands ``a`` and ``b`` (each ``(k, 3, W, 3)``: a middle row with the rows above and
    below), whether the two are equal on every pixel of the three rows within :data:`REACH` columns of it (the
    edges repeated) → ``(k, W)`` bool."""
    same = np.all(a == b, axis=(1, 3))  # (k, W): the column of three pixels alike
    w = same.shape[1]
    padded = np.pad(same, ((0, 0), (REACH, REACH)), mode="edge")
    out = np.ones_like(same)
    for dx in range(2 * REACH + 1):
        out &= padded[:, dx : dx + w]
    return out


def windows(counted: np.ndarray, middles: np.ndarray, height: int) -> np.ndarray:
    """The pixels a count on the middle rows ``middles`` reads (``(H, W)`` bool): every pixel within :data:`REACH`
    columns of a pixel ``counted`` (``(k, W)`` bool, one row per middle), on the middle row and the rows either
    side (all that :func:`kept_off` reads of a counted pixel: its 3×3 neighbourhood and :func:`agreed`'s)."""
    near = counted.copy()
    for dx in range(1, REACH + 1):
        near[:, dx:] |= counted[:, :-dx]
        near[:, :-dx] |= counted[:, dx:]
    wanted = np.zeros((height, counted.shape[1]), dtype=bool)
    for dy in (-1, 0, 1):
        wanted[np.clip(middles + dy, 0, height - 1)] |= near
    return wanted


def kept_off(
    ends: tuple[np.ndarray, np.ndarray], submitted: np.ndarray, tolerance: float, shut: np.ndarray | None
) -> int:
    """The middle rows' pixels of ``submitted`` (bands, ``(k, 3, W, 3)``) off even nearby against the range of the
    two ``ends`` (bands of two neighbouring rungs' renders) where the two agree (:func:`agreed`); ``shut``
    (``(k, W)``, True: not counted) the pixels the format leaves open."""
    low, high = np.minimum(*ends), np.maximum(*ends)
    counted = (rows_distance(low, high, submitted) > tolerance) & agreed(*ends)
    if shut is not None:
        counted &= ~shut
    return int(np.count_nonzero(counted))


def settled(
    bands: Callable[[int], np.ndarray],
    rungs: int,
    submitted: np.ndarray,
    tolerance: float,
    shut: np.ndarray | None,
    beyond: Callable[[int], bool],
) -> bool:
    """Whether no range of two neighbouring rungs of a ladder, nor any narrower range between two of them, can leave
    few enough pixels off (module docstring): for every two neighbours, :data:`MARGIN` times what ``beyond`` refuses
    is off where they agree.  ``bands(k)``: rung ``k``'s bands (ascending; rung 0 the reference where the ladder
    starts from it), asked for in order, and none past the first two neighbours that do not settle it; they need be
    right only within :func:`windows` of the pixels counted (those ``shut`` leaves: it may shut any, for a lower
    bound)."""
    return rungs >= 2 and unsettled(bands, rungs, submitted, tolerance, shut, beyond) is None


def unsettled(
    bands: Callable[[int], np.ndarray],
    rungs: int,
    submitted: np.ndarray,
    tolerance: float,
    shut: np.ndarray | None,
    beyond: Callable[[int], bool],
    start: int = 1,
) -> int | None:
    """The first two neighbouring rungs from ``start`` on (``k − 1`` and ``k``: ``k`` given) that do not settle the
    ladder, as :func:`settled` asks of every two; None when none of them is left (every pair from ``start`` on
    settles it).  ``bands(k)`` is asked for rungs ``start − 1`` on alone, in order.

    The resumed look: pairs before ``start`` settled it on some of these middle rows (a look at fewer rows, the
    same pixels of theirs counted), and a count on more rows is at least the count on those (each middle row's
    count reads its own band alone): they settle it here too, and their rungs are not rendered on the rows added.
    """
    if not submitted.shape[0]:
        return start
    previous = bands(start - 1)
    for k in range(start, rungs):
        current = bands(k)
        if not beyond(kept_off((previous, current), submitted, tolerance, shut) // MARGIN):
            return k
        previous = current
    return None
