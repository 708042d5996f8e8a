"""The typed read with row-by-row naming of the lines it cannot take (``read_typed_csv`` +
``check_split``) against the row-by-row path on the whole file: identical tables and rejects
on messy files (bad lines of every kind, ON/OFF spellings, ISO and Unix stamps, rows out of
order, duplicates), and the pieces it is built of against their references."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit._testing import reader_oracles
from onebit.readers import kernels
from onebit.readers.beams import (
    BEAM_COLUMNS,
    _beam_dtypes,
    decode_beam_log,
    decode_raw_beams,
)
from onebit.readers.motion import (
    TOGGLE_COLUMNS,
    TOGGLE_VALUES,
    DebounceRules,
    read_motion,
    read_motion_csv,
    repeats,
)
from onebit.readers.rows import (
    line_texts,
    physical_lines,
    read_csv_rows,
    read_typed_csv,
)
from onebit.readers.timebase import TimeOrigin, column_origin, parts_origin

BEAMS = ("a", "b", "c")
SENSORS = ("p1", "p2", "p3")
SETTINGS = settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow]
)


def _same_beams(path: Path, epoch=None):
    fast = decode_beam_log(path, BEAMS, epoch=epoch)
    slow = decode_raw_beams(read_csv_rows(path, BEAM_COLUMNS), BEAMS, epoch=epoch, path=path)
    for name in ("events", "crossings", "aborted", "unfinished", "rejects"):
        a, b = getattr(fast, name), getattr(slow, name)
        assert a.schema == b.schema and a.equals(b), (name, a, b)
    return fast


def _same_toggles(path: Path, epoch=None):
    rules = DebounceRules(chatter_window=0.4, min_on=0.2)
    fast = read_motion_csv(path, SENSORS, epoch=epoch, rules=rules)
    slow = read_motion(read_csv_rows(path, TOGGLE_COLUMNS), SENSORS, epoch=epoch, path=path, rules=rules)
    for name in ("motion", "rejects", "suppressed"):
        a, b = getattr(fast, name), getattr(slow, name)
        assert a.schema == b.schema and a.equals(b), (name, a, b)
    assert fast.reordered == slow.reordered
    return fast


# --------------------------------------------------------------------------- messy files

STAMPS = st.one_of(
    st.sampled_from(
        ["0", "0.5", "1", "1.5", "2", "2.5", "3", "10", "10.25", "1e11", "-1", "nan", "inf", "abc", "", " 2 ", "1.0 "]
    ),
    st.floats(0, 20, allow_nan=False).map(lambda v: f"{round(v, 1)}"),
    st.floats(0, 20, allow_nan=False).map(lambda v: f"{1.7e9 + round(v, 1)}"),
    st.sampled_from(["2024-05-01T10:00:00Z", "2024-05-01 10:00:01.5", "2024-05-01T10:00:03+00:00", "2024-05-01 10:00"]),
)
BAD_LINES = st.sampled_from(
    [
        "",
        "   ",
        "\t",
        "1,a",
        "1,a,b,1,x",
        "1,a,b,1,",
        ",,,",
        '"1",a,b,1',
        '1,"a,b",b,1',
        '1,a"b,a,1',
        '1,"a',
        "1,a,b,1\r",
        "1\r,a,b,1",
        "1,\xff,a,1",
        "1,a,a,1\udcff",
        "\x00",
        "t,beam,pair,blocked",
        "é,a,a,1",
        "1,a,a,1,é",
    ]
)


#: the strategies of the files' lines, made once (a strategy made inside a draw is made and
#: checked again for every line)
ONE_IN_TEN = st.integers(0, 9)
BEAM_NAMES = st.sampled_from(["a", "b", "c", "a", "b", "zz", " a", "A"])
PAIR_NAMES = st.sampled_from(["a", "b", "a", "b", "A", "B", "c"])
BLOCKED = st.sampled_from(["0", "1", "0", "1", "on", "OFF", "true", "2", "01"])
BEAM_ENDS = st.sampled_from(["\n", "", "\r\n"])
TOGGLE_BAD_LINES = BAD_LINES.map(lambda line: line.replace("1,a,b,1", "1,p1,1"))
TOGGLE_SENSORS = st.sampled_from(["p1", "p2", "p3", "p1", "zz", " p2"])
TOGGLE_SPELLINGS = st.sampled_from([*TOGGLE_VALUES, "ON", "Off", "2", "yes", ""])
ENDS = st.sampled_from(["\n", ""])


@st.composite
def beam_file(draw) -> bytes:
    n = draw(st.integers(0, 40))
    lines = []
    for _ in range(n):
        if draw(ONE_IN_TEN) == 0:
            lines.append(draw(BAD_LINES))
        else:
            t = draw(STAMPS)
            beam = draw(BEAM_NAMES)
            pair = draw(PAIR_NAMES)
            blocked = draw(BLOCKED)
            lines.append(f"{t},{beam},{pair},{blocked}")
    if lines and draw(st.booleans()):  # duplicates
        lines.insert(draw(st.integers(0, len(lines))), draw(st.sampled_from(lines)))
    end = draw(BEAM_ENDS)
    sep = "\r\n" if end == "\r\n" else "\n"
    return (sep.join(["t,beam,pair,blocked", *lines]) + end).encode("utf-8", errors="surrogateescape")


@st.composite
def toggle_file(draw) -> bytes:
    n = draw(st.integers(0, 40))
    lines = []
    for _ in range(n):
        if draw(ONE_IN_TEN) == 0:
            lines.append(draw(TOGGLE_BAD_LINES))
        else:
            t = draw(STAMPS)
            sensor = draw(TOGGLE_SENSORS)
            lines.append(f"{t},{sensor},{draw(TOGGLE_SPELLINGS)}")
    if lines and draw(st.booleans()):
        lines.insert(draw(st.integers(0, len(lines))), draw(st.sampled_from(lines)))
    return ("\n".join(["t,sensor,value", *lines]) + draw(ENDS)).encode("utf-8", errors="surrogateescape")


EPOCHS = st.sampled_from(
    [
        None,
        "2024-05-01T09:59:00Z",
        TimeOrigin(origin=0.0, numeric=0.0, iso=1714557600.0, lo=0.0, hi=30.0, source="data"),
    ]
)


@SETTINGS
@given(blob=beam_file(), epoch=EPOCHS)
def test_messy_beam_logs_give_the_row_by_row_result(tmp_path_factory, blob, epoch):
    path = Path(tmp_path_factory.mktemp("beams")) / "beams.csv"
    path.write_bytes(blob)
    if b"\n" in blob.rstrip(b"\r\n"):  # a data line: the typed read takes the file
        assert read_typed_csv(path, _beam_dtypes(BEAMS)) is not None
    _same_beams(path, epoch)


@SETTINGS
@given(blob=toggle_file(), epoch=EPOCHS)
def test_messy_toggle_logs_give_the_row_by_row_result(tmp_path_factory, blob, epoch):
    path = Path(tmp_path_factory.mktemp("motion")) / "motion.csv"
    path.write_bytes(blob)
    _same_toggles(path, epoch)


def _beam_rows(rng, n):
    """``n`` good lines of a beam log in time order (drawn as whole columns: a large file in
    milliseconds, not one draw per field)."""
    t = np.round(np.cumsum(rng.exponential(0.05, n)), 3).tolist()
    beam, pair = rng.choice(BEAMS, n).tolist(), rng.choice(["a", "b"], n).tolist()
    return [f"{a},{b},{c},{d}" for a, b, c, d in zip(t, beam, pair, rng.integers(0, 2, n).tolist())]


@pytest.mark.parametrize(
    "bad", ["1,a,b,1,x", "1,zz,a,1", '1,"a",a,1', "1,a,a,1\udcff", "nan,a,a,1", "1,a", "   ", "1e11,a,a,1"]
)
def test_a_few_bad_lines_in_a_large_file(tmp_path, bad):
    """Past the kernels' MIN_ROWS, with the long-line count on every line: only the bad lines
    are typed row by row, the result is the row-by-row path's."""
    rng = np.random.default_rng(1)
    rows = _beam_rows(rng, 25_000)
    for k in (3, 12_000, 24_990):
        rows.insert(k, bad)
    path = tmp_path / "beams.csv"
    path.write_bytes(("\n".join(["t,beam,pair,blocked", *rows]) + "\n").encode("utf-8", errors="surrogateescape"))
    split = read_typed_csv(path, _beam_dtypes(BEAMS))
    assert split is not None and split.good.height >= 25_000 - 3
    out = _same_beams(path)
    assert out.rejects.height >= (0 if bad == "   " else 3)


