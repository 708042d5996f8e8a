"""Active tracking (O'Kane section VII) and the ``okane`` experiment."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
import shapely
from shapely.geometry import Point, box

from onebit.datasets.okane_sim import fig9_environment
from onebit.experiments.okane import qualitative
from onebit.experiments.okane import run as run_experiment
from onebit.experiments.okane_active import ActiveConfig, sensing_squares, simulate_active
from onebit.trackers.istate.active import (
    ShortestPaths,
    advance,
    greedy_centres,
    match_destinations,
    partition_cells,
    performance,
    select_destinations,
    weighted_kmeans,
    worst_distances,
)
from onebit.trackers.istate.core import IState
from onebit.viz.inspect import entity_paths, verify


def test_performance_eq1_by_hand():
    targets = np.array([[[0, 0], [10, 0]], [[0, 1], [10, 1]]], float)  # (K=2, n=2)
    trackers = np.array([[[0, 3]], [[10, 1]]], float)  # (K=2, m=1)
    # stage 1: distances 3 and sqrt(109); stage 2: 10 and 0
    p = performance(targets, trackers)
    assert p[0] == pytest.approx((3 + np.sqrt(109)) / 2)
    assert p[1] == pytest.approx((3 + np.sqrt(109) + 10 + 0) / 4)


def test_cells_and_upper_bounds_fig5():
    """Fig. 5: two elements of two overlapping regions in a square; t(c) is the largest
    number of one element's regions covering the cell."""
    W = box(0, 0, 10, 10)
    a, b = box(0, 0, 6, 6), box(4, 4, 10, 10)  # element 1: overlap in [4, 6]^2
    c, d = box(0, 0, 6, 10), box(4, 0, 10, 10)  # element 2: overlap in the strip x in [4, 6]
    eta = IState.from_elements([[a, b], [c, d]])
    cells = partition_cells(eta, W)
    assert cells.area.sum() == pytest.approx(100.0)
    probe = {(5, 5): 2, (5, 1): 2, (1, 1): 1, (9, 9): 1}
    for (x, y), t in probe.items():
        k = np.flatnonzero(shapely.contains_xy(cells.polygons, x, y))
        assert len(k) == 1 and cells.bound[k[0]] == t, (x, y)


def test_greedy_centres_spread_over_high_bound_cells():
    W = box(0, 0, 10, 10)
    eta = IState.from_elements([[box(0, 0, 2, 2), box(8, 8, 10, 10)]])
    cells = partition_cells(eta, W)
    c = greedy_centres(cells, 2)
    got = sorted(map(tuple, np.round(c, 6)))
    assert got == [(1.0, 1.0), (9.0, 9.0)]
    dest = select_destinations(eta, W, 2)
    assert sorted(map(tuple, np.round(dest, 6))) == [(1.0, 1.0), (9.0, 9.0)]


def test_weighted_kmeans_moves_to_weighted_mean():
    pts = np.array([[0.0, 0], [1, 0], [10, 0], [11, 0]])
    w = np.array([3.0, 1.0, 1.0, 1.0])
    c = weighted_kmeans(pts, w, np.array([[0.5, 0], [10.5, 0]]))
    assert np.allclose(c, [[0.25, 0], [10.5, 0]])


def test_matching_minimises_largest_possible_distance():
    dest = np.array([[0.0, 0.0], [10.0, 0.0]])
    # tracker 0 certainly at (9, 0); tracker 1 somewhere in a disk of radius 3 around (1, 0)
    possible = [Point(9, 0).buffer(1e-9), Point(1, 0).buffer(3, quad_segs=8)]
    wd = worst_distances(possible, dest)
    assert wd[1, 0] == pytest.approx(4.0, abs=1e-6)
    assert list(match_destinations(wd)) == [1, 0]


def test_shortest_paths_go_around_obstacles():
    free = shapely.difference(box(0, 0, 10, 10), box(4, 0, 6, 8))
    sp = ShortestPaths(free, margin=1e-6)
    w = sp.path((1, 1), (9, 1))
    seg = shapely.linestrings(np.stack([w[:-1], w[1:]], axis=1))
    assert shapely.covers(free, seg).all()
    expected = 2 * np.hypot(3, 7) + 2  # up to (4, 8), along the top, down from (6, 8)
    assert np.hypot(*np.diff(w, axis=0).T).sum() == pytest.approx(expected, rel=1e-5)
    assert np.allclose(advance(w, 1e6), (9, 1))


def test_sensing_squares_grid():
    sq = sensing_squares(np.array([50.0, 50.0]), 4.0)
    assert len(sq) == 9 and np.allclose(shapely.area(sq), 16.0)
    assert shapely.union_all(sq).equals(box(44, 44, 56, 56))


def test_active_simulation_invariants():
    cfg = ActiveConfig(trackers=2, targets=2, stages=40, r_c=200.0)  # always in range
    res = simulate_active(cfg, seed=3)
    free = shapely.difference(*fig9_environment()[:1], shapely.union_all(fig9_environment()[1]))
    assert res.contained.all()  # every tracker's I-state holds the truth at every stage
    assert res.elements.max() <= cfg.max_elements
    pts = res.trackers.reshape(-1, 2)
    assert shapely.covers(free.buffer(1e-6), shapely.points(pts)).all()
    step = np.hypot(*np.diff(res.trackers, axis=0).transpose(2, 0, 1))
    assert step.max() <= cfg.s_trk + 1e-9
    # always communicating: both trackers hold the same I-state, so their destinations differ
    assert (np.hypot(*(res.destinations[:, 0] - res.destinations[:, 1]).T) > 1e-9).mean() > 0.9
    assert np.all(np.isfinite(res.performance)) and len(res.links[-1]) == 1


def test_active_simulation_deterministic():
    cfg = ActiveConfig(trackers=2, targets=1, stages=15)
    a, b = simulate_active(cfg, seed=1), simulate_active(cfg, seed=1)
    assert np.array_equal(a.performance, b.performance) and np.array_equal(a.trackers, b.trackers)


def test_experiment_quick(tmp_path):
    out = run_experiment(tmp_path / "okane", seed=0, trials=1, quick=True, echo=lambda s: None, workers=1)
    res = pl.read_parquet(out / "results.parquet")
    assert res.height == 4 and set(res["trackers"]) == {1, 2} and set(res["targets"]) == {1, 3}
    assert (res["containment"] == 1.0).all()
    assert (out / "P_vs_m.png").stat().st_size > 1000
    assert "Paper (section VIII) beside ours" in (out / "README.md").read_text()
    rrd = out / "rrd" / "okane.rrd"
    verify(rrd)
    ents = entity_paths(rrd)
    assert {
        "okane/P",
        "okane/links",
        "okane/trackers/0",
        "okane/trackers/0/sensing",
        "okane/trackers/1/destination",
        "okane/istate/0/0",
        "truth/target1",
    } <= ents


def test_qualitative_summary():
    s = pl.DataFrame({"trackers": [1, 1, 2, 2], "targets": [1, 2, 1, 2], "P_mean": [5.0, 9.0, 3.0, 6.0]})
    q = qualitative(s)
    assert q == {"more_trackers_better": 1.0, "fewer_targets_better": 1.0}
