"""No input exhausts memory (#26 item 8): the documented limits of the CSV readers, each
refusing a file with an error naming it and the line, checked on small files with the limits
lowered (the functions read the module's limits when called)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit.core.errors import InputError
from onebit.readers import lines, rows
from onebit.readers.motion import read_motion_csv
from onebit.readers.rows import (
    check_line_lengths,
    header_names,
    malformed_lines,
    read_csv_column,
    read_csv_rows,
)

SENSORS = ("p1", "p2")


def _write(tmp_path: Path, data: bytes, name: str = "motion.csv") -> Path:
    p = tmp_path / name
    p.write_bytes(data)
    return p


def _longest_reference(data: bytes, limit: int) -> int | None:
    """The first 1-based line longer than ``limit`` bytes (its ``\\n`` not counted), by splitting."""
    for k, line in enumerate(data.split(b"\n"), start=1):
        if len(line) > limit:
            return k
    return None


@settings(max_examples=150, deadline=None)
@given(
    data=st.lists(st.sampled_from([b"a", b"\n", b",", b"xyz"]), max_size=120).map(b"".join),
    limit=st.integers(1, 12),
    step=st.integers(1, 20),
)
def test_line_length_check_finds_the_first_long_line_across_scan_steps(data, limit, step):
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(lines, "MAX_LINE_BYTES", limit)
        mp.setattr(lines, "_SCAN_BYTES", step)
        want = _longest_reference(data, limit)
        if want is None:
            check_line_lengths(data, "f.csv")
            return
        with pytest.raises(InputError, match=rf"^f\.csv:{want}: line longer than the {limit} bytes"):
            check_line_lengths(data, "f.csv")


def test_a_file_that_is_one_huge_line_is_refused_before_it_is_split(tmp_path, monkeypatch):
    monkeypatch.setattr(lines, "MAX_LINE_BYTES", 1000)
    garbage = np.random.default_rng(0).integers(32, 127, size=5000, dtype=np.uint8).tobytes().replace(b"\n", b" ")
    p = _write(tmp_path, garbage)
    with pytest.raises(InputError, match=r"motion\.csv:1: line longer than the 1000 bytes"):
        read_motion_csv(p, SENSORS)
    later = _write(tmp_path, b"t,sensor,value\n1,p1,1\n" + garbage + b"\n2,p1,0\n", "later.csv")
    with pytest.raises(InputError, match=r"later\.csv:3: line longer than the 1000 bytes"):
        read_csv_rows(later, ("t", "sensor", "value"))
    with pytest.raises(InputError, match=r"later\.csv:3"):  # the time origin's read refuses it too
        read_csv_column(later, "t")


@pytest.mark.parametrize("header", [b"", b"t,sensor,value\n"])
def test_random_bytes_are_not_a_text_file(tmp_path, header):
    """Random bytes (with or without a valid header) are refused from the first 64 KiB, naming the
    first line that is not UTF-8 -- before, every bad byte cost a Python object (200 MB: 4 GB)."""
    noise = np.random.default_rng(1).integers(0, 256, size=300_000, dtype=np.uint8).tobytes()
    p = _write(tmp_path, header + noise)
    first = 1 + bool(header)
    with pytest.raises(InputError, match=rf"motion\.csv:{first}: not a text file: \d+ of the first \d+ lines"):
        read_motion_csv(p, SENSORS)
    with pytest.raises(InputError, match="not a text file"):
        header_names(p)


def test_a_few_bad_bytes_are_still_rejected_line_by_line(tmp_path):
    """A crash's NUL run, a flipped bit: a few lines that are not text stay rejects of their own."""
    good = b"".join(b"%d,p1,%d\n" % (k, k % 2) for k in range(1, 40))
    p = _write(tmp_path, b"t,sensor,value\n" + good + b"\xff\xfe\x00,p2\n" * 7 + b"50,p2,1\n")
    res = read_motion_csv(p, SENSORS)
    bad = res.rejects.filter(pl.col("reason").str.starts_with("not UTF-8"))
    assert bad.height == 7 and bad["line"].to_list() == list(range(41, 48))
    assert res.motion.height == 40


def _malformed_reference(data: bytes, n_fields: int, after_line: int) -> int:
    """Lines after ``after_line`` without a quote, not blank, with another number of commas."""
    count = 0
    for k, line in enumerate(data.split(b"\n"), start=1):
        if k <= after_line or b'"' in line or not line.strip(b" \t\r"):
            continue
        count += line.count(b",") != n_fields - 1
    return count


@settings(max_examples=150, deadline=None)
@given(
    data=st.lists(st.sampled_from([b"a", b"\n", b",", b'"', b" ", b"\r\n", b"1,2,3\n"]), max_size=150).map(b"".join),
    n=st.integers(1, 4),
    after=st.integers(0, 3),
    step=st.integers(1, 40),
)
def test_malformed_line_count_matches_a_line_by_line_count(data, n, after, step):
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(lines, "_SHAPE_BYTES", step)
        count, first = malformed_lines(data, n, after)
    assert count == _malformed_reference(data, n, after)
    assert (first is None) == (count == 0)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(body=st.lists(st.sampled_from(["1,p1,1", "2,p2", "3,p1,0,9", "4,p2,1", "x", "", "5,p1"]), max_size=30))
