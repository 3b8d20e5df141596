"""A uniform grid over the BVH's primitives: for each cell, every primitive whose box comes near it.

This is the walk's other way (besides :mod:`tracer.proxies`' neighbour
lists) to know, after Embree reports a crossing, which primitives must be
tested exactly before the walk may step on.  When Embree reports a crossing
at a point ``x``, every primitive registered in the cell that holds ``x`` is
tested in float64, and the walk goes on from where the ray leaves that cell:
any surface the ray could meet inside the cell, or any proxy that contains
the point where it goes on, has a box that comes near the cell, so it was
tested.  A ray that starts on a surface does the same with the cell of its
start.

The lists cost a sort of a few registrations per primitive, where neighbour
pairs cost a box test of every pair of nearby primitives; a cell is about as
large as a primitive, so a crossing tests about as many primitives either
way.  :func:`build_cells` gives up (returns None) when the primitives'
sizes are so mixed that the registrations would pass :data:`BUDGET_PER`
per primitive.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .proxies import stable_order
from .vec import highest, lowest, most
from .world import median_of

#: the cell's edge over the largest box among those up to four times the median size
CELL_SCALE = 0.5
#: boxes over at most this many cells along every axis are registered an offset at a time
SPAN = 3
#: the registrations a scene may have, per primitive (beyond a floor of 2^20), before cells give way to pairs
BUDGET_PER = 32


@dataclass
class Cells:
    origin: np.ndarray  # (3,) the low corner of cell (0, 0, 0)
    size: float  # the edge of a cell
    dims: np.ndarray  # (3,) int64 cells along each axis
    keys: np.ndarray  # (C,) int64 sorted keys of the cells that hold something
    start: np.ndarray  # (C + 1,) members of cell c: ``members[start[c]:start[c + 1]]``
    members: np.ndarray  # (R,) int64 primitive ids

    def locate(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For points (N, 3): the index of each one's cell in :attr:`keys` (−1 for a cell that holds
        nothing) and that cell's box, lo and hi (N, 3) each."""
        with np.errstate(invalid="ignore", over="ignore"):
            k = np.floor((points - self.origin) / self.size)
        k = np.clip(np.nan_to_num(k, nan=-1.0), -1, self.dims).astype(np.int64)
        lo = self.origin + k * self.size
        hi = self.origin + (k + 1) * self.size
        inside = np.all((k >= 0) & (k < self.dims), axis=1)
        key = self._key(np.where(inside[:, None], k, 0))
        at = np.minimum(np.searchsorted(self.keys, key), len(self.keys) - 1)
        found = inside & (self.keys[at] == key)
        return np.where(found, at, -1), lo, hi

    def _key(self, k: np.ndarray) -> np.ndarray:
        return (k[:, 0] * self.dims[1] + k[:, 1]) * self.dims[2] + k[:, 2]

    def pairs(self, rows: np.ndarray, cell: np.ndarray, but: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(ray, primitive) pairs: each of ``rows`` with every member of its ``cell`` (−1: none), except the
        primitive ``but`` names for that row (when given; −1 for none)."""
        some = cell >= 0
        first = np.where(some, self.start[np.maximum(cell, 0)], 0)
        count = np.where(some, self.start[np.maximum(cell, 0) + 1] - first, 0)
        offset = np.repeat(first - np.cumsum(count) + count, count)
        ray, prim = np.repeat(rows, count), self.members[offset + np.arange(len(offset))]
        if but is None:
            return ray, prim
        keep = prim != np.repeat(but, count)
        return ray[keep], prim[keep]


def build_cells(lo: np.ndarray, hi: np.ndarray, reach: float) -> Cells | None:
    """Cells for primitives with boxes ``lo..hi (P, 3)``, each registered wherever it comes within
    ``reach`` of a cell; None when that would take more than the budget."""
    n = len(lo)
    if n == 0:
        return None
    lo, hi = lo - reach, hi + reach
    extent = most(hi - lo)
    median = median_of(extent)
    with np.errstate(invalid="ignore"):
        ordinary = extent <= 4.0 * median
    if not np.all(np.isfinite(extent)) or not ordinary.any():
        return None
    size = CELL_SCALE * float(np.max(extent[ordinary]))
    if not size > 0:
        return None
    origin = lowest(lo)
    top = np.floor((highest(hi) - origin) / size)
    if not np.all(top < 2.0**20):  # keys must fit in 63 bits
        return None
    dims = top.astype(np.int64) + 1
    k_lo = np.clip(np.floor((lo - origin) / size), 0, dims - 1).astype(np.int64)
    k_hi = np.clip(np.floor((hi - origin) / size), 0, dims - 1).astype(np.int64)
    span = k_hi - k_lo + 1
    count = span[:, 0] * span[:, 1] * span[:, 2]
    total = int(count.sum())
    if total > BUDGET_PER * n + (1 << 20):
        return None
    cells = Cells(origin=origin, size=size, dims=dims, keys=np.zeros(0, np.int64), start=np.zeros(1, np.int64),
                  members=np.zeros(0, np.int64))
    base = cells._key(k_lo)
    stride = np.array([dims[1] * dims[2], dims[2], 1])
    owners, keys = [], []
    few = np.all(span <= SPAN, axis=1)
    reaches = [[span[:, axis] > o for o in range(SPAN)] for axis in range(3)]
    for dx in range(SPAN):  # the common boxes, an offset at a time
        in_x = few & reaches[0][dx]
        for dy in range(SPAN):
            in_xy = in_x & reaches[1][dy]
            for dz in range(SPAN):
                sel = np.flatnonzero(in_xy & reaches[2][dz])
                owners.append(sel)
                keys.append(base[sel] + int(dx * stride[0] + dy * stride[1] + dz))
    many = np.flatnonzero(~few)
    if len(many):  # boxes over more cells: registration r of box b is the r-th cell of its span, x, y, z order
        c = count[many]
        owner = np.repeat(many, c)
        r = np.arange(len(owner), dtype=np.int64) - np.repeat(np.cumsum(c) - c, c)
        sy, sz = span[owner, 1], span[owner, 2]
        k = k_lo[owner] + np.stack([r // (sy * sz), (r // sz) % sy, r % sz], axis=1)
        owners.append(owner)
        keys.append(cells._key(k))
    owner, key = np.concatenate(owners), np.concatenate(keys)
    order = stable_order(key, int(dims.prod()))  # stable: the same members in the same order on every run
    key, members = key[order], owner[order]
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    cells.keys = key[first]
    cells.start = np.r_[first, total].astype(np.int64)
    cells.members = members
    return cells