def test_extra_columns_and_a_short_line_in_a_large_file(tmp_path):
    rng = np.random.default_rng(2)
    rows = [f"{r},note" for r in _beam_rows(rng, 25_000)]
    rows[100] = rows[100].rsplit(",", 1)[0]  # too few fields: only the unwanted last one is missing
    rows[200] = rows[200] + ",more"
    path = tmp_path / "beams.csv"
    path.write_text("\n".join(["t,beam,pair,blocked,note", *rows]) + "\n")
    out = _same_beams(path)
    shape = out.rejects.filter(pl.col("reason").str.contains("fields"))
    assert shape["line"].to_list() == [102, 202] and shape["reason"].to_list() == [
        "too few fields (4 of 5)",
        "too many fields (6 of 5)",
    ]


# --------------------------------------------------------------------------- the pieces


@settings(max_examples=150, deadline=None)
@given(blob=st.binary(max_size=300), extra=st.lists(st.integers(-2, 40), max_size=12))
def test_line_texts_are_physical_lines(blob, extra):
    every = physical_lines(blob)
    want = sorted(set(every["line"].to_list()[::2] + extra))
    assert line_texts(blob, want).equals(every.filter(pl.col("line").is_in(want)))


@settings(max_examples=150, deadline=None)
@given(blob=st.binary(max_size=300).map(lambda b: b.replace(b"\x01", b",")))
def test_separator_kernel_equals_reference(blob):
    buf = np.frombuffer(blob, dtype=np.uint8)
    assert np.array_equal(
        kernels.separators_per_line(buf, ord(",")), reader_oracles.separators_per_line_reference(buf, ord(","))
    )


