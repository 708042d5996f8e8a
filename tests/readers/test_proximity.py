"""The proximity reader stage: debounce via the toggle reader, frames at instants, rejects."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit._testing.reader_oracles import proximity_frames_reference
from onebit.core.errors import ConfigError, InputError
from onebit.core.tables import FRAMES, PROXIMITY
from onebit.datasets.proximity_sim import SCENARIO_SPECS, make_world
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.readers.proximity import (
    ProximityConfig,
    proximity_frames,
    read_proximity_csv,
)


def frames_matrix(frames: pl.DataFrame, ids: list[str]) -> np.ndarray:
    return frames.sort(["slot"]).pivot("sensor", index="slot", values="on").select(ids).to_numpy()


def test_pir_line_chatter_is_undone_by_the_debounce(tmp_path):
    d = SCENARIO_SPECS["pir-line"].write(tmp_path / "pir", seed=3, params={})
    w = make_world("pir-line", seed=3)
    ids = [f"p{i + 1:02d}" for i in range(5)]
    raw = read_proximity_csv(d / "proximity.csv", ids)  # no debounce: the chatter shows
    fr_raw = proximity_frames(raw.motion, ids, period=1.0, start=0.0, instants=20)
    res = read_proximity_csv(d / "proximity.csv", ids, rules=ProximityConfig(chatter_window=0.3).rules)
    assert res.suppressed.height > 0 and res.rejects.height == 0
    assert res.motion.schema == PROXIMITY
    fr = proximity_frames(res.motion, ids, period=1.0, start=0.0, instants=20)
    assert fr.schema == FRAMES and fr.height == 20 * 5
    np.testing.assert_array_equal(frames_matrix(fr, ids), w.on)
    # every accepted + rejected + suppressed row accounts for the whole log
    n_rows = pl.read_csv(d / "proximity.csv").height
    assert res.motion.height + res.suppressed.height + res.rejects.height == n_rows
    # without the chatter window the flickers stay in the accepted edges
    assert raw.motion.height == res.motion.height + res.suppressed.height
    assert fr_raw.height == fr.height


def test_bad_rows_go_to_rejects_with_line_and_reason(tmp_path):
    p = tmp_path / "proximity.csv"
    p.write_text("t,sensor,value\n0,a,1\n1,zz,1\nx,a,0\n2,a,7\n3,a,0\n")
    res = read_proximity_csv(p, ["a"])
    rej = res.rejects.sort("line")
    assert rej["line"].to_list() == [3, 4, 5]
    reasons = rej["reason"].to_list()
    assert "sensor" in reasons[0] and "'t'" in reasons[1] and "value" in reasons[2]
    assert res.motion["t"].to_list() == [0.0, 3.0]


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.floats(0, 10, allow_nan=False), st.booleans()), min_size=0, max_size=20),
    st.floats(0.2, 2.0),
    st.integers(1, 15),
)
def test_frames_hold_the_state_after_the_last_edge(edges, period, n):
    df = pl.DataFrame(
        {"t": [e[0] for e in edges], "sensor": ["a"] * len(edges), "on": [e[1] for e in edges]}, schema=PROXIMITY
    ).sort("t", maintain_order=True)
    fr = proximity_frames(df, ["a"], period=period, start=0.0, instants=n)
    assert fr.height == n
    for k, (t, on) in enumerate(zip(fr["t"].to_list(), fr["on"].to_list())):  # brute-force check
        before = [e for e in df.iter_rows() if e[0] <= t]
        assert on == (before[-1][2] if before else False)
        assert abs(t - k * period) < 1e-9


@settings(max_examples=80, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, 40), st.sampled_from(["a", "b", "c", "x"]), st.booleans()), min_size=0, max_size=40
    ),
    st.sampled_from([0.25, 0.3, 0.5, 1.0]),
    st.one_of(st.none(), st.sampled_from([0.0, 1.0, 2.5])),
    st.one_of(st.none(), st.integers(1, 30)),
)
def test_frames_equal_the_as_of_join_reference(edges, period, start, instants):
    """The numpy frames equal the polars as-of join: several sensors, a sensor not asked for
    (``x``), stamps shared by several edges of one sensor (the later row holds), edges
    between and past the instants, a chosen or default start and count."""
    df = pl.DataFrame(
        {"t": [e[0] / 4 for e in edges], "sensor": [e[1] for e in edges], "on": [e[2] for e in edges]},
        schema=PROXIMITY,
    ).sort("t", maintain_order=True)
    ids = ["c", "a", "b"]
    fast = proximity_frames(df, ids, period=period, start=start, instants=instants)
    ref = proximity_frames_reference(df, ids, period=period, start=start, instants=instants)
    assert fast.schema == FRAMES
    assert fast.equals(ref, null_equal=True)


def test_frames_of_edges_sharing_a_stamp_take_the_later_row():
    df = pl.DataFrame({"t": [1.0, 1.0, 1.0], "sensor": ["a", "a", "b"], "on": [True, False, True]}, schema=PROXIMITY)
    fr = proximity_frames(df, ["a", "b"], period=1.0, start=0.0, instants=3)
    assert fr["on"].to_list() == [False, False, False, True, False, True]
    assert fr.equals(proximity_frames_reference(df, ["a", "b"], period=1.0, start=0.0, instants=3), null_equal=True)


def test_pipeline_reads_proximity_from_the_dataset_run_toml(tmp_path):

    d = SCENARIO_SPECS["pir-line"].write(tmp_path / "pir", seed=1, params={})
    res = run_pipeline(d, tmp_path / "run", trackers=("clustertrack",), config={"clustertrack": {"consensus_runs": 2}})
    assert res.status["proximity"].startswith("ok")
    assert metric(res.report, "proximity/instants") == 20
    assert metric(res.report, "proximity/suppressed") > 0
    assert metric(res.report, "proximity/rejected") == 0


def test_config_rejects_non_finite_values_naming_the_field():
    import pytest

    for field, bad in (
        ("start", float("nan")),
        ("start", float("inf")),
        ("period", float("inf")),
        ("chatter_window", float("inf")),
        ("instants", -1),
    ):
        with pytest.raises(ConfigError, match=f"ProximityConfig.{field}"):
            ProximityConfig(**{field: bad})


def test_broken_dataset_run_toml_is_refused_naming_the_file(tmp_path):

    d = SCENARIO_SPECS["pir-line"].write(tmp_path / "pir", seed=1, params={})
    (d / "run.toml").write_text("[proximity\nperiod = 1.0\n")
    with pytest.raises(InputError, match=r"run\.toml.*TOML"):  # checked when the run starts
        run_pipeline(d, tmp_path / "run", trackers=())
