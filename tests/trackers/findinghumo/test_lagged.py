"""Lagged decoding (FindingHuMo's live requirement): the same committed paths however the slots
arrive, slots never revised once final, a lag that bounds when a block is committed, and the
config that keeps the whole-log EATG out of it."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.errors import ConfigError, InputError
from onebit.datasets.builtin import builtin_site
from onebit.datasets.hallway_sim import write_hallway_dataset
from onebit.models.graph_hmm.adaptive import RESUME_SLOTS, DecoderParams, WindowDecoder, decode_run
from onebit.models.graph_hmm.decoding import UserCap, cap_users, signature_indices
from onebit.models.graph_hmm.eatg import eatg_from_table, hop_matrix, layout_eatg, trained_eatg
from onebit.readers.motion import read_motion_csv
from onebit.trackers.findinghumo.lagged import LaggedDecoder, lagged_paths, stack_blocks
from onebit.trackers.findinghumo.stage import FindingHumoConfig, HmmConfig, slot_activity


@pytest.fixture(scope="module")
def hallway(tmp_path_factory):
    site = builtin_site("hallway")
    g = site.sensor_graph
    eatg = layout_eatg(g.nodes, hop_matrix(g.nodes, g.edges))
    ds = write_hallway_dataset(tmp_path_factory.mktemp("hw"), seed=3, duration=90.0, users=3, drop=0.0)
    mo = read_motion_csv(ds / "motion.csv", list(g.nodes)).motion
    active, _ = slot_activity(mo, g.nodes, 1.0)
    return site, eatg, active


def _cuts(rng, n):
    i = 0
    while i < n:
        j = min(n, i + int(rng.integers(1, 12)))
        yield i, j
        i = j


@pytest.mark.parametrize("mode", ["adaptive", "full2"])
def test_window_decoder_in_pieces_equals_decode_run(hallway, mode):
    site, eatg, active = hallway
    sigs = signature_indices(site.sensor_graph, eatg)
    params = DecoderParams(mode=mode)
    ref = decode_run(active, eatg, signatures=sigs, params=params)
    rng = np.random.default_rng(1)
    dec = WindowDecoder(eatg, active.shape[1], signatures=sigs, params=params)
    finals = []
    for i, j in _cuts(rng, active.shape[0]):
        dec.extend(active[i:j])
        dec.advance()
        f = dec.final_slots
        assert f <= max(
            0, j - params.d_max - RESUME_SLOTS + params.tau
        )  # final only after the window and re-entry time
        finals.append(dec.paths(0, f))
    dec.advance(final=True)
    assert np.array_equal(dec.result().paths, ref.paths) and dec.result().windows == ref.windows
    for p in finals:  # a slot once final is never changed by a later window
        assert np.array_equal(p, ref.paths[: p.shape[0], : p.shape[1]])
    assert ref.paths.shape[0] >= 2  # the run has several users: the test can fail


@pytest.mark.parametrize("cls", [FindingHumoConfig, HmmConfig])
def test_lagged_in_pieces_equals_all_at_once(hallway, cls):
    site, eatg, active = hallway
    cfg = cls(eatg="layout", decoding="lagged", joint="before-cpda")
    cw = cfg.c_windows if cls is FindingHumoConfig else None
    mode = "adaptive" if cls is FindingHumoConfig else "full2"
    ref, ref_dec = lagged_paths(mode, active, site, cfg, eatg, cpda_windows=cw)
    assert ref.shape[1] == active.shape[0] and (ref >= 0).sum() > 100
    for seed in (0, 1):
        rng = np.random.default_rng(seed)
        lag = LaggedDecoder(mode, site, cfg, eatg, cpda_windows=cw)
        blocks = []
        for i, j in _cuts(rng, active.shape[0]):
            lag.extend(active[i:j])
            got = lag.commit()
            for b0, p in got:  # a block is committed only once D' slots after it have arrived
                assert b0 + p.shape[1] - 1 + cfg.decision_lag < j + cfg.tau
            blocks += got
        assert blocks, "nothing committed before the end: not online"
        blocks += lag.commit(final=True)
        assert np.array_equal(stack_blocks(blocks, active.shape[0]), ref)
        assert lag.switches == ref_dec.switches and lag.joint_log == ref_dec.joint_log


def test_user_cap_in_pieces_equals_whole(hallway):
    site, eatg, active = hallway
    rng = np.random.default_rng(4)
    paths = rng.integers(-1, active.shape[1], size=(5, active.shape[0]))
    whole = cap_users(paths, active, eatg.hops, 2)
    cap = UserCap(2, eatg.hops)
    parts = [cap.step(paths[:, i:j], active[i:j]) for i, j in _cuts(rng, active.shape[0])]
    assert np.array_equal(np.concatenate(parts, axis=1), whole)


def test_lagged_needs_a_graph_known_beforehand():
    with pytest.raises(ConfigError, match="eatg"):
        FindingHumoConfig(decoding="lagged")  # eatg = "trained" learns from the whole log
    with pytest.raises(ConfigError, match="decision_lag"):
        HmmConfig(eatg="layout", decoding="lagged", decision_lag=5 + RESUME_SLOTS - 1)
    with pytest.raises(ConfigError, match="eatg_file"):
        HmmConfig(eatg="file")
    with pytest.raises(ConfigError, match="decoding"):
        HmmConfig(decoding="live")
    from onebit.trackers.findinghumo_flow.stage import FlowConfig

    with pytest.raises(ConfigError, match=r"FlowConfig\.decoding = 'lagged'; allowed values: \['batch'\]"):
        FlowConfig(eatg="layout", decoding="lagged")


def test_eatg_table_round_trip_and_errors(hallway, tmp_path):
    site, _, active = hallway
    g = site.sensor_graph
    hops = hop_matrix(g.nodes, g.edges)
    trained = trained_eatg(active, g.nodes, hops)
    back = eatg_from_table(trained.table(), g.nodes, hops)
    assert np.allclose(back.a1, trained.a1) and np.allclose(back.a2, trained.a2)
    bad = trained.table().with_columns(pl.lit("nope").alias("src"))
    with pytest.raises(InputError, match="nope"):
        eatg_from_table(bad, g.nodes, hops, source="x.parquet")


def test_online_advance_poll_by_poll_equals_the_lagged_run(tmp_path):
    """The follower's side: the motion table as it grows, poll by poll, through
    :func:`advance` (recent edges only) publishes exactly the lagged run's TRACKS rows,
    silent stretches dropped -- here a log with a 90 s empty hallway in the middle."""
    from onebit.trackers.findinghumo import lagged
    from onebit.trackers.findinghumo.stage import run_findinghumo

    site = builtin_site("hallway")
    g = site.sensor_graph
    ds = write_hallway_dataset(tmp_path, seed=5, duration=60.0, users=2, drop=0.0)
    mo = read_motion_csv(ds / "motion.csv", list(g.nodes)).motion
    mo = pl.concat([mo, mo.with_columns(pl.col("t") + 150.0)])  # nobody there for about 90 s between
    cfg = FindingHumoConfig(eatg="layout", decoding="lagged")
    ref = run_findinghumo({"motion": mo}, site, cfg)["tracks"]
    eatg = layout_eatg(g.nodes, hop_matrix(g.nodes, g.edges))
    state = lagged.start("findinghumo", "adaptive", site, cfg, eatg, cpda_windows=cfg.c_windows)
    got, settle = [], 1.5
    for h in np.arange(float(mo["t"].min()), float(mo["t"].max()) + 5.0, 1.7):
        got.append(lagged.advance(state, mo.filter(pl.col("t") <= h), settled_until=h - settle, final=False))
    early = sum(x.height for x in got)
    got.append(lagged.advance(state, mo, settled_until=np.inf, final=True))
    got = pl.concat(got)
    assert early > ref.height // 2  # most rows published while the log grew
    assert ref.filter((pl.col("t") > 70.0) & (pl.col("t") < 140.0)).height == 0  # the silence is dropped
    assert got.sort(["track", "t"]).equals(ref.sort(["track", "t"]))
    assert state.cut_row > mo.height // 2  # the follower looked at recent edges only


def test_the_joint_neighbourhood_is_a_hop_count():
    assert FindingHumoConfig().joint_hops == 0  # exact: the nodes the pair can reach
    assert HmmConfig(joint_hops=2).joint_hops == 2  # the paper's 2-hop state set for overlapping motion
    with pytest.raises(ConfigError, match="joint_hops"):
        FindingHumoConfig(joint_hops=-1)
    with pytest.raises(ConfigError, match="joint_hops"):
        HmmConfig(joint_hops=1.5)