@settings(max_examples=200, deadline=None)
@given(
    blob=st.binary(max_size=300).map(lambda b: b.replace(b"\x01", b",").replace(b"\x02", b"\n")),
    step=st.integers(1, 64),
)
def test_separator_count_in_numpy_equals_reference(blob, step):
    """The numpy count (used while numba is not loaded), in steps of any size (lines cut across
    steps, steps without a newline), gives the reference's count of every line."""
    buf = np.frombuffer(blob, dtype=np.uint8)
    assert np.array_equal(
        kernels.separators_per_line_vectorised(buf, ord(","), step),
        reader_oracles.separators_per_line_reference(buf, ord(",")),
    )


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["p1", "p2", "p3"]), st.booleans()), max_size=60))
def test_repeat_kernel_equals_reference(edges):
    ok = pl.DataFrame(edges, schema={"sensor": pl.String, "on": pl.Boolean}, orient="row")
    assert repeats(ok, compiled=True).equals(repeats(ok, compiled=False))
    enum = ok.with_columns(pl.col("sensor").cast(pl.Enum(list(SENSORS))))
    assert repeats(enum, compiled=True).equals(repeats(ok, compiled=False))


@settings(max_examples=150, deadline=None)
@given(
    stamps=st.lists(
        st.one_of(st.floats(-5, 30, allow_nan=False).map(lambda v: repr(round(v, 2))), STAMPS), max_size=30
    ),
    cut=st.integers(0, 30),
    epoch=st.sampled_from([None, "2024-05-01T09:59:00Z"]),
)
def test_parts_origin_equals_column_origin(stamps, cut, epoch):
    """Numbers parsed by the typed read plus the rest as strings give the origin of the whole column."""
    col = pl.Series("t", stamps, dtype=pl.String)
    num = col.str.strip_chars().cast(pl.Float64, strict=False)
    typed = num.is_finite().fill_null(False) & (
        pl.int_range(0, col.len(), eager=True) < cut
    )  # any subset of the finite numbers
    numbers = num.filter(typed)
    strings = col.filter(~typed)
    assert parts_origin(numbers, strings, epoch) == column_origin(pl.DataFrame({"t": col}), "t", epoch)


# --------------------------------------------------------------------------- canonical tables


