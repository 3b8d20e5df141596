"""Flat surfaces of different objects that lie in one plane: the groups they form and the plane each group shares.

A glass box resting on a floor has its bottom face in the floor's plane.  A ray that meets the two there meets
them at one point, but their ``t``, each computed from its own numbers, differ by rounding, and the nearer by a
unit in the last place would win: the floor at one pixel, the glass face at the next (and a ray leaving that
face starts on the floor, so meets it nowhere: the sky shows through), a different speckle at every scale.
So flat surfaces (planes, triangles, mesh faces) of different objects that lie in one plane and whose boxes
meet are joined in a *group*, transitively, and every member's ``t`` is computed from one plane, the group's
first member's (planes before triangles, then by index; :meth:`Groups.retime`): where members overlap, a ray
meets them at bit for bit the same ``t``, and :class:`tracer.exact.best.Best` settles the tie by the order of
:class:`tracer.exact.ties.Ties`, whatever order the candidates come in.  A ray that leaves a member leaves the
group: it starts in their plane, and meets none of them at t > 0 (:meth:`Groups.leaving`).

**In one plane** means: normals parallel to :data:`SINE` (the sine of their angle), and every corner of the
smaller surface within :data:`TOLERANCE` of the magnitudes of both (as :func:`tracer.scene.shapes.on_tolerance`
takes them) of the larger's plane (a plane is larger than any triangle; of two planes, each holds the other's
point).  Both are relative, so the same scene scaled by 10⁻³⁰ to 10³⁰, or moved by 10⁶, makes the same groups:
the roundings of its input, of a move and of the eye's frame are a few 2^-53 of those magnitudes, far below,
while surfaces 2^-44 of them apart (a shell 10⁻⁶ thick at 10⁶ is 2^-40) stay apart.

**Found** without comparing every pair: each surface is filed under its plane (canonical normal and offset, on a
grid of :data:`QUANTUM`, and under the neighbouring cell too where it lies within a quarter of a cell of one,
so that two surfaces in one plane always share a key), and then under the cells of a uniform grid that its box
meets; pairs are made within those cells, and a surface whose box spans more than two cells along an axis is
paired with every surface of its plane's key.  Past :data:`PAIRS` candidate pairs (two large meshes in one
plane, face against face) no groups are made, and ties there go by rounding as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kinds import PLANE, TRIANGLE
from .shapes import plane_side
from .surfaces import Planes, Triangles
from .vec import dot

#: how far (relative to the magnitudes of both) a corner may lie from another surface's plane and be in it
TOLERANCE = 2.0**-48
#: how far from parallel (the sine of the angle) the normals of two surfaces in one plane may be
SINE = 2.0**-26
#: the grid a plane's canonical normal (two of its components) and its offset (relative to the largest point) are
#: filed on, in cells of this size; a surface within :data:`EDGE` of a cell's edge is filed under the neighbour
#: too.  Surfaces in one plane differ by at most 2^-25 in each (normals parallel within SINE, offsets within
#: SINE of the largest point plus TOLERANCE), under EDGE: they share a key
QUANTUM = 2.0**-16
EDGE = 2.0**-24 / QUANTUM
#: the most candidate pairs examined; past it, no groups
PAIRS = 1 << 24
#: a direction no plane of a scene is likely to be perpendicular to, for the canonical sign of a normal (a normal
#: nearly perpendicular to it is filed under both signs)
GENERIC = np.array([0.5298988890761731, 0.6570739146137293, 0.5362541302442428])


@dataclass(frozen=True)
class Groups:
    """The world's coplanar groups: each plane's and triangle's group (−1 for none), and each group's plane."""

    plane: np.ndarray  # (Q,) int64
    triangle: np.ndarray  # (T,) int64
    point: np.ndarray  # (G, 3) local: a point of the group's plane (its first member's)
    normal: np.ndarray  # (G, 3) unit: its normal

    def of(self, kind: np.ndarray, index: np.ndarray) -> np.ndarray:
        """The group of each surface ``kind``, ``index`` (−1 for none, and for spheres and misses). Shape (N,)."""
        out = np.full(len(kind), -1, dtype=np.int64)
        for k, groups in ((PLANE, self.plane), (TRIANGLE, self.triangle)):
            rows = np.flatnonzero(kind == k)
            if len(rows):
                out[rows] = groups[index[rows]]
        return out

    def leaving(self, from_group: np.ndarray, group: np.ndarray | int) -> np.ndarray:
        """Which rays, leaving surfaces of groups ``from_group`` (N,), leave a member of ``group`` (one, or (N,)):
        they start in its plane and meet no member at t > 0. Shape (N,), bool."""
        return (from_group >= 0) & (from_group == group)

    def retime(self, t: np.ndarray, origins: np.ndarray, dirs: np.ndarray, group: np.ndarray | int) -> np.ndarray:
        """``t`` of hits on members of ``group`` (one group, or one per ray) computed on their group's plane,
        where a member's own test found a hit and the plane's is one too; the rest as they are.  The same
        operations on the same numbers in every caller, so members overlapping there get the same bits."""
        if isinstance(group, (int, np.integer)):
            if group < 0:
                return t
            rows = np.flatnonzero(np.isfinite(t))
            point, normal = self.point[group], self.normal[group]
        else:
            rows = np.flatnonzero((group >= 0) & np.isfinite(t))
            point, normal = self.point[group[rows]], self.normal[group[rows]]
        if len(rows) == 0:
            return t
        o, d = origins[rows], dirs[rows]
        with np.errstate(divide="ignore", invalid="ignore"):
            shared = -plane_side(o, point, normal) / dot(d, np.broadcast_to(normal, d.shape))
        ok = np.isfinite(shared) & (shared > 0)
        out = t.copy()
        out[rows[ok]] = shared[ok]
        return out


@dataclass(frozen=True)
class _Flat:
    """The flat surfaces as one list, planes first: what grouping reads of each."""

    kind: np.ndarray  # (F,) PLANE or TRIANGLE
    obj: np.ndarray  # (F,) the object
    normal: np.ndarray  # (F, 3)
    point: np.ndarray  # (F, 3) local: a plane's point, a triangle's first corner
    e1: np.ndarray  # (F, 3) a triangle's edges from its first corner (0 for a plane)
    e2: np.ndarray  # (F, 3)
    mag: np.ndarray  # (F,) world magnitude
    lo: np.ndarray  # (F, 3) the box (−inf for a plane)
    hi: np.ndarray  # (F, 3) (inf for a plane)
    extent: np.ndarray  # (F,) the box's largest side (inf for a plane)

    def corner(self, rows: np.ndarray, k: int) -> np.ndarray:
        """The ``k``-th corner of the surfaces ``rows`` (a plane's point, for each k). Shape (len(rows), 3)."""
        return self.point[rows] + (0.0 if k == 0 else (self.e1 if k == 1 else self.e2)[rows])

    @property
    def usable(self) -> np.ndarray:
        """Which surfaces have finite numbers (a hostile 1e300 may overflow in the eye's frame). Shape (F,)."""
        ok = np.isfinite(self.mag) & ((self.kind == PLANE) | np.isfinite(self.extent))
        for a in (self.point, self.normal):
            ok &= np.isfinite(a[:, 0]) & np.isfinite(a[:, 1]) & np.isfinite(a[:, 2])
        return ok


def _flat(planes: Planes, triangles: Triangles) -> _Flat:
    q, t = len(planes.normal), len(triangles.v0)
    v0, e1, e2 = triangles.v0, triangles.e1, triangles.e2
    v1, v2 = v0 + e1, v0 + e2
    infinite = np.full((q, 3), np.inf)
    lo = np.concatenate([-infinite, np.minimum(np.minimum(v0, v1), v2)])
    hi = np.concatenate([infinite, np.maximum(np.maximum(v0, v1), v2)])
    side = hi - lo
    zeros = np.zeros((q, 3))
    return _Flat(
        kind=np.concatenate([np.full(q, PLANE), np.full(t, TRIANGLE)]).astype(np.int8),
        obj=np.concatenate([planes.object, triangles.object]).astype(np.int64),
        normal=np.concatenate([planes.normal, triangles.normal]),
        point=np.concatenate([planes.point, v0]),
        e1=np.concatenate([zeros, e1]),
        e2=np.concatenate([zeros, e2]),
        mag=np.concatenate([planes.mag, triangles.mag]),
        lo=lo,
        hi=hi,
        extent=np.maximum(np.maximum(side[:, 0], side[:, 1]), side[:, 2]),
    )


def coplanar_groups(planes: Planes, triangles: Triangles) -> Groups | None:
    """The groups of the world's flat surfaces (module docstring); None where there are none."""
    if len(planes.normal) + len(triangles.v0) < 2:
        return None
    flat = _flat(planes, triangles)
    with np.errstate(all="ignore"):
        pairs = _candidates(flat)
        if pairs is None:
            return None
        a, b = pairs
        keep = _in_one_plane(flat, a, b)
    a, b = a[keep], b[keep]
    if len(a) == 0:
        return None
    label = _components(len(flat.kind), a, b)
    size = np.bincount(label, minlength=len(label))
    first = np.flatnonzero(size >= 2)  # each group's first member (its label: the least of its members)
    number = np.full(len(label), -1, dtype=np.int64)
    number[first] = np.arange(len(first))
    group = number[label]
    q = len(planes.normal)
    return Groups(
        plane=group[:q],
        triangle=group[q:],
        point=np.ascontiguousarray(flat.point[first]),
        normal=np.ascontiguousarray(flat.normal[first]),
    )


def _candidates(flat: _Flat) -> tuple[np.ndarray, np.ndarray] | None:
    """Pairs ``(a, b)``, ``a < b``, of surfaces of different objects that may lie in one plane with meeting boxes:
    every pair that does is among them.  None past :data:`PAIRS`."""
    none = np.zeros(0, np.int64), np.zeros(0, np.int64)
    if flat.obj.min() == flat.obj.max():  # one object: no pair
        return none
    entry, key = _plane_keys(flat)
    order = np.argsort(key, kind="stable")
    entry, key = entry[order], key[order]
    starts = np.r_[0, np.flatnonzero(key[1:] != key[:-1]) + 1] if len(key) else np.zeros(0, np.int64)
    bucket = np.repeat(np.arange(len(starts)), np.diff(np.r_[starts, len(entry)]))
    objects = flat.obj[entry]
    if len(entry) == 0:
        return none
    lowest, highest = np.minimum.reduceat(objects, starts), np.maximum.reduceat(objects, starts)
    shared = (lowest != highest)[bucket]  # a key that holds more than one object
    entry, bucket = entry[shared], bucket[shared]
    if len(entry) == 0:
        return none
    return _near_pairs(flat, entry, bucket)


def _plane_keys(flat: _Flat) -> tuple[np.ndarray, np.ndarray]:
    """Each surface filed under its plane: ``(entry, key)``, the surface of each filing and one int64 of its
    three grid cells (two components of the canonical normal, and the offset); a surface is filed more than
    once near a cell's edge (:data:`EDGE`) or where its normal's sign is in doubt."""
    ok = flat.usable
    n, p = flat.normal, flat.point
    size = np.sqrt(p[:, 0] * p[:, 0] + p[:, 1] * p[:, 1] + p[:, 2] * p[:, 2])
    scale = float(np.max(size[ok], initial=0.0))
    scale = scale if scale > 0 else 1.0
    side = n[:, 0] * GENERIC[0] + n[:, 1] * GENERIC[1] + n[:, 2] * GENERIC[2]
    sign = np.where(side >= 0, 1.0, -1.0)
    offset = (n[:, 0] * p[:, 0] + n[:, 1] * p[:, 1] + n[:, 2] * p[:, 2]) * sign / scale
    x = np.column_stack([n[:, 0] * sign, n[:, 1] * sign, offset]) / QUANTUM  # each within ±2^16·√3
    doubt = np.flatnonzero(ok & (np.abs(side) <= 2.0**-24))  # filed under both signs
    entry = np.concatenate([np.flatnonzero(ok), doubt])
    x = np.concatenate([x[ok], -x[doubt]])
    cell = np.floor(x)
    frac = x - cell
    cells = cell.astype(np.int64) + (1 << 18)
    for axis in range(3):  # near a cell's edge: filed under the neighbour too
        for near, step in ((frac[:, axis] < EDGE, -1), (frac[:, axis] > 1.0 - EDGE, 1)):
            more = np.flatnonzero(near)
            if len(more) == 0:
                continue
            extra = cells[more].copy()
            extra[:, axis] += step
            entry, cells = np.concatenate([entry, entry[more]]), np.concatenate([cells, extra])
            frac = np.concatenate([frac, frac[more]])
    return entry, (cells[:, 0] << 38) | (cells[:, 1] << 19) | cells[:, 2]


def _near_pairs(flat: _Flat, entry: np.ndarray, bucket: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Pairs of the surfaces ``entry`` sharing a plane's key (``bucket``) whose boxes may meet: within the cells
    of a uniform grid each small box meets, and a large box (or a plane) with every surface of its key."""
    extent = flat.extent[entry]
    finite = extent[np.isfinite(extent)]
    cell = float(np.median(finite)) if len(finite) else 1.0
    cell = cell if cell > 0 else 1.0
    lo, hi = np.floor(flat.lo[entry] / cell), np.floor(flat.hi[entry] / cell)
    small = np.all(np.isfinite(lo) & np.isfinite(hi) & (hi - lo <= 1), axis=1)
    a, b = [], []
    s = np.flatnonzero(small)
    reg_entry, reg_key = [], []
    for corner in range(8):  # each small box in the (up to) eight cells it meets
        step = np.array([(corner >> k) & 1 for k in range(3)])
        c = lo[s] + step
        inside = np.all(c <= hi[s], axis=1)
        reg_entry.append(s[inside])
        reg_key.append(np.column_stack([bucket[s[inside]], c[inside].astype(np.int64)]))
    within = _pairs_in_runs(np.concatenate(reg_entry), np.concatenate(reg_key))
    if within is None:
        return None
    a.append(within[0])
    b.append(within[1])
    large = np.flatnonzero(~small)  # each large box with every surface of its key
    if len(large):
        starts = np.searchsorted(bucket, np.arange(bucket.max() + 2))
        first, last = starts[bucket[large]], starts[bucket[large] + 1]
        count = last - first
        if int(count.sum()) > PAIRS:
            return None
        a.append(np.repeat(large, count))
        b.append(_ranges(first, count))
    i, j = entry[np.concatenate(a)], entry[np.concatenate(b)]
    keep = flat.obj[i] != flat.obj[j]
    i, j = np.minimum(i[keep], j[keep]), np.maximum(i[keep], j[keep])
    code = np.unique(i * len(flat.kind) + j)
    return code // len(flat.kind), code % len(flat.kind)


def _ranges(first: np.ndarray, count: np.ndarray) -> np.ndarray:
    """``first[k] .. first[k] + count[k] − 1`` for every k, concatenated."""
    total = int(count.sum())
    offsets = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
    return np.repeat(first, count) + offsets


def _pairs_in_runs(items: np.ndarray, key: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Every pair of ``items`` that share a ``key`` row: positions into ``items``' own numbering. None past
    :data:`PAIRS`."""
    if len(items) < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    order = np.lexsort(key.T[::-1])
    items, key = items[order], key[order]
    starts = np.r_[0, np.flatnonzero(np.any(key[1:] != key[:-1], axis=1)) + 1]
    size = np.diff(np.r_[starts, len(items)])
    run_of = np.repeat(np.arange(len(starts)), size)
    after = starts[run_of] + size[run_of] - np.arange(len(items)) - 1  # the run's items after each
    if int(after.sum()) > PAIRS:
        return None
    return np.repeat(items, after), items[_ranges(np.arange(len(items)) + 1, after)]


def _in_one_plane(flat: _Flat, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Which pairs lie in one plane, with meeting boxes (module docstring). Shape (P,), bool."""
    na, nb = flat.normal[a], flat.normal[b]
    cross = np.cross(na, nb)
    ok = np.sqrt(dot(cross, cross)) <= SINE
    tol = TOLERANCE * (flat.mag[a] + flat.mag[b])
    ok &= np.all((flat.lo[a] <= flat.hi[b] + tol[:, None]) & (flat.lo[b] <= flat.hi[a] + tol[:, None]), axis=1)
    # the larger holds the smaller's corners (a plane: every triangle's; two planes: each the other's point)
    swap = (flat.extent[b] > flat.extent[a]) | ((flat.extent[b] == flat.extent[a]) & (b < a))
    big, little = np.where(swap, b, a), np.where(swap, a, b)
    for k in range(3):
        off = plane_side(flat.corner(little, k), flat.point[big], flat.normal[big])
        ok &= np.abs(off) <= tol
    both_planes = (flat.kind[a] == PLANE) & (flat.kind[b] == PLANE)
    back = plane_side(flat.point[big], flat.point[little], flat.normal[little])
    ok &= ~both_planes | (np.abs(back) <= tol)
    return ok


def _components(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The connected components of ``n`` items joined by the pairs ``(a, b)``: each item's label, the least item
    of its component."""
    label = np.arange(n)
    while True:
        low = np.minimum(label[a], label[b])
        joined = label.copy()
        np.minimum.at(joined, label[a], low)
        np.minimum.at(joined, label[b], low)
        while True:  # each label to its own label's, until every item points at its component's least
            deeper = joined[joined]
            if np.array_equal(deeper, joined):
                break
            joined = deeper
        if np.array_equal(joined, label):
            return label
        label = joined
