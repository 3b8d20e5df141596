"""The walk's grid of cells (tracer/exact/cells.py): what each part of a cell holds, whatever the boxes' sizes.

The walk's guarantee rests on one property: every box is registered in every
part of a cell it comes within the reach of.  The scenes here walk among
spheres and meshes of mixed sizes and must agree with the float64 brute force.
"""

from dataclasses import replace
from unittest import mock

import numpy as np
import pytest
from test_exactness import agrees_with_brute_force, scene
from test_sightlines import BALL, sphere_mesh

import schemas
from tracer import render
from tracer.exact.cells import SUB, build_cells, stable_order


def random_boxes(n, seed=3, size=0.1):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-1, 1, (n, 3))
    return lo, lo + rng.uniform(0.2, 1.0, (n, 3)) * size


def test_every_box_is_in_every_part_of_a_cell_it_comes_near():
    lo, hi = random_boxes(400)
    reach = 0.01
    cells = build_cells(lo, hi, reach)
    assert cells is not None
    rng = np.random.default_rng(5)
    for b in range(0, 400, 7):  # points of the grown box, corners included: their parts hold the box
        t = np.vstack([rng.uniform(0, 1, (50, 3)), [[0, 0, 0], [1, 1, 1], [0, 1, 0], [1, 0, 1]]])
        points = lo[b] - reach + t * (hi[b] - lo[b] + 2 * reach)
        region, p_lo, p_hi = cells.locate(points)
        assert np.all(region >= 0)
        assert np.all((p_lo <= points) & (points <= p_hi))
        assert np.allclose(p_hi - p_lo, cells.size / SUB)
        rows, prims = cells.pairs(np.arange(len(points)), region)
        assert set(rows[prims == b].tolist()) == set(range(len(points)))


def test_a_part_holds_only_boxes_that_come_near_it():
    lo, hi = random_boxes(300)
    reach = 0.01
    cells = build_cells(lo, hi, reach)
    points = np.random.default_rng(8).uniform(-1, 1.1, (2000, 3))
    region, p_lo, p_hi = cells.locate(points)
    rows, prims = cells.pairs(np.arange(len(points)), region)
    assert len(prims) > 100 and len(prims) == len(set(zip(rows.tolist(), prims.tolist())))
    near = np.all((lo[prims] - reach <= p_hi[rows] + 1e-12) & (hi[prims] + reach >= p_lo[rows] - 1e-12), axis=1)
    assert near.all()
    whole = np.all((lo[prims] - reach <= p_lo[rows]) & (hi[prims] + reach >= p_hi[rows]), axis=1)
    assert not whole.all()  # parts are finer than boxes: some boxes only graze the part they are in


def test_a_whole_cell_holds_every_member_of_its_parts_and_its_box_holds_theirs():
    lo, hi = random_boxes(300)
    cells = build_cells(lo, hi, 0.01)
    points = np.random.default_rng(9).uniform(-1, 1.1, (500, 3))
    part, p_lo, p_hi = cells.locate(points)
    cell, c_lo, c_hi = cells.locate(points, whole=True)
    assert np.array_equal(part >= 0, cell >= 0) and np.all(cell[cell >= 0] >= cells.whole_base)
    assert np.all((c_lo <= p_lo) & (p_hi <= c_hi + 1e-12))
    assert np.allclose(c_hi - c_lo, cells.size)
    by_part = set(zip(*(a.tolist() for a in cells.pairs(np.arange(500), part))))
    by_cell = set(zip(*(a.tolist() for a in cells.pairs(np.arange(500), cell))))
    assert by_part < by_cell  # every member of the part, and the members of the cell's other parts too
    at = cell[cell >= 0] - cells.whole_base
    members = {
        (r, m)
        for r, c in zip(np.flatnonzero(cell >= 0).tolist(), at.tolist())
        for m in cells.members[cells.start[c] : cells.start[c + 1]].tolist()
    }
    assert by_cell == members


def test_points_in_no_cell_and_pairs():
    lo, hi = random_boxes(50)
    cells = build_cells(lo, hi, 0.0)
    region, _, _ = cells.locate(np.array([[50.0, 0, 0], [np.nan, 0, 0], [-50.0, 3, 1]]))
    assert np.all(region == -1)
    inside, _, _ = cells.locate((lo[:3] + hi[:3]) / 2)
    rows, prims = cells.pairs(np.array([10, 11, 12, 13]), np.r_[inside, -1])
    for r, b in zip((10, 11, 12), range(3)):
        assert b in prims[rows == r]
    assert 13 not in rows
    rows_but, prims_but = cells.pairs(np.array([10, 11, 12]), inside, np.array([0, -1, 2]))
    assert 0 not in prims_but[rows_but == 10] and 2 not in prims_but[rows_but == 12]
    assert np.array_equal(prims_but[rows_but == 11], prims[rows == 11])


def test_a_grid_too_large_for_a_table_finds_the_same_cells_by_search():
    lo, hi = random_boxes(300)
    cells = build_cells(lo, hi, 0.01)
    assert cells.table is not None  # a small grid: cells are found by a table
    points = np.vstack(
        [
            np.random.default_rng(4).uniform(-1.2, 1.3, (3000, 3)),
            (lo + hi) / 2,
            [[np.nan, 0, 0], [np.inf, 0, 0], [-np.inf, 1e300, 0]],
        ]
    )
    searched = replace(cells, table=None)
    for whole in (False, True):
        by_table, by_search = cells.locate(points, whole), searched.locate(points, whole)
        assert (by_table[0] >= 0).sum() > 300 and (by_table[0] < 0).sum() > 300
        for a, b in zip(by_table, by_search):
            assert np.array_equal(a, b, equal_nan=True)


