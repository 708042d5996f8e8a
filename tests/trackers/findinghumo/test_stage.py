"""FindingHuMo stages: Adaptive-HMM invariants (Theorem 1, user count), the hallway run end to end."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import ConfigError
from onebit.core.site import load_site
from onebit.core.tables import MOTION, TRACKS
from onebit.datasets.builtin import builtin_site
from onebit.datasets.hallway_sim import write_hallway_dataset
from onebit.models.graph_hmm.adaptive import DecoderParams, decode_run, decode_users
from onebit.models.graph_hmm.eatg import hop_matrix, layout_eatg
from onebit.models.graph_hmm.window import max_independent
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.readers.motion import read_motion_csv
from onebit.scoring.findinghumo import score as score_findinghumo
from onebit.trackers.findinghumo.stage import FindingHumoConfig, HmmConfig, build_eatg, run_findinghumo, slot_activity
from onebit.viz.inspect import entity_paths


@pytest.fixture(scope="module")
def hallway():
    site = builtin_site("hallway")
    g = site.sensor_graph
    return site, layout_eatg(g.nodes, hop_matrix(g.nodes, g.edges))


def test_user_count_is_a_maximum_independent_set(hallway):
    site, eatg = hallway
    i = eatg.index
    adj = eatg.hops == 1
    on = lambda *ns: np.array(sorted(i[n] for n in ns))  # noqa: E731
    assert max_independent(on("99", "111"), adj, {}) == 1  # adjacent: one user can trigger both
    assert max_independent(on("95", "111"), adj, {}) == 2  # two hops apart: two users
    assert max_independent(on("95", "99", "111"), adj, {}) == 2
    assert max_independent(on("104", "97", "103", "102", "101"), adj, {}) == 3


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_theorem1_reduced_states_give_the_full_path(hallway, seed):
    """Theorem 1: on one user's windows the reduced state set (active nodes, their 2-hop
    neighbours and the user's last nodes) yields the same optimal path as all states."""
    import tempfile

    site, eatg = hallway
    with tempfile.TemporaryDirectory() as tmp:
        ds = write_hallway_dataset(tmp, seed=seed, duration=60.0, users=1, drop=0.0)
        mo = read_motion_csv(ds / "motion.csv", list(eatg.nodes)).motion
    active, _ = slot_activity(mo, eatg.nodes, 1.0)
    params = DecoderParams()
    full_states = np.arange(len(eatg.nodes))
    checked = 0
    prev: list[int] = []
    for s in range(0, active.shape[0] - 5, 3):
        obs = active[s : s + 5]
        if not obs.any():
            continue
        for order in (1, 2):
            full = decode_users(obs, full_states, [prev], [0], [-1], order=order, eatg=eatg, params=params)[0]
            keep = np.unique(np.concatenate([np.flatnonzero(obs.any(axis=0)), prev]).astype(np.int64))
            reduced_states = np.flatnonzero((eatg.hops[keep] <= 2).any(axis=0))
            red = decode_users(obs, reduced_states, [prev], [0], [-1], order=order, eatg=eatg, params=params)[0]
            np.testing.assert_array_equal(red, full)
            checked += 1
        prev = [int(full[1]), int(full[2])]
    assert checked >= 10


def test_two_users_crossing_are_both_explained(hallway):
    """Two users walk towards each other through the kitchen; K = 2 paths explain every activation."""
    site, eatg = hallway
    i = eatg.index
    a = ["95", "95", "99", "99", "111", "111"]
    b = ["111", "111", "99", "99", "95", "95"]
    obs = np.zeros((6, len(eatg.nodes)), bool)
    for t, (x, y) in enumerate(zip(a, b)):
        obs[t, [i[x], i[y]]] = True
    paths = decode_users(
        obs,
        np.arange(len(eatg.nodes)),
        [[i["96"], i["95"]], [i["110"], i["111"]]],
        [0, 0],
        [-1, -1],
        order=2,
        eatg=eatg,
        params=DecoderParams(),
    )
    assert np.all(obs[np.arange(6)[:, None], paths.T])  # every decoded node is active
    explained = np.zeros_like(obs)
    explained[np.arange(6)[None, :].repeat(2, 0), paths] = True
    assert np.array_equal(explained, obs)  # and together they explain all activations


def test_config_errors_name_the_field():
    with pytest.raises(ConfigError, match="d_max"):
        HmmConfig(d_max=0)
    with pytest.raises(ConfigError, match="tau"):
        HmmConfig(d_max=5, tau=6)
    with pytest.raises(ConfigError, match="eatg"):
        FindingHumoConfig(eatg="nope")
    with pytest.raises(ConfigError, match="c_windows"):
        FindingHumoConfig(c_windows=0)


