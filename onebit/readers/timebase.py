"""The time base of a run: one origin for every table, chosen once from the raw logs.

Every canonical table carries ``t`` = seconds since the run's **time origin**. Raw logs give
their stamps either as numbers (seconds: relative, or Unix seconds like ``1.7e9``) or as ISO
wall-clock strings (``2010-11-04 00:03:50.209589``, ``2024-05-01T10:00:00Z``, an offset
``+01:00``; naive times are taken as they are written, i.e. as UTC). On one common
"absolute" scale -- numbers as written, ISO stamps as Unix seconds -- the origin is:

* ``epoch`` set in ``site.toml``: the epoch. ISO stamps are measured from it; numbers are
  seconds since it and are taken as they are (``source = "epoch"``);
* otherwise the **data's own start**: the earliest stamp of all the run's logs, floored to a
  whole second (``source = "data"``). Numbers and ISO stamps are both measured from it, so
  ``t`` starts within the first second whatever the logs' clock (relative seconds starting
  at 0 keep their values).

Absurd spans
------------
A lone stamp far from the rest (a row with ``t = 1e11`` in a log of Unix seconds, a stray
``0`` among them) would stretch every slot array a tracker builds over the span. The stamps
of all logs, sorted, are cut into clusters wherever two consecutive stamps are more than
``max_gap_s`` apart (default one day: a smart-home log may be silent all night). Clusters at
either end of the time line holding at most ``max(1, lone_fraction * n)`` of the ``n``
stamps (default 1 %) are *lone*: their rows are rejected by the readers (``rejects``, with a
reason naming the field ``t`` and the accepted window), the rest is the accepted window
``[lo, hi]``. If what remains still spans more than ``max_span_s`` (default 366 days: two
large clusters from different clocks, say), the run stops with an
:class:`~onebit.core.errors.InputError` naming the file, the line and the field of the
stamps at both ends. Nothing here allocates anything sized by the span.

The runner calls :func:`run_time_origin` once per run (every source of the dataset, before
the first reader stage), passes the :class:`TimeOrigin` as ``epoch=`` to every reader and
records :meth:`TimeOrigin.as_dict` in ``run.toml`` (``[time]``).

Examples
--------
>>> import polars as pl
>>> o = time_origin({"motion.csv": pl.DataFrame({"line": [2, 3, 4], "t": ["1700000000.5", "1700000010", "1e11"]})})
>>> o.source, o.origin, o.lo, o.hi, o.lone
('data', 1700000000.0, 0.5, 10.0, 1)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np
import polars as pl

from onebit.core.errors import InputError

#: Formats tried, in order, on an ISO stamp (after ``T`` -> space and ``Z`` -> ``+00:00``).
ISO_FORMATS = ("%Y-%m-%d %H:%M:%S%.f", "%Y-%m-%d %H:%M:%S%.f%z", "%Y-%m-%d %H:%M", "%Y-%m-%d %H:%M%z")

#: Consecutive stamps further apart than this (s) start a new cluster.
MAX_GAP_S = 86_400.0
#: A cluster at either end with at most this fraction of the stamps (and at least 1) is lone.
LONE_FRACTION = 0.01
#: A run whose accepted stamps span more than this (s) is refused.
MAX_SPAN_S = 366 * 86_400.0


def iso_unix_us(expr: pl.Expr) -> pl.Expr:
    """Unix microseconds (Int64) of ISO wall-clock strings; null where the string is not one."""
    s = (
        expr.str.strip_chars()
        .str.replace(r"^(\d{4}-\d{2}-\d{2})[Tt ]+(\d)", "${1} ${2}")
        .str.replace(r"[Zz]$", "+00:00")
    )
    parsed = [s.str.to_datetime(f, time_unit="us", time_zone="UTC", strict=False) for f in ISO_FORMATS]
    return pl.coalesce(parsed).dt.epoch("us")


def iso_unix(expr: pl.Expr) -> pl.Expr:
    """Unix seconds (Float64) of ISO wall-clock strings; null where the string is not one."""
    return iso_unix_us(expr).cast(pl.Float64) / 1e6


def number(expr: pl.Expr) -> pl.Expr:
    """Float64 of numeric strings (null otherwise; ``nan``/``inf`` stay, the caller rejects them)."""
    return expr.str.strip_chars().cast(pl.Float64, strict=False)


def epoch_unix(epoch: str) -> float:
    """Unix seconds of ``site.toml``'s ``epoch`` (naive = UTC)."""
    try:
        ep = datetime.fromisoformat(str(epoch).strip().replace("Z", "+00:00"))
    except ValueError:
        raise InputError(f"not an ISO date/time: {epoch!r}", field="epoch") from None
    if ep.tzinfo is None:
        ep = ep.replace(tzinfo=UTC)
    return ep.timestamp()


