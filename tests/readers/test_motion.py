"""The PIR toggle reader: typing, no-change edges, debounce rules (slots: tests/core/test_frames.py)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit._testing.oracles import motion_frames_reference
from onebit.core.errors import ConfigError
from onebit.core.frames import motion_frames
from onebit.core.tables import MOTION, REJECTS
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.readers.motion import (
    DebounceRules,
    read_motion,
    read_motion_csv,
    rules_by_type,
)
from onebit.readers.rows import RawRows
from onebit.viz.inspect import entity_paths

SENSORS = ("p1", "p2", "p3")


def raw_rows(rows: list[tuple[object, object, object]]) -> RawRows:
    """String rows as ``read_csv_rows`` makes them (line = file line, header = 1)."""
    frame = pl.DataFrame(
        {
            "line": list(range(2, 2 + len(rows))),
            "t": [None if r[0] is None else str(r[0]) for r in rows],
            "sensor": [None if r[1] is None else str(r[1]) for r in rows],
            "value": [None if r[2] is None else str(r[2]) for r in rows],
            "raw": [",".join("" if x is None else str(x) for x in r) for r in rows],
        },
        schema={"line": pl.Int64, "t": pl.String, "sensor": pl.String, "value": pl.String, "raw": pl.String},
    )
    return RawRows("motion.csv", frame, pl.DataFrame(schema=REJECTS))


def accounted(res, n_input: int) -> bool:
    lines = res.motion.height + res.rejects.height + res.suppressed.height
    return lines == n_input


# --------------------------------------------------------------------------- clean logs + chatter


@st.composite
def clean_log_with_chatter(draw):
    """A clean alternating log per sensor plus chatter pairs inside on-periods.

    Clean off-gaps and on-periods are longer than the window; each chatter pair is an off
    edge and an on edge at most ``window`` apart, strictly inside an on-period.
    """
    window = draw(st.sampled_from([0.05, 0.1, 0.3]))
    clean, chatter = [], []
    for s in draw(st.lists(st.sampled_from(SENSORS), min_size=1, max_size=3, unique=True)):
        t = draw(st.floats(0.0, 5.0))
        for _ in range(draw(st.integers(1, 5))):
            on_len = draw(st.floats(4 * window + 0.01, 5.0))
            clean.append((t, s, 1))
            k = draw(st.integers(0, 2))
            # k chatter pairs in k disjoint sub-intervals of the on-period
            for j in range(k):
                lo = t + on_len * (j + 0.25) / (k + 0.5)
                g = draw(st.floats(0.0, 1.0)) * window
                chatter += [(lo, s, 0), (lo + g, s, 1)]
            clean.append((t + on_len, s, 0))
            t += on_len + draw(st.floats(window * 1.5 + 0.01, 5.0))
    return window, clean, chatter


@given(clean_log_with_chatter())
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_chatter_removed_exactly_by_the_rule(case):
    window, clean, chatter = case
    rows = sorted(clean + chatter, key=lambda r: r[0])
    res = read_motion(raw_rows(rows), SENSORS, rules=DebounceRules(chatter_window=window))
    want = sorted(clean, key=lambda r: r[0])
    got = list(zip(res.motion["t"].to_list(), res.motion["sensor"].to_list(), res.motion["on"].cast(pl.Int8).to_list()))
    assert sorted(got) == sorted((float(a), b, c) for a, b, c in want)
    assert res.suppressed.height == len(chatter)
    assert set(res.suppressed["rule"].to_list()) <= {"chatter"}
    assert res.rejects.height == 0
    assert accounted(res, len(rows))
    # without the rule nothing is suppressed and every chatter edge is an accepted edge
    plain = read_motion(raw_rows(rows), SENSORS)
    assert plain.motion.height == len(rows) and plain.suppressed.height == 0


@given(
    st.lists(st.tuples(st.floats(0.01, 0.5), st.floats(0.01, 3.0)), min_size=1, max_size=12),
    st.sampled_from([0.1, 0.2]),
)
@settings(max_examples=60, deadline=None)
def test_min_on_removes_exactly_the_short_pulses(pulses, min_on):
    rows, t, keep = [], 0.0, []
    for on_len, gap in pulses:
        rows += [(t, "p1", 1), (t + on_len, "p1", 0)]
        if on_len >= min_on:
            keep += [t, t + on_len]
        t += on_len + gap
    res = read_motion(raw_rows(rows), SENSORS, rules=DebounceRules(min_on=min_on))
    assert res.motion["t"].to_list() == pytest.approx(keep)
    assert res.suppressed.height == len(rows) - len(keep)
    assert set(res.suppressed["rule"].to_list()) <= {"min_on"}
    assert accounted(res, len(rows))


# --------------------------------------------------------------------------- arbitrary junk: nothing lost

junk_value = st.sampled_from(["0", "1", "on", "off", "2", "", "x", None])
junk_time = st.one_of(
    st.floats(0, 20, allow_nan=False).map(lambda v: round(v, 1)), st.sampled_from(["nan", "abc", "", None, "inf"])
)
junk_sensor = st.sampled_from(["p1", "p2", "p3", "zz", "", None])


@given(st.lists(st.tuples(junk_time, junk_sensor, junk_value), max_size=40), st.floats(0, 0.5), st.floats(0, 0.5))
@settings(max_examples=120, deadline=None)
def test_nothing_lost_and_edges_alternate(rows, window, min_on):
    res = read_motion(raw_rows(rows), SENSORS, rules=DebounceRules(chatter_window=window, min_on=min_on))
    assert accounted(res, len(rows))
    assert res.motion.schema == MOTION and res.rejects.schema == REJECTS
    lines = res.rejects["line"].to_list() + res.suppressed["line"].to_list()
    assert len(set(lines)) == len(lines)
    t = res.motion["t"].to_numpy()
    assert np.all(np.diff(t) >= 0)
    for s in SENSORS:
        on = res.motion.filter(pl.col("sensor") == s)["on"].to_list()
        # every sensor starts off: accepted edges are on, off, on, ...
        assert on == [k % 2 == 0 for k in range(len(on))]
    assert all(r for r in res.rejects["reason"].to_list())


def test_rejects_name_line_field_and_reason():
    rows = [
        (0.0, "p1", 1),
        (1.0, "p1", 1),  # no state change
        (2.0, "p9", 1),  # unknown sensor
        (3.0, "p1", 7),  # bad value
        (-0.5, "p2", 1),  # backwards (more than the 1 s reorder tolerance)
        (4.0, "p1", 0),
        (4.0, "p1", 0),  # duplicate
    ]
    res = read_motion(raw_rows(rows), SENSORS)
    by_line = dict(zip(res.rejects["line"].to_list(), res.rejects["reason"].to_list()))
    assert "already on" in by_line[3] and "motion" not in by_line[3]
    assert "unknown sensor 'p9'" in by_line[4] and "field 'sensor'" in by_line[4]
    assert "field 'value'" in by_line[5]
    assert "backwards" in by_line[6]
    assert "duplicate of line 7" in by_line[8]
    assert res.motion["t"].to_list() == [0.0, 4.0]
    assert accounted(res, len(rows))


def test_csv_file_reader_keeps_raw_text(tmp_path: Path):
    p = tmp_path / "motion.csv"
    p.write_text("t,sensor,value\n0,p1,1\n0.02,p1,0\n0.05,p1,1\n1.5,p1,0\nbad,p1,1\n")
    res = read_motion_csv(p, SENSORS, rules=DebounceRules(chatter_window=0.1))
    assert res.motion["t"].to_list() == [0.0, 1.5]
    assert res.suppressed["line"].to_list() == [3, 4]
    assert res.rejects["raw"].to_list() == ["bad,p1,1"] and res.rejects["line"].to_list() == [6]


def test_per_sensor_rules_apply_only_to_their_sensor():
    rows = [(0, "p1", 1), (1, "p1", 0), (1.05, "p1", 1), (0, "p2", 1), (1, "p2", 0), (1.05, "p2", 1)]
    rows.sort(key=lambda r: r[0])
    rules = rules_by_type({"p1": "x10", "p2": "beam"}, {"x10": DebounceRules(chatter_window=0.1)})
    res = read_motion(raw_rows(rows), SENSORS, rules=rules)
    assert res.suppressed["sensor"].to_list() == ["p1", "p1"]
    assert res.motion.filter(pl.col("sensor") == "p2").height == 3


@pytest.mark.parametrize("bad", [{"chatter_window": -1.0}, {"min_on": math.nan}, {"min_on": "1"}])
def test_rules_validated_naming_the_field(bad):
    with pytest.raises(ConfigError, match=next(iter(bad))):
        DebounceRules(**bad)


# --------------------------------------------------------------------------- the pipeline stage

SITE = """name = "room"
units = "m"
[boundary]
polygon = [[0, 0], [10, 0], [10, 10], [0, 10]]
[[motion_sensors]]
id = "p1"
position = [0, 0]
type = "x10"
[[motion_sensors]]
id = "p2"
position = [10, 0]
type = "other"
[sensor_types.x10]
chatter_window = 0.1
"""


def test_motion_stage_reads_debounces_and_reports(tmp_path: Path):

    data = tmp_path / "data"
    data.mkdir()
    (data / "site.toml").write_text(SITE)
    (data / "motion.csv").write_text(
        "t,sensor,value\n0.5,p1,1\n0.7,p2,1\n1.0,p1,0\n1.05,p1,1\n2.5,p1,0\n3.0,p2,0\n3.2,p2,0\n4.0,p3,1\n"
    )
    res = run_pipeline(data, tmp_path / "run", trackers=("beams",), config={"motion": {"chatter_window": 0.1}})
    assert res.status["motion"].startswith("ok"), res.status
    assert metric(res.report, "motion/edges") == 4.0
    assert metric(res.report, "motion/suppressed") == 2.0
    rejects = pl.read_parquet(tmp_path / "run" / "tables" / "rejects.parquet")
    assert sorted(rejects["line"].to_list()) == [8, 9]
    # p1: on 0.5, off 2.5 (the 1.0 off / 1.05 on chatter pair suppressed); p2: on 0.7, off 3.0
    motion = pl.read_parquet(tmp_path / "run" / "tables" / "motion.parquet").sort("t")
    assert motion.schema == MOTION
    assert list(zip(motion["t"], motion["sensor"], motion["on"])) == [
        (0.5, "p1", True),
        (0.7, "p2", True),
        (2.5, "p1", False),
        (3.0, "p2", False),
    ]
    assert not (tmp_path / "run" / "tables" / "frames.parquet").exists()  # each tracker samples its own slots

    assert {"sensors/p1", "sensors/p2"} <= entity_paths(tmp_path / "run" / "rrd" / "motion.rrd")
    with pytest.raises(ConfigError, match=r"\[motion\].*chatter_window"):  # refused when the run starts
        run_pipeline(data, tmp_path / "run2", trackers=("beams",), config={"motion": {"chatter_window": -1}})


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.sampled_from(["m1", "m2", "m3"]), st.integers(0, 400)), max_size=60, unique=True),
    st.sampled_from([0.5, 1.0, 2.5]),
    st.sampled_from([None, (-3.0, 50.0), (10.0, 90.0)]),
)
def test_frames_by_arrays_equal_the_join_reference(edges, period, window):
    """The numpy FRAMES builder gives the polars-join reference's table (state at each slot
    start, rising edges in the slot), with and without an explicit slot window."""
    rows = sorted((t / 10.0, s) for s, t in edges)
    on, state = [], {}
    for _, s in rows:  # alternating per sensor, starting on
        state[s] = not state.get(s, False)
        on.append(state[s])
    motion = pl.DataFrame(
        {"t": [t for t, _ in rows], "sensor": [s for _, s in rows], "on": on},
        schema={"t": pl.Float64, "sensor": pl.String, "on": pl.Boolean},
    )
    kw = {} if window is None else {"t0": window[0], "t1": window[1]}
    got = motion_frames(motion, ["m1", "m2", "m3", "m4"], period=period, **kw)
    want = motion_frames_reference(motion, ["m1", "m2", "m3", "m4"], period=period, **kw)
    assert got.equals(want)
