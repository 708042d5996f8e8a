"""``truth_count.csv`` (t, end, count): every line not taken is a reject with its reason."""

from __future__ import annotations

import polars as pl
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.tables import TRUTH_COUNT
from onebit.readers.tables_csv import read_truth_count_csv


def _read(tmp_path, body: str):
    p = tmp_path / "truth_count.csv"
    p.write_text("t,end,count\n" + body)
    return read_truth_count_csv(p)


def test_good_intervals_are_read(tmp_path):
    tc, rej = _read(tmp_path, "0,60,2\n60,120,1\n200,260,0\n")
    assert tc.schema == TRUTH_COUNT
    assert tc.rows() == [(0.0, 60.0, 2), (60.0, 120.0, 1), (200.0, 260.0, 0)]
    assert rej.height == 0


def test_bad_lines_are_rejected_with_reasons(tmp_path):
    tc, rej = _read(
        tmp_path,
        "0,60,2\n"  # line 2: good
        "100,100,1\n"  # line 3: end == t
        "130,120,1\n"  # line 4: end < t
        "140,150,-1\n"  # line 5: negative
        "160,170,1.5\n"  # line 6: not whole
        "180,190,x\n"  # line 7: not a number
        "200,260,1\n",  # line 8: good
    )
    assert tc.rows() == [(0.0, 60.0, 2), (200.0, 260.0, 1)]
    by_line = dict(zip(rej["line"].to_list(), rej["reason"].to_list()))
    assert set(by_line) == {3, 4, 5, 6, 7}
    assert "'end'" in by_line[3] and "not after t" in by_line[3]
    assert "'end'" in by_line[4] and "not after t" in by_line[4]
    assert "'count'" in by_line[5] and "whole number" in by_line[5]
    assert "'count'" in by_line[6] and "whole number" in by_line[6]
    assert "'count'" in by_line[7]
    assert set(rej["source"].to_list()) == {"truth_count.csv"}


def test_an_overlap_is_rejected(tmp_path):
    tc, rej = _read(tmp_path, "0,60,2\n30,90,1\n90,120,0\n")
    assert tc.rows() == [(0.0, 60.0, 2), (90.0, 120.0, 0)]
    assert rej.height == 1
    assert "overlap" in rej["reason"][0]
    assert rej["raw"][0].startswith("30.0,90.0,1")
    assert rej["source"][0] == "truth_count.csv"  # named as the reader's other rejects


@settings(max_examples=40, deadline=None)
@given(
    rows=st.lists(
        st.tuples(
            st.integers(-5, 50), st.integers(-5, 50), st.one_of(st.integers(-2, 4), st.sampled_from(["1.5", "a", ""]))
        ),
        max_size=12,
    )
)
def test_every_line_is_taken_or_rejected(tmp_path_factory, rows):
    p = tmp_path_factory.mktemp("tc") / "truth_count.csv"
    p.write_text("t,end,count\n" + "".join(f"{a},{b},{c}\n" for a, b, c in rows))
    tc, rej = read_truth_count_csv(p)
    assert tc.height + rej.height == len(rows)
    assert (tc["end"] > tc["t"]).all() and (tc["count"] >= 0).all()
    assert tc["t"].is_sorted()
    ok = tc.sort("t")
    assert (ok["t"].to_numpy()[1:] >= ok["end"].to_numpy()[:-1]).all()  # no overlap left
    assert rej["reason"].null_count() == 0 and isinstance(rej, pl.DataFrame)
