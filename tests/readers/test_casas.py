"""The CASAS reader (issue 12, item 4): lines -> events, kinds, annotations, rejects; logs info."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit._testing.casas_sim import write_casas_log
from onebit.core.errors import OnebitError
from onebit.readers.casas import read_casas
from onebit.readers.loginfo import log_info

KIND_ROWS = {"motion", "contact", "door", "temperature", "item", "light", "analog", "other"}

LOG = (
    "2010-11-04 00:03:50.209589\tM003\tON\tSleeping begin\n"  # line 1
    "2010-11-04 00:03:49.9\tM004\tON\n"  # line 2: 0.31 s out of order (sorted, counted)
    "2010-11-04 00:03:51\tD001\tOPEN\n"  # line 3
    "\n"  # line 4: blank (skipped)
    "2010-11-04 00:03:52.5 T001 21.5\n"  # line 5: spaces, temperature
    "2010-11-04 00:03:53\tLS001\t13\n"  # line 6: a light (L###)
    "2010-11-04 00:03:54\tM003\tmaybe\n"  # line 7: unreadable motion value
    "2010-11-04\tM003\n"  # line 8: too few fields
    "2010-13-04 00:03:55\tM003\tOFF\n"  # line 9: no such month
    "2010-11-04 00:03:40\tM003\tOFF\n"  # line 10: 13 s backwards
    "2010-11-04 00:03:56\tD001\tCLOSE\n"  # line 11
    "2010-11-04 00:03:56\tD001\tCLOSE\n"  # line 12: duplicate
    "2011-11-04 00:03:57\tM003\tOFF\n"  # line 13: a year later, alone
    "2010-11-04 00:03:58\tm005\toff\tSleeping end\n"  # line 14: not a CASAS id: a named sensor, motion by its value
)


def _write(tmp_path: Path, text: str, name: str = "log.txt") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_events_kinds_annotations_and_rejects(tmp_path):
    log = read_casas(_write(tmp_path, LOG))
    assert log.lines == 13  # non-blank
    assert log.events.height + log.rejects.height == log.lines
    ev = {r["line"]: r for r in log.events.iter_rows(named=True)}
    assert set(ev) == {1, 2, 3, 5, 6, 11, 14}
    assert ev[1]["kind"] == "motion" and ev[1]["on"] is True and ev[1]["annotation"] == "Sleeping begin"
    assert ev[3]["kind"] == "contact" and ev[3]["on"] is True  # a D### contact is no door unless a layout says so
    assert ev[11]["on"] is False  # CLOSE
    assert ev[5]["kind"] == "temperature" and ev[5]["value"] == "21.5" and ev[5]["on"] is None
    assert ev[6]["kind"] == "light" and ev[14]["kind"] == "motion" and ev[14]["on"] is False
    assert ev[1]["activity"] == "Sleeping" and ev[1]["activity_edge"] == "begin" and ev[1]["residents"] is None
    # time: seconds since the log's first second; sorted, the late line counted
    assert log.origin.source == "data"
    assert ev[1]["t"] - ev[2]["t"] == pytest.approx(0.309589, abs=1e-6)
    assert log.origin.as_dict()["origin"] == "2010-11-04T00:03:40Z"  # the earliest stamp's second (line 10's)
    assert log.events["t"].is_sorted()
    assert log.reordered == 1
    rej = dict(zip(log.rejects["line"].to_list(), log.rejects["reason"].to_list()))
    assert set(rej) == {7, 8, 9, 10, 12, 13}
    assert "'maybe' is not a motion value" in rej[7]
    assert "too few fields" in rej[8]
    assert "field 't'" in rej[9] or "field 'time'" in rej[9]
    assert "backwards" in rej[10]
    assert "duplicate of line 11" in rej[12]
    assert "lone time stamp" in rej[13]
    assert log.rejects.filter(pl.col("line") == 7)["raw"][0].endswith("maybe")


def test_every_value_spelling_is_read(tmp_path):
    rows = [
        ("ON", True),
        ("OFF", False),
        ("on", True),
        ("off", False),
        ("1", True),
        ("0", False),
        ("true", True),
        ("FALSE", False),
        ("OPEN", True),
        ("CLOSE", False),
        ("PRESENT", True),
        ("absent", False),
    ]
    text = "".join(f"2012-01-01 10:00:{k:02d}.000000\tM{k:03d}\t{v}\n" for k, (v, _) in enumerate(rows))
    log = read_casas(_write(tmp_path, text))
    assert log.rejects.height == 0
    assert log.events.sort("line")["on"].to_list() == [b for _, b in rows]


def test_the_fixture_home(tmp_path):
    """The generated one-resident home log: a few hundred lines, doors, repeated ON, late lines."""
    p = write_casas_log(tmp_path / "home.txt", seed=0)
    log = read_casas(p)
    assert 250 <= log.lines <= 500 and log.rejects.height == 0
    counts = log.kind_counts()
    assert counts["motion"] > 200 and counts["contact"] >= 6 and counts["temperature"] > 5
    assert log.reordered > 0  # stamps out of order by up to 0.7 s are sorted, not rejected
    on = log.events.filter(pl.col("kind") == "motion").sort("t")
    repeated = on.filter(pl.col("on") & (pl.col("on").shift(1).over("sensor") == True))  # noqa: E712
    assert repeated.height > 0  # repeated ON


def test_logs_info_describes_a_casas_log(tmp_path):
    p = write_casas_log(tmp_path / "home.txt", seed=1)
    info = log_info(p)
    by = {r["source"]: r for r in info.iter_rows(named=True)}
    assert {"home.txt", "home.txt:motion", "home.txt:contact", "home.txt:temperature", "home.txt:light"} <= set(by)
    assert by["home.txt:motion"]["sensors"] == 10 and by["home.txt:contact"]["sensors"] == 2
    assert by["home.txt"]["rows"] == sum(by[k]["rows"] for k in by if ":" in k and k.split(":")[1] in KIND_ROWS)
    assert by["home.txt"]["span_s"] > 300 and by["home.txt:motion"]["rate_hz"] > 0


def test_a_damaged_file_is_read_line_by_line(tmp_path):
    p = tmp_path / "bad.txt"
    p.write_bytes(b"\xff\xfe\x00garbage\n2012-01-01 10:00:00\tM001\tON\n\x00\x00\n")
    log = read_casas(p)
    assert log.events.height == 1 and log.rejects.height == 2


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lines=st.lists(st.text(alphabet=st.sampled_from("0123456789-: .\tMDTONFX"), max_size=40), max_size=30))
def test_any_text_reads_or_fails_cleanly(tmp_path, lines):
    p = _write(tmp_path, "\n".join(lines) + "\n", "fuzz.txt")
    try:
        log = read_casas(p)
    except OnebitError:
        return
    assert log.events.height + log.rejects.height == log.lines
