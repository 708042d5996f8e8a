"""Trajectory exports -> truth (issue 12, item 5): delimiters, names, units, transforms, joins."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit.core.errors import ConfigError, InputError, OnebitError
from onebit.core.tables import TRUTH
from onebit.readers.trajectories import TrajectoryFormat, read_trajectories


def _write(tmp_path: Path, text: str, name: str = "walks.csv") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_people_counter_export_in_ms_and_mm(tmp_path):
    p = _write(
        tmp_path,
        "timestamp;person_id;pos_x;pos_y\n"
        "1700000000500;7;1000;2000\n"
        "1700000000000;7;900;2000\n"  # out of order: sorted, not rejected
        "1700000000000;9;5000;2000\n"
        "1700000001000;12;4900;1900\n"  # re-identified 9
        "oops;9;1;1\n"  # line 6: bad time
        "1700000001000;7;1200\n"  # line 7: too few fields
        "1700000001500;7;;2100\n",  # line 8: missing x
    )
    r = read_trajectories(p, TrajectoryFormat(scale=0.001, join=(("9", "12"),)))
    assert r.columns == {"time": "timestamp", "track": "person_id", "x": "pos_x", "y": "pos_y"} and r.time_unit == "ms"
    assert r.truth.schema == TRUTH
    assert r.truth.select("t", "target", pl.col("x").round(9), pl.col("y").round(9)).rows() == [
        (0.0, "7", 0.9, 2.0),
        (0.0, "9", 5.0, 2.0),
        (0.5, "7", 1.0, 2.0),
        (1.0, "9", 4.9, 1.9),
    ]
    assert r.origin.origin == 1700000000.0 and r.joined == 1
    rej = dict(zip(r.rejects["line"].to_list(), r.rejects["reason"].to_list()))
    assert set(rej) == {6, 7, 8}
    assert "field 't'" in rej[6] and "too few fields" in rej[7] and "field 'x'" in rej[8]
    assert r.rejects.filter(pl.col("line") == 6)["raw"][0] == "oops;9;1;1"
    assert r.truth.height + r.rejects.height == 7


def test_iso_times_tabs_named_columns_and_axis_flips(tmp_path):
    p = _write(
        tmp_path,
        "when\tobj\teast\tnorth\n2024-05-01T10:00:00Z\ta\t1\t2\n2024-05-01T10:00:00.5Z\ta\t2\t2\n2024-05-01 10:00:01\tb\t3\t4\n",
        "positions.tsv",
    )
    fmt = TrajectoryFormat(time="when", track="obj", x="east", y="north", flip_y=True, offset=(10.0, 20.0), scale=2.0)
    r = read_trajectories(p, fmt)
    assert r.time_unit == "iso" and r.origin.as_dict()["origin"] == "2024-05-01T10:00:00Z"
    assert r.truth.select("t", "target", "x", "y").rows() == [
        (0.0, "a", 12.0, 16.0),
        (0.5, "a", 14.0, 16.0),
        (1.0, "b", 16.0, 12.0),
    ]
    swapped = read_trajectories(p, TrajectoryFormat(time="when", track="obj", x="east", y="north", swap_xy=True))
    assert swapped.truth["x"].to_list() == [2.0, 2.0, 4.0]


def test_duplicates_after_a_join_and_a_lone_stamp_are_rejected(tmp_path):
    p = _write(tmp_path, "t,id,x,y\n0,a,0,0\n0,b,1,1\n1,a,0,1\n1e9,a,9,9\n")
    r = read_trajectories(p, TrajectoryFormat(join=(("a", "b"),)))
    rej = dict(zip(r.rejects["line"].to_list(), r.rejects["reason"].to_list()))
    assert "duplicate of line 2 (same t and target)" in rej[3] and "lone time stamp" in rej[5]
    assert r.truth.height == 2


def test_bad_options_and_missing_columns_name_the_problem(tmp_path):
    p = _write(tmp_path, "time,who,x,y\n0,a,0,0\n")
    with pytest.raises(InputError, match="no track column"):
        read_trajectories(p)
    assert read_trajectories(p, TrajectoryFormat(track="who")).truth.height == 1
    with pytest.raises(InputError, match="no column 'lat'"):
        read_trajectories(p, TrajectoryFormat(track="who", y="lat"))
    with pytest.raises(ConfigError, match="join"):
        TrajectoryFormat(join=(("a",),))
    with pytest.raises(ConfigError, match="scale"):
        TrajectoryFormat(scale=0.0)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    rows=st.lists(
        st.lists(
            st.sampled_from(["0", "1.5", "-3", "1e11", "1700000000", "x", "", "2024-01-01 00:00:00", "a", "nan"]),
            min_size=2,
            max_size=5,
        ),
        max_size=20,
    )
)
def test_any_rows_read_or_fail_cleanly(tmp_path, rows):
    p = _write(tmp_path, "t,id,x,y\n" + "".join(",".join(r) + "\n" for r in rows), "fuzz.csv")
    try:
        r = read_trajectories(p)
    except OnebitError:
        return
    nonblank = sum(1 for r_ in rows if any(v != "" for v in r_))  # a line of empty fields is blank
    assert r.truth.height + r.rejects.height == nonblank
