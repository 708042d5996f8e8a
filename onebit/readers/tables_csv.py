"""Readers of already-canonical logs: ``crossings.csv``, ``truth.csv``, ``truth_crossings.csv``, ``truth_events.csv``.

Each log has one reader of its CSV file or its MCAP channel's rows (:data:`~onebit.readers.logs.Log`):
:func:`read_crossings`, :func:`read_truth`, :func:`read_true_crossings`, :func:`read_truth_events`.
A CSV file is typed in one read (``read_*_csv``), only the lines that read cannot take row by
row; an MCAP channel's rows are typed row by row (``*_from_rows``). Each returns
``(table, rejects)``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.core.tables import (
    COUNT_PROFILE,
    CROSSINGS,
    RESIDENTS_PROFILE,
    TRUE_CROSSINGS,
    TRUTH,
    TRUTH_COUNT,
    TRUTH_EVENTS,
    conform,
)
from onebit.readers.logs import Log, csv_path
from onebit.readers.rows import (
    RawRows,
    TypedRows,
    check_split,
    header_names,
    parse_choice,
    parse_float,
    parse_name,
    parse_time,
    read_csv_rows,
    read_typed_csv,
    type_rows,
)
from onebit.readers.timebase import TimeOrigin

_FLAG = {"0": False, "1": True, "false": False, "true": True}
_DIRECTION = {"1": 1, "+1": 1, "-1": -1, "f": 1, "b": -1, "forward": 1, "backward": -1}


def _crossing_parsers(beam_ids, epoch, frame: pl.DataFrame, *, target: bool = False) -> dict:
    parsers = {
        "t": parse_time("t", epoch, frame),
        "beam": parse_name("beam", tuple(beam_ids), "beam"),
        "direction": parse_choice("direction", _DIRECTION, pl.Int8),
    }
    if target:
        parsers["target"] = parse_name("target", None, "target")
    return parsers


def crossings_from_rows(raw: RawRows, beam_ids, *, epoch=None, path: Path | None = None):
    """Type crossing rows: t, known beam, direction +1|-1. Returns ``(crossings, rejects)``."""
    ok, rej = type_rows(raw, _crossing_parsers(beam_ids, epoch, raw.frame), key=("t", "beam", "direction"), path=path)
    return conform(ok, CROSSINGS), rej


def true_crossings_from_rows(raw: RawRows, beam_ids, *, epoch=None, path: Path | None = None):
    """Type true-crossing rows; a ``dropped`` column (simulator flag 0|1), when read, is kept."""
    parsers = _crossing_parsers(beam_ids, epoch, raw.frame, target=True)
    if "dropped" in raw.frame.columns:
        parsers["dropped"] = parse_choice("dropped", _FLAG, pl.Boolean)
    ok, rej = type_rows(raw, parsers, key=("t", "beam", "direction", "target"), path=path)
    out = conform(ok, TRUE_CROSSINGS)
    return (out.with_columns(ok["dropped"]) if "dropped" in parsers else out), rej


def true_crossings_columns(path: Path) -> tuple[str, ...]:
    """Columns to read from ``truth_crossings.csv``: TRUE_CROSSINGS, plus ``dropped`` if the header has it."""
    base = tuple(TRUE_CROSSINGS.names())
    try:
        header = header_names(path)[0]
    except InputError:
        return base  # absent or unreadable: read_csv_rows reports it
    return base + ("dropped",) if "dropped" in header else base


def _truth_parsers(epoch, frame: pl.DataFrame) -> dict:
    return {
        "t": parse_time("t", epoch, frame),
        "target": parse_name("target", None, "target"),
        "x": parse_float("x"),
        "y": parse_float("y"),
    }


def truth_from_rows(raw: RawRows, *, epoch=None, path: Path | None = None):
    """Type truth rows: t, target, x, y (world units). Returns ``(truth, rejects)``.

    Time order is checked per file; a target may appear at most once per time stamp.
    """
    ok, rej = type_rows(raw, _truth_parsers(epoch, raw.frame), key=("t", "target"), path=path)
    return conform(ok, TRUTH), rej


#: The typed read of a direction: its spellings (``_DIRECTION``) as an enum, and their values.
_DIRECTION_ENUM = pl.Enum(list(_DIRECTION))
_DIRECTION_VALUES = pl.Series(list(_DIRECTION.values()), dtype=pl.Int8)


def _typed_crossings(path: Path, beam_ids, *, epoch, target: bool) -> TypedRows | None:
    """Crossing rows of ``path`` by one typed read, the lines it cannot take typed row by row
    (:func:`~onebit.readers.rows.read_typed_csv`); ``None``: the row-by-row path reads the file."""
    beam_ids = tuple(beam_ids)
    dtypes = {"t": pl.Float64, "beam": pl.Enum(list(dict.fromkeys(beam_ids))), "direction": _DIRECTION_ENUM}
    if target:
        dtypes["target"] = pl.String
    split = read_typed_csv(path, dtypes)
    if split is None:
        return None
    good = split.good.with_columns(_DIRECTION_VALUES.gather(split.good["direction"].to_physical()).alias("direction"))
    key = ("t", "beam", "direction", "target") if target else ("t", "beam", "direction")
    return check_split(
        split,
        good,
        lambda origin, frame: _crossing_parsers(beam_ids, origin, frame, target=target),
        epoch=epoch,
        key=key,
        tolerance=0.0,
        path=path,
    )


def read_crossings_csv(path, beam_ids, *, epoch=None):
    """``crossings.csv``: typed in one read, only the lines that read cannot take row by row
    (same result as :func:`crossings_from_rows` of :func:`~onebit.readers.rows.read_csv_rows`)."""
    path = Path(path)
    typed = _typed_crossings(path, beam_ids, epoch=epoch, target=False)
    if typed is None:
        return crossings_from_rows(read_csv_rows(path, ("t", "beam", "direction")), beam_ids, epoch=epoch, path=path)
    return conform(typed.accepted, CROSSINGS), typed.rejects


def read_true_crossings_csv(path, beam_ids, *, epoch=None):
    """``truth_crossings.csv`` (t, beam, direction, target), as :func:`read_crossings_csv`."""
    path = Path(path)
    typed = _typed_crossings(path, beam_ids, epoch=epoch, target=True)
    if typed is None:
        return true_crossings_from_rows(
            read_csv_rows(path, ("t", "beam", "direction", "target")), beam_ids, epoch=epoch, path=path
        )
    return conform(typed.accepted, TRUE_CROSSINGS), typed.rejects


def read_truth_csv(path, *, epoch=None):
    """``truth.csv`` (t, target, x, y), as :func:`read_crossings_csv`."""
    path = Path(path)
    split = read_typed_csv(path, {"t": pl.Float64, "target": pl.String, "x": pl.Float64, "y": pl.Float64})
    if split is None:
        return truth_from_rows(read_csv_rows(path, ("t", "target", "x", "y")), epoch=epoch, path=path)
    typed = check_split(split, split.good, _truth_parsers, epoch=epoch, key=("t", "target"), tolerance=0.0, path=path)
    return conform(typed.accepted, TRUTH), typed.rejects


def _residents(col: str) -> tuple[pl.Expr, pl.Expr]:
    """Resident ids separated by ``;`` (spaces and empty ids dropped), sorted as text and
    joined with ``;`` -- the canonical ``residents`` of :data:`~onebit.core.tables.TRUTH_EVENTS`."""
    ids = pl.col(col).str.split(";").list.eval(pl.element().str.strip_chars()).list.filter(pl.element() != "")
    value = ids.list.unique().list.sort().list.join(";")
    reason = pl.when(pl.col(col).is_null() | (value == "")).then(pl.lit(f"field '{col}': no resident id"))
    return value, reason.otherwise(None)


def truth_events_from_rows(raw: RawRows, *, epoch=None, path: Path | None = None):
    """Type ``truth_events.csv`` rows: t, sensor, residents (``1;2``). Returns ``(truth_events, rejects)``.

    The log is a toggle log (CASAS stamps are up to 0.7 s out of order): rows up to 1 s back
    are sorted into place; an identical (t, sensor) row is a duplicate."""
    parsers = {
        "t": parse_time("t", epoch, raw.frame),
        "sensor": parse_name("sensor", None, "sensor"),
        "residents": _residents("residents"),
    }
    ok, rej = type_rows(raw, parsers, key=("t", "sensor"), path=path, tolerance=1.0)
    return conform(ok, TRUTH_EVENTS), rej


def read_truth_events_csv(path, *, epoch=None):
    """``truth_events.csv`` (t, sensor, residents): the per-event identity truth written by
    ``onebit import casas`` (the CASAS resident annotations), as :data:`~onebit.core.tables.TRUTH_EVENTS`.
    Returns ``(truth_events, rejects)``; every line not taken is a reject with its reason."""
    path = Path(path)
    return truth_events_from_rows(read_csv_rows(path, tuple(TRUTH_EVENTS.names())), epoch=epoch, path=path)


def read_crossings(log: Log, beam_ids, *, epoch=None) -> tuple[pl.DataFrame, pl.DataFrame]:
    """The crossings reader: ``crossings.csv`` (:func:`read_crossings_csv`) or an MCAP
    ``/crossings`` channel's rows (:func:`crossings_from_rows`)."""
    if isinstance(log, RawRows):
        return crossings_from_rows(log, beam_ids, epoch=epoch)
    return read_crossings_csv(csv_path(log), beam_ids, epoch=epoch)


