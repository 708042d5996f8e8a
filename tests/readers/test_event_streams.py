"""Issue 12: random event streams through every reader.

Streams with empty stretches, out-of-order stamps, huge and tiny times (Unix seconds, 1e11,
1e-300, negative), ISO times and mixed value spellings go through every reader with the
run's time origin computed from the same stream. Nothing is lost -- accepted + rejected +
suppressed = input rows -- and nothing but an :class:`OnebitError` is ever raised.
"""

from __future__ import annotations

from pathlib import Path

import polars as pl
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit.core.errors import OnebitError
from onebit.core.tables import REJECTS
from onebit.readers.beams import decode_raw_beams
from onebit.readers.casas import read_casas
from onebit.readers.motion import DebounceRules, read_motion
from onebit.readers.proximity import read_proximity
from onebit.readers.rows import RawRows
from onebit.readers.tables_csv import crossings_from_rows, truth_from_rows
from onebit.readers.timebase import time_origin
from onebit.readers.trajectories import read_trajectories

SENSORS = ("s1", "s2", "s3")
VALUES = ("ON", "OFF", "on", "off", "1", "0", "true", "False", "OPEN", "CLOSE", "PRESENT", "absent", "maybe", "", "2")

base = st.sampled_from([0.0, 1.7e9, 1.3e9])
offsets = st.one_of(
    st.floats(min_value=-5.0, max_value=600.0, allow_nan=False),  # small and out of order
    st.floats(min_value=3000.0, max_value=10000.0),  # an empty stretch
    st.sampled_from([1e11, -1e11, 1e-300, 5e-324, 1e300]),  # huge and tiny
)


@st.composite
def streams(draw):
    b = draw(base)
    n = draw(st.integers(0, 25))
    rows = []
    for _ in range(n):
        kind = draw(st.sampled_from(["num", "num", "num", "iso", "junk"]))
        off = draw(offsets)
        if kind == "num":
            t = repr(b + off)
        elif kind == "iso":
            sec = int(min(max(off, 0.0), 86000.0))
            t = f"2024-05-01 {sec // 3600:02d}:{sec % 3600 // 60:02d}:{sec % 60:02d}.{draw(st.integers(0, 999999)):06d}"
        else:
            t = draw(st.sampled_from(["", "x", "nan", "inf", "-inf", "1e400"]))
        rows.append((t, draw(st.sampled_from(SENSORS + ("zz",))), draw(st.sampled_from(VALUES))))
    return rows


def _raw(rows, cols=("t", "sensor", "value")) -> RawRows:
    frame = pl.DataFrame(
        {
            "line": list(range(2, 2 + len(rows))),
            **{c: [r[i] for r in rows] for i, c in enumerate(cols)},
            "raw": [None] * len(rows),
        },
        schema={"line": pl.Int64, **{c: pl.String for c in cols}, "raw": pl.String},
    )
    return RawRows("stream.csv", frame, pl.DataFrame(schema=REJECTS))


def _origin(rows):
    return time_origin(
        {
            "stream.csv": pl.DataFrame(
                {"line": list(range(2, 2 + len(rows))), "t": [r[0] for r in rows]},
                schema={"line": pl.Int64, "t": pl.String},
            )
        }
    )


def _casas_stamp(t: str) -> str:
    """A CASAS wall-clock stamp for a stream stamp (junk stays junk)."""
    try:
        v = float(t)
    except ValueError:
        return t
    if v != v or abs(v) == float("inf"):
        return t
    sec = int(abs(v)) % 86400
    return f"2011-06-15 {sec // 3600:02d}:{sec % 3600 // 60:02d}:{sec % 60:02d}.{int(abs(v) * 1e6) % 1000000:06d}"


SETTINGS = settings(max_examples=35, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@SETTINGS
@given(rows=streams(), chatter=st.sampled_from([0.0, 0.3]))
def test_toggle_readers(rows, chatter):
    try:
        origin = _origin(rows)
        for read in (read_motion, read_proximity):
            res = read(_raw(rows), SENSORS, epoch=origin, rules=DebounceRules(chatter_window=chatter, min_on=chatter))
            assert res.motion.height + res.rejects.height + res.suppressed.height == len(rows)
            assert res.motion["t"].is_sorted()
            assert res.rejects.schema == REJECTS
    except OnebitError:
        pass


@SETTINGS
@given(rows=streams())
def test_beam_crossing_and_truth_readers(rows):
    beam_rows = [
        (t, "a" if s != "zz" else "zz", "a" if v.lower() in ("on", "1", "true") else "b", v) for t, s, v in rows
    ]
    try:
        origin = _origin(rows)
        dec = decode_raw_beams(_raw(beam_rows, ("t", "beam", "pair", "blocked")), ("a",), epoch=origin)
        assert dec.events.height + dec.rejects.height == len(rows)
        cr, rej = crossings_from_rows(
            _raw([(t, "a", v) for t, _, v in rows], ("t", "beam", "direction")), ("a",), epoch=origin
        )
        assert cr.height + rej.height == len(rows)
        tr, rej = truth_from_rows(_raw([(t, s, v, "1.0") for t, s, v in rows], ("t", "target", "x", "y")), epoch=origin)
        assert tr.height + rej.height == len(rows)
    except OnebitError:
        pass


@SETTINGS
@given(rows=streams())
def test_casas_and_trajectory_readers(tmp_path_factory, rows):
    tmp = tmp_path_factory.mktemp("streams")
    iso = [(_casas_stamp(t), s, v) for t, s, v in rows]
    casas = tmp / "log.txt"
    casas.write_text(
        "".join(f"{t}\t{'M00' + s[-1] if s != 'zz' else 'T001'}\t{v}\n" for t, s, v in iso), encoding="utf-8"
    )
    traj = Path(tmp / "walks.csv")
    traj.write_text("t,id,x,y\n" + "".join(f"{t},{s},{v or 0},1\n" for t, s, v in rows), encoding="utf-8")
    try:
        log = read_casas(casas)
        assert log.events.height + log.rejects.height == log.lines
    except OnebitError:
        pass
    try:
        r = read_trajectories(traj)
        assert r.truth.height + r.rejects.height == len(rows)
    except OnebitError:
        pass
