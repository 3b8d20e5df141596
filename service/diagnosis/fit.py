"""The terms out of scale: a non-negative least-squares fit of the submission's linear values against the
reference's additive passes, a term freed at a time."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .records import Term
from .renders import Renders

#: a fitted term is out of scale when its coefficient is further than this from 1
TERM_SLACK = 0.15
#: a term too faint to matter: less than this share of the image's light
TERM_FLOOR = 0.02
#: the residual (RMS, of 1) that rounding to 8 bits alone leaves: no term is freed below it
ROUNDING = 1.0 / 255
#: at most this many terms are freed
MAX_TERMS = 3

#: a fit whose matrix (the used values × the terms) takes at most this is solved on the matrix itself; a larger
#: one on a factor of its Gram matrix, summed a block of pixels at a time (:class:`_Fit`)
FIT_MATRIX_BYTES = 32 << 20
#: ... and at most this many terms (each try of a term sums all the others over every row)
FIT_MATRIX_TERMS = 64
#: pixels per block when the fit's columns are taken from passes held whole
FIT_BLOCK_PIXELS = 1 << 14
BASE_TERMS = ("background", "ambient", "reflection", "refraction")


def fit_terms(submitted: np.ndarray, renders: Renders) -> list[Term]:
    """The additive terms out of scale, most out of scale first, by forward selection of least squares fits.

    The submission's linear values ≈ Σ coefficient · pass over the reference's additive passes (background,
    ambient, each light's diffuse and specular, reflection, refraction), on the pixels neither image clips.
    Terms that look alike on those pixels (ambient light and a directional light on a flat floor) cannot be
    told apart by one fit of every coefficient, so the coefficients start at 1 and are freed one at a time:
    each round frees the term whose non-negative fit (with the terms freed before it) leaves the smallest
    residual, and stops when that does not at least halve the residual or the residual is down to rounding.

    The passes come a block of pixels at a time (:attr:`Renders.blocks`), and the fit holds the used values
    while they take at most :data:`FIT_MATRIX_BYTES` (then it solves on them, as one matrix); past that, it
    keeps only the Gram matrix MᵀM of M = [terms | submission], summed block by block, and solves on a factor
    F of it (FᵀF = MᵀM): ‖M z‖ = ‖F z‖ for every z, so every fit and residual is the same least squares
    problem on (terms + 1) rows instead of the used values (the same answer up to rounding), and memory does
    not grow with the pixels."""
    columns = [(name, None) for name in BASE_TERMS] + [
        (term, k) for k, kind in enumerate(renders.lights) if kind != "ambient" for term in ("diffuse", "specular")
    ]
    fit = _Fit(
        [name if k is None else f"{name}:{k}" for name, k in columns],
        submitted.reshape(-1, 3).astype(np.float64) / 255.0,
        renders.check,
    )
    renders.blocks(fit.fold)
    free, coef = fit.solve()
    terms = [
        Term(columns[i][0], columns[i][1], float(c), fit.share(i, float(c)))
        for i, c in zip(free, coef)
        if abs(c - 1.0) > TERM_SLACK
    ]
    return sorted(terms, key=lambda t: -abs(t.scale - 1.0))


class _Fit:
    """The term fit of :func:`fit_terms`, fed a block of pixels at a time (:meth:`fold`), then :meth:`solve`."""

    def __init__(self, names: list[str], submitted: np.ndarray, check: Callable[[], None]):
        self.names, self.sub, self.check = names, submitted, check
        self.rows: list[np.ndarray] = []  # the used values of each block, (m_i, n): while they are small
        self.values: list[np.ndarray] = []  # the submission's there, (m_i,)
        self.held = 0
        self.gram: np.ndarray | None = None  # once they are not: MᵀM of M = [terms | submission], (n + 1, n + 1)
        self.energy = np.zeros(len(names))
        self.used = 0
        self.magnitude = np.zeros(len(names))  # Σ |term| over the used values, per term
        self.gap = 0.0  # Σ |submission − reference| over the used values

    def fold(self, first: int, part: dict[str, np.ndarray]) -> None:
        self.check()
        cols = [part[name] for name in self.names]
        total = sum(cols)  # (in the order the whole image's sum takes: the same values)
        sub = self.sub[first : first + len(cols[0])]
        use = (total < 1.0 - 1e-3) & (sub > 0) & (sub < 1)  # neither image clips there: the values are linear
        count = int(use.sum())
        if count == 0:
            return
        a = np.stack([c[use] for c in cols], axis=1)
        b = sub[use]
        self.used += count
        self.magnitude += np.abs(a).sum(axis=0)
        self.gap += float(np.abs(b - a.sum(axis=1)).sum())
        if self.gram is None:
            self.rows.append(a)
            self.values.append(b)
            self.held += a.nbytes + b.nbytes
            if self.held <= FIT_MATRIX_BYTES and len(self.names) <= FIT_MATRIX_TERMS:
                return
            a, b = np.concatenate(self.rows), np.concatenate(self.values)
            self.rows, self.values, self.gram = [], [], np.zeros((len(self.names) + 1,) * 2)
        self.energy += a.sum(axis=0)
        m = np.column_stack([a, b])
        self.gram += m.T @ m

    def share(self, term: int, scale: float) -> float:
        """How much of the submission's difference from the reference (Σ |difference| over the used values) term
        ``term`` at ``scale`` accounts for: |scale − 1| × Σ |term|, at most all of it."""
        return min(1.0, abs(scale - 1.0) * float(self.magnitude[term]) / self.gap) if self.gap > 0 else 0.0

    def solve(self) -> tuple[list[int], np.ndarray]:
        """The terms freed and their coefficients."""
        if self.used < 16:
            return [], np.zeros(0)
        if self.gram is None:  # the used values themselves: one matrix
            a, b = np.concatenate(self.rows), np.concatenate(self.values)
            energy = np.array([np.ascontiguousarray(a[:, i]).sum() for i in range(a.shape[1])])
            return _forward(a, b, energy, None, self.check)
        # a factor F of the Gram matrix (FᵀF = MᵀM, from its eigenvectors: it may be singular, a term zero
        # everywhere), whose rows stand for the used values: ‖M z‖ = ‖F z‖ for every z
        self.check()
        values, vectors = np.linalg.eigh(self.gram)
        f = np.sqrt(np.maximum(values, 0.0))[:, None] * vectors.T
        return _forward(f[:, :-1], f[:, -1], self.energy, self.used, self.check)


def _forward(
    a: np.ndarray, b: np.ndarray, energy: np.ndarray, used: int | None, check: Callable[[], None]
) -> tuple[list[int], np.ndarray]:
    """Forward selection over the columns of ``a`` against ``b``: the used values themselves (``used`` None), or
    the rows of their triangular factor, which give the same sums of squares, over ``used`` values."""
    keep = [i for i, e in enumerate(energy) if e > TERM_FLOOR * energy.sum()]
    n = a.shape[1]
    every = None if used is None else a.sum(axis=1)  # (R's rows are few: the others' sum from the whole's)

    def rms(r: np.ndarray) -> float:
        return float(np.sqrt(np.mean(r**2))) if used is None else float(np.sqrt(np.sum(r**2) / used))

    def fitted(free: list[int]) -> tuple[float, np.ndarray]:
        if every is None:
            rest = b - a[:, [i for i in range(n) if i not in free]].sum(axis=1)
        else:
            rest = b - (every - a[:, free].sum(axis=1))
        coef = nnls(a[:, free], rest)
        return rms(a[:, free] @ coef - rest), coef

    free: list[int] = []
    coef = np.zeros(0)
    residual = rms(a.sum(axis=1) - b)
    while residual > ROUNDING and len(free) < MAX_TERMS:
        tries = []
        for i in keep:
            if i not in free:
                check()
                tries.append((fitted(free + [i]), i))
        if not tries:
            break
        (best, best_coef), i = min(tries, key=lambda t: t[0][0])
        if best > 0.5 * residual:
            break
        free, coef, residual = free + [i], best_coef, best
    return free, coef


def nnls(a: np.ndarray, b: np.ndarray, rounds: int = 200) -> np.ndarray:
    """min ‖a x − b‖ over x ≥ 0, by the Lawson–Hanson active-set method. ``a (m, n)``, ``b (m,)``."""
    m, n = a.shape
    x = np.zeros(n)
    free = np.zeros(n, dtype=bool)
    for _ in range(rounds):
        w = a.T @ (b - a @ x)
        if free.all() or np.max(np.where(free, -np.inf, w)) <= 1e-12:
            break
        free[int(np.argmax(np.where(free, -np.inf, w)))] = True
        for _ in range(rounds):
            z = np.zeros(n)
            z[free] = np.linalg.lstsq(a[:, free], b, rcond=None)[0]
            if np.all(z[free] > 0):
                x = z
                break
            bad = free & (z <= 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                alpha = np.min(np.where(bad, x / (x - z), np.inf))
            x = x + alpha * (z - x)
            free &= x > 1e-12
    return x