def read_truth(log: Log, *, epoch=None) -> tuple[pl.DataFrame, pl.DataFrame]:
    """The truth reader: ``truth.csv`` (:func:`read_truth_csv`) or an MCAP ``/truth`` channel's
    rows (:func:`truth_from_rows`)."""
    if isinstance(log, RawRows):
        return truth_from_rows(log, epoch=epoch)
    return read_truth_csv(csv_path(log), epoch=epoch)


def read_true_crossings(log: Log, beam_ids, *, epoch=None) -> tuple[pl.DataFrame, pl.DataFrame]:
    """The true-crossings reader: ``truth_crossings.csv`` (:func:`read_true_crossings_csv`; row
    by row when it has the simulator's ``dropped`` column, which is kept) or an MCAP
    ``/truth_crossings`` channel's rows (:func:`true_crossings_from_rows`)."""
    if isinstance(log, RawRows):
        return true_crossings_from_rows(log, beam_ids, epoch=epoch)
    log = csv_path(log)
    columns = true_crossings_columns(log)
    if "dropped" in columns:
        return true_crossings_from_rows(read_csv_rows(log, columns), beam_ids, epoch=epoch, path=log)
    return read_true_crossings_csv(log, beam_ids, epoch=epoch)


def read_truth_events(log: Log, *, epoch=None) -> tuple[pl.DataFrame, pl.DataFrame]:
    """The per-event identity truth reader: ``truth_events.csv`` (:func:`read_truth_events_csv`)
    or an MCAP ``/truth_events`` channel's rows (:func:`truth_events_from_rows`)."""
    if isinstance(log, RawRows):
        return truth_events_from_rows(log, epoch=epoch)
    return read_truth_events_csv(csv_path(log), epoch=epoch)


