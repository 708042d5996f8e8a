"""The run's time origin (issue 12, item 2): the data's own start, an epoch, lone stamps, spans."""

from __future__ import annotations

import math
import tomllib

import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import InputError
from onebit.core.tables import REJECTS
from onebit.datasets.catalogue import get_scenario
from onebit.pipeline.runner import run_pipeline
from onebit.readers.motion import read_motion
from onebit.readers.rows import RawRows
from onebit.readers.timebase import column_origin, time_origin


def _frame(ts: list[str]) -> pl.DataFrame:
    return pl.DataFrame({"line": list(range(2, 2 + len(ts))), "t": ts})


def test_unix_seconds_count_from_the_data_start_and_a_lone_row_is_cut_off():
    o = time_origin({"motion.csv": _frame(["1700000000.25", "1700000030", "1e11"])})
    assert (o.source, o.origin, o.lo, o.hi, o.lone) == ("data", 1700000000.0, 0.25, 30.0, 1)
    assert o.as_dict()["origin"] == "2023-11-14T22:13:20Z"


def test_iso_times_without_epoch_count_from_the_first_second_not_midnight():
    o = time_origin({"a.csv": _frame(["2024-05-01 23:59:58.5", "2024-05-02T00:00:03Z"])})
    assert o.lo == pytest.approx(0.5) and o.hi == pytest.approx(5.0)
    # a reader on its own does the same with ISO stamps, and keeps numbers as they are
    assert column_origin(_frame(["2024-05-01 23:59:58.5"]), "t", None).iso == o.iso
    assert column_origin(_frame(["3.5", "7"]), "t", None).numeric == 0.0


def test_epoch_sets_the_origin():
    o = time_origin({"a.csv": _frame(["2024-05-01 00:00:10", "2024-05-01 00:00:20"])}, epoch="2024-05-01T00:00:00")
    assert (o.source, o.lo, o.hi) == ("epoch", 10.0, 20.0)


def test_an_absurd_span_is_an_error_naming_file_line_and_field():
    with pytest.raises(InputError) as err:
        time_origin({"motion.csv": _frame(["0", "1", "2", "3", "1700000000", "1700000001", "1700000002"])})
    msg = str(err.value)
    assert msg.startswith("motion.csv:2: field 't':") and "days" in msg and "motion.csv:8" in msg


def test_the_reader_rejects_the_lone_row_with_its_line():
    frame = pl.DataFrame(
        {
            "line": [2, 3, 4, 5],
            "t": ["1700000000.0", "1700000001.0", "1e11", "1700000002.0"],
            "sensor": ["m1"] * 4,
            "value": ["1", "0", "1", "1"],
            "raw": [None] * 4,
        },
        schema_overrides={"raw": pl.String},
    )
    origin = time_origin({"motion.csv": frame})
    res = read_motion(RawRows("motion.csv", frame, pl.DataFrame(schema=REJECTS)), ["m1"], epoch=origin)
    assert res.motion["t"].to_list() == [0.0, 1.0, 2.0]
    assert res.rejects["line"].to_list() == [4] and "lone time stamp" in res.rejects["reason"][0]


def test_out_of_order_rows_within_the_tolerance_are_sorted_and_counted():
    frame = pl.DataFrame(
        {
            "line": [2, 3, 4, 5],
            "t": ["10.0", "10.7", "10.1", "8.0"],
            "sensor": ["a", "b", "c", "a"],
            "value": ["ON", "on", "1", "OFF"],
            "raw": [None] * 4,
        },
        schema_overrides={"raw": pl.String},
    )
    res = read_motion(RawRows("motion.csv", frame, pl.DataFrame(schema=REJECTS)), ["a", "b", "c"])
    assert res.motion["t"].to_list() == [10.0, 10.1, 10.7] and res.reordered == 1
    assert res.rejects["line"].to_list() == [5] and "backwards" in res.rejects["reason"][0]