@st.composite
def table_file(draw, header: str, fields) -> bytes:
    lines = []
    for _ in range(draw(st.integers(0, 30))):
        if draw(ONE_IN_TEN) == 0:
            lines.append(draw(BAD_LINES))
        else:
            lines.append(",".join(draw(f) for f in fields))
    if lines and draw(st.booleans()):
        lines.insert(draw(st.integers(0, len(lines))), draw(st.sampled_from(lines)))
    return ("\n".join([header, *lines]) + draw(ENDS)).encode("utf-8", errors="surrogateescape")


NAMES = st.sampled_from(["w1", "w2", "w1", " w2", "w3 ", ""])
NUMBERS = st.sampled_from(["0", "1.5", "-2", "nan", "x", "", " 3", "1e3"])
DIRECTIONS = st.sampled_from(["1", "-1", "+1", "f", "b", "forward", "backward", "F", "0", ""])


@SETTINGS
@given(blob=table_file("t,target,x,y", [STAMPS, NAMES, NUMBERS, NUMBERS]), epoch=EPOCHS)
def test_messy_truth_gives_the_row_by_row_result(tmp_path_factory, blob, epoch):
    from onebit.readers.tables_csv import read_truth_csv, truth_from_rows

    path = Path(tmp_path_factory.mktemp("truth")) / "truth.csv"
    path.write_bytes(blob)
    fast = read_truth_csv(path, epoch=epoch)
    slow = truth_from_rows(read_csv_rows(path, ("t", "target", "x", "y")), epoch=epoch, path=path)
    for a, b in zip(fast, slow):
        assert a.schema == b.schema and a.equals(b), (a, b)


@pytest.mark.parametrize("end", [b"", b"\n"])
def test_a_last_line_with_a_field_too_many_is_rejected_with_or_without_its_newline(tmp_path, end):
    """The strict read takes ``1,a,b,1,`` as four fields when it is the last line and has no
    newline; the fast read must reject it as the row-by-row one does."""
    from onebit.readers.tables_csv import read_true_crossings_csv, true_crossings_from_rows

    path = tmp_path / "crossings.csv"
    path.write_bytes(b"t,beam,direction,target\n0,a,1,w1\n1,a,b,1," + end)
    fast = read_true_crossings_csv(path, BEAMS, epoch=None)
    slow = true_crossings_from_rows(
        read_csv_rows(path, ("t", "beam", "direction", "target")), BEAMS, epoch=None, path=path
    )
    assert fast[0].height == 1 and fast[1]["reason"].to_list() == ["too many fields (5 of 4)"]
    for a, b in zip(fast, slow):
        assert a.schema == b.schema and a.equals(b), (a, b)


@SETTINGS
@given(
    blob=table_file("t,beam,direction,target", [STAMPS, st.sampled_from(["a", "b", "zz", " a"]), DIRECTIONS, NAMES]),
    epoch=EPOCHS,
)
def test_messy_crossings_give_the_row_by_row_result(tmp_path_factory, blob, epoch):
    from onebit.readers.tables_csv import (
        crossings_from_rows,
        read_crossings_csv,
        read_true_crossings_csv,
        true_crossings_from_rows,
    )

    path = Path(tmp_path_factory.mktemp("crossings")) / "crossings.csv"
    path.write_bytes(blob)
    fast = read_crossings_csv(path, BEAMS, epoch=epoch)
    slow = crossings_from_rows(read_csv_rows(path, ("t", "beam", "direction")), BEAMS, epoch=epoch, path=path)
    for a, b in zip(fast, slow):
        assert a.schema == b.schema and a.equals(b), (a, b)
    fast = read_true_crossings_csv(path, BEAMS, epoch=epoch)
    slow = true_crossings_from_rows(
        read_csv_rows(path, ("t", "beam", "direction", "target")), BEAMS, epoch=epoch, path=path
    )
    for a, b in zip(fast, slow):
        assert a.schema == b.schema and a.equals(b), (a, b)