def test_stage_contract(tmp_path, hallway):
    site, _ = hallway
    ds = write_hallway_dataset(tmp_path / "d", seed=4, duration=40.0, users=2)
    mo = read_motion_csv(ds / "motion.csv", [m.id for m in site.motion_sensors]).motion
    out1 = run_findinghumo({"motion": mo}, site, FindingHumoConfig())
    out2 = run_findinghumo({"motion": mo}, site, FindingHumoConfig())
    assert out1["tracks"].schema == TRACKS
    assert out1["tracks"].equals(out2["tracks"])  # deterministic
    # every decoded node is a graph node and consecutive slots of a user are <= 1 hop apart
    eatg = build_eatg(site, slot_activity(mo, site.sensor_graph.nodes, 1.0)[0], FindingHumoConfig())
    idx = eatg.index
    for _, g in out1["tracks"].group_by("track"):
        k = np.array([idx[n] for n in g.sort("t")["node"].to_list()])
        assert np.all(eatg.hops[k[:-1], k[1:]] <= 1)
    empty = run_findinghumo({"motion": mo.clear()}, site, FindingHumoConfig())
    assert empty["tracks"].height == 0 and empty["tracks"].schema == TRACKS


@pytest.fixture(scope="module")
def hallway_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("hallway")
    out = {}
    for seed in range(5):
        ds = write_hallway_dataset(root / f"d{seed}", seed=seed, duration=150.0, users=3)
        res = run_pipeline(ds, root / f"r{seed}", trackers=("findinghumo", "hmm1", "hmm2", "findinghumo-flow"))
        out[seed] = res
    return out


def test_hallway_runs_end_to_end(hallway_runs):
    res = hallway_runs[0]
    assert res.ok, res.status
    rep = res.report
    for tr in ("findinghumo", "hmm1", "hmm2"):
        assert metric(rep, f"{tr}/users_true") == 3
        assert metric(rep, f"{tr}/users_decoded") >= 1
        for u in ("user1", "user2", "user3"):
            assert 0 <= metric(rep, f"{tr}/hop_error/{u}") <= 10
    assert (res.out / "tables" / "findinghumo_switches.parquet").exists()
    eatg = pl.read_parquet(res.out / "tables" / "findinghumo_eatg.parquet")
    assert set(eatg["kind"]) == {"a1", "a2"}
    ents = entity_paths(res.out / "rrd" / "findinghumo.rrd")
    for e in (
        "findinghumo/eatg/a1",
        "findinghumo/eatg/nodes",
        "findinghumo/activations",
        "findinghumo/decoded/user1",
        "findinghumo/cpda",
    ):
        assert any(p.strip("/") == e for p in ents), (e, sorted(ents)[:20])
    flow = entity_paths(res.out / "rrd" / "findinghumo-flow.rrd")
    assert any(p.strip("/") == "findinghumo-flow/joins" for p in flow), sorted(flow)[:20]
    cp = pl.read_parquet(res.out / "tables" / "findinghumo_cpda.parquet")
    assert cp.height > 0 and cp["p_chosen"].is_between(0, 1).all() and (cp["p_chosen"] >= cp["p_keep"] - 1e-9).all()


def _mean(runs, name):
    return float(np.mean([metric(r.report, f"{name}/hop_error") for r in runs.values()]))


def _mean_decoded_hmm(runs):
    """findinghumo's Adaptive-HMM output before CPDA (table ``findinghumo_decoded_hmm``), scored alike."""
    out = []
    for seed, r in runs.items():
        tables = {
            "findinghumo_tracks": pl.read_parquet(r.out / "tables" / "findinghumo_decoded_hmm.parquet").with_columns(
                tracker=pl.lit("findinghumo")
            ),
            "truth": pl.read_parquet(r.out / "tables" / "truth.parquet"),
        }
        rows, _ = score_findinghumo("findinghumo", tables, load_site(r.out.parent / f"d{seed}" / "site.toml"))
        out.append(next(v for _, m, v, _ in rows if m == "hop_error"))
    return float(np.mean(out))


