"""A uniform grid over the BVH's primitives: for each part of a cell, every primitive whose box comes near it.

This is the walk's other way (besides :mod:`tracer.exact.proxies`' neighbour
lists) to know, after Embree reports a crossing, which primitives must be
tested exactly before the walk may step on.  Each cell is cut into
``SUB³`` parts, and each primitive registered in a cell carries a bit mask
of the parts its box comes near.  When Embree reports a crossing at a point
``x``, every member of the part that holds ``x`` is tested in float64, and
the walk goes on from where the ray leaves that part: any surface the ray
could meet inside the part, or any proxy that contains the point where it
goes on, has a box that comes near the part, so it was tested.  A ray that
starts on a surface does the same with the part of its start.

The lists cost a sort of a few registrations per primitive, where neighbour
pairs cost a box test of every pair of nearby primitives; a cell is about as
large as the largest ordinary primitive, so a part holds a few.
:func:`build_cells` makes the cells coarser where the primitives' sizes are
so mixed that the registrations would pass :data:`BUDGET_PER` per primitive.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.vec import highest, lowest, median_of, minus, most, plus, rows_of

#: the cell's edge over the largest box among those up to four times the median size
CELL_SCALE = 1.0
#: each cell is cut into SUB × SUB × SUB parts; a member's bit mask says which parts its box comes near
SUB = 4
#: boxes over at most this many cells along every axis are registered an offset at a time
SPAN = 2
#: the registrations a scene may have, per primitive (beyond a floor of 2^20), before cells grow coarser
BUDGET_PER = 32
#: a grid of at most this many cells (or 4 per occupied cell) finds cells by a table, not a binary search
TABLE_MAX = 1 << 22


def _spans() -> np.ndarray:
    """``(3, SUB, SUB)`` bit masks: for axis a and parts lo..hi along it, the bits of every part of the
    cell whose index along a lies in lo..hi (part (i, j, k) is bit (i·SUB + j)·SUB + k)."""
    out = np.zeros((3, SUB, SUB), dtype=np.uint64)
    for axis in range(3):
        for lo in range(SUB):
            for hi in range(lo, SUB):
                bits = 0
                for part in np.ndindex(SUB, SUB, SUB):
                    if lo <= part[axis] <= hi:
                        bits |= 1 << ((part[0] * SUB + part[1]) * SUB + part[2])
                out[axis, lo, hi] = bits
    return out


SPANS = _spans()


@dataclass
class Cells:
    origin: np.ndarray  # (3,) the low corner of cell (0, 0, 0)
    size: float  # the edge of a cell
    dims: np.ndarray  # (3,) int64 cells along each axis
    keys: np.ndarray  # (C,) int64 sorted keys of the cells that hold something
    start: np.ndarray  # (C + 1,) members of cell c: ``members[start[c]:start[c + 1]]``
    members: np.ndarray  # (R,) int64 primitive ids
    parts: np.ndarray  # (R,) uint64 which parts of its cell each member's box comes near
    #: (dims.prod(),) int32 each cell's index in :attr:`keys`, −1 for none; None for a grid too large for it
    table: np.ndarray | None = None

    def locate(self, points: np.ndarray, whole: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For points (N, 3): the part of a cell each lies in, as ``cell · SUB³ + part`` with the cell's index
        in :attr:`keys` (−1 for a cell that holds nothing), and that part's box, lo and hi (N, 3) each.

        With ``whole``, the region is the whole cell instead, numbered :attr:`whole_base` ``+ cell``, and the
        box is the cell's: a coarser region (every member of every part), for rays that step far."""
        with np.errstate(invalid="ignore", over="ignore"):
            k = np.floor(minus(points, self.origin) / self.size)  # (a column at a time, see tracer.scene.vec)
        k = np.clip(_finite(k, -1.0), -1, self.dims).astype(np.int64)
        corner = plus(self.origin, k * self.size)
        inside = (k[:, 0] >= 0) & (k[:, 1] >= 0) & (k[:, 2] >= 0)  # (a column at a time, see tracer.scene.vec)
        inside &= (k[:, 0] < self.dims[0]) & (k[:, 1] < self.dims[1]) & (k[:, 2] < self.dims[2])
        key = self._key(np.where(inside[:, None], k, 0))
        if self.table is not None:
            at = np.take(self.table, key).astype(np.int64)
            found = inside & (at >= 0)
        else:
            at = np.minimum(np.searchsorted(self.keys, key), len(self.keys) - 1)
            found = inside & (self.keys[at] == key)
        if whole:
            return np.where(found, self.whole_base + at, -1), corner, corner + self.size
        part = self._parts_of(points, corner)
        step = self.size / SUB
        lo = corner + part * step
        hi = lo + step
        return np.where(found, at * SUB**3 + (part[:, 0] * SUB + part[:, 1]) * SUB + part[:, 2], -1), lo, hi

    @property
    def whole_base(self) -> int:
        """Region numbers from here on name whole cells (:meth:`locate` with ``whole``); below, parts."""
        return len(self.keys) * SUB**3

    def _parts_of(self, points: np.ndarray, corner: np.ndarray) -> np.ndarray:
        """The part (i, j, k) of the cell with low corner ``corner`` that holds each point, clipped into it."""
        with np.errstate(invalid="ignore", over="ignore"):
            part = np.floor((points - corner) / (self.size / SUB))
        return np.clip(_finite(part, 0.0), 0, SUB - 1).astype(np.int64)

    def _key(self, k: np.ndarray) -> np.ndarray:
        return (k[:, 0] * self.dims[1] + k[:, 1]) * self.dims[2] + k[:, 2]

    def groups(self, region: np.ndarray, most: int) -> list[slice]:
        """Consecutive slices of ``region`` (from :meth:`locate`) whose cells hold at most ``most`` candidates
        together (or one region, when its own cell holds more): :meth:`pairs` of each slice in turn then holds
        bounded memory, however many primitives many rays' cells share (10,000 spheres around the eye)."""
        cell = np.where(region >= self.whole_base, region - self.whole_base, region // SUB**3)
        count = np.where(
            region >= 0, np.take(self.start, cell + 1, mode="clip") - np.take(self.start, cell, mode="clip"), 0
        )
        ends = np.cumsum(count)
        if len(ends) == 0 or ends[-1] <= most:
            return [slice(0, len(region))]
        cuts = np.unique(np.searchsorted(ends, np.arange(most, ends[-1], most), side="right"))
        edges = [0, *(int(c) for c in cuts if 0 < c < len(region)), len(region)]
        return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]

    def pairs(
        self, rows: np.ndarray, region: np.ndarray, but: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(ray, primitive) pairs: each of ``rows`` with every member of its ``region`` (from :meth:`locate`;
        −1: none) that comes near that part of the cell (or, for a whole cell, every member), except the
        primitives ``but`` names for that row (when given: ``(n,)`` or ``(n, k)``; −1 for none)."""
        some = np.flatnonzero(region >= 0)
        if len(some) < len(region):
            rows, region = rows[some], region[some]
            but = None if but is None else but[some]
        whole = region >= self.whole_base
        some_whole = bool(whole.any())
        cell, bit = np.divmod(region, SUB**3)
        if some_whole:
            cell = np.where(whole, region - self.whole_base, cell)
        first = self.start[cell]
        count = self.start[cell + 1] - first
        own = np.repeat(np.arange(len(region)), count)  # each candidate's row; the rest are gathers by it
        at = np.take(first - np.cumsum(count) + count, own) + np.arange(len(own))
        keep = ((np.take(self.parts, at) >> np.take(bit.astype(np.uint64), own)) & np.uint64(1)).astype(bool)
        if some_whole:
            keep |= np.take(whole, own)
        kept = np.flatnonzero(keep)  # (a gather by index is several times faster than by a mask here)
        own, members = np.take(own, kept), np.take(self.members, np.take(at, kept))
        if but is not None:  # (on the few candidates the parts keep)
            keep = np.ones(len(own), dtype=bool)
            for column in (but[:, None] if but.ndim == 1 else but).T:
                keep &= members != np.take(column, own)
            kept = np.flatnonzero(keep)
            own, members = np.take(own, kept), np.take(members, kept)
        return np.take(rows, own), members


def _finite(a: np.ndarray, fill: float) -> np.ndarray:
    """``a`` with NaN as ``fill`` (infinities are clipped by the caller); no copy when all is finite."""
    return a if np.isfinite(a).all() else np.where(np.isnan(a), fill, a)


def build_cells(lo: np.ndarray, hi: np.ndarray, reach: float) -> Cells:
    """Cells for primitives with boxes ``lo..hi (P, 3)`` (finite, P ≥ 1), each registered wherever it comes
    within ``reach`` of a cell.

    A cell is as large as the largest box among those up to four times the median size; where that would
    make more than 2^20 cells along an axis, or more registrations than the budget (:data:`BUDGET_PER` per
    primitive beyond a floor of 2^20, as when many boxes are far larger than the rest), cells double in size
    until it does not.  Any size is correct (a box is registered in every cell it comes near); the size
    only decides how many members a part holds."""
    n = len(lo)
    lo, hi = lo - reach, hi + reach
    origin, size = _grid(lo, hi)
    dims, k_lo, k_hi = _box_cells(lo, hi, origin, size)
    span = k_hi - k_lo + 1
    count = span[:, 0] * span[:, 1] * span[:, 2]
    total = int(count.sum())
    cells = Cells(
        origin=origin,
        size=size,
        dims=dims,
        keys=np.zeros(0, np.int64),
        start=np.zeros(1, np.int64),
        members=np.zeros(0, np.int64),
        parts=np.zeros(0, np.uint64),
    )
    # the parts each box's ends lie in, within the first and the last cell of its span along each axis
    p_lo = cells._parts_of(lo, origin + k_lo * size)
    p_hi = cells._parts_of(hi, origin + k_hi * size)
    top_part = np.full(n, SUB - 1)

    def along_axis(axis: int, offset: np.ndarray | int) -> np.ndarray:
        """The mask of the parts a box comes near, along ``axis``, in the cell ``offset`` into its span."""
        first = np.where(np.equal(offset, 0), p_lo[:, axis], 0)
        last = np.where(np.equal(offset, span[:, axis] - 1), p_hi[:, axis], top_part)
        return SPANS[axis, first, last]

    owners, keys, parts = [], [], []
    base = cells._key(k_lo)
    stride = (dims[1] * dims[2], dims[2], 1)
    few = np.all(span <= SPAN, axis=1)
    reaches = [[span[:, axis] > o for o in range(SPAN)] for axis in range(3)]
    masks = [[along_axis(axis, o) for o in range(SPAN)] for axis in range(3)]
    for dx in range(SPAN):  # the common boxes, an offset at a time
        in_x = few & reaches[0][dx]
        for dy in range(SPAN):
            in_xy = in_x & reaches[1][dy]
            for dz in range(SPAN):
                sel = np.flatnonzero(in_xy & reaches[2][dz])
                owners.append(sel)
                keys.append(base[sel] + int(dx * stride[0] + dy * stride[1] + dz))
                parts.append(masks[0][dx][sel] & masks[1][dy][sel] & masks[2][dz][sel])
    many = np.flatnonzero(~few)
    if len(many):  # boxes over more cells: registration r of box b is the r-th cell of its span, x, y, z order
        c = count[many]
        owner = np.repeat(many, c)
        r = np.arange(len(owner), dtype=np.int64) - np.repeat(np.cumsum(c) - c, c)
        sy, sz = span[owner, 1], span[owner, 2]
        offset = np.stack([r // (sy * sz), (r // sz) % sy, r % sz], axis=1)
        owners.append(owner)
        keys.append(cells._key(rows_of(k_lo, owner) + offset))
        mask = np.full(len(owner), ~np.uint64(0))
        for axis in range(3):
            o, sp = offset[:, axis], span[owner, axis]
            first = np.where(o == 0, p_lo[owner, axis], 0)
            last = np.where(o == sp - 1, p_hi[owner, axis], SUB - 1)
            mask &= SPANS[axis, first, last]
        parts.append(mask)
    owner, key, part = np.concatenate(owners), np.concatenate(keys), np.concatenate(parts)
    order = stable_order(key, int(dims.prod()))  # stable: the same members in the same order on every run
    key = key[order]
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    cells.keys = key[first]
    cells.start = np.r_[first, total].astype(np.int64)
    grid = int(dims.prod())
    if grid <= max(TABLE_MAX, 4 * len(cells.keys)) and grid < 1 << 31:
        cells.table = np.full(grid, -1, dtype=np.int32)
        cells.table[cells.keys] = np.arange(len(cells.keys), dtype=np.int32)
    cells.members = owner[order]
    cells.parts = part[order]
    return cells


def _box_cells(
    lo: np.ndarray, hi: np.ndarray, origin: np.ndarray, size: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The grid's cells along each axis, and the first and last cell each box ``lo..hi`` comes into."""
    dims = np.floor((highest(hi) - origin) / size).astype(np.int64) + 1
    k_lo = np.clip(np.floor((lo - origin) / size), 0, dims - 1).astype(np.int64)
    k_hi = np.clip(np.floor((hi - origin) / size), 0, dims - 1).astype(np.int64)
    return dims, k_lo, k_hi


def _grid(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """The grid's corner and its cells' size for boxes ``lo..hi`` (reach already added): the size of
    :func:`build_cells`, doubled until the registrations fit the budget."""
    n = len(lo)
    extent = most(hi - lo)
    ordinary = extent <= 4.0 * median_of(extent)
    origin = lowest(lo)
    span_all = float(np.max(highest(hi) - origin))
    size = max(CELL_SCALE * float(np.max(extent[ordinary])), span_all * 2.0**-20, float(np.max(extent)) * 2.0**-20)
    if not size > 0:
        size = 1.0
    while True:  # at most ~20 doublings: at a size of the whole span, every box has one registration
        dims, k_lo, k_hi = _box_cells(lo, hi, origin, size)
        span = k_hi - k_lo + 1
        if int((span[:, 0] * span[:, 1] * span[:, 2]).sum()) <= BUDGET_PER * n + (1 << 20) or np.all(dims == 1):
            return origin, size
        size *= 2.0


def stable_order(keys: np.ndarray, bound: int) -> np.ndarray:
    """``np.argsort(keys, kind="stable")`` for integer keys in ``0..bound-1``, by 16-bit digits: NumPy sorts
    those by radix, two to three times faster than a comparison sort of the whole keys."""
    order: np.ndarray | None = None
    shift = 0
    while True:
        digit = ((keys if order is None else keys[order]) >> shift) & 0xFFFF
        step = np.argsort(digit.astype(np.uint16), kind="stable")
        order = step if order is None else order[step]
        shift += 16
        if bound <= 1 << shift:
            return order
