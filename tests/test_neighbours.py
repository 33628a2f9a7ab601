"""Neighbour search against the brute-force oracle (PySPH NNPS-style tests)."""

import math

import numpy as np
import pytest

from ipsph.boundary import Boundary
from ipsph.neighbours import NeighbourSearch, brute_force_neighbours, cell_ids


def _lists(idx, cnt):
    return [np.sort(idx[i, : cnt[i]]) for i in range(len(cnt))]


@pytest.mark.parametrize("seed,n,nb", [(0, 500, 0), (1, 800, 300), (2, 50, 1000)])
def test_matches_brute_force_after_sorting(seed, n, nb):
    rng = np.random.default_rng(seed)
    h = 0.1
    fluid = rng.uniform(0, 0.6, (n, 3))
    walls = rng.uniform(-0.1, 0.7, (nb, 3))
    boundary = Boundary(walls, h, 1000.0)
    search = NeighbourSearch(h, boundary, k_fluid=16, k_boundary=8)  # small strides: forces growth
    perm = search.update(fluid)
    xs = fluid[perm]
    nl = search.lists
    want_f = brute_force_neighbours(xs, xs, h, True)
    assert all(np.array_equal(a, b) for a, b in zip(_lists(nl.fluid, nl.fluid_count), want_f))
    want_b = brute_force_neighbours(xs, boundary.x, h, False)
    got_b = _lists(nl.boundary, nl.boundary_count)
    assert all(np.array_equal(a, b) for a, b in zip(got_b, want_b))
    # the strides grew by the documented rule, from the oracle's longest lists: while a list does not
    # fit, both strides become at least 1.25 x their longest list, rounded up to a multiple of 16
    most_f, most_b = (max((len(w) for w in want), default=0) for want in (want_f, want_b))
    kf, kb = 16, 8 if nb else 0  # no wall particles (field walls): no wall lists at all
    while most_f > kf or most_b > kb:
        kf = max(kf, math.ceil(most_f * 1.25 / 16) * 16)
        kb = max(kb, math.ceil(most_b * 1.25 / 16) * 16)
    assert (nl.fluid.shape[1], nl.boundary.shape[1]) == (kf, kb), (most_f, most_b)
    # the permutation is a permutation, and sorted particles are grouped by cell (x fastest)
    assert np.array_equal(np.sort(perm), np.arange(n))
    g = search.grid
    cells = np.empty(n, dtype=np.int64)
    cell_ids(xs, g.origin, g.inv_cell, g.dims, cells)
    assert np.all(np.diff(cells) >= 0)
    assert len(np.unique(cells)) > 1  # several cells, so the order is a real constraint


def test_fluid_far_from_walls_skips_the_wall_search_and_misses_nothing():
    # a floor of wall points under a tall column: most fluid is out of the walls' reach, and the
    # particles just within reach (above the floor, at the cell edges of the mask) must keep theirs
    rng = np.random.default_rng(3)
    h = 0.1
    gx, gz = np.meshgrid(np.arange(0, 0.6, 0.0375), np.arange(0, 0.6, 0.0375))
    floor = np.column_stack([gx.ravel(), np.zeros(gx.size), gz.ravel()])
    fluid = rng.uniform([0, 0.0, 0], [0.6, 1.2, 0.6], (1500, 3))
    search = NeighbourSearch(h, Boundary(floor, h, 1000.0))
    xs = fluid[search.update(fluid)]
    nl, g = search.lists, search.grid
    want = brute_force_neighbours(xs, search.boundary.x, h, False)
    assert all(np.array_equal(a, b) for a, b in zip(_lists(nl.boundary, nl.boundary_count), want))
    cells = np.empty(len(xs), dtype=np.int64)
    cell_ids(xs, g.origin, g.inv_cell, g.dims, cells)
    skipped = np.diff(search.wall_start)[cells] == 0  # cells without wall candidates
    assert skipped.mean() > 0.5  # the mask does skip most of the column
    assert np.all(nl.boundary_count[skipped] == 0)  # and only particles without wall neighbours
    assert np.any((nl.boundary_count == 0) & ~skipped)  # the mask is conservative near its edge
    # each cell's candidates: ascending, and every wall point within h of some point of the cell
    start, cand = search.wall_start, search.wall_cand
    for c in np.unique(cells[~skipped]):
        got = cand[start[c] : start[c + 1]]
        assert np.all(np.diff(got) > 0)
        idx = np.array(np.unravel_index(c, g.dims[::-1])[::-1])
        lo = g.origin + idx * g.cell
        gap = np.maximum(np.maximum(lo - search.boundary.x, search.boundary.x - (lo + g.cell)), 0.0)
        d2 = np.sum(gap * gap, axis=1)
        assert set(np.flatnonzero(d2 < (h * (1 - 1e-6)) ** 2)) <= set(got)  # none missing
        assert set(got) <= set(np.flatnonzero(d2 < (h * (1 + 1e-6)) ** 2))  # none far beyond


def test_strict_radius_and_self_excluded():
    h = 0.1
    x = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.0999999, 0.0, 0.0]]) + 0.5
    search = NeighbourSearch(h, Boundary(np.zeros((0, 3)), h, 1000.0))
    perm = search.update(x)
    xs = x[perm]
    nl = search.lists
    for i in range(3):
        got = set(nl.fluid[i, : nl.fluid_count[i]])
        assert i not in got
        want = {j for j in range(3) if j != i and np.linalg.norm(xs[i] - xs[j]) < h}
        assert got == want


def test_grid_grows_when_fluid_leaves_it():
    h = 0.1
    rng = np.random.default_rng(3)
    x = rng.uniform(0, 0.3, (200, 3))
    search = NeighbourSearch(h, Boundary(rng.uniform(0, 0.3, (50, 3)), h, 1000.0))
    search.update(x)
    x2 = x + np.array([5.0, 0, 0])  # the whole block moved far away
    perm = search.update(x2)
    xs = x2[perm]
    want = brute_force_neighbours(xs, xs, h, True)
    nl = search.lists
    assert all(np.array_equal(np.sort(nl.fluid[i, : nl.fluid_count[i]]), want[i]) for i in range(len(xs)))
    assert nl.boundary_count.sum() == 0
