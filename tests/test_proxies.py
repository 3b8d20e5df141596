"""Neighbour finding and proxies (tracer/proxies.py) against brute force."""

import numpy as np
import pytest

from tracer.proxies import _csr, overlapping_pairs, stable_order


def brute(lo, hi):
    over = np.all(lo[:, None] <= hi[None], axis=2) & np.all(lo[None] <= hi[:, None], axis=2)
    i, j = np.nonzero(np.triu(over, 1))
    return set(zip(i.tolist(), j.tolist()))


@pytest.mark.parametrize("seed", range(6))
def test_overlapping_pairs_are_exactly_the_overlapping_boxes(seed):
    rng = np.random.default_rng(seed)
    n = 400
    lo = rng.random((n, 3)) * [4, 1, 0.01 if seed % 2 else 4]  # some nearly flat layouts
    size = rng.random((n, 3)) * 0.3
    big = rng.random(n) < 0.05  # a few boxes far above the median size
    size[big] *= 20
    size[rng.random(n) < 0.05] = 0.0  # and some points
    hi = lo + size
    i, j = overlapping_pairs(lo, hi)
    got = set(zip(i.tolist(), j.tolist()))
    assert len(got) == len(i)  # no pair twice
    assert np.all(i < j)
    assert got == brute(lo, hi)


def test_touching_boxes_in_adjacent_cells_and_far_apart_coordinates():
    # boxes that only touch, exactly a cell apart, and a layout far wider than 2^20 cells
    lo = np.array([[0.0, 0, 0], [1.0, 0, 0], [1.0, 1.0, 1.0], [1e9, 0, 0], [1e9 + 0.5, 0.5, 0.5], [-3.0, 5.0, 2.0]])
    hi = lo + 1.0
    i, j = overlapping_pairs(lo, hi)
    assert set(zip(i.tolist(), j.tolist())) == brute(lo, hi)


def test_non_finite_boxes_overlap_nothing():
    lo = np.array([[0.0, 0, 0], [0.5, 0.5, 0.5], [np.nan, 0, 0], [2.0, 2, 2]])
    hi = lo + 1.0
    i, j = overlapping_pairs(lo, hi)
    assert set(zip(i.tolist(), j.tolist())) == {(0, 1)}


def test_csr_lists_each_neighbour_of_each_box_in_order():
    i, j = np.array([0, 2, 1, 0]), np.array([3, 3, 2, 1])
    start, nb = _csr(5, i, j)
    lists = [nb[start[k]:start[k + 1]].tolist() for k in range(5)]
    assert [sorted(x) for x in lists] == [[1, 3], [0, 2], [1, 3], [0, 2], []]


@pytest.mark.parametrize("bound", [1, 7, 1 << 16, (1 << 16) + 3, 5_000_000, 1 << 40])
def test_stable_order_is_numpys_stable_argsort(bound):
    keys = np.random.default_rng(bound % 97).integers(0, bound, 20_000)
    keys[::7] = keys[0]  # many ties: their order must be kept
    assert np.array_equal(stable_order(keys, bound), np.argsort(keys, kind="stable"))