#: A profile row's ``bin``: ``session k/n`` or ``day k/n`` with ``0 <= k < n``.
PROFILE_BIN = r"^(session|day) ([0-9]+)/([0-9]+)$"


def residents_profile_from_rows(raw: RawRows, *, path: Path | None = None):
    """Type ``residents_profile.csv`` rows: resident, from (empty: the resident's habit row), to,
    count (a finite number >= 0), bin (empty, or ``session k/n`` / ``day k/n`` on a habit row).
    Returns ``(residents_profile, rejects)``; a second row with the same resident, from, to and
    bin is a duplicate (rejected, counted)."""
    frm = pl.col("from").str.strip_chars()
    cnt, cnt_bad = parse_float("count")
    b = pl.col("bin").str.strip_chars()
    k, n = b.str.extract(PROFILE_BIN, 2).cast(pl.Int64), b.str.extract(PROFILE_BIN, 3).cast(pl.Int64)
    bin_bad = (
        pl.when(b.is_null() | (b == ""))
        .then(None)
        .when(k.is_null() | (k >= n))
        .then(pl.format("field 'bin': '{}' is not 'session k/n' or 'day k/n' with 0 <= k < n", b))
        .when(frm != "")
        .then(pl.lit("field 'bin': only on a habit row (empty 'from')"))
    )
    parsers = {
        "resident": parse_name("resident", None, "resident"),
        "from": (pl.when(frm == "").then(None).otherwise(frm), pl.lit(None, pl.String)),
        "to": parse_name("to", None, "sensor"),
        "count": (cnt, pl.coalesce(cnt_bad, pl.when(cnt < 0).then(pl.format("field 'count': negative: {}", cnt)))),
        "bin": (pl.when(b == "").then(None).otherwise(b), bin_bad),
    }
    ok, rej = type_rows(raw, parsers, key=("resident", "from", "to", "bin"), path=path)
    return conform(ok, RESIDENTS_PROFILE), rej


