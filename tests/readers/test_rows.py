"""The CSV layer (:mod:`onebit.readers.rows`): physical lines, one reject per bad line, bounded text.

Besides the cases the issue names (a ``\\xff`` byte, an unbalanced quote, extra fields on the
first data row, a quoted newline, a 5 MB line), every reader is fuzzed with raw random bytes
and with mutated valid files (flipped bytes, inserted quotes, line breaks, NULs, extra
fields, huge lines). For each it checks: no exception but ``OnebitError``; accepted +
rejected + suppressed = the non-blank lines after the header; every reject's line number
and raw text are those of the physical line; every message and raw text is bounded.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import polars as pl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit.core.errors import MAX_MESSAGE, MAX_QUOTE, InputError, OnebitError, bounded
from onebit.core.tables import REJECTS
from onebit.readers.beams import decode_beam_log, decode_raw_beams
from onebit.readers.casas import read_casas
from onebit.readers.mcap_io import MAGIC, read_mcap, write_mcap
from onebit.readers.motion import read_motion, read_motion_csv
from onebit.readers.proximity import read_proximity_csv
from onebit.readers.rows import RawRows, physical_lines, raw_lines, read_csv_rows
from onebit.readers.tables_csv import crossings_from_rows, read_crossings_csv, read_true_crossings_csv, read_truth_csv

BEAMS = ("a", "b", "c")
SENSORS = ("p1", "p2")

#: A small valid file per CSV reader.
VALID: dict[str, str] = {
    "beams": "t,beam,pair,blocked\n1.0,a,a,1\n1.1,a,b,1\n1.2,a,a,0\n1.3,a,b,0\n2.0,b,b,1\n2.1,b,a,1\n2.2,b,b,0\n2.3,b,a,0\n",
    "crossings": "t,beam,direction\n1,a,1\n2,b,-1\n3,c,1\n4,a,-1\n5,b,1\n",
    "truth": "t,target,x,y\n0,A,1,2\n0,B,3,4\n1,A,1.5,2\n1,B,3,4.5\n2,A,2,2\n",
    "truth_crossings": "t,beam,direction,target,dropped\n1,a,1,A,0\n2,b,-1,B,1\n3,c,1,A,0\n",
    "motion": "t,sensor,value\n0.5,p1,1\n0.7,p2,1\n1.0,p1,0\n1.5,p1,1\n2.5,p1,0\n3.0,p2,0\n",
    "proximity": "t,sensor,value\n0,p1,1\n1,p2,1\n2,p1,0\n3,p2,0\n4,p1,1\n",
}


def read_any(kind: str, path: Path) -> tuple[int, pl.DataFrame, int]:
    """(accepted rows, rejects, suppressed rows) of the ``kind`` reader on ``path``."""
    if kind == "beams":
        dec = decode_beam_log(path, BEAMS)
        return dec.events.height, dec.rejects, 0
    if kind == "crossings":
        ok, rej = read_crossings_csv(path, BEAMS)
        return ok.height, rej, 0
    if kind == "truth":
        ok, rej = read_truth_csv(path)
        return ok.height, rej, 0
    if kind == "truth_crossings":
        ok, rej = read_true_crossings_csv(path, BEAMS)
        return ok.height, rej, 0
    if kind == "motion":
        res = read_motion_csv(path, SENSORS)
        return res.motion.height, res.rejects, res.suppressed.height
    if kind == "proximity":
        res = read_proximity_csv(path, SENSORS)
        return res.motion.height, res.rejects, res.suppressed.height
    raise AssertionError(kind)


KINDS = tuple(VALID)


def expected_lines(data: bytes) -> list[str]:
    """The physical lines as an editor shows them (the spec the reader must follow)."""
    if not data:
        return []
    parts = data.split(b"\n")
    if data.endswith(b"\n"):
        parts = parts[:-1]
    out = [(p[:-1] if p.endswith(b"\r") else p).decode("utf-8", "replace") for p in parts]
    out[0] = out[0].removeprefix("\ufeff")
    return out


def data_line_numbers(lines: list[str]) -> list[int]:
    """1-based numbers of the non-blank lines after the header (the first non-blank line)."""
    nonblank = [i + 1 for i, s in enumerate(lines) if not re.fullmatch(r"[ \t]*", s)]
    return nonblank[1:]


def assert_bounded_message(exc: BaseException) -> None:
    assert isinstance(exc, OnebitError), f"not an OnebitError: {exc!r}"
    assert len(str(exc)) <= MAX_MESSAGE + 300, len(str(exc))


def assert_bounded_rejects(rej: pl.DataFrame) -> None:
    limit = MAX_QUOTE + len("... (999999999 characters)")
    assert rej.schema == REJECTS
    assert (rej["reason"].str.len_chars().fill_null(0) <= limit).all()
    assert (rej["raw"].str.len_chars().fill_null(0) <= limit).all()


def check_reader(kind: str, path: Path) -> None:
    """The invariants of the module docstring for one file."""
    data = path.read_bytes()
    try:
        accepted, rej, suppressed = read_any(kind, path)
    except Exception as exc:  # noqa: BLE001 - the point: only OnebitError may escape
        assert_bounded_message(exc)
        return
    assert_bounded_rejects(rej)
    lines = expected_lines(data)
    numbers = data_line_numbers(lines)
    assert accepted + rej.height + suppressed == len(numbers), (accepted, rej.height, suppressed, len(numbers))
    got = rej["line"].to_list()
    assert len(set(got)) == len(got), "one reject per line"
    assert set(got) <= set(numbers)
    for line, raw in zip(got, rej["raw"].to_list()):
        assert raw == bounded(lines[line - 1]), (line, raw, lines[line - 1])


# --------------------------------------------------------------------------- the cases


def _csv(tmp_path: Path, data: bytes, name: str = "crossings.csv") -> Path:
    p = tmp_path / name
    p.write_bytes(data)
    return p


def test_one_bad_byte_costs_its_line_only(tmp_path):
    p = _csv(tmp_path, b"t,beam,direction\n1,a,1\n2,b\xff,1\n3,c,1\n")
    ok, rej = read_crossings_csv(p, BEAMS)
    assert ok["t"].to_list() == [1.0, 3.0]
    assert rej.select("line", "reason").rows() == [(3, "not UTF-8 text: byte 0xFF at column 4")]
    assert rej["raw"][0] == "2,b\ufffd,1"


def test_unbalanced_quote_rejects_its_line_and_numbers_stay_physical(tmp_path):
    p = _csv(tmp_path, b't,beam,direction\n1,a,1\n2,"b,1\n3,c,1\n4,a,-1\n')
    ok, rej = read_crossings_csv(p, BEAMS)
    assert ok["t"].to_list() == [1.0, 3.0, 4.0]
    assert rej["line"].to_list() == [3] and "unbalanced quote" in rej["reason"][0]
    assert rej["raw"][0] == '2,"b,1'


def test_quoted_newline_does_not_shift_line_numbers(tmp_path):
    # a quoted field spanning a line break: both halves are bad lines; line 5 is reported as 5
    p = _csv(tmp_path, b't,beam,direction\n1,a,1\n2,"b\nc",1\n3,zz,1\n4,a,1\n')
    ok, rej = read_crossings_csv(p, BEAMS)
    assert rej["line"].to_list() == [3, 4, 5]
    assert rej["raw"].to_list()[2] == "3,zz,1" and "unknown beam" in rej["reason"][2]
    assert ok["t"].to_list() == [1.0, 4.0]


def test_extra_fields_on_the_first_data_row(tmp_path):
    p = _csv(tmp_path, b"t,beam,direction\n1,a,1,9,9\n2,b,1\n")
    ok, rej = read_crossings_csv(p, BEAMS)
    assert ok["t"].to_list() == [2.0]
    assert rej.select("line", "reason").rows() == [(2, "too many fields (5 of 3)")]


def test_ascii_garbage_lines_are_rejected_one_by_one(tmp_path):
    p = _csv(tmp_path, b"t,beam,direction\n1,a,1\n%%%%\n@@,##\n!!,??,**\n5,c,-1\n")
    ok, rej = read_crossings_csv(p, BEAMS)
    assert ok["t"].to_list() == [1.0, 5.0]
    assert rej["line"].to_list() == [3, 4, 5]


def test_quoted_fields_and_stray_quotes(tmp_path):
    p = _csv(tmp_path, b't,beam,direction\n"1","a","1"\n2,a"b"c,1\n"3",c,-1\n')
    ok, rej = read_crossings_csv(p, BEAMS)
    assert ok["t"].to_list() == [1.0, 3.0]
    assert rej["line"].to_list() == [3] and rej["reason"][0].startswith("stray quote")


def test_huge_line_is_one_bounded_reject(tmp_path):
    huge = b"9," + b"x" * 5_000_000 + b",1"
    p = _csv(tmp_path, b"t,beam,direction\n1,a,1\n" + huge + b"\n2,b,1\n")
    ok, rej = read_crossings_csv(p, BEAMS)
    assert ok["t"].to_list() == [1.0, 2.0]
    assert rej["line"].to_list() == [3]
    assert rej["raw"][0] == bounded(huge.decode()) and rej["raw"][0].endswith("(5000004 characters)")
    assert len(rej["reason"][0]) <= MAX_QUOTE + 30
    nosep = _csv(tmp_path, b"t,beam,direction\n" + b"y" * 3_000_000, "nosep.csv")
    assert read_csv_rows(nosep, ("t", "beam", "direction")).rejects["raw"][0].endswith("(3000000 characters)")


def test_bom_crlf_blank_lines_and_no_final_newline(tmp_path):
    p = _csv(tmp_path, b"\xef\xbb\xbft,beam,direction\r\n1,a,1\r\n\r\n   \r\n2,b,-1")
    ok, rej = read_crossings_csv(p, BEAMS)
    assert ok["t"].to_list() == [1.0, 2.0] and rej.height == 0
    raw = read_csv_rows(p, ("t", "beam", "direction"))
    assert raw.frame["line"].to_list() == [2, 5] and raw.frame["raw"].to_list() == ["1,a,1", "2,b,-1"]


def test_header_problems_name_the_file_and_line(tmp_path):
    with pytest.raises(InputError, match=r"crossings\.csv:1: cannot read the CSV header: not UTF-8"):
        read_crossings_csv(_csv(tmp_path, b"t,be\xffam,direction\n1,a,1\n"), BEAMS)
    with pytest.raises(InputError, match=r":1: cannot read the CSV header: unbalanced quote"):
        read_crossings_csv(_csv(tmp_path, b't,"beam,direction\n1,a,1\n'), BEAMS)
    with pytest.raises(InputError, match=r":2: field 'direction': missing column"):
        read_crossings_csv(_csv(tmp_path, b"\nt,beam\n1,a\n"), BEAMS)
    with pytest.raises(InputError, match="named twice"):
        read_crossings_csv(_csv(tmp_path, b"t,beam,beam,direction\n1,a,a,1\n"), BEAMS)
    with pytest.raises(InputError, match="is a folder"):
        read_crossings_csv(tmp_path, BEAMS)
    empty = read_crossings_csv(_csv(tmp_path, b""), BEAMS)
    assert empty[0].height == 0 and empty[1].height == 0


def test_absurdly_wide_header_is_an_error_and_wide_headers_read_fast(tmp_path):
    # found by the fuzz test: a 100 000-field header made the field split build a 100 000-field struct
    wide = b"t,sensor,value" + b"," * 100_000 + b"\n1,p1,1" + b"," * 100_000 + b"\n"
    with pytest.raises(InputError, match=r":1: cannot read the CSV header: 100003 fields"):
        read_proximity_csv(_csv(tmp_path, wide), ("p1",))
    extra = ",".join(f"x{i}" for i in range(900)).encode()
    ok = b"t,sensor,value," + extra + b"\n1,p1,1," + b"," * 899 + b"\n2,p1,0," + b"," * 899 + b"\n"
    rows = read_csv_rows(_csv(tmp_path, ok), ("t", "sensor", "value"))
    assert rows.frame["value"].to_list() == ["1", "0"] and rows.rejects.height == 0


def test_physical_lines_and_raw_lines(tmp_path):
    data = b"a\r\nb\xfe\xffc\n\nlast"
    lines = physical_lines(data)
    assert lines["line"].to_list() == [1, 2, 3, 4]
    assert lines["text"].to_list() == ["a", "b\ufffd\ufffdc", "", "last"]
    assert lines["_reason"].to_list() == [None, "not UTF-8 text: byte 0xFE at column 2", None, None]
    p = _csv(tmp_path, data, "x.csv")
    assert raw_lines(p, [2, 4]) == {2: "b\ufffd\ufffdc", 4: "last"}


def test_every_bad_line_of_a_toggle_log_is_one_reject(tmp_path):
    text = VALID["motion"].encode() + b'4,p1,"1\n5,p2,1,1\n6,p\xff2,0\n7,p2,1\n'
    p = _csv(tmp_path, text, "motion.csv")
    res = read_motion_csv(p, SENSORS)
    assert res.rejects["line"].to_list() == [8, 9, 10]
    check_reader("motion", p)


# --------------------------------------------------------------------------- fuzzing every reader


@st.composite
def mutated(draw, valid: bytes) -> bytes:
    """A valid file with a few damaging edits."""
    data = bytearray(valid)
    for _ in range(draw(st.integers(1, 5))):
        pos = draw(st.integers(0, len(data)))
        op = draw(
            st.sampled_from(
                ["flip", "quote", "newline", "crlf", "cr", "fields", "huge", "ff", "nul", "delete", "blank", "bom"]
            )
        )
        if op == "flip" and data:
            i = min(pos, len(data) - 1)
            data[i] ^= 1 << draw(st.integers(0, 7))
        elif op == "quote":
            data[pos:pos] = b'"'
        elif op == "newline":
            data[pos:pos] = b"\n"
        elif op == "crlf":
            data[pos:pos] = b"\r\n"
        elif op == "cr":
            data[pos:pos] = b"\r"
        elif op == "fields":
            data[pos:pos] = b",x" * draw(st.integers(1, 3))
        elif op == "huge":
            data[pos:pos] = draw(st.sampled_from([b"z", b",", b'"'])) * draw(st.sampled_from([250, 4000, 100_000]))
        elif op == "ff":
            data[pos:pos] = draw(st.sampled_from([b"\xff", b"\xc3", b"\xe2\x82", b"\xed\xa0\x80"]))
        elif op == "nul":
            data[pos:pos] = b"\x00" * draw(st.integers(1, 4))
        elif op == "delete":
            del data[pos : pos + draw(st.integers(1, 8))]
        elif op == "blank":
            data[pos:pos] = b"\n  \t\n"
        elif op == "bom":
            data[pos:pos] = b"\xef\xbb\xbf"
    return bytes(data)


def _inputs(kind: str):
    valid = VALID[kind].encode()
    header = valid.split(b"\n", 1)[0] + b"\n"
    return st.one_of(
        st.binary(max_size=400),  # raw random bytes
        st.binary(max_size=400).map(lambda b: header + b),  # a good header, random bytes after it
        mutated(valid),
    )


@pytest.mark.parametrize("kind", KINDS)
@settings(
    max_examples=70, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow]
)
@given(data=st.data())
def test_reader_fuzz(kind, tmp_path_factory, data):
    blob = data.draw(_inputs(kind), label="file")
    path = Path(tmp_path_factory.mktemp(kind)) / f"{kind}.csv"
    path.write_bytes(blob)
    check_reader(kind, path)


@pytest.mark.parametrize("kind", KINDS)
def test_valid_samples_are_accepted_whole(kind, tmp_path):
    p = _csv(tmp_path, VALID[kind].encode(), f"{kind}.csv")
    accepted, rej, suppressed = read_any(kind, p)
    assert rej.height == 0 and accepted + suppressed == VALID[kind].count("\n") - 1
    check_reader(kind, p)


# --------------------------------------------------------------------------- CASAS (no header; blank = whitespace only)

VALID_CASAS = (
    "2010-11-04 00:03:50.209589\tM003\tON\tSleeping begin\n2010-11-04 00:03:51\tD001\tOPEN\n"
    "2010-11-04 00:03:52\tT001\t21.5\n2010-11-04 00:03:55\tM003\tOFF\n2010-11-04 00:04:00\tL005\tON\n"
)


def check_casas(path: Path) -> None:
    try:
        log = read_casas(path)
    except Exception as exc:  # noqa: BLE001
        assert_bounded_message(exc)
        return
    assert_bounded_rejects(log.rejects)
    lines = [s.replace("\x00", "\ufffd") for s in expected_lines(path.read_bytes())]
    blank = pl.Series(lines, dtype=pl.String).str.strip_chars().eq("").to_list() if lines else []
    numbers = [i + 1 for i, b in enumerate(blank) if not b]
    assert log.events.height + log.rejects.height == len(numbers) == log.lines
    got = log.rejects["line"].to_list()
    assert len(set(got)) == len(got) and set(got) <= set(numbers)
    for line, raw in zip(got, log.rejects["raw"].to_list()):
        assert raw == bounded(lines[line - 1]), (line, raw, lines[line - 1])


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_casas_fuzz(tmp_path_factory, data):
    blob = data.draw(st.one_of(st.binary(max_size=400), mutated(VALID_CASAS.encode())), label="file")
    path = Path(tmp_path_factory.mktemp("casas")) / "log.txt"
    path.write_bytes(blob)
    check_casas(path)


def test_casas_line_numbers_are_physical(tmp_path):
    p = tmp_path / "log.txt"
    p.write_bytes(
        VALID_CASAS.encode().replace(b"D001\tOPEN", b"D001\x0c\rOPEN")
        + b"bad \xff line\n2010-11-04 00:05:00\tM003\tON\n"
    )
    log = read_casas(p)
    assert log.rejects["line"].to_list() == [2, 6] and log.events.height == 5
    check_casas(p)


# --------------------------------------------------------------------------- MCAP


def _mcap_tables() -> dict[str, pl.DataFrame]:
    def frame(kind: str) -> pl.DataFrame:
        return pl.read_csv(VALID[kind].encode(), infer_schema=False)

    return {"/beams": frame("beams"), "/crossings": frame("crossings"), "/motion": frame("motion")}


def _typed(topic: str, raw) -> tuple[int, pl.DataFrame, int]:
    if topic == "/beams":
        dec = decode_raw_beams(raw, BEAMS)
        return dec.events.height, dec.rejects, 0
    if topic == "/crossings":
        ok, rej = crossings_from_rows(raw, BEAMS)
        return ok.height, rej, 0
    res = read_motion(raw, SENSORS)
    return res.motion.height, res.rejects, res.suppressed.height


def check_mcap(path: Path, messages: dict[str, int] | None = None) -> None:
    """Only OnebitError; bounded rejects; each channel's rows accounted for by its reader;
    with ``messages`` (per topic, when the framing is intact) every message accounted for."""
    try:
        contents = read_mcap(path)
    except Exception as exc:  # noqa: BLE001
        assert_bounded_message(exc)
        return
    assert_bounded_rejects(contents.rejects)
    for topic, frame in contents.channels.items():
        from_reader = contents.rejects.filter(pl.col("source") == f"{path.name}:{topic}")
        raw = RawRowsFactory(f"{path.name}:{topic}", frame)
        accepted, rej, suppressed = _typed(topic, raw)
        assert_bounded_rejects(rej)
        assert accepted + rej.height + suppressed == frame.height
        if messages is not None and not contents.truncated:
            assert frame.height + from_reader.height == messages[topic]


def RawRowsFactory(source: str, frame: pl.DataFrame) -> RawRows:
    return RawRows(source, frame, pl.DataFrame(schema=REJECTS))


@pytest.fixture(scope="module")
def valid_mcap(tmp_path_factory) -> bytes:
    p = Path(tmp_path_factory.mktemp("mcap")) / "recording.mcap"
    write_mcap(p, _mcap_tables())
    return p.read_bytes()


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_mcap_fuzz_bytes(valid_mcap, tmp_path_factory, data):
    blob = data.draw(
        st.one_of(st.binary(max_size=300), st.binary(max_size=300).map(lambda b: MAGIC + b), mutated(valid_mcap)),
        label="file",
    )
    path = Path(tmp_path_factory.mktemp("mcap")) / "recording.mcap"
    path.write_bytes(blob)
    check_mcap(path)


junk_text = st.one_of(
    st.sampled_from(["1", "a", "p1", "-1", "", '"', 'x"y', "\n", "\r\n", "1,2", "\x00", "nan", "inf", "on", "ON"]),
    st.text(max_size=8),
    st.integers(0, 3).map(lambda k: "q" * (10**k * 300)),
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.tuples(junk_text, junk_text, junk_text), max_size=12))
def test_mcap_junk_messages_are_all_accounted_for(tmp_path_factory, rows):
    frame = pl.DataFrame(rows, schema={"t": pl.String, "beam": pl.String, "direction": pl.String}, orient="row")
    motion = pl.DataFrame(rows, schema={"t": pl.String, "sensor": pl.String, "value": pl.String}, orient="row")
    path = Path(tmp_path_factory.mktemp("mcapj")) / "recording.mcap"
    write_mcap(path, {"/crossings": frame, "/motion": motion})
    check_mcap(path, {"/crossings": len(rows), "/motion": len(rows)})


def test_mcap_message_with_huge_payload_is_bounded(tmp_path):
    path = tmp_path / "recording.mcap"
    write_mcap(
        path, {"/crossings": pl.DataFrame({"t": ["1", "x" * 1_000_000], "beam": ["a", "a"], "direction": ["1", "1"]})}
    )
    contents = read_mcap(path)
    ok, rej = crossings_from_rows(RawRowsFactory("recording.mcap:/crossings", contents.channels["/crossings"]), BEAMS)
    assert ok.height == 1 and rej["line"].to_list() == [2]
    assert_bounded_rejects(rej)
    assert json.loads(contents.channels["/crossings"]["raw"][1])["t"].startswith("xxx")


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.text(alphabet='ab,1. \t\r"', max_size=12), min_size=0, max_size=200),
    st.booleans(),
    st.lists(st.integers(-2, 230), min_size=0, max_size=150),
)
def test_ascii_lines_cut_out_at_once_equal_one_by_one(body, trailing_newline, wanted):
    """line_texts of many lines of an ASCII file (cut out in one go) equals the line-by-line cut."""
    import numpy as np

    from onebit._testing.reader_oracles import line_texts_reference as _line_texts_reference
    from onebit.readers.linetext import _ascii_line_texts
    from onebit.readers.rows import FileLines, line_texts, newlines

    data = "\n".join(body).encode() + (b"\n" if trailing_newline and body else b"")
    got = line_texts(data, wanted)
    assert got.equals(_line_texts_reference(data, wanted))
    nl = newlines(data)
    n_lines = nl.size + (len(data) > 0 and not data.endswith(b"\n"))
    want = np.unique(np.asarray(wanted, dtype=np.int64))
    want = want[(want >= 1) & (want <= n_lines)]
    assert _ascii_line_texts(data, want, *FileLines(data).bounds(want)).equals(_line_texts_reference(data, wanted))


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.text(alphabet="ab,1\r\u00e9", max_size=12), min_size=0, max_size=120),
    st.booleans(),
    st.lists(st.integers(-2, 130), min_size=0, max_size=80),
    st.integers(1, 40),
)
def test_lines_found_by_step_counts_equal_the_newline_list(body, trailing_newline, wanted, step):
    """FileLines finds a named line's text from its newlines counted per step (steps of any
    size, lines across steps) as from the list of every newline, and as one by one."""
    from onebit._testing.reader_oracles import line_texts_reference as _line_texts_reference
    from onebit.readers.rows import FileLines, newlines

    data = "\n".join(body).encode() + (b"\n" if trailing_newline and body else b"")
    by_steps = FileLines(data, step=step)
    listed = FileLines(data)
    listed._nl = newlines(data)
    assert by_steps.n_lines == listed.n_lines
    got = by_steps.lines(wanted)
    assert got.equals(listed.lines(wanted))
    assert got.select("line", "text").equals(_line_texts_reference(data, wanted).select("line", "text"))


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 6), st.sampled_from(["a", "b", None]), st.booleans()), min_size=0, max_size=60),
    st.booleans(),
)
def test_duplicates_found_among_equal_stamps_only_equal_the_plain_search(rows, in_order):
    """duplicate_rows on a log in time order (only the runs of equal stamps sorted) finds what
    the search over every row finds, and both what a plain scan finds: each row equal in the
    key (nulls equal) to an earlier one, with the line of the first."""
    from onebit.readers.rows import duplicate_of, duplicate_rows, in_time_order, mark_in_order

    if in_order:
        rows = sorted(rows, key=lambda r: r[0])
    ok = pl.DataFrame(
        {
            "line": list(range(2, len(rows) + 2)),
            "t": [float(r[0]) for r in rows],
            "beam": [r[1] for r in rows],
            "on": [r[2] for r in rows],
        },
        schema={"line": pl.Int64, "t": pl.Float64, "beam": pl.String, "on": pl.Boolean},
    )
    key = ("t", "beam", "on")
    want, seen = [], {}
    for i, r in enumerate(rows):
        want.append(seen.get(r))
        seen.setdefault(r, i + 2)
    assert duplicate_of(ok, key).to_list() == want
    plain = duplicate_rows(ok, key, in_order=False)
    assert dict(zip(plain["_i"], plain["_first"])) == {i: w for i, w in enumerate(want) if w is not None}
    assert in_time_order(ok["t"]) == (in_order or [r[0] for r in rows] == sorted(r[0] for r in rows))
    if in_time_order(ok["t"]):
        assert duplicate_rows(ok, key, in_order=True).sort("_i").equals(plain.sort("_i"))
        assert in_time_order(mark_in_order(ok, "t")["t"])


def test_a_column_flagged_sorted_with_nan_or_nulls_is_not_in_time_order():
    """The sorted flag alone never vouches for a column with NaN or nulls (never in order)."""
    from onebit.readers.rows import in_time_order

    assert not in_time_order(pl.Series([1.0, 2.0, float("nan")]).set_sorted())
    assert not in_time_order(pl.Series([1.0, None, 2.0]).set_sorted())
    assert in_time_order(pl.Series([1.0, 1.0, 2.0]).set_sorted())


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=700), st.integers(1, 300))
def test_newlines_per_block_equal_one_block_at_a_time(data, step):
    """block_newlines (eight words summed, their byte lanes by one product; any step size,
    blocks and steps cut anywhere) counts each 64-byte block's newlines as counting them one
    block at a time does."""
    import numpy as np

    from onebit._testing.reader_oracles import block_newlines_reference
    from onebit.readers.rows import block_newlines

    buf = np.frombuffer(data.replace(b"\x00", b"\n"), dtype=np.uint8)  # (more newlines)
    assert block_newlines(buf, step).tolist() == block_newlines_reference(buf).tolist()


@settings(max_examples=100, deadline=None)
@given(
    st.lists(st.text(alphabet="ab,1\r\u00e9", max_size=90), min_size=0, max_size=60),
    st.booleans(),
    st.lists(st.integers(-2, 70), min_size=1, max_size=40),
    st.sampled_from([None, 5, MAX_QUOTE]),
)
def test_named_lines_text_equals_their_rows(body, trailing_newline, wanted, limit):
    """FileLines.texts (ASCII files: each line cut out and bounded in Python, no table) gives
    each named line the text of its row in FileLines.lines, cut to ``limit`` as bounded cuts it,
    for ASCII files and others alike."""
    from onebit.readers.rows import FileLines

    data = "\n".join(body).encode() + (b"\n" if trailing_newline and body else b"")
    rows = FileLines(data).lines(wanted)
    want = {k: (t if limit is None else bounded(t, limit)) for k, t in rows.select("line", "text").iter_rows()}
    assert FileLines(data).texts(wanted, limit=limit) == want


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from([0.0, 1.5, 2.0, -0.0, float("nan"), 3.25]),
            st.sampled_from(["a", "b", "c"]),
            st.sampled_from([True, False, None]),
            st.sampled_from(["x", "y", None]),
        ),
        min_size=1,
        max_size=40,
    ),
    st.permutations(range(40)),
    st.sampled_from([("t", "beam", "on"), ("t", "beam"), ("t", "name"), ("t", "on", "name")]),
)
def test_duplicates_in_numpy_equal_the_polars_search(rows, lines, key):
    """_duplicates_numpy (enum codes, booleans and finite floats compared in numpy) finds the
    rows and first lines _duplicates_polars finds, and declines (None) the keys numpy would
    compare otherwise: text, nulls, NaN, a negative zero."""
    from onebit.readers.rowchecks import _duplicates_numpy, _duplicates_polars

    cand = pl.DataFrame(
        {
            "_i": list(range(len(rows))),
            "line": [lines[i] + 2 for i in range(len(rows))],
            "t": [r[0] for r in rows],
            "beam": [r[1] for r in rows],
            "on": [r[2] for r in rows],
            "name": [r[3] for r in rows],
        },
        schema={
            "_i": pl.Int64,
            "line": pl.Int64,
            "t": pl.Float64,
            "beam": pl.Enum(["c", "a", "b"]),
            "on": pl.Boolean,
            "name": pl.String,
        },
    )
    plain = _duplicates_polars(cand, key).sort("_i")
    fast = _duplicates_numpy(cand, key)
    declines = "name" in key or any(
        cand[k].null_count()
        or (cand[k].dtype == pl.Float64 and any(math.isnan(x) or math.copysign(1, x) < 0 and x == 0 for x in cand[k]))
        for k in key
    )
    assert (fast is None) == declines
    if fast is not None:
        assert fast.sort("_i").equals(plain)
