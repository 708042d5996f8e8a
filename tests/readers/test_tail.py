"""The incremental readers of ``onebit follow`` (onebit/readers/tail.py): a log cut at random
byte offsets and fed chunk by chunk gives, concatenated, exactly one batch read's tables and
rejects (with their line numbers)."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import polars as pl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit.core.errors import InputError
from onebit.readers.beams import decode_beam_log
from onebit.readers.motion import DebounceRules, read_motion_csv
from onebit.readers.tables_csv import read_crossings_csv
from onebit.readers.tail import BeamTail, CrossingTail, CsvTail, ToggleTail
from onebit.readers.timebase import TimeOrigin

SENSORS = ("p1", "p2", "p3")
BEAMS = ("b1", "b2")
ORIGIN = TimeOrigin(origin=100.0, numeric=100.0, lo=-50.0, hi=math.inf, source="data")


def _cuts(draw, data: bytes) -> list[bytes]:
    """``data`` split at random byte offsets (some chunks empty, some mid-line, mid-CRLF)."""
    n = draw(st.integers(0, 8))
    at = sorted(draw(st.lists(st.integers(0, len(data)), min_size=n, max_size=n)))
    bounds = [0, *at, len(data)]
    return [data[a:b] for a, b in zip(bounds, bounds[1:])]


def _stamp(draw, t: float) -> str:
    return draw(st.sampled_from([f"{t + 100.0:.3f}", f"{t + 100.0:.2f}"]))


@st.composite
def toggle_logs(draw):
    """A messy toggle log: alternating edges, repeats, chatter and short pulses, rows out of
    order within and beyond the 1 s tolerance, duplicates, bad fields, unknown sensors, lone
    stamps, blank and ragged lines, CRLF endings, and maybe no final newline."""
    lines = ["t,sensor,value"]
    t = 0.0
    for _ in range(draw(st.integers(0, 40))):
        kind = draw(st.sampled_from(["edge"] * 8 + ["back", "dup", "bad", "blank", "ragged", "unknown", "lone"]))
        t += draw(st.sampled_from([0.0, 0.02, 0.05, 0.1, 0.3, 0.7, 1.5]))
        s = draw(st.sampled_from(SENSORS))
        v = draw(st.sampled_from(["1", "0", "on", "off"]))
        if kind == "edge":
            lines.append(f"{_stamp(draw, t)},{s},{v}")
        elif kind == "back":
            lines.append(f"{_stamp(draw, max(t - draw(st.sampled_from([0.5, 1.0, 2.5])), 0.0))},{s},{v}")
        elif kind == "dup" and len(lines) > 1:
            lines.append(draw(st.sampled_from(lines[1:])))
        elif kind == "bad":
            lines.append(f"{_stamp(draw, t)},{s},maybe")
        elif kind == "blank":
            lines.append(draw(st.sampled_from(["", "  "])))
        elif kind == "ragged":
            lines.append(f"{_stamp(draw, t)},{s}")
        elif kind == "unknown":
            lines.append(f"{_stamp(draw, t)},zz,{v}")
        elif kind == "lone":
            lines.append(f"1.0,{s},{v}")
    eol = draw(st.sampled_from(["\n", "\r\n"]))
    text = eol.join(lines) + draw(st.sampled_from([eol, ""]))
    rules = {
        s: DebounceRules(
            chatter_window=draw(st.sampled_from([0.0, 0.05, 0.3])), min_on=draw(st.sampled_from([0.0, 0.1, 0.7]))
        )
        for s in SENSORS
    }
    held = frozenset(draw(st.sets(st.sampled_from(SENSORS), max_size=1)))
    data = text.encode()
    return data, _cuts(draw, data), rules, held


def _cat(parts: list[pl.DataFrame], like: pl.DataFrame) -> pl.DataFrame:
    return pl.concat(parts) if parts else like.clear()


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(toggle_logs())
def test_toggle_tail_equals_one_batch_read(log):
    data, chunks, rules, held = log
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "motion.csv"
        path.write_bytes(data)
        batch = read_motion_csv(path, SENSORS, epoch=ORIGIN, rules=rules, held=held)
    tail = ToggleTail("motion.csv", SENSORS, origin=ORIGIN, rules=rules, held=held)
    outs = [tail.feed(c) for c in chunks]
    emitted = sum(o.motion.height for o in outs)
    # what is out is settled: every batch row before settled_until has been emitted
    before = batch.motion.filter(pl.col("t") < tail.settled_until).height
    assert emitted >= before
    outs.append(tail.finish())
    motion = _cat([o.motion for o in outs], batch.motion)
    assert motion.equals(batch.motion)
    assert _cat([o.suppressed for o in outs], batch.suppressed).equals(batch.suppressed)
    rejects = _cat([o.rejects for o in outs], batch.rejects)
    assert rejects.equals(batch.rejects), (rejects, batch.rejects)
    assert sum(o.held for o in outs) == batch.held
    assert sum(o.reordered for o in outs) == batch.reordered
    assert tail.settled_until == math.inf


@st.composite
def beam_logs(draw):
    lines = ["t,beam,pair,blocked"]
    t = 0.0
    for _ in range(draw(st.integers(0, 40))):
        kind = draw(st.sampled_from(["edge"] * 8 + ["back", "dup", "bad", "blank"]))
        t += draw(st.sampled_from([0.0, 0.1, 0.4]))
        b, p, v = draw(st.sampled_from(BEAMS)), draw(st.sampled_from("ab")), draw(st.sampled_from("01"))
        if kind == "edge":
            lines.append(f"{_stamp(draw, t)},{b},{p},{v}")
        elif kind == "back":
            lines.append(f"{_stamp(draw, max(t - 0.5, 0.0))},{b},{p},{v}")
        elif kind == "dup" and len(lines) > 1:
            lines.append(draw(st.sampled_from(lines[1:])))
        elif kind == "bad":
            lines.append(f"{_stamp(draw, t)},{b},c,{v}")
        elif kind == "blank":
            lines.append("")
    data = ("\n".join(lines) + draw(st.sampled_from(["\n", ""]))).encode()
    return data, _cuts(draw, data)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(beam_logs())
def test_beam_tail_equals_one_batch_read(log):
    data, chunks = log
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "beams.csv"
        path.write_bytes(data)
        batch = decode_beam_log(path, BEAMS, epoch=ORIGIN)
    tail = BeamTail("beams.csv", BEAMS, origin=ORIGIN)
    outs = [tail.feed(c) for c in chunks]
    outs.append(tail.finish())
    assert _cat([o.events for o in outs], batch.events).equals(batch.events)
    assert _cat([o.crossings for o in outs], batch.crossings).equals(batch.crossings)
    assert _cat([o.aborted for o in outs], batch.aborted).equals(batch.aborted)
    assert _cat([o.rejects for o in outs], batch.rejects).equals(batch.rejects)
    assert outs[-1].unfinished.equals(batch.unfinished)


@st.composite
def crossing_logs(draw):
    lines = ["t,beam,direction"]
    t = 0.0
    for _ in range(draw(st.integers(0, 30))):
        kind = draw(st.sampled_from(["row"] * 6 + ["back", "dup", "bad"]))
        t += draw(st.sampled_from([0.0, 0.2, 1.0]))
        b, d = draw(st.sampled_from(BEAMS)), draw(st.sampled_from(["1", "-1"]))
        if kind == "row":
            lines.append(f"{_stamp(draw, t)},{b},{d}")
        elif kind == "back":
            lines.append(f"{_stamp(draw, max(t - 0.5, 0.0))},{b},{d}")
        elif kind == "dup" and len(lines) > 1:
            lines.append(draw(st.sampled_from(lines[1:])))
        elif kind == "bad":
            lines.append(f"{_stamp(draw, t)},{b},2")
    data = ("\n".join(lines) + draw(st.sampled_from(["\n", ""]))).encode()
    return data, _cuts(draw, data)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(crossing_logs())
def test_crossing_tail_equals_one_batch_read(log):
    data, chunks = log
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "crossings.csv"
        path.write_bytes(data)
        crossings, rejects = read_crossings_csv(path, BEAMS, epoch=ORIGIN)
    tail = CrossingTail("crossings.csv", BEAMS, origin=ORIGIN)
    outs = [tail.feed(c) for c in chunks]
    outs.append(tail.finish())
    assert _cat([o.crossings for o in outs], crossings).equals(crossings)
    assert _cat([o.rejects for o in outs], rejects).equals(rejects)


def test_a_line_being_written_waits_for_its_newline():
    tail = CsvTail("motion.csv", ("t", "sensor", "value"))
    assert tail.feed(b"t,sensor,value\n100.0,p1,1\n100.5,p").frame["line"].to_list() == [2]
    assert tail.feed(b"2").frame.height == 0  # still no newline: not a row, not a reject
    rows = tail.feed(b",0\n")
    assert rows.frame.select("line", "sensor", "value").rows() == [(3, "p2", "0")]
    assert rows.rejects.height == 0


def test_a_chattering_sensor_keeps_a_bounded_tail():
    """A sensor chattering for a long time: every chatter pair is settled when its on edge
    arrives, so the rows waiting stay few however long the chain (and the batch agrees)."""
    rules = DebounceRules(chatter_window=0.1, min_on=0.5)
    tail = ToggleTail("motion.csv", ("p1",), origin=ORIGIN, rules=rules)
    tail.feed(b"t,sensor,value\n100.0,p1,1\n")
    body, waiting = [], []
    for k in range(1, 120):
        t = 100.0 + k * 0.3
        chunk = f"{t:.2f},p1,0\n{t + 0.05:.2f},p1,1\n"
        body.append(chunk)
        tail.feed(chunk.encode())
        waiting.append(len(tail.edges) + len(tail.order.heap))
    assert max(waiting) < 20
    out = tail.finish()
    assert out.motion.height == 0 or out.motion["t"].min() >= 0.0
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "motion.csv"
        path.write_text("t,sensor,value\n100.0,p1,1\n" + "".join(body))
        batch = read_motion_csv(path, ("p1",), epoch=ORIGIN, rules=rules)
    assert batch.motion.height == 1 and batch.suppressed.height == 2 * 119


def test_a_line_that_never_ends_is_refused_naming_it(monkeypatch):
    import onebit.readers.tail as tail_module

    monkeypatch.setattr(tail_module, "MAX_LINE_BYTES", 64)
    tail = CsvTail("motion.csv", ("t", "sensor", "value"))
    tail.feed(b"t,sensor,value\n100.0,p1,1\n")
    tail.feed(b"x" * 40)
    with pytest.raises(InputError, match="line longer") as err:
        tail.feed(b"x" * 40)
    assert err.value.line == 3


def test_a_bad_header_names_the_file_and_line():
    tail = CsvTail("motion.csv", ("t", "sensor", "value"))
    with pytest.raises(InputError, match="missing column"):
        tail.feed(b"\ntime,sensor,value\n")


def test_a_duplicate_far_back_is_named_from_the_archive():
    """Keys far behind the newest stamp leave the dict for compact arrays; a row repeating one
    (it also goes backwards) is still a duplicate of its first line, as in the batch read."""
    tail = ToggleTail("motion.csv", ("p1", "p2"), origin=ORIGIN)
    tail.feed(b"t,sensor,value\n100.0,p1,1\n100.5,p2,1\n")
    for k in range(1, 40):
        tail.feed(f"{100.0 + 5 * k:.1f},p1,{k % 2 ^ 1}\n".encode())
    assert len(tail.order.seen.recent) < 5 and len(tail.order.seen) == 41
    rej = tail.feed(b"100.5,p2,1\n100.5,p2,0\n").rejects
    rej = pl.concat([rej, tail.finish().rejects])
    assert rej.select("line", "reason").rows() == [
        (43, "duplicate of line 3 (same t, sensor and value)"),
        (44, "timestamp goes backwards (0.5 after 195.0, more than 1.0 s)"),
    ]