def holds_every_box_in_every_part_it_comes_near(cells, lo, hi, reach, seed=5):
    rng = np.random.default_rng(seed)
    for b in range(0, len(lo), max(1, len(lo) // 60)):
        t = np.vstack([rng.uniform(0, 1, (30, 3)), [[0, 0, 0], [1, 1, 1], [0, 1, 0], [1, 0, 1]]])
        points = lo[b] - reach + t * (hi[b] - lo[b] + 2 * reach)
        region, p_lo, p_hi = cells.locate(points)
        assert np.all(region >= 0)
        rows, prims = cells.pairs(np.arange(len(points)), region)
        assert set(rows[prims == b].tolist()) == set(range(len(points)))


def test_past_their_budget_cells_grow_coarser_and_still_hold_every_box():
    lo, hi = random_boxes(200, size=0.01)
    fine = build_cells(lo, hi, 0.0)
    big_lo, big_hi = np.vstack([lo, [[-1, -1, -1]] * 3]), np.vstack([hi, [[1, 1, 1]] * 3])  # 10^6 cells each
    coarse = build_cells(big_lo, big_hi, 0.0)
    assert coarse.size > fine.size
    assert len(coarse.members) <= 32 * len(big_lo) + (1 << 20)
    holds_every_box_in_every_part_it_comes_near(coarse, big_lo, big_hi, 0.0)


def test_boxes_far_apart_and_tiny_get_a_grid_that_fits_its_keys():
    # a layout far wider than 2^20 cells of the boxes' own size: cells grow to fit, every box still held
    lo = np.array([[0.0, 0, 0], [1e9, 0, 0], [0, -1e9, 3], [5e8, 5e8, 5e8]])
    hi = lo + 1e-3
    cells = build_cells(lo, hi, 1e-6)
    assert np.all(cells.dims <= (1 << 20) + 1)
    holds_every_box_in_every_part_it_comes_near(cells, lo, hi, 1e-6)


def test_a_fan_of_slivers_round_one_vertex_gets_cells():
    # thousands of long, thin boxes through one point: each part there holds them all, and that is allowed
    angle = np.linspace(0, 2 * np.pi, 8001)[:-1]
    tip = np.stack([np.cos(angle), np.zeros_like(angle), np.sin(angle)], axis=1)
    lo, hi = np.minimum(tip, 0.0), np.maximum(tip, 0.0)
    cells = build_cells(lo, hi, 1e-4)
    holds_every_box_in_every_part_it_comes_near(cells, lo, hi, 1e-4)


def spheres_about(center, radius, count, gap, seed=11):
    """``count`` small spheres whose surfaces come within ``gap`` of the sphere (center, radius)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        r = float(rng.uniform(0.03, 0.08))
        out.append(
            {
                "type": "sphere",
                "material": "m",
                "radius": r,
                "center": (np.asarray(center) + d * (radius + r + gap)).tolist(),
            }
        )
    return out


INNER = sphere_mesh([0.9, 0.4, 0.1], 0.3, level=2)
CASES = {
    # spheres in the BVH beside a mesh: touching it, cutting through it, nested in each other
    "mesh ball among small spheres": scene(
        [
            BALL,
            *spheres_about([0, 0.6, 0], 0.6, 12, 1e-6),
            {"type": "sphere", "material": "m", "center": [0.6, 0.6, 0], "radius": 0.1},
            {"type": "sphere", "material": "m", "center": [-0.7, 0.3, 0.3], "radius": 0.2},
            {"type": "sphere", "material": "m", "center": [-0.7, 0.3, 0.3], "radius": 0.05},
        ],
        [{"type": "point", "color": 1, "position": [2, 3, 2]}],
        {"position": [0, 1.2, 3], "look_at": [0, 0.6, 0], "fov": 40},
    ),
    # two meshes 1e-6 apart, one inside the other's box, and faces of very different sizes
    "nested meshes of mixed sizes": scene(
        [BALL, INNER, sphere_mesh([0.9, 0.4, 0.1], 0.3 + 1e-6, level=1)],
        [{"type": "point", "color": 1, "position": [-2, 3, 3]}],
        {"position": [0.5, 1.0, 3], "look_at": [0.5, 0.5, 0], "fov": 45},
    ),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_walking_by_cells_agrees_with_the_brute_force(name):
    agrees_with_brute_force(CASES[name])


def test_a_scene_over_the_cells_budget_walks_coarser_cells_to_the_same_pixels():
    data = CASES["mesh ball among small spheres"]
    with mock.patch("tracer.exact.cells.BUDGET_PER", -(10**9)):
        pixels = render(schemas.validate_scene(data))
    assert np.array_equal(pixels, render(schemas.validate_scene(data)))


@pytest.mark.parametrize("bound", [1, 7, 1 << 16, (1 << 16) + 3, 5_000_000, 1 << 40])
def test_stable_order_is_numpys_stable_argsort(bound):
    keys = np.random.default_rng(bound % 97).integers(0, bound, 20_000)
    keys[::7] = keys[0]  # many ties: their order must be kept
    assert np.array_equal(stable_order(keys, bound), np.argsort(keys, kind="stable"))