@SETTINGS
@given(blob=st.one_of(beam_file(), toggle_file()))
def test_one_column_read_gives_the_row_by_row_stamps_and_origin(tmp_path_factory, blob):
    """The run's time origin reads only ``t`` (``read_csv_column``): the same (line, t) rows as
    the row-by-row path, hence the same origin."""
    from onebit.readers.rows import read_csv_column
    from onebit.readers.timebase import time_origin

    path = Path(tmp_path_factory.mktemp("stamps")) / "log.csv"
    path.write_bytes(blob)
    fast = read_csv_column(path, "t")
    slow = read_csv_rows(path, ("t",)).frame.select("line", "t")
    assert fast.equals(slow), (fast, slow)

    def origin(frame):
        try:
            return time_origin({"log.csv": frame})
        except Exception as exc:  # an absurd span: the same error, naming the same lines
            return repr(exc)

    assert origin(fast) == origin(slow)


@pytest.mark.parametrize(
    "header,long",
    [
        ("t,sensor,value,a,b", "2,p1,1,x,y,z"),  # columns after the wanted ones, not read
        ("t,a,sensor,value", "2,x,p1,1,z"),  # a column between them
    ],
)
def test_a_long_line_is_rejected_when_some_columns_are_not_read(tmp_path, header, long):
    """The strict typed read does not notice a long line when it does not read every column:
    the separators are counted then, and the line goes row by row, rejected as there."""
    width = header.count(",") + 1
    rows = [",".join(["0", "p1", "1"] + ["x"] * (width - 3)), long, ",".join(["3", "p1", "0"] + ["x"] * (width - 3))]
    if header.startswith("t,a,"):
        rows = ["0,x,p1,1", long, "3,x,p1,0"]
    path = tmp_path / "motion.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    res = _same_toggles(path)
    assert res.rejects.height == 1 and "too many fields" in res.rejects["reason"][0]


def test_a_long_messy_file_is_split_without_numba(tmp_path, monkeypatch):
    """A file past MIN_ROWS lines with a line of too many fields has its separators counted on
    every line; while numba is not loaded that count is numpy's (a reader never pays numba's
    load for a messy file), and the result is the row-by-row path's."""
    from onebit.readers import typedread

    def refuse(*args):
        raise AssertionError("the compiled separator count ran while numba was not loaded")

    monkeypatch.setattr(typedread, "numba_loaded", lambda: False)
    monkeypatch.setattr(kernels, "separators_per_line", refuse)
    n = kernels.MIN_ROWS + 10
    lines = [f"{k * 0.5},{'abc'[k % 3]},{'ab'[k % 2]},{(k // 2) % 2}" for k in range(n)]
    lines[7] += ",extra"  # too many fields: only the count of every line finds it
    path = tmp_path / "beams.csv"
    path.write_text("t,beam,pair,blocked\n" + "\n".join(lines) + "\n")
    fast = _same_beams(path)
    assert "too many fields" in fast.rejects.filter(pl.col("line") == 9)["reason"].item()


def test_a_long_log_decoded_on_two_threads_equals_the_row_by_row_path(tmp_path, monkeypatch):
    """Past MIN_ROWS events, with numba not loaded, the decoder builds the events table and
    names the rejected lines on a second thread while numpy finds the passes: the tables and
    the rejects (reasons, lines, raw text) are the row-by-row path's."""
    from onebit.readers import beams

    monkeypatch.setattr(beams, "numba_loaded", lambda: False)
    pools = []

    class Pool(beams.ThreadPoolExecutor):
        def submit(self, fn, *args):
            pools.append(fn)
            return super().submit(fn, *args)

    monkeypatch.setattr(beams, "ThreadPoolExecutor", Pool)
    rng = np.random.default_rng(5)
    n = kernels.MIN_ROWS + 3000
    t = np.cumsum(rng.choice([0.0, 0.05, 0.1, 0.2], n)).round(2)
    beam = rng.choice(list(BEAMS), n)
    pair = rng.choice(["a", "b"], n)
    blocked = (rng.random(n) < 0.5).astype(int)  # many no-change edges, passes of every kind
    body = "\n".join(f"{a},{b},{c},{d}" for a, b, c, d in zip(t.tolist(), beam, pair, blocked))
    path = tmp_path / "beams.csv"
    path.write_text("t,beam,pair,blocked\n" + body + "\n")
    fast = _same_beams(path)
    assert fast.rejects.height > 1000 and fast.crossings.height > 100 and fast.aborted.height > 100
    assert fast.rejects["raw"].null_count() == 0
    # on the second thread: both paths' events tables, the typed path's rejected lines' text
    assert sorted(f.__name__ for f in pools) == ["events_table", "events_table", "texts"]