def _iso_text(unix: float) -> str:
    try:
        return datetime.fromtimestamp(unix, tz=UTC).isoformat().replace("+00:00", "Z")
    except (OverflowError, OSError, ValueError):  # beyond the calendar: the number itself
        return repr(unix)


@dataclass(frozen=True)
class TimeOrigin:
    """Where ``t = 0`` is, and which stamps are accepted (module docstring).

    origin : the absolute value (numbers as written, ISO as Unix seconds) at ``t = 0`` for
        the data's own start; for an epoch, the epoch's Unix seconds.
    numeric : subtracted from numeric stamps (the origin, or 0 with an epoch).
    iso : subtracted from the Unix seconds of ISO stamps (the origin or the epoch); ``None``
        = each column's own first ISO stamp floored to a second (a reader used on its own).
    lo, hi : the accepted window of ``t``; stamps outside it are lone and rejected.
    source : ``"epoch"``, ``"data"`` or ``"none"`` (no stamp parsed).
    lone : stamps left out of the window; span_s : ``hi - lo``.
    """

    origin: float = 0.0
    numeric: float = 0.0
    iso: float | None = None
    lo: float = -math.inf
    hi: float = math.inf
    source: str = "none"
    lone: int = 0

    @property
    def span_s(self) -> float:
        return self.hi - self.lo if math.isfinite(self.hi - self.lo) else 0.0

    def as_dict(self) -> dict:
        """The ``[time]`` table of ``run.toml``."""
        out = {"source": self.source, "origin_s": self.origin, "span_s": self.span_s, "lone_stamps": self.lone}
        if self.iso is not None or self.source != "none":
            out["origin"] = _iso_text(self.iso if self.iso is not None else self.origin)
        if math.isfinite(self.lo):
            out["t_min"], out["t_max"] = self.lo, self.hi
        return out

    def t_expr(self, col: str, *, numbers_only: bool = False) -> pl.Expr:
        """``t`` of the string column ``col``: numbers minus ``numeric``, ISO minus ``iso``
        (``numbers_only``: the column holds no ISO stamp, skip ISO parsing)."""
        s = pl.col(col)
        if numbers_only:
            return number(s) - self.numeric
        iso = iso_unix_us(s)  # integer microseconds: no rounding of Unix seconds in a float
        if self.iso is not None and not abs(self.iso) < 9e12:  # beyond any date: float arithmetic, no overflow
            return pl.coalesce(number(s) - self.numeric, iso.cast(pl.Float64) / 1e6 - self.iso)
        ref = pl.lit(round(self.iso * 1e6), pl.Int64) if self.iso is not None else (iso.min() // 1_000_000) * 1_000_000
        return pl.coalesce(number(s) - self.numeric, (iso - ref).cast(pl.Float64) / 1e6)


def _stamps(sources: Mapping[str, pl.DataFrame | list[pl.DataFrame]], col: str) -> pl.DataFrame:
    """(source, line, abs, text, iso) of every finite stamp: numbers as written, ISO as Unix
    seconds. A source is a frame or a list of frames (a typed read's good rows with a numeric
    ``col`` and its other rows as strings); a numeric ``col`` is taken as it is (``text`` null)."""
    parts = []
    for name, frames in sources.items():
        for df in frames if isinstance(frames, list) else [frames]:
            if df is None or col not in df.columns or df.height == 0:
                continue
            line = (
                pl.col("line").cast(pl.Int64) if "line" in df.columns else pl.int_range(1, pl.len() + 1, dtype=pl.Int64)
            )
            if df.schema[col].is_numeric():  # already parsed (a typed read): no text, no ISO
                s = df.select(
                    pl.lit(name, pl.String).alias("source"),
                    line.alias("line"),
                    pl.lit(None, pl.String).alias("text"),
                    pl.col(col).cast(pl.Float64).alias("abs"),
                    pl.lit(False).alias("iso"),
                )
                parts.append(s.filter(pl.col("abs").is_finite()).select("source", "line", "abs", "text", "iso"))
                continue
            s = df.select(
                pl.lit(name, pl.String).alias("source"), line.alias("line"), pl.col(col).cast(pl.String).alias("text")
            ).with_columns(number(pl.col("text")).alias("abs"))
            s = s.with_columns(iso=pl.col("abs").is_null() & pl.col("text").is_not_null())
            todo = s.filter(pl.col("iso"))
            if todo.height:  # ISO parsing only where a stamp is not a number (the costly part)
                s = pl.concat([s.filter(~pl.col("iso")), todo.with_columns(iso_unix(pl.col("text")).alias("abs"))])
            parts.append(s.filter(pl.col("abs").is_finite()).select("source", "line", "abs", "text", "iso"))
    if not parts:
        return pl.DataFrame(
            schema={"source": pl.String, "line": pl.Int64, "abs": pl.Float64, "text": pl.String, "iso": pl.Boolean}
        )
    return pl.concat(parts).sort("abs")


#: Stamps per piece of :func:`gap_cuts`.
_GAP_PIECE = 1 << 16


def gap_cuts(a: np.ndarray, max_gap_s: float, piece: int = _GAP_PIECE) -> np.ndarray:
    """The indices ``i`` of sorted ``a`` with ``a[i] - a[i - 1] > max_gap_s`` (ascending), one piece
    of ``piece`` stamps at a time: a piece spanning at most ``max_gap_s`` holds no such gap (every
    gap in it is at most its span) and is skipped, so a log of a few clusters costs a look at
    each piece's ends, not a 10^6-row array of differences. Equal to
    ``np.flatnonzero(np.diff(a) > max_gap_s) + 1`` (tests)."""
    out = []
    for lo in range(0, a.shape[0] - 1, piece):
        hi = min(a.shape[0] - 1, lo + piece)  # the gaps a[i + 1] - a[i] for lo <= i < hi
        if not a[hi] - a[lo] <= max_gap_s:
            out.append(np.flatnonzero(np.diff(a[lo : hi + 1]) > max_gap_s) + (lo + 1))
    return np.concatenate(out) if out else np.empty(0, dtype=np.int64)


def _kept_span(v: pl.Series | np.ndarray, max_gap_s: float, lone_fraction: float) -> tuple[int, int]:
    """``[i0, i1)``: the stamps of sorted ``v`` (non-empty) left once the lone clusters at either
    end are cut off (module docstring)."""
    a = v if isinstance(v, np.ndarray) else v.to_numpy()
    n = a.size
    if a[n - 1] - a[0] <= max_gap_s:  # no two stamps further apart: one cluster
        return 0, n
    cut = gap_cuts(a, max_gap_s)  # a cluster starts at each of these indices
    bounds = [0, *cut.tolist(), n]
    sizes = [b - a for a, b in zip(bounds[:-1], bounds[1:])]
    limit = max(1, int(lone_fraction * n))
    first, last = 0, len(sizes) - 1
    while first < last and sizes[first] <= limit:
        first += 1
    while last > first and sizes[last] <= limit:
        last -= 1
    return bounds[first], bounds[last + 1]


def number_column_origin(values: pl.Series, epoch: str | TimeOrigin | None) -> TimeOrigin:
    """:func:`column_origin` of a column whose stamps are all finite numbers, from their values
    (Float64): what :func:`~onebit.readers.rows.parse_time` applies to a clean numeric log
    without parsing its strings again. A :class:`TimeOrigin` is returned as it is."""
    if isinstance(epoch, TimeOrigin):
        return epoch
    if values.len() == 0:
        return TimeOrigin(iso=epoch_unix(epoch) if epoch is not None else None)
    a = values.to_numpy()
    v = values if a.size < 2 or (a[1:] >= a[:-1]).all() else values.sort()  # logs are mostly in order
    i0, i1 = _kept_span(v, MAX_GAP_S, LONE_FRACTION)
    lo_abs, hi_abs = float(v[i0]), float(v[i1 - 1])
    lone = v.len() - (i1 - i0)
    if epoch is not None:
        e = epoch_unix(epoch)
        return TimeOrigin(origin=e, numeric=0.0, iso=e, lo=lo_abs, hi=hi_abs, source="epoch", lone=lone)
    origin = float(math.floor(lo_abs))
    lo, hi = lo_abs - origin, hi_abs - origin  # as time_origin, then column_origin, compute them
    return TimeOrigin(origin=0.0, numeric=0.0, iso=None, lo=lo + origin, hi=hi + origin, source="data", lone=lone)


def _numeric_origin(sources, col, epoch, max_gap_s, lone_fraction, max_span_s) -> TimeOrigin | None:
    """:func:`time_origin` when every stamp is already a number (the good rows of typed reads,
    no string rows left): from the values alone, in numpy, with no table of stamps; ``None``
    when some stamp is a string, or when the span is absurd (the table of stamps names both
    ends' file and line)."""
    values, flagged = [], []
    for frames in sources.values():
        for df in frames if isinstance(frames, list) else [frames]:
            if df is None or col not in df.columns or df.height == 0:
                continue
            if not df.schema[col].is_numeric():
                return None
            v = df[col].cast(pl.Float64)
            values.append(v.to_numpy())
            flagged.append(bool(v.flags.get("SORTED_ASC")) and v.null_count() == 0)
    a = np.concatenate(values) if len(values) > 1 else values[0] if values else np.empty(0)
    in_order = len(values) == 1 and flagged[0]  # one column flagged sorted (polars sorts NaN last)
    ends = a[[0, -1]] if in_order and a.size else a
    if a.size and not (np.isfinite(ends.min()) and np.isfinite(ends.max())):  # (NaN and inf show in min or max)
        a = a[np.isfinite(a)]
        in_order = False
    if a.size > 1 and not in_order and not (a[1:] >= a[:-1]).all():  # a log is mostly in order: no sort then
        a = np.sort(a)
    if a.size == 0:
        if epoch is not None:
            return TimeOrigin(origin=epoch_unix(epoch), numeric=0.0, iso=epoch_unix(epoch), source="epoch")
        return TimeOrigin()
    i0, i1 = _kept_span(a, max_gap_s, lone_fraction)
    lo_abs, hi_abs = float(a[i0]), float(a[i1 - 1])
    if hi_abs - lo_abs > max_span_s:
        return None
    lone = a.size - (i1 - i0)
    return _origin(lo_abs, hi_abs, lone, epoch)


def time_origin(
    sources: Mapping[str, pl.DataFrame],
    *,
    epoch: str | None = None,
    col: str = "t",
    max_gap_s: float = MAX_GAP_S,
    lone_fraction: float = LONE_FRACTION,
    max_span_s: float = MAX_SPAN_S,
) -> TimeOrigin:
    """The run's :class:`TimeOrigin` from the string stamps of every source (module docstring).

    ``sources`` maps a source name (``motion.csv``, ``rec.mcap:/motion``) to a frame with the
    string column ``col`` and, when known, ``line`` -- or to a list of frames, where ``col``
    may be numeric (the good rows of a typed read, :func:`~onebit.readers.rows.read_typed_csv`:
    the same numbers the strings give, without turning them back into text). Raises :class:`InputError` when the
    accepted stamps span more than ``max_span_s``, naming both ends' file, line and field.
    """
    fast = _numeric_origin(sources, col, epoch, max_gap_s, lone_fraction, max_span_s)
    if fast is not None:
        return fast
    st = _stamps(sources, col)
    n = st.height
    if epoch is not None:
        e = epoch_unix(epoch)
        # in t units: numbers as written, ISO minus the epoch
        st = st.with_columns(pl.col("abs") - pl.when(pl.col("iso")).then(e).otherwise(0.0))
        st = st.sort("abs")
    if n == 0:
        if epoch is not None:
            return TimeOrigin(origin=epoch_unix(epoch), numeric=0.0, iso=epoch_unix(epoch), source="epoch")
        return TimeOrigin()
    i0, i1 = _kept_span(st["abs"], max_gap_s, lone_fraction)
    keep = st.slice(i0, i1 - i0)
    lo_abs, hi_abs = float(keep["abs"][0]), float(keep["abs"][-1])
    if hi_abs - lo_abs > max_span_s:
        a, b = keep.row(0, named=True), keep.row(keep.height - 1, named=True)
        for r in (a, b):  # a stamp of a typed read has no text: its number as written
            r["text"] = r["text"] if r["text"] is not None else repr(r["abs"])
        raise InputError(
            f"the logs span {(hi_abs - lo_abs) / 86400:.1f} days, from {a['text']!r} here to {b['text']!r} at "
            f"{b['source']}:{b['line']} (more than {max_span_s / 86400:g} days): mixed clocks (relative seconds "
            "and Unix seconds or ISO times?) -- give every log the same clock, or set 'epoch' in site.toml",
            file=a["source"],
            line=a["line"],
            field=col,
        )
    lone = n - keep.height
    return _origin(lo_abs, hi_abs, lone, epoch)


def parts_origin(numbers: pl.Series, strings: pl.Series, epoch: str | None) -> TimeOrigin:
    """:func:`column_origin` of a column given in two parts: ``numbers``, stamps already parsed
    (finite Float64: the typed read's good rows) and ``strings``, the other stamps as written
    (the rows the row-by-row path types). Same result as :func:`column_origin` of all the
    stamps as strings, without turning the numbers back into text."""
    if numbers.len() == 0 and strings.len() == 0:
        return TimeOrigin(iso=epoch_unix(epoch) if epoch is not None else None)
    text = strings.cast(pl.String)
    num = text.str.strip_chars().cast(pl.Float64, strict=False)
    todo = text.filter(num.is_null() & text.is_not_null())  # ISO parsing only where a stamp is not a number
    iso_v = todo.to_frame("s").select(iso_unix(pl.col("s"))).to_series().drop_nulls()
    iso_v = iso_v.filter(iso_v.is_finite())
    e = epoch_unix(epoch) if epoch is not None else None
    a = numbers.cast(pl.Float64).to_numpy()
    more = np.concatenate([num.filter(num.is_finite()).to_numpy(), iso_v.to_numpy() - (e if e is not None else 0.0)])
    if more.size:
        a = np.concatenate([a, more])
    if a.size > 1 and not (a[1:] >= a[:-1]).all():  # logs are mostly in order: no sort then
        a = np.sort(a)
    n = a.size
    if n == 0:
        o = TimeOrigin(origin=e, numeric=0.0, iso=e, source="epoch") if e is not None else TimeOrigin()
    else:
        i0, i1 = _kept_span(pl.Series(a), MAX_GAP_S, LONE_FRACTION)
        lo_abs, hi_abs = float(a[i0]), float(a[i1 - 1])
        lone = n - (i1 - i0)
        if e is not None:
            o = TimeOrigin(origin=e, numeric=0.0, iso=e, lo=lo_abs, hi=hi_abs, source="epoch", lone=lone)
        else:
            origin = float(math.floor(lo_abs))
            o = TimeOrigin(
                origin=origin,
                numeric=origin,
                iso=origin,
                lo=lo_abs - origin,
                hi=hi_abs - origin,
                source="data",
                lone=lone,
            )
    if o.source != "data":
        return o if o.source == "epoch" else TimeOrigin()
    if numbers.len() == 0 and num.null_count() == num.len():  # ISO stamps only: from the column's own start
        return o
    if iso_v.len():  # numbers keep their values, ISO stamps count from the column's first second
        return TimeOrigin(origin=0.0, numeric=0.0, iso=None, source="data")
    return TimeOrigin(
        origin=0.0, numeric=0.0, iso=None, lo=o.lo + o.origin, hi=o.hi + o.origin, source="data", lone=o.lone
    )


def column_origin(frame: pl.DataFrame | None, col: str, epoch: str | None) -> TimeOrigin:
    """The origin a reader used on its own applies to one column (no run around it): numbers
    as written (offset 0), ISO from ``epoch`` or from the column's own first stamp, and the
    lone-stamp window of :func:`time_origin` over this column alone."""
    if frame is None or frame.height == 0 or col not in frame.columns:
        return TimeOrigin(iso=epoch_unix(epoch) if epoch is not None else None)
    o = time_origin({"": frame}, epoch=epoch, col=col, max_span_s=math.inf)
    if o.source != "data":
        return o if o.source == "epoch" else TimeOrigin()
    has_numbers = frame.select(number(pl.col(col).cast(pl.String)).is_not_null().any()).item()
    if not has_numbers:  # ISO stamps only: from the column's own start
        return o
    # numbers keep their values (ISO stamps, if any, count from the column's first second)
    has_iso = frame.select(iso_unix(pl.col(col).cast(pl.String)).is_not_null().any()).item()
    if has_iso:
        return TimeOrigin(origin=0.0, numeric=0.0, iso=None, source="data")
    return TimeOrigin(
        origin=0.0, numeric=0.0, iso=None, lo=o.lo + o.origin, hi=o.hi + o.origin, source="data", lone=o.lone
    )


def _origin(lo_abs: float, hi_abs: float, lone: int, epoch) -> TimeOrigin:
    """The origin of stamps spanning ``[lo_abs, hi_abs]``: the ``epoch`` when given, else the
    first stamp floored to a second (the data's own start)."""
    if epoch is not None:
        e = epoch_unix(epoch)
        return TimeOrigin(origin=e, numeric=0.0, iso=e, lo=lo_abs, hi=hi_abs, source="epoch", lone=lone)
    origin = float(math.floor(lo_abs))
    return TimeOrigin(
        origin=origin, numeric=origin, iso=origin, lo=lo_abs - origin, hi=hi_abs - origin, source="data", lone=lone
    )