@pytest.mark.parametrize("clock", ["unix", "iso"])
def test_a_run_on_wall_clock_logs_builds_slots_from_the_data_not_from_1970(tmp_path, clock):
    """pir14 with its stamps moved to Unix seconds / ISO times: the same report as on 0-based
    seconds (the intruder filter's slots span the data: no 6 GB allocation, no abort)."""
    data = get_scenario("pir14").write(
        tmp_path / "d", seed=2, duration=30.0, agents=None, drop=0.0, camera=False, params={}
    )
    ref = run_pipeline(data, tmp_path / "ref", trackers=("intruder",))
    for name in ("motion.csv", "truth.csv"):
        df = pl.read_csv(data / name)
        if clock == "unix":
            df = df.with_columns((pl.col("t") + 1.7e9).alias("t"))
        else:
            stamp = pl.datetime(2024, 5, 1, 23, 59, 30, time_zone="UTC") + pl.duration(
                microseconds=(pl.col("t") * 1e6).round().cast(pl.Int64)
            )
            df = df.with_columns(stamp.dt.strftime("%Y-%m-%dT%H:%M:%S%.6fZ").alias("t"))
        df.write_csv(data / name)
    res = run_pipeline(data, tmp_path / "wall", trackers=("intruder",))
    assert res.status["intruder"].startswith("ok")
    time_doc = tomllib.loads((tmp_path / "wall" / "run.toml").read_text())["time"]  # the origin is in the run record
    assert time_doc["source"] == "data" and time_doc["t_min"] == 0.0
    assert time_doc["origin"] == ("2023-11-14T22:13:20Z" if clock == "unix" else "2024-05-01T23:59:30Z")
    assert res.report.filter(pl.col("stage") == "intruder").equals(ref.report.filter(pl.col("stage") == "intruder"))


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(0, 1e6, allow_nan=False), min_size=1, max_size=30),
    st.lists(st.sampled_from(["12.5", "2024-05-01T10:00:00Z", "bad", "1e11", " 7 "]), max_size=4),
    st.sampled_from([None, "2024-05-01T00:00:00Z"]),
)
def test_a_typed_reads_numbers_give_the_origin_their_strings_give(numbers, rest, epoch):
    """The runner reads a log once, typed: the good rows' numeric ``t`` and the other rows'
    strings give the same origin as every stamp as a string (one read instead of two)."""
    text = [repr(v) for v in numbers]
    good = pl.DataFrame({"line": range(2, 2 + len(numbers)), "t": numbers}, schema={"line": pl.Int64, "t": pl.Float64})
    others = pl.DataFrame({"line": range(100, 100 + len(rest)), "t": rest}, schema={"line": pl.Int64, "t": pl.String})
    strings = pl.concat([good.with_columns(pl.Series("t", text)), others])
    try:
        want = time_origin({"log.csv": strings}, epoch=epoch)
    except InputError as exc:
        with pytest.raises(InputError) as got:
            time_origin({"log.csv": [good, others]}, epoch=epoch)
        assert (got.value.file, got.value.line) == (exc.file, exc.line)
        return
    assert time_origin({"log.csv": [good, others]}, epoch=epoch) == want


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.one_of(st.floats(-1e10, 1e10), st.sampled_from([math.inf, -math.inf])), min_size=0, max_size=30),
    st.lists(st.one_of(st.floats(0, 1e5), st.just(math.nan)), min_size=0, max_size=30),
    st.sampled_from([None, "2024-05-01T00:00:00Z"]),
)
def test_numeric_stamps_alone_give_the_origin_their_strings_give(a, b, epoch):
    """Typed reads with no string row left: the origin from the numbers alone (no table of
    stamps) equals the one of the same stamps as strings, error (file, line) included."""
    frames = [
        pl.DataFrame({"line": range(2, 2 + len(v)), "t": v}, schema={"line": pl.Int64, "t": pl.Float64}) for v in (a, b)
    ]
    strings = {
        name: f.with_columns(pl.col("t").map_elements(repr, return_dtype=pl.String))
        for name, f in zip(("a.csv", "b.csv"), frames)
    }
    try:
        want = time_origin(strings, epoch=epoch)
    except InputError as exc:
        with pytest.raises(InputError) as got:
            time_origin({"a.csv": [frames[0]], "b.csv": [frames[1]]}, epoch=epoch)
        assert (got.value.file, got.value.line, got.value.field) == (exc.file, exc.line, exc.field)
        return
    assert time_origin({"a.csv": [frames[0]], "b.csv": [frames[1]]}, epoch=epoch) == want


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.floats(0, 1e6, allow_nan=False), min_size=1, max_size=300),
    st.sampled_from([0.5, 10.0, 1000.0, 86_400.0]),
    st.integers(1, 40),
)
def test_gap_cuts_by_pieces_equal_the_cuts_of_every_difference(values, gap, piece):
    """gap_cuts (pieces whose span is at most the gap skipped) finds the indices of the gaps
    over ``max_gap_s`` that the differences of every pair of neighbours find, for any piece size."""
    import numpy as np

    from onebit.readers.timebase import gap_cuts

    a = np.sort(np.asarray(values, dtype=np.float64))
    got = gap_cuts(a, gap, piece)
    assert got.tolist() == (np.flatnonzero(np.diff(a) > gap) + 1).tolist()


@settings(max_examples=150, deadline=None)
@given(
    st.lists(
        st.one_of(st.floats(0, 3e5, allow_nan=False), st.sampled_from([float("nan"), float("inf"), -float("inf")])),
        min_size=1,
        max_size=60,
    )
)
def test_a_column_flagged_sorted_gives_the_origin_of_its_values(values):
    """The time origin of a column polars knows to be sorted (read from the flag: no pass over the
    values for order, finiteness from its ends) equals the origin of the same values without
    the flag; NaN and infinities (polars sorts NaN last) are left out either way."""
    import polars as pl

    from onebit.readers.rows import in_time_order

    t = pl.Series("t", values, dtype=pl.Float64).sort()
    flagged = pl.DataFrame({"line": range(t.len()), "t": t})
    plain = pl.DataFrame({"line": range(t.len()), "t": pl.Series("t", t.to_list(), dtype=pl.Float64)})
    assert flagged["t"].flags["SORTED_ASC"] and (t.len() < 2 or not plain["t"].flags["SORTED_ASC"])
    assert time_origin({"motion.csv": flagged}) == time_origin({"motion.csv": plain})
    assert in_time_order(flagged["t"]) == in_time_order(plain["t"])