def read_residents_profile_csv(path):
    """``residents_profile.csv`` (resident, from, to, count) as
    :data:`~onebit.core.tables.RESIDENTS_PROFILE`; every line not taken is a reject with its reason."""
    path = Path(path)
    header, _ = header_names(path)
    cols = tuple(c for c in RESIDENTS_PROFILE.names() if c != "bin" or "bin" in [h.strip() for h in header])
    raw = read_csv_rows(path, cols)
    if "bin" not in cols:  # a profile without a clock (the column may be left out)
        raw = RawRows(raw.source, raw.frame.with_columns(bin=pl.lit(None, pl.String)), raw.rejects)
    return residents_profile_from_rows(raw, path=path)


def truth_count_from_rows(raw: RawRows, *, epoch=None, path: Path | None = None):
    """Type ``truth_count.csv`` rows: ``t`` and ``end`` (seconds or ISO times, ``end > t``),
    ``count`` (a whole number >= 0) -- people in over ``[t, end)``. Returns ``(truth_count,
    rejects)``; an interval that starts before the previous one ends is rejected (overlap)."""
    cnt, cnt_bad = parse_float("count")
    # an interval may start before the first logged stamp and end after the last: the run's
    # window of accepted stamps is not applied to it
    open_ = replace(epoch, lo=-math.inf, hi=math.inf) if isinstance(epoch, TimeOrigin) else epoch
    end, end_bad = parse_time("end", open_, raw.frame)
    t, t_bad = parse_time("t", open_, raw.frame)
    parsers = {
        "t": (t, t_bad),
        "end": (end, pl.coalesce(end_bad, pl.when(end <= t).then(pl.format("field 'end': not after t: {}", end)))),
        "count": (
            cnt.cast(pl.Int64, strict=False),
            pl.coalesce(
                cnt_bad,
                pl.when((cnt < 0) | (cnt != cnt.round(0)))
                .then(pl.format("field 'count': not a whole number >= 0: {}", cnt))
                .otherwise(None),
            ),
        ),
    }
    ok, rej = type_rows(raw, parsers, key=("t",), path=path)
    ok = conform(ok, TRUTH_COUNT).sort("t")
    overlap = ok["t"].to_numpy()[1:] < ok["end"].to_numpy()[:-1] - 1e-9 if ok.height > 1 else []
    if len(overlap) and overlap.any():
        import numpy as np

        bad = np.r_[False, overlap]
        extra = pl.DataFrame(
            {
                "source": raw.source,
                "line": pl.Series([None] * int(bad.sum()), dtype=pl.Int64),
                "reason": "an interval that starts before the previous one ends (overlap)",
                "raw": [f"{a},{b},{c}" for a, b, c in ok.filter(pl.Series(bad)).iter_rows()],
            }
        )
        ok = ok.filter(~pl.Series(bad))
        rej = pl.concat([rej, extra.cast(rej.schema)]) if rej.height else extra
    return ok, rej


def read_truth_count_csv(path, *, epoch=None):
    """``truth_count.csv`` (t, end, count): how many people are in, as intervals
    (:data:`~onebit.core.tables.TRUTH_COUNT`); every line not taken is a reject with its reason."""
    path = Path(path)
    return truth_count_from_rows(read_csv_rows(path, tuple(TRUTH_COUNT.names())), epoch=epoch, path=path)


def read_count_profile_csv(path):
    """``count_profile.csv`` (term, state, key, count): the count model's statistics learned by
    ``onebit learn residents`` (:data:`~onebit.core.tables.COUNT_PROFILE`)."""
    path = Path(path)
    raw = read_csv_rows(path, tuple(COUNT_PROFILE.names()))
    cnt, cnt_bad = parse_float("count")
    st, st_bad = parse_float("state")
    terms = ("bins", "active", "far", "fired", "held", "hour", "door", "quiet", "start")
    parsers = {
        "term": parse_name("term", terms, "term"),
        "state": (
            st.cast(pl.Int64, strict=False),
            pl.coalesce(st_bad, pl.when((st < 0) | (st != st.round(0))).then(pl.lit("field 'state': not a count"))),
        ),
        "key": (pl.col("key").fill_null("").str.strip_chars(), pl.lit(None, pl.String)),
        "count": (cnt, pl.coalesce(cnt_bad, pl.when(cnt < 0).then(pl.format("field 'count': negative: {}", cnt)))),
    }
    ok, rej = type_rows(raw, parsers, key=("term", "state", "key"), path=path)
    return conform(ok, COUNT_PROFILE), rej
