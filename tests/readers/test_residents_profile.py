"""``residents_profile.csv``: the known-residents profile's reader (rejects name line and field)."""

from __future__ import annotations

import polars as pl
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.tables import RESIDENTS_PROFILE
from onebit.readers.tables_csv import read_residents_profile_csv


def test_rows_and_rejects(tmp_path):
    p = tmp_path / "residents_profile.csv"
    p.write_text(
        "resident,from,to,count\n"
        "1,,M01,3\n"  # a habit row: from empty
        "1,M01,M02,2.5\n"
        "2,,M02,-1\n"  # negative
        "2,,,4\n"  # no sensor
        "2,M02,M03,many\n"  # not a number
        "1,,M01,7\n"  # duplicate of line 2
    )
    prof, rej = read_residents_profile_csv(p)
    assert prof.schema == RESIDENTS_PROFILE
    assert prof.rows() == [("1", None, "M01", 3.0, None), ("1", "M01", "M02", 2.5, None)]
    why = dict(zip(rej["line"].to_list(), rej["reason"].to_list()))
    assert set(why) == {4, 5, 6, 7}
    assert "count" in why[4] and "negative" in why[4]
    assert "'to'" in why[5]
    assert "'count'" in why[6]
    assert "duplicate of line 2" in why[7]
    assert (rej["source"] == "residents_profile.csv").all()


@settings(max_examples=30, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from(["1", "2", "3"]),
            st.sampled_from(["", "M01", "M02"]),
            st.sampled_from(["M01", "M02"]),
            st.floats(0, 1e6),
        ),
        max_size=20,
    )
)
def test_every_line_is_a_row_or_a_reject(tmp_path_factory, rows):
    p = tmp_path_factory.mktemp("prof") / "residents_profile.csv"
    p.write_text("resident,from,to,count\n" + "".join(f"{r},{f},{t},{c!r}\n" for r, f, t, c in rows))
    prof, rej = read_residents_profile_csv(p)
    assert prof.height + rej.height == len(rows)
    assert prof.select(pl.struct("resident", "from", "to").is_duplicated().any()).item() is False


def test_the_clock_column(tmp_path):
    p = tmp_path / "residents_profile.csv"
    p.write_text(
        "resident,from,to,count,bin\n"
        "1,,M01,3,\n"
        "1,,M01,2,session 0/10\n"
        "1,,M01,1,session 10/10\n"  # k >= n
        "1,M01,M02,1,session 1/10\n"  # a bin on a transition row
        "2,,M02,1,week 1/7\n"  # not a clock
    )
    prof, rej = read_residents_profile_csv(p)
    assert prof["bin"].to_list() == [None, "session 0/10"]
    why = dict(zip(rej["line"].to_list(), rej["reason"].to_list()))
    assert set(why) == {4, 5, 6} and all("'bin'" in w for w in why.values())
