"""A run's CSV log (:class:`onebit.readers.logs.CsvLog`) owns its one typed read: the
time-origin step reads it and keeps it, the reader takes it, and the tables and rejects are
those of the reader on the plain path. A kept read is never served for another file state or
other types."""

from __future__ import annotations

import os
from pathlib import Path

import polars as pl
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from polars.testing import assert_frame_equal

from onebit.readers import logs
from onebit.readers.beams import beam_dtypes, read_beams
from onebit.readers.logs import CsvLog, csv_path, log_name, typed_stamps
from onebit.readers.motion import read_motion, toggle_dtypes
from onebit.readers.timebase import time_origin

SENSORS = ("m1", "m2")
LOG = "t,sensor,value\n0,m1,1\n1.5,m1,0\n2,m2,on\n2,m2,on\nx,m1,1\n3,m9,1\n4,m2,0\n"


def _counted(monkeypatch) -> list[str]:
    """The files read by the typed read of :mod:`onebit.readers.logs`, in order."""
    calls: list[str] = []
    real = logs.read_typed_csv

    def counted(path, dtypes):
        calls.append(Path(path).name)
        return real(path, dtypes)

    monkeypatch.setattr(logs, "read_typed_csv", counted)
    return calls


def _same(a, b) -> None:
    for name in ("motion", "rejects", "suppressed"):
        assert_frame_equal(getattr(a, name), getattr(b, name))
    assert (a.reordered, a.held) == (b.reordered, b.held)


def _origin(log):
    return time_origin({log_name(log): typed_stamps(log, toggle_dtypes(SENSORS))})


def test_the_origin_step_and_the_reader_read_the_file_once(tmp_path, monkeypatch):
    path = tmp_path / "motion.csv"
    path.write_text(LOG)
    plain = read_motion(path, SENSORS, epoch=_origin(path))  # a plain path: read by the reader
    calls = _counted(monkeypatch)
    log = CsvLog(path)
    origin = _origin(log)
    assert log.holds_read and calls == ["motion.csv"]
    _same(read_motion(log, SENSORS, epoch=origin), plain)
    assert not log.holds_read and calls == ["motion.csv"]  # taken, not read again; then dropped
    _same(read_motion(log, SENSORS, epoch=origin), plain)  # a second read reads the file
    assert calls == ["motion.csv", "motion.csv"]


def test_a_kept_read_is_not_served_for_a_file_that_changed(tmp_path):
    path = tmp_path / "motion.csv"
    path.write_text(LOG)
    log = CsvLog(path)
    origin = _origin(log)
    with path.open("a") as f:  # the log grows (onebit follow): the kept read is stale
        f.write("5,m1,1\n")
    res = read_motion(log, SENSORS, epoch=origin)
    assert 9 in res.rejects["line"].to_list()  # the new line was read (past the first read's clock: a lone stamp)
    _same(res, read_motion(path, SENSORS, epoch=origin))

    path.write_text(LOG.replace("1.5,m1", "1.6,m1"))  # same size, new content: the mtime says so
    st = path.stat()
    log.typed(toggle_dtypes(SENSORS))
    path.write_text(LOG)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))
    _same(read_motion(log, SENSORS, epoch=origin), read_motion(path, SENSORS, epoch=origin))


def test_a_kept_read_is_served_only_in_its_types(tmp_path, monkeypatch):
    path = tmp_path / "motion.csv"
    path.write_text(LOG)
    log = CsvLog(path)
    typed_stamps(log, toggle_dtypes(("m1",)))  # another sensor list: other enum types
    plain = read_motion(path, SENSORS, epoch=None)
    calls = _counted(monkeypatch)
    _same(read_motion(log, SENSORS, epoch=None), plain)
    assert calls == ["motion.csv"]
    assert typed_stamps(log, toggle_dtypes(SENSORS), keep=False) is not None and not log.holds_read


def test_a_csv_log_is_its_path(tmp_path):
    path = tmp_path / "beams.csv"
    path.write_text("t,beam,pair,blocked\n0,a,a,1\n0.1,a,b,1\n0.2,a,a,0\n0.3,a,b,0\n")
    log = CsvLog(path)
    assert Path(log) == path and csv_path(log) == path and csv_path(str(path)) == path
    assert log.name == log_name(log) == "beams.csv"
    origin = time_origin({"beams.csv": typed_stamps(log, beam_dtypes(("a",)))})
    a, b = read_beams(log, ("a",), epoch=origin), read_beams(path, ("a",), epoch=origin)
    for name in ("events", "crossings", "aborted", "unfinished", "rejects"):
        assert_frame_equal(getattr(a, name), getattr(b, name))
    assert a.crossings.height == 1 and not log.holds_read


stamp = st.sampled_from(["0", "0.5", "1", "1.25", "2", "3", "x", "", "90", "2.0"])
sensor = st.sampled_from(["m1", "m2", "m3", "M1", ""])
value = st.sampled_from(["0", "1", "on", "off", "ON", "2", ""])


@given(st.lists(st.tuples(stamp, sensor, value), max_size=30), st.booleans())
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_a_log_read_through_its_csv_log_is_read_as_its_path(tmp_path, rows, extra_field):
    path = tmp_path / "motion.csv"
    lines = [f"{t},{s},{v}" + (",z" if extra_field and i == 0 else "") for i, (t, s, v) in enumerate(rows)]
    path.write_text("t,sensor,value\n" + "".join(line + "\n" for line in lines))
    log = CsvLog(path)
    frames = typed_stamps(log, toggle_dtypes(SENSORS))
    origin = time_origin({"motion.csv": frames if frames is not None else pl.DataFrame(schema={"line": pl.Int64})})
    _same(read_motion(log, SENSORS, epoch=origin), read_motion(path, SENSORS, epoch=origin))