def test_hallway_what_is_reached(hallway_runs):
    """What issue #15 reached over seeds 0-4 (3 users, 150 s, drop 0.02), measured: hmm1 1.59,
    hmm2 0.70, findinghumo 0.68, findinghumo-flow 0.46 hops (five seeds are too few to order
    findinghumo and hmm2: the 20-seed ordering is tested in
    tests/experiments/test_findinghumo_diagnose.py; docs/findinghumo.md has why <= 0.1 is not
    reached: two thirds of the swaps left are exact ties of the model). Held: the
    second-order HMM beats the first-order one, CPDA lowers the error of the Adaptive-HMM it
    starts from, and the global flow association is at or below hmm2, whose paths it starts from."""
    h1, h2, fh, flow = (_mean(hallway_runs, n) for n in ("hmm1", "hmm2", "findinghumo", "findinghumo-flow"))
    pre = _mean_decoded_hmm(hallway_runs)
    assert h2 < h1, (h2, h1)
    assert fh < pre, (fh, pre)  # CPDA puts right more than it breaks
    assert fh < h1, (fh, h1)
    assert flow <= h2, (flow, h2)
    assert flow < 0.75 and h2 < 0.8 and h1 > 1.2, (flow, h2, h1)  # the measured levels, with a margin


@settings(max_examples=40, deadline=None)
@given(gaps=st.lists(st.floats(0.05, 3.0), min_size=2, max_size=16), start=st.floats(0.0, 2.0))
def test_mid_slot_sampling(gaps, start):
    """``b_j(k)`` is the state at the slot's mid time, and no on-period is lost: one shorter than
    a slot that holds no mid time is kept in the slot of its own mid time."""
    t = start + np.cumsum(gaps)
    on = np.arange(t.size) % 2 == 0  # alternating edges from off
    motion = pl.DataFrame({"t": t, "sensor": "a", "on": on}, schema=MOTION)
    act, t0 = slot_activity(motion, ("a", "b"), 1.0, "mid")
    assert not act[:, 1].any()
    d = act.shape[0]
    mids = t0 + np.arange(d) + 0.5
    state = np.zeros(d, bool)
    k = np.searchsorted(t, mids, side="right") - 1  # last edge at or before each mid time
    state[k >= 0] = on[k[k >= 0]]
    lo, hi = t[on], np.append(t[~on], t0 + d)[: on.sum()]  # an open period ends with the grid
    for a, b in zip(lo, hi):  # every on-period shows in some slot it overlaps
        inside = (mids >= a) & (mids < b)
        slots = np.arange(d)[(t0 + np.arange(d) + 1 > a) & (t0 + np.arange(d) < b)]
        assert act[slots, 0].any()
        if inside.any():
            assert act[inside, 0].all()
    short = np.zeros(d, bool)  # slots holding the mid time of a period that covers no mid time
    for a, b in zip(lo, hi):
        if not ((mids >= a) & (mids < b)).any():
            short[min(int(np.floor((a + b) / 2 - t0)), d - 1)] = True
    np.testing.assert_array_equal(act[:, 0], state | short)


def test_user_walking_through_the_door_keeps_its_identity(hallway):
    """103 -> 104 -> 97 is an exit signature then an entry one: the same user, not a new one."""
    site, eatg = hallway
    i = eatg.index
    seq = ["102"] * 3 + ["103"] * 4 + ["104"] * 4 + ["97"] * 4 + ["96"] * 4
    active = np.zeros((len(seq), len(eatg.nodes)), bool)
    active[np.arange(len(seq)), [i[n] for n in seq]] = True
    sigs = [(i[a], i[b]) for a, b in site.sensor_graph.signatures]
    for mode in ("adaptive", "full1", "full2"):
        res = decode_run(active, eatg, signatures=sigs, params=DecoderParams(mode=mode))
        assert res.paths.shape[0] == 1, mode
        assert [eatg.nodes[j] for j in res.paths[0]] == seq, mode


def test_joint_redecoding_is_tabled_and_logged(hallway_runs):
    """Every meeting the joint re-decoding considered is in ``findinghumo_joint`` (gain >= 0:
    it never lowers the model's log-likelihood), and each one it changed is a labelled point
    in the recording under ``findinghumo/joint``; the baselines do not run it."""
    from onebit.viz.inspect import component_rows

    changed = 0
    for _seed, r in hallway_runs.items():
        joint = pl.read_parquet(r.out / "tables" / "findinghumo_joint.parquet")
        assert joint.height > 0 and (joint["gain"] >= 0).all()
        assert not (r.out / "tables" / "hmm2_joint.parquet").exists()
        n = int((joint["gain"] > 0).sum())
        if n:
            labels = [
                x
                for row in component_rows(r.out / "rrd" / "findinghumo.rrd", "findinghumo/joint", "Points2D:labels")
                for x in (row or [])
            ]
            assert len(labels) == n and all(lb.startswith("joint: users ") for lb in labels), labels
        changed += n
    assert changed > 0