def test_malformed_count_is_the_readers_field_count_rejects(tmp_path_factory, body):
    """On quote-free files the budget counts exactly the lines the reader rejects for their field count."""
    data = ("t,sensor,value\n" + "\n".join(body) + "\n").encode()
    p = _write(tmp_path_factory.mktemp("m"), data)
    rej = read_csv_rows(p, ("t", "sensor", "value")).rejects
    shape = rej.filter(pl.col("reason").str.contains("fields")).height
    assert malformed_lines(data, 3, 1)[0] == shape


def test_too_many_malformed_lines_refuse_the_file_naming_the_first(tmp_path, monkeypatch):
    monkeypatch.setattr(lines, "MAX_MALFORMED_LINES", 5)
    head = b"t,sensor,value\n1,p1,1\n2,p1,0\n"
    ok = _write(tmp_path, head + b"garbage line\n" * 5 + b"3,p2,1\n", "ok.csv")
    assert read_motion_csv(ok, SENSORS).rejects.height == 5  # at the limit: rejected line by line
    bad = _write(tmp_path, head + b"garbage line\n" * 6 + b"3,p2,1\n", "bad.csv")
    with pytest.raises(InputError, match=r"bad\.csv:4: 6 lines are not records of the header's 3 fields"):
        read_motion_csv(bad, SENSORS)
    with pytest.raises(InputError, match=r"bad\.csv:4: 6 lines"):
        read_csv_column(bad, "t")


def test_ascii_garbage_after_a_valid_header_is_refused(tmp_path):
    """A moderately sized file of printable garbage lines (about 2 MB, 130 000 lines) under the
    real limit: refused by one scan instead of 130 000 rejects holding their text."""
    rng = np.random.default_rng(2)
    junk = rng.integers(32, 127, size=2_000_000, dtype=np.uint8)
    junk[rng.random(junk.size) < 1 / 15] = 10
    junk[junk == ord('"')] = ord("x")
    p = _write(tmp_path, b"t,sensor,value\n" + junk.tobytes())
    with pytest.raises(InputError, match=r"motion\.csv:\d+: \d+ lines are not records of the header's 3 fields"):
        read_motion_csv(p, SENSORS)


@settings(max_examples=200, deadline=None)
@given(
    data=st.lists(
        st.sampled_from([b"a", b"\n", b"\r\n", b",", b"\xff", b"\xc3\xa9", b"\xef\xbb\xbf", b" ", b"\xe2\x82"]),
        max_size=60,
    ).map(b"".join),
    step=st.integers(1, 12),
)
def test_physical_lines_split_in_spans_as_in_one_piece(data, step):
    """The file is split a span at a time (bounded temporaries): the same lines, texts and reasons."""
    whole = rows.physical_lines(data)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(lines, "_SCAN_BYTES", step)
        spans = rows.physical_lines(data)
    assert spans.equals(whole), (spans, whole)
    assert whole.height == data.count(b"\n") + (not data.endswith(b"\n")) - (data in (b"", b"\xef\xbb\xbf"))


def _undated_reference(data: bytes) -> int:
    count = 0
    for line in data.split(b"\n"):
        if line[:1] in (b"", b" ", b"\t", b"\r"):
            continue
        count += not (len(line) >= 5 and line[:4].isdigit() and line[4:5] == b"-")
    return count


@settings(max_examples=150, deadline=None)
@given(
    data=st.lists(
        st.sampled_from([b"2010-11-04 M1 ON", b"\n", b"x", b"201", b"-", b" ", b"\t", b"9999-"]), max_size=40
    ).map(b"".join),
    step=st.integers(1, 30),
)
def test_undated_casas_lines_match_a_line_by_line_count(data, step):
    from onebit.readers.casas import undated_lines

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(lines, "_SCAN_BYTES", step)
        count, first = undated_lines(data)
    assert count == _undated_reference(data) and (first is None) == (count == 0)


def test_a_casas_log_of_garbage_is_refused(tmp_path, monkeypatch):
    from onebit.readers import casas

    monkeypatch.setattr(casas, "MAX_MALFORMED_LINES", 3)
    good = "2010-11-04 00:03:50\tM003\tON\n2010-11-04 00:03:55\tM003\tOFF\n"
    ok = _write(tmp_path, (good + "junk\n" * 3).encode(), "ok.txt")
    assert casas.read_casas(ok).rejects.height == 3
    bad = _write(tmp_path, (good + "junk\n" * 4).encode(), "bad.txt")
    with pytest.raises(InputError, match=r"bad\.txt:3: 4 lines do not start with a date"):
        casas.read_casas(bad)