# --------------------------------------------------------------------------- columns made in numpy


def _bits(s: pl.Series) -> np.ndarray:
    a = s.to_numpy()
    return a.view(np.uint64) if s.dtype == pl.Float64 else a


def _same_column(fast: pl.Series, plain: pl.Series) -> None:
    """Bit for bit (-0.0 and 0.0 differ), the same name, dtype, nulls and sorted flags."""
    assert fast.name == plain.name and fast.dtype == plain.dtype and fast.null_count() == plain.null_count()
    assert dict(fast.flags) == dict(plain.flags), (fast.flags, plain.flags)
    if plain.null_count():
        assert fast.equals(plain)
    else:
        assert np.array_equal(_bits(fast), _bits(plain))


NUMBERS = st.one_of(
    st.floats(allow_nan=False, width=64),
    st.sampled_from([0.0, -0.0, 6.0, 1.7e9, 1e-300, -1e300, float("inf"), float("-inf")]),
)


@SETTINGS
@given(
    values=st.lists(NUMBERS, max_size=40),
    cuts=st.lists(st.integers(0, 40), max_size=4),
    c=st.floats(allow_nan=False, allow_infinity=False),
    flag=st.booleans(),
    ints=st.booleans(),
    null=st.booleans(),
    data=st.data(),
)
def test_columns_made_in_numpy_equal_polars_own(monkeypatch, values, cuts, c, flag, ints, null, data):
    """``one_buffer`` / ``minus_constant`` / ``kept_rows`` (a large column copied, shifted or
    filtered in numpy, for numpy's huge pages) against ``rechunk`` / ``s - c`` / ``filter``:
    bit for bit, with the same sorted flags; a column with nulls is left to polars. The size
    from which numpy is used is lowered so that small columns take that path."""
    from onebit.readers import rows, typedread

    monkeypatch.setattr(typedread, "_NUMPY_COPY_BYTES", 8)
    if ints:
        values = [int(max(-(2**62), min(2**62, v))) if math.isfinite(v) else 7 for v in values]
    dtype = pl.Int64 if ints else pl.Float64
    if flag:
        values = sorted(values)
    pieces = [values[a:b] for a, b in zip([0, *sorted(cuts)], [*sorted(cuts), len(values)])]
    parts = [pl.Series("t", p, dtype=dtype) for p in pieces]
    if null and values:
        parts.append(pl.Series("t", [None], dtype=dtype))
    s = pl.concat(parts, rechunk=False)
    if flag and not (null and values):
        s = s.set_sorted()
    frame = pl.DataFrame([s, pl.Series("k", range(s.len()), dtype=pl.UInt8 if s.len() < 256 else pl.Int64)])
    one = rows.one_buffer(frame)
    assert one.schema == frame.schema and all(col.n_chunks() == 1 for col in one.iter_columns())
    for name in frame.columns:
        _same_column(one[name], frame[name].rechunk())
    if not ints:
        _same_column(rows.minus_constant(s, c), s - c)
    keep = np.array(data.draw(st.lists(st.booleans(), min_size=s.len(), max_size=s.len())), dtype=np.bool_)
    _same_column(rows.kept_rows(s, keep), s.filter(pl.Series(keep)))
    assert rows.kept_rows(s, None) is s


@SETTINGS
@given(blob=beam_file(), tblob=toggle_file(), epoch=EPOCHS)
def test_readers_with_columns_made_in_numpy_give_the_row_by_row_result(
    tmp_path_factory, monkeypatch, blob, tblob, epoch
):
    """The beam and toggle readers with every large-column shortcut taken (the size lowered):
    the typed read's one buffer per column, the time origin taken off and the kept edges' times
    in numpy give the row-by-row path's tables."""
    from onebit.readers import typedread

    monkeypatch.setattr(typedread, "_NUMPY_COPY_BYTES", 8)
    folder = Path(tmp_path_factory.mktemp("numpy"))
    (folder / "beams.csv").write_bytes(blob)
    (folder / "motion.csv").write_bytes(tblob)
    _same_beams(folder / "beams.csv", epoch)
    _same_toggles(folder / "motion.csv", epoch)
