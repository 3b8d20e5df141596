"""The nearest hit so far of each ray of a batch, whatever order its candidates come in; and where a ray's line
crosses a box (the walk's start, and each part of a cell it steps through)."""

from __future__ import annotations

import numpy as np

from ..scene.shapes import MISS
from .ties import INDEX_MASK, KIND_SHIFT, Ties, surface_key

#: a ray's key (:class:`Best`) while it has hit nothing
NO_HIT = _NONE = np.iinfo(np.int64).max


def slab(origins: np.ndarray, dirs: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each ray's line enters and leaves the box ``lo..hi`` (empty when enter > leave). Each (N,).

    An axis at a time, on 1-D columns.  Along an axis the ray does not move on (a zero direction), the
    slab is all of the line when the origin lies in it (closed) and none of it otherwise."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    n = len(origins)
    near, far = np.full(n, -np.inf), np.full(n, np.inf)
    t0, t1, inv = np.empty(n), np.empty(n), np.empty(n)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for a in range(3):  # in place: a few passes per axis and no temporaries
            o, d = origins[:, a], dirs[:, a]
            la, ha = (lo[..., a], hi[..., a])
            np.divide(1.0, d, out=inv)
            np.subtract(la, o, out=t0)
            t0 *= inv
            np.subtract(ha, o, out=t1)
            t1 *= inv
            flat = d == 0
            if flat.any():
                inside = (o >= la) & (o <= ha)
                t0[flat] = np.where(inside[flat], -np.inf, np.inf)  # outside: both inf, the slab is empty
                t1[flat] = np.inf
            np.maximum(near, np.minimum(t0, t1), out=near)
            np.minimum(far, np.maximum(t0, t1), out=far)
    return near, far


class Best:
    """Running best hit per ray, updated so that the answer never depends on the order candidates come in: the
    least ``t``, and of equal ``t`` the least key (:mod:`tracer.exact.ties`: the tie order, with ``ties``; else kind
    and index).  With the ``ties`` of a world that has coplanar groups, :attr:`open` says which rays met, at
    their best ``t``, surfaces of two objects, one in a coplanar group: a tie the format leaves open."""

    def __init__(self, limit: np.ndarray, ties: Ties | None = None):
        n = len(limit)
        self.t = limit.astype(np.float64, copy=True)
        self.key = np.full(n, _NONE, dtype=np.int64)
        self.uv = np.zeros((n, 2))
        self.ties = ties
        #: with coplanar groups: of the candidates at each ray's best t, the least and greatest object, and
        #: whether one is in a group (monotone over the candidates, so in any order the same)
        self._objects: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        if ties is not None and ties.groups is not None:
            self._objects = (np.full(n, _NONE, dtype=np.int64), np.full(n, -1, dtype=np.int64), np.zeros(n, bool))

    @property
    def open(self) -> np.ndarray | None:
        """(N,) bool: the ray met surfaces of two objects at its best ``t``, one of them in a coplanar group (None
        for a world without groups, where no tie is open)."""
        if self._objects is None:
            return None
        low, high, grouped = self._objects
        return (high > low) & grouped

    def _keys(self, kind: int | np.ndarray, index: np.ndarray) -> np.ndarray:
        if self.ties is None:
            return np.asarray(surface_key(kind, index), dtype=np.int64)
        return self.ties.key(kind, index)

    def offer(
        self,
        rows: np.ndarray,
        t: np.ndarray,
        kind: int | np.ndarray,
        index: np.ndarray,
        u: np.ndarray | None = None,
        v: np.ndarray | None = None,
        unique: bool = False,
    ) -> None:
        """Offer hits ``t`` of surfaces (kind, index) to rays ``rows``; rows may repeat unless ``unique``."""
        hit = np.isfinite(t)
        if not np.any(hit):
            return
        rows, t, index = rows[hit], t[hit], index[hit]
        kinds = np.broadcast_to(kind, hit.shape)[hit] if isinstance(kind, np.ndarray) else kind
        key = self._keys(kinds, index)
        if unique or len(rows) <= 1 or bool(np.all(rows[1:] > rows[:-1])):  # one hit per ray (as usual)
            pick = np.arange(len(rows))
            if self._objects is not None:
                self._meet(rows, t, *self._of(key))
        else:
            order = np.lexsort((key, t, rows))
            first = np.r_[True, rows[order][1:] != rows[order][:-1]]
            pick = order[first]
            if self._objects is not None:
                self._meet(rows[pick], t[pick], *self._levels(t[order], key[order], first))
        r, tt, kk = rows[pick], t[pick], key[pick]
        better = (tt < self.t[r]) | ((tt == self.t[r]) & (kk < self.key[r]))
        r, pick = r[better], pick[better]
        self.t[r], self.key[r] = tt[better], kk[better]
        if u is not None and v is not None:
            self.uv[r, 0], self.uv[r, 1] = u[hit][pick], v[hit][pick]

    def offer_all(
        self, t: np.ndarray, kind: int, index: int, u: np.ndarray | None = None, v: np.ndarray | None = None
    ) -> None:
        """:meth:`offer` of one surface's hits ``t`` to every ray, in order (each ray once): the same rule, a
        finite hit taken where it is nearer or, as near, of a smaller key, with no rows gathered."""
        key = self.ties.key_of(kind, index) if self.ties is not None else int(surface_key(kind, index))
        if self._objects is not None:
            rows = np.flatnonzero(np.isfinite(t) & (t <= self.t))
            self._meet(rows, t[rows], *self._of(np.full(len(rows), key, dtype=np.int64)))
        with np.errstate(invalid="ignore"):
            better = t < self.t
            better |= (t == self.t) & (key < self.key)
            better &= np.isfinite(t)
        np.copyto(self.t, t, where=better)
        np.copyto(self.key, key, where=better)
        if u is not None and v is not None:
            np.copyto(self.uv[:, 0], u, where=better)
            np.copyto(self.uv[:, 1], v, where=better)

    def _of(self, key: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The objects of surfaces ``key`` (twice: the least and greatest of one), and which are in a group."""
        assert self.ties is not None
        obj, grouped = self.ties.objects_of(key)
        return obj, obj, grouped

    def _levels(self, t: np.ndarray, key: np.ndarray, first: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For candidates sorted by ray, t and key (``first`` marks each ray's first), the least and greatest
        object of those at their ray's first t, and whether one is in a group. Each (rays,)."""
        assert self.ties is not None
        obj, grouped = self.ties.objects_of(key)
        lead = np.maximum.accumulate(np.where(first, np.arange(len(t)), 0))  # each candidate's ray's first
        level = t == t[lead]
        starts = np.flatnonzero(first)
        low = np.minimum.reduceat(np.where(level, obj, _NONE), starts)
        high = np.maximum.reduceat(np.where(level, obj, -1), starts)
        return low, high, np.logical_or.reduceat(level & grouped, starts)

    def _meet(self, r: np.ndarray, t: np.ndarray, low: np.ndarray, high: np.ndarray, grouped: np.ndarray) -> None:
        """Rays ``r`` (distinct) meet, at ``t``, objects ``low..high`` (one in a group where ``grouped``): a nearer
        ``t`` starts their account afresh, an equal one adds to it."""
        assert self._objects is not None
        lows, highs, groups = self._objects
        now = self.t[r]
        nearer, same = t < now, t == now
        a, b = r[nearer], r[same]
        lows[a], highs[a], groups[a] = low[nearer], high[nearer], grouped[nearer]
        lows[b] = np.minimum(lows[b], low[same])
        highs[b] = np.maximum(highs[b], high[same])
        groups[b] |= grouped[same]

    def block(self, rows: np.ndarray, t: np.ndarray) -> None:
        """For an any-hit walk, where only whether a ray's ``t`` falls below its limit matters: lower the
        rays ``rows`` (which may repeat) to hits ``t`` nearer than they have."""
        nearer = t < self.t[rows]
        self.t[rows[nearer]] = t[nearer]  # (of a repeated row, any of its nearer hits: each blocks it)

    @property
    def kind(self) -> np.ndarray:
        return np.where(self.key == _NONE, MISS, (self.key >> KIND_SHIFT) & 3).astype(np.int8)

    @property
    def index(self) -> np.ndarray:
        return np.where(self.key == _NONE, -1, self.key & INDEX_MASK)
