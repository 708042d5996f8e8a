"""The bidirectional-beam state machine (Figs. 5-7) and the readers' handling of bad rows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import InputError
from onebit.readers.beams import decode_beam_log
from onebit.readers.tables_csv import read_crossings_csv, read_truth_csv

SPACING = 0.1
HALF_WIDTH = 0.2  # body half-width, wider than the spacing (paper: spacing < agent width)


def _events_from_positions(xs: list[float]) -> tuple[list[tuple[float, str, int]], list[int], int]:
    """Beam edges for a body at positions ``xs`` along the beam normal (pair a at -s/2, b at +s/2).

    Returns the events, the expected crossing directions (one per pass that ends on the
    other side) and the expected number of start-and-return passes.
    """
    a_pos, b_pos = -SPACING / 2, SPACING / 2
    # the body moves continuously: walk between the given positions in steps << spacing
    dense = [xs[0]]
    for x0, x1 in zip(xs[:-1], xs[1:]):
        n = max(1, int(np.ceil(abs(x1 - x0) / (SPACING / 8))))
        dense += list(np.linspace(x0, x1, n + 1)[1:])
    xs = dense
    events, expected, aborted = [], [], 0
    state = {"a": False, "b": False}
    side = -1 if xs[0] < 0 else 1
    in_pass = False
    for k, x in enumerate(xs):
        new = {"a": abs(x - a_pos) < HALF_WIDTH, "b": abs(x - b_pos) < HALF_WIDTH}
        # one pair changes at a time: order the edges by which pair the body reaches first
        order = ["a", "b"] if x > (xs[k - 1] if k else x) else ["b", "a"]
        for p in order:
            if new[p] != state[p]:
                state[p] = new[p]
                events.append((float(k) + (0.0 if p == order[0] else 0.5), p, int(new[p])))
                if state["a"] or state["b"]:
                    in_pass = True
        if in_pass and not state["a"] and not state["b"]:
            in_pass = False
            now = -1 if x < 0 else 1
            if now != side:
                expected.append(1 if now > side else -1)
            else:
                aborted += 1
            side = now
    return events, expected, aborted


outside = st.one_of(st.floats(-1.0, -0.31), st.floats(0.31, 1.0))
inside = st.floats(-0.3, 0.3)


@settings(max_examples=300, deadline=None)
@given(start=outside, middle=st.lists(st.one_of(inside, outside), min_size=0, max_size=25), end=outside)
def test_every_interleaving_decodes_right(tmp_path_factory, start, middle, end):
    xs = [start, *middle, end]
    events, expected, aborted = _events_from_positions(xs)
    path = Path(tmp_path_factory.mktemp("beam")) / "beams.csv"
    pl.DataFrame(
        {
            "t": [e[0] for e in events],
            "beam": ["a"] * len(events),
            "pair": [e[1] for e in events],
            "blocked": [e[2] for e in events],
        },
        schema={"t": pl.Float64, "beam": pl.String, "pair": pl.String, "blocked": pl.Int64},
    ).write_csv(path)
    dec = decode_beam_log(path, ("a",))
    assert dec.crossings["direction"].to_list() == expected
    assert dec.aborted.height == aborted
    assert dec.rejects.height == 0
    assert dec.unfinished.height == 0


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_clean_forward_backward_and_start_and_return(tmp_path):
    p = _write(
        tmp_path,
        "beams.csv",
        "t,beam,pair,blocked\n"
        "1.0,a,a,1\n1.1,a,b,1\n1.2,a,a,0\n1.3,a,b,0\n"  # forward
        "2.0,a,b,1\n2.1,a,a,1\n2.2,a,b,0\n2.3,a,a,0\n"  # backward
        "3.0,a,a,1\n3.1,a,a,0\n",  # start and return
    )
    dec = decode_beam_log(p, ("a",))
    assert dec.crossings.select("t", "direction").rows() == [(1.3, 1), (2.3, -1)]
    assert dec.aborted.height == 1


def test_bad_rows_go_to_rejects_with_file_line_reason(tmp_path):
    good = "1.0,a,a,1\n1.1,a,b,1\n1.2,a,a,0\n1.3,a,b,0\n"
    p = _write(
        tmp_path,
        "beams.csv",
        "t,beam,pair,blocked\n" + good + "oops,a,a,1\n"  # line 6: malformed time
        "1.4,zz,a,1\n"  # line 7: unknown beam
        "0.5,a,a,1\n"  # line 8: timestamp goes backwards
        "1.3,a,b,0\n"  # line 9: duplicated event
        "1.5,a,a\n"  # line 10: too few fields
        "1.6,a,c,1\n",  # line 11: pair not a|b
    )
    dec = decode_beam_log(p, ("a",))
    rej = {r["line"]: r for r in dec.rejects.iter_rows(named=True)}
    assert set(rej) == {6, 7, 8, 9, 10, 11}
    assert all(r["source"] == "beams.csv" for r in rej.values())
    assert "not a number" in rej[6]["reason"] and rej[6]["raw"] == "oops,a,a,1"
    assert "unknown beam 'zz'" in rej[7]["reason"]
    assert "backwards" in rej[8]["reason"]
    assert "duplicate of line 5" in rej[9]["reason"]
    assert "too few fields" in rej[10]["reason"]
    assert "'c' is not one of" in rej[11]["reason"]
    # no accepted row is lost: the 4 good edges still decode to the crossing
    assert dec.events.height == 4
    assert dec.crossings.height == 1


def test_missing_column_is_a_clear_error(tmp_path):

    p = _write(tmp_path, "beams.csv", "t,beam,blocked\n1,a,1\n")
    with pytest.raises(InputError, match=r"beams.csv:1: field 'pair'"):
        decode_beam_log(p, ("a",))


def test_crossings_and_truth_readers(tmp_path):
    c = _write(tmp_path, "crossings.csv", "t,beam,direction\n1,a,1\n2,b,-1\n3,a,2\n1.5,a,1\n")
    cr, rej = read_crossings_csv(c, ("a", "b"))
    assert cr.rows() == [(1.0, "a", 1), (2.0, "b", -1)]
    assert sorted(rej["line"].to_list()) == [4, 5]
    t = _write(tmp_path, "truth.csv", "t,target,x,y\n0,p,1,2\n0,q,1,x\n0,p,1,2\n")
    tr, rej = read_truth_csv(t)
    assert tr.height == 1 and sorted(rej["line"].to_list()) == [3, 4]


def test_iso_timestamps_become_seconds(tmp_path):
    c = _write(tmp_path, "crossings.csv", "t,beam,direction\n2026-01-01T10:00:00Z,a,1\n2026-01-01T10:00:01.5Z,a,-1\n")
    cr, rej = read_crossings_csv(c, ("a",), epoch="2026-01-01T10:00:00Z")
    assert rej.height == 0
    assert cr["t"].to_list() == [0.0, 1.5]


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.one_of(st.floats(0, 100, allow_nan=False).map(lambda v: f"{v:.3f}"), st.text(max_size=4)),
            st.sampled_from(["a", "b", "x", ""]),
            st.sampled_from(["1", "-1", "0", "f", "?"]),
        ),
        max_size=30,
    )
)
def test_crossings_reader_loses_no_row(tmp_path_factory, rows):
    """Every data line is either accepted or rejected, never both and never neither."""
    lines = [",".join(r).replace("\n", " ").replace("\r", " ").replace('"', "") for r in rows]
    lines = [ln for ln in lines if ln.strip(", ") != "" and "," in ln]
    p = Path(tmp_path_factory.mktemp("cr")) / "crossings.csv"
    p.write_text("t,beam,direction\n" + "".join(ln + "\n" for ln in lines))
    try:
        cr, rej = read_crossings_csv(p, ("a", "b"))
    except Exception as exc:  # the reader must not raise on bad rows
        raise AssertionError(f"reader raised on user data: {exc!r}") from exc
    assert cr.height + rej.height == len(lines)
    assert cr["t"].is_sorted()
