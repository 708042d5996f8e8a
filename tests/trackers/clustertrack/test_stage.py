"""CLUSTERTRACK (Algorithm 1, Appendix B, consensus) and the ``clustertrack`` stage."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment
from shapely.geometry import box

from onebit._testing.oracles import scan_clusters_direct
from onebit.core.errors import ConfigError
from onebit.core.site import site_from_dict
from onebit.core.tables import FRAMES
from onebit.datasets.proximity_sim import SCENARIO_SPECS, make_world
from onebit.experiments import get_experiment
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.scoring.clustertrack import match_tracks
from onebit.trackers.clustertrack.algorithm import (
    _norm,
    clustertrack,
    consensus,
    rules_of_thumb,
    scan_clusters,
    trajectory_distance,
    usage,
)
from onebit.trackers.clustertrack.feasible import SensorArray
from onebit.trackers.clustertrack.space import FeasibleSpace
from onebit.trackers.clustertrack.stage import (
    PARALLEL_MIN,
    ClusterTrackConfig,
    build_space,
    params_for,
    run,
    run_cores,
    track_bound,
)
from onebit.viz.inspect import entity_paths


def world_space(name: str, seed: int, **params):
    w = make_world(name, seed=seed, params=params)
    sa = SensorArray(tuple(f"p{i}" for i in range(len(w.sensor_xy))), w.sensor_xy, w.r_inner, w.r_outer)
    dim = 1 if sa.is_1d else 2
    sp = FeasibleSpace.build(w.on, np.arange(w.on.shape[0], dtype=float), sa, box(*w.boundary), dim=dim, cell=0.1)
    return w, sp, sa.radius


@settings(max_examples=40, deadline=None)
@given(
    st.integers(0, 10**6),
    st.integers(1, 6),
    st.integers(1, 40),
    st.integers(2, 200),
    st.floats(0.05, 2.0),
    st.integers(1, 4),
)
def test_vectorised_scan_equals_direct_algorithm1(seed, H, K, L, D0, t):
    rng = np.random.default_rng(seed)
    kprev, m = int(rng.integers(1, 12)), int(rng.integers(1, 15))
    prev = rng.uniform(0, 5, size=(kprev, t - 1, 1))
    pd = np.sum(_norm(prev[:, None] - prev[None, :])[..., None], axis=(2, 3)) if t > 1 else np.zeros((kprev, kprev))
    parent = np.repeat(np.arange(kprev), m)
    x = rng.uniform(0, 5, size=(kprev * m, 1))
    cost = rng.random(kprev * m)  # distinct costs: no ties
    kept, label, is_head, scanned = scan_clusters(
        cost, parent, x, pd, t, H=H, K=K, L=L, D0=D0, rng=np.random.default_rng(1)
    )
    full = np.concatenate([prev[parent], x[:, None, :]], axis=1)
    k2, l2, s2 = scan_clusters_direct(np.argsort(cost), full, H=H, K=K, L=L, D0=D0)
    np.testing.assert_array_equal(kept, k2)
    np.testing.assert_array_equal(label, l2)
    assert scanned == s2
    # Algorithm 1's invariants: at most K kept, at most L scanned, at most H per cluster
    assert kept.size <= K and scanned <= L and np.bincount(label).max() <= H
    # the head of every cluster is its first (cheapest) kept member
    _, first = np.unique(label, return_index=True)
    assert is_head.sum() == first.size and np.all(is_head[first])


def test_five_well_separated_targets_found_in_18_of_20_seeds():
    ok = 0
    for seed in range(20):
        w, sp, R = world_space("proximity-line", seed, variant="separated")
        p = rules_of_thumb(sp, H=25, m_o=15.0 / R)
        res = clustertrack(sp, p, np.random.default_rng(seed))
        D = trajectory_distance(w.truth[:, :, :1], res.tracks)
        a, b = linear_sum_assignment(D)
        ok += int(np.sum(D[a, b] <= p.D0) == 5)
        # the K / L / H limits hold at every instant
        assert (
            np.all(res.first.kept <= p.K) and np.all(res.first.scanned <= p.L) and np.all(res.first.max_cluster <= p.H)
        )
    assert ok >= 18


def test_same_seed_same_tracks_and_appendix_b_satisfies_bounds():
    w, sp, R = world_space("proximity-line", 3)
    p = rules_of_thumb(sp, H=25, m_o=15.0)
    a = clustertrack(sp, p, np.random.default_rng(7))
    b = clustertrack(sp, p, np.random.default_rng(7))
    np.testing.assert_array_equal(a.tracks, b.tracks)
    np.testing.assert_array_equal(a.costs, b.costs)
    assert a.satisfied
    for t, u in enumerate(usage(sp, a.tracks)):
        assert np.all(u >= sp.comp_bounds_all[t])
    # rules of thumb (section 4.2.2)
    assert p.Q_hat == sp.max_lower_bound and p.K == 25 * p.Q_hat
    assert p.L == max(p.K, round(25 * 15.0 * sp.sizes_all.mean()))
    assert p.D0 == pytest.approx(sp.sizes_all.mean() / p.Q_hat)


def test_rerun_reverses_time_and_one_run_version_does_not_rerun():
    w, sp, R = world_space("proximity-line", 1, variant="crossing")
    p = rules_of_thumb(sp, H=25, m_o=15.0)
    one = clustertrack(sp, p, np.random.default_rng(0), rerun=False)
    assert one.reruns == 0 and np.all(one.origin == 0)
    rev = sp.reversed()
    assert rev.size(0) == sp.size(sp.T - 1)
    # a restricted space samples only inside the chosen component
    t = int(np.argmax(sp.bounds_all))
    sub = sp.restricted(t, 0)
    pts = sub.sample(t, 200, np.random.default_rng(0))
    assert np.all(sp.component_of(t, pts) == 0)


def test_consensus_counts_separated_targets():
    w, sp, R = world_space("proximity-line", 2, variant="separated")
    p = rules_of_thumb(sp, H=25, m_o=15.0)
    c = consensus(sp, p, list(range(6)))
    assert c.count == 5
    assert np.all(c.costs <= 10 * c.costs.min() + 1e-9)


def test_2d_grid_two_targets():
    w, sp, R = world_space("proximity-grid", 0)
    p = rules_of_thumb(sp, H=50, m_o=50.0)
    res = clustertrack(sp, p, np.random.default_rng(0), rerun=False)
    D = trajectory_distance(w.truth, res.tracks)
    assert np.sum(D.min(axis=1) <= p.D0) == 2


def test_config_errors_name_the_field():
    with pytest.raises(ConfigError, match="h"):
        ClusterTrackConfig(h=0)
    with pytest.raises(ConfigError, match="dim"):
        ClusterTrackConfig(dim="3d")


def test_stage_on_empty_frames():

    site = site_from_dict(
        {
            "boundary": {"polygon": [[0, -0.5], [5, -0.5], [5, 0.5], [0, 0.5]]},
            "proximity_sensors": [{"id": "a", "position": [1.0, 0.0], "radius": 1.0}],
        }
    )
    out = run({"proximity_frames": pl.DataFrame(schema=FRAMES)}, site, ClusterTrackConfig(consensus_runs=0))
    assert out["tracks"].height == 0


def test_pipeline_end_to_end(tmp_path):

    data = SCENARIO_SPECS["proximity-line"].write(tmp_path / "d", seed=4, params={"variant": "separated"})
    res = run_pipeline(
        data, tmp_path / "run", trackers=("clustertrack",), config={"clustertrack": {"consensus_runs": 3}}
    )
    assert res.status["clustertrack"].startswith("ok"), res.status
    rep = res.report
    assert metric(rep, "clustertrack/targets_true") == 5
    assert metric(rep, "clustertrack/count_lower_bound") == 5
    assert metric(rep, "clustertrack/targets_found") >= 4
    assert metric(rep, "clustertrack/mean_error_R") < 0.6
    assert metric(rep, "clustertrack/count_consensus") >= 4
    tracks = pl.read_parquet(tmp_path / "run" / "tables" / "clustertrack_tracks.parquet")
    assert tracks.columns == ["tracker", "track", "t", "x", "y", "region", "node"]
    ents = entity_paths(tmp_path / "run" / "rrd" / "clustertrack.rrd")
    assert {"clustertrack/particles", "clustertrack/feasible", "clustertrack/sensors/outer"} <= ents
    assert any(e.startswith("clustertrack/space_time/tracks") for e in ents)


def test_quick_singh_experiment_writes_table_and_plots(tmp_path):

    out = get_experiment("singh").run(tmp_path / "exp", seed=0, trials=2, quick=True, echo=lambda s: None)
    res = pl.read_parquet(out / "results.parquet")
    assert set(res["setting"]) >= {"ideal", "nonideal 0.7/1.3", "nonideal 0.5/1.5", "pir-line"}
    assert res.filter(pl.col("setting") == "ideal")["error_R"].max() < 1.0
    assert (out / "error_vs_density.png").stat().st_size > 1000 and (out / "found_spurious.png").exists()


def test_match_tracks_pairs_every_track_row_with_the_nearest_truth_of_every_target():

    rng = np.random.default_rng(5)
    truth = pl.DataFrame(
        {
            "t": np.repeat(np.arange(12) * 0.5, 3),
            "target": ["b", "a", "c"] * 12,
            "x": rng.random(36),
            "y": rng.random(36),
        }
    )
    tracks = pl.DataFrame(
        {
            "track": np.repeat(["c2", "c1"], 9),
            "t": np.tile(np.arange(9) * 0.7, 2),
            "x": rng.random(18),
            "y": rng.random(18),
        }
    )
    targets, names, D, pairs = match_tracks(truth, tracks)
    assert targets == ["a", "b", "c"] and names == ["c1", "c2"]
    assert pairs.height == 3 * tracks.height
    for i, g in enumerate(targets):  # brute force: nearest truth time of target g, mean distance
        tg = truth.filter(pl.col("target") == g).sort("t")
        tt, tx, ty = tg["t"].to_numpy(), tg["x"].to_numpy(), tg["y"].to_numpy()
        for j, k in enumerate(names):
            tk = tracks.filter(pl.col("track") == k)
            near = np.abs(tk["t"].to_numpy()[:, None] - tt[None, :]).argmin(axis=1)
            err = np.hypot(tk["x"].to_numpy() - tx[near], tk["y"].to_numpy() - ty[near])
            assert D[i, j] == pytest.approx(err.mean())


def test_minimal_targets_explain_every_1d_snapshot():
    """The stored minimal target set of each instant has the greedy's size (the lower bound)
    and puts a target in the on-range of every on-sensor whose g_i is not empty."""
    w, sp, R = world_space("proximity-line", 2)
    for t, pos in enumerate(sp.minimal_targets):
        assert pos.size == sp.bounds_all[t]
        hull, s = sp.f1d[t].hulls()
        assert np.all(np.any((pos[None, :] >= hull[:, :1] - 1e-9) & (pos[None, :] <= hull[:, 1:] + 1e-9), axis=1))


def test_ten_targets_reruns_are_not_monopolised_by_jump_trajectories():
    """Appendix B with Q = 10 parallel targets (issue 5 follow-up): a rerun with K = H q
    (one cluster) is captured by a zero-cost jump between components and returns a high-cost
    trajectory that satisfies (t_o, c_o) but is no target. Repeating such a rerun with
    K = H Q_hat finds the targets: all 10, few spurious tracks, far fewer reruns."""
    w = make_world("proximity-line", seed=0, targets=10, params={"variant": "separated"})
    sa = SensorArray(tuple(f"p{i}" for i in range(len(w.sensor_xy))), w.sensor_xy, w.r_inner, w.r_outer)
    sp = FeasibleSpace.build(w.on, np.arange(w.on.shape[0], dtype=float), sa, box(*w.boundary), dim=1, cell=0.1)
    p = rules_of_thumb(sp, H=25, m_o=15.0)
    assert p.Q_hat == 10 and np.all(sp.bounds_all == 10)

    def score(res):
        D = trajectory_distance(w.truth[:, :, :1], res.tracks)
        a, b = linear_sum_assignment(D)
        found = int(np.sum(D[a, b] <= p.D0))
        return found, res.tracks.shape[0] - found

    fixed = clustertrack(sp, p, np.random.default_rng(0))
    literal = clustertrack(sp, p, np.random.default_rng(0), high_cost=0.0)
    found, spurious = score(fixed)
    lit_found, lit_spurious = score(literal)
    assert fixed.satisfied and found == 10 and spurious <= 3
    assert fixed.reruns <= 10 < literal.reruns and lit_spurious >= spurious + 10 and lit_found <= found
    # every rerun retains at most its deficit q (here every component's bound is 1)
    assert np.all(np.bincount(fixed.origin)[1:] <= 1) and np.all(np.bincount(literal.origin)[1:] <= 1)
    # the retained rerun tracks pass through the component they were run for: bounds hold
    for t, u in enumerate(usage(sp, fixed.tracks)):
        assert np.all(u >= sp.comp_bounds_all[t])


def test_tracks_never_exceed_targets_nor_the_count_estimate():
    """Spurious firings raise per-component lower bounds; Appendix B reruns must still stop at
    min(targets, Q_hat) tracks (issue 23: 11-38 tracks for 3-6 people)."""
    from onebit.trackers.clustertrack.stage import ClusterTrackConfig, run

    frames, site = _grid_frames(seed=5, T=12)  # scattered spurious firings: many components per instant
    for targets, bound in ((0, 2), (1, 1)):
        out = run(
            {"proximity_frames": frames},
            site,
            ClusterTrackConfig(consensus_runs=2, targets=targets, h_2d=10, m_o_r2=10.0),
        )
        q_hat = int(out["params"]["Q_hat"][0])
        n = out["tracks"].group_by("t").len()["len"].max()
        assert q_hat >= 2 and n <= min(bound, q_hat)


def test_clustertrack_and_binpf_beyond_their_instant_bounds_are_skipped_saying_why(tmp_path):
    """A frame log of more instants than [clustertrack] max_instants / [binpf] max_frames skips
    the stage in a default run, naming the setting; 0 lifts the bound."""
    data = SCENARIO_SPECS["proximity-line"].write(tmp_path / "d", seed=4, params={"variant": "separated"})
    tight = {"clustertrack": {"max_instants": 5, "consensus_runs": 0, "reruns": 0}, "binpf": {"max_frames": 5}}
    res = run_pipeline(
        data, tmp_path / "bounded", trackers=("clustertrack", "binpf", "istate"), config=tight, rrd=False
    )
    for name, field in (("clustertrack", "max_instants = 5"), ("binpf", "max_frames = 5")):
        reason = res.status[name]
        assert reason.startswith("skipped") and field in reason and "instants" in reason, reason
    assert not res.ok and any("max_instants" in p for p in res.problems)  # asked for by name
    lifted = {"clustertrack": {"max_instants": 0, "consensus_runs": 0, "reruns": 0}, "binpf": {"max_frames": 0}}
    res = run_pipeline(data, tmp_path / "lifted", trackers=("clustertrack", "binpf"), config=lifted, rrd=False)
    assert res.status["clustertrack"].startswith("ok") and res.status["binpf"].startswith("ok"), res.status


def _grid_frames(seed: int = 5, T: int = 12):
    rng = np.random.default_rng(seed)
    xy = [(1.0 + 1.5 * i, 1.0 + 1.5 * j) for i in range(5) for j in range(5)]
    site = site_from_dict(
        {
            "boundary": {"polygon": [[0, 0], [8, 0], [8, 8], [0, 8]]},
            "units": "m",
            "targets": 2,
            "proximity_sensors": [{"id": f"s{k}", "position": list(p), "radius": 0.9} for k, p in enumerate(xy)],
        }
    )
    on = rng.random((T, len(xy))) < 0.12
    frames = pl.DataFrame(
        {
            "slot": np.repeat(np.arange(T), len(xy)),
            "t": np.repeat(np.arange(T) * 0.5, len(xy)),
            "sensor": [f"s{k}" for k in range(len(xy))] * T,
            "on": on.ravel(),
            "fired": on.ravel(),
        },
        schema={"slot": pl.Int64, "t": pl.Float64, "sensor": pl.String, "on": pl.Boolean, "fired": pl.Boolean},
    )
    return frames, site


@pytest.mark.parametrize("reruns", [10, 0])
def test_runs_side_by_side_in_worker_processes_give_the_same_tables(reruns):
    """``cores`` deals the independent runs (the stage's and the other consensus seeds') to this
    process and workers; every table is the same as with every run here, in one process."""
    frames, site = _grid_frames()
    base = dict(consensus_runs=4, reruns=reruns, h_2d=10, m_o_r2=10.0, seed=3)
    one = run({"proximity_frames": frames}, site, ClusterTrackConfig(cores=1, **base))
    three = run({"proximity_frames": frames}, site, ClusterTrackConfig(cores=3, **base))
    assert one.keys() == three.keys()
    for name in one:
        if not isinstance(one[name], pl.DataFrame):
            continue
        assert one[name].equals(three[name]), name
    assert one["consensus"].height > 0
    # and both are what consensus() makes by itself, run after run
    sp, R, _ = build_space(frames, site, ClusterTrackConfig(**base))
    p = params_for(sp, R, ClusterTrackConfig(**base))
    cons = consensus(
        sp, p, [3, 4, 5, 6], max_reruns=reruns, max_tracks=track_bound(p, site, ClusterTrackConfig(**base))
    )
    assert np.array_equal(cons.costs, one["consensus"]["cost"].to_numpy())


def test_run_cores_auto_follows_the_job_and_the_cores_available(monkeypatch):
    cfg = ClusterTrackConfig()
    monkeypatch.setenv("ONEBIT_CORES", "4")
    assert run_cores(cfg, PARALLEL_MIN - 1, 3) == 1  # small job: every run here
    assert run_cores(cfg, PARALLEL_MIN, 3) == 4
    assert run_cores(cfg, PARALLEL_MIN, 1) == 2  # never more lanes than runs
    assert run_cores(ClusterTrackConfig(cores=1), 10**9, 3) == 1
    assert run_cores(ClusterTrackConfig(cores=3), 10, 3) == 3  # an explicit count holds for any job
    monkeypatch.setenv("ONEBIT_CORES", "1")  # a run-many worker
    assert run_cores(cfg, 10**9, 3) == 1
    with pytest.raises(ConfigError, match="cores"):
        ClusterTrackConfig(cores=-1)
