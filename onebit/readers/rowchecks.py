"""Typing and checking string rows: parsers per field, duplicates, time order, rejects.

The step after the CSV layer (:mod:`onebit.readers.rows`): a reader gives :func:`check_rows`
(or :func:`type_rows`) one parser per column (``parse_time``, ``parse_float``,
``parse_choice``, ``parse_name``: a value and a reason expression each); a row failing any
parser, a duplicate or a row going back in time is a reject with the first reason that
applies (:func:`order_checks`). Toggle logs sort rows up to :data:`REORDER_TOLERANCE_S` back
into place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.tables import REJECTS
from onebit.readers.csvfields import RawRows
from onebit.readers.linetext import FileLines, make_rejects, raw_lines
from onebit.readers.timebase import (
    MAX_GAP_S,
    TimeOrigin,
    column_origin,
)


def parse_time(col: str, epoch: str | TimeOrigin | None, frame: pl.DataFrame | None = None) -> tuple[pl.Expr, pl.Expr]:
    """Expression for ``t`` (seconds since the time origin) from numbers or ISO wall-clock strings.

    Returns ``(t, reason)``; ``reason`` is null where the value parsed. ``epoch`` is the run's
    :class:`~onebit.readers.timebase.TimeOrigin` (the pipeline's: one origin for every
    table) or, for a reader used on its own, the site's ``epoch`` string or ``None``: then
    numbers are taken as they are and ISO strings are measured from the epoch, else from the
    column's own first stamp (floored to a second) -- never from midnight. A stamp outside the
    origin's window (a lone stamp far from the rest, :mod:`onebit.readers.timebase`) is rejected.
    """
    origin = epoch if isinstance(epoch, TimeOrigin) else column_origin(frame, col, epoch)
    s = pl.col(col).str.strip_chars()
    numbers_only = (
        frame is not None
        and frame.height > 0
        and not frame.select((s.cast(pl.Float64, strict=False).is_null() & pl.col(col).is_not_null()).any()).item()
    )
    t = origin.t_expr(col, numbers_only=numbers_only)
    reason = (
        pl.when(pl.col(col).is_null() | (s == ""))
        .then(pl.lit(f"field '{col}': missing"))
        .when(t.is_null())
        .then(pl.format("field '{}': not a number or ISO time: '{}'", pl.lit(col), s))
        .when(~t.is_finite())
        .then(pl.format("field '{}': not finite: '{}'", pl.lit(col), s))
    )
    if math.isfinite(origin.lo) or math.isfinite(origin.hi):
        lo, hi = origin.lo, origin.hi  # the window was found in float Unix seconds: 1 ms slack
        reason = reason.when((t < lo - 1e-3) | (t > hi + 1e-3)).then(
            pl.format(
                "field '{}': '{}' is a lone time stamp far from the rest of the data (accepted span {} .. {} s "
                "after the time origin; gaps over {} days cut it off)",
                pl.lit(col),
                s,
                pl.lit(round(lo, 6)),
                pl.lit(round(hi, 6)),
                pl.lit(MAX_GAP_S / 86400),
            )
        )
    return t, reason.otherwise(None)


def parse_float(col: str) -> tuple[pl.Expr, pl.Expr]:
    s = pl.col(col).str.strip_chars()
    v = s.cast(pl.Float64, strict=False)
    reason = (
        pl.when(pl.col(col).is_null() | (s == ""))
        .then(pl.lit(f"field '{col}': missing"))
        .when(v.is_null() | ~v.is_finite())
        .then(pl.format("field '{}': not a finite number: '{}'", pl.lit(col), s))
        .otherwise(None)
    )
    return v, reason


def parse_choice(
    col: str, mapping: dict[str, object], dtype: pl.DataType, *, case_insensitive: bool = False
) -> tuple[pl.Expr, pl.Expr]:
    """Map string values through ``mapping``; anything else is rejected naming the allowed values.

    With ``case_insensitive`` the value is lower-cased first (``mapping``'s keys are lower case).
    """
    s = pl.col(col).str.strip_chars()
    key = s.str.to_lowercase() if case_insensitive else s
    v = key.replace_strict(list(mapping), list(mapping.values()), default=None, return_dtype=dtype)
    allowed = "|".join(mapping)
    reason = (
        pl.when(pl.col(col).is_null() | (s == ""))
        .then(pl.lit(f"field '{col}': missing"))
        .when(v.is_null())
        .then(pl.format("field '{}': '{}' is not one of {}", pl.lit(col), s, pl.lit(allowed)))
        .otherwise(None)
    )
    return v, reason


def parse_name(col: str, known: tuple[str, ...] | None, what: str) -> tuple[pl.Expr, pl.Expr]:
    """A sensor/target name; when ``known`` is given, unknown names are rejected."""
    s = pl.col(col).str.strip_chars()
    reason = pl.when(pl.col(col).is_null() | (s == "")).then(pl.lit(f"field '{col}': missing"))
    if known is not None:
        reason = reason.when(~s.is_in(list(known))).then(
            pl.format("field '{}': unknown {} '{}'", pl.lit(col), pl.lit(what), s)
        )
    return s, reason.otherwise(None)


#: Toggle logs (motion, proximity, CASAS): rows up to this many seconds earlier than an
#: accepted row before them are sorted into place, not rejected (CASAS logs are up to 0.7 s
#: out of order: sensors' clocks and the gateway's queue); a row further back is rejected as
#: going backwards. Raw beam events, crossings and truth keep a strict order (tolerance 0):
#: a beam pass takes a tenth of a second, so a reordered edge would change the decoding.
REORDER_TOLERANCE_S = 1.0


@dataclass(frozen=True)
class TypedRows:
    """What :func:`check_rows` made of string rows: ``accepted`` (sorted by ``t``, file order
    within a stamp, with ``line``), ``rejects`` and how many accepted rows were out of order
    within the tolerance and sorted into place (``reordered``); ``file``: the CSV's
    :class:`FileLines` when read whole (to name more lines)."""

    accepted: pl.DataFrame
    rejects: pl.DataFrame
    reordered: int = 0
    file: FileLines | None = None


def check_rows(
    raw: RawRows,
    parsers: dict[str, tuple[pl.Expr, pl.Expr]],
    *,
    key: tuple[str, ...],
    path: Path | None = None,
    tolerance: float = 0.0,
) -> TypedRows:
    """Apply ``parsers`` (column -> (value, reason)), then the ordering checks, and split.

    Checks, in order: each field's own reason; a row identical in ``key`` to an earlier row
    is a duplicate; a row whose ``t`` is more than ``tolerance`` seconds earlier than an
    accepted row before it goes backwards. Rows less far back are accepted, sorted into
    place and counted (``reordered``).
    """
    df = raw.frame
    value_exprs = [v.alias(c) for c, (v, _) in parsers.items()]
    reasons = [r for _, r in parsers.values()]
    typed = df.with_columns(pl.coalesce(reasons).alias("_reason")).with_columns(value_exprs)
    ok = typed.filter(pl.col("_reason").is_null())
    return order_checks(
        ok,
        key=key,
        tolerance=tolerance,
        field_bad=typed.filter(pl.col("_reason").is_not_null()),
        prior=raw.rejects,
        source=raw.source,
        path=path,
        columns=tuple(parsers),
    )


def in_time_order(t: pl.Series) -> bool:
    """Whether ``t`` never decreases (one pass in numpy; nulls and NaN are never in order); a
    column polars knows to be sorted (its flag: :func:`mark_in_order`), without nulls or NaN,
    needs no pass over its values."""
    if t.flags.get("SORTED_ASC") and t.null_count() == 0 and not (t.dtype.is_float() and t.len() and math.isnan(t[-1])):
        return True  # (polars sorts NaN last: a sorted column holds one only if its last value is NaN)
    v = t.to_numpy()
    return bool(v.size < 2 or (v[1:] >= v[:-1]).all())


def mark_in_order(rows: pl.DataFrame, *columns: str) -> pl.DataFrame:
    """``rows`` with ``columns`` flagged as sorted ascending for polars, once found in order
    (:func:`in_time_order`): later checks of the same rows read the flag instead of the values."""
    return rows.with_columns(pl.col(c).set_sorted() for c in columns)


def by_time(rows: pl.DataFrame) -> pl.DataFrame:
    """``rows`` sorted by ``t``, then ``line`` (file order within a stamp); no sort when both
    already increase (the accepted rows of a log written in time order)."""
    if in_time_order(rows["t"]) and in_time_order(rows["line"]):
        return rows
    return rows.sort(["t", "line"])


def duplicate_of(ok: pl.DataFrame, key: tuple[str, ...]) -> pl.Series:
    """For every row of ``ok`` (``line`` + the ``key`` columns, ``t`` among them), the first
    ``line`` of an earlier row with the same ``key`` (nulls equal), else null
    (:func:`duplicate_rows`, as a column)."""
    out = pl.Series("_dup", [], dtype=pl.Int64).extend_constant(None, ok.height)
    dup = duplicate_rows(ok, key)
    return out.scatter(dup["_i"], dup["_first"]) if dup.height else out


def duplicate_rows(ok: pl.DataFrame, key: tuple[str, ...], *, in_order: bool | None = None) -> pl.DataFrame:
    """The rows of ``ok`` (``line`` + the ``key`` columns, ``t`` among them) identical in ``key``
    to an earlier row (nulls equal): their index ``_i`` and the ``line`` of the first such
    row, ``_first``. Found by one sort on the key and a comparison of neighbours (no window
    over the key). Rows whose ``t`` no other row has cannot be duplicates; when ``t`` never
    decreases in file order (the usual log; ``in_order``: already known) only the runs of
    equal ``t`` are sorted, and a log without two equal stamps costs one comparison."""
    none = pl.DataFrame(schema={"_i": pl.Int64, "_first": pl.Int64})
    v = ok["t"].to_numpy() if "t" in ok.columns else None  # a time-free table: every row a candidate
    if v is not None and (in_order if in_order is not None else in_time_order(ok["t"])):
        eq = v[1:] == v[:-1]
        if not eq.any():  # no two rows share a stamp: no duplicate
            return none
        first = np.flatnonzero(eq)  # rows whose stamp the next row has
        at = np.unique(np.concatenate([first, first + 1]))  # only the rows in a run of equal stamps
        cand = ok[at].select(pl.Series("_i", at, dtype=pl.Int64), "line", *key)
        found = _duplicates_numpy(cand, key)  # (a few rows: numpy's sort beats a polars query)
        return found if found is not None else _duplicates_polars(cand, key)
    cand = ok.select(pl.int_range(pl.len(), dtype=pl.Int64).alias("_i"), "line", *key)
    return _duplicates_polars(cand, key)


def _duplicates_polars(cand: pl.DataFrame, key: tuple[str, ...]) -> pl.DataFrame:
    """:func:`duplicate_rows` of candidate rows (``_i``, ``line``, the ``key`` columns): one sort
    on the key and line, each row compared with the one before (nulls equal)."""
    cand = cand.sort([*key, "line"])
    same = pl.all_horizontal([pl.col(k).eq_missing(pl.col(k).shift(1)) for k in key]).fill_null(False)
    cand = cand.with_columns(pl.when(same).then(None).otherwise(pl.col("line")).forward_fill().alias("_first"))
    return cand.filter(pl.col("_first") != pl.col("line")).select("_i", "_first")


def _key_values(s: pl.Series) -> np.ndarray | None:
    """The values of a key column as numpy compares them the way polars' ``eq_missing`` does
    (enum codes, booleans, integers, finite floats without a negative zero, no nulls), else
    ``None``."""
    if s.null_count():
        return None
    if isinstance(s.dtype, pl.Enum):
        return s.to_physical().to_numpy()
    if s.dtype == pl.Boolean or s.dtype.is_integer():
        return s.to_numpy()
    if s.dtype.is_float():
        a = s.to_numpy()
        return a if np.isfinite(a).all() and not (np.signbit(a) & (a == 0)).any() else None
    return None


def _duplicates_numpy(cand: pl.DataFrame, key: tuple[str, ...]) -> pl.DataFrame | None:
    """:func:`_duplicates_polars` in numpy (one ``lexsort`` on the key and line, neighbours
    compared), for key columns numpy compares as polars does (:func:`_key_values`); ``None``
    for others (text, nulls, NaN). Equal to it (tests)."""
    values = [_key_values(cand[k]) for k in key]
    if cand.height == 0 or any(v is None for v in values):
        return None
    line = cand["line"].to_numpy()
    order = np.lexsort((line, *values[::-1]))  # by the key (its first column first), then line
    same = np.ones(max(line.size - 1, 0), dtype=np.bool_)
    for v in values:
        vs = v[order]
        same &= vs[1:] == vs[:-1]
    start = np.ones(line.size, dtype=np.bool_)  # a row that starts its group of equal keys
    start[1:] = ~same
    first = line[order][np.maximum.accumulate(np.where(start, np.arange(line.size), 0))]
    dup = np.flatnonzero(~start)
    return pl.DataFrame(
        {"_i": cand["_i"].to_numpy()[order][dup], "_first": first[dup]},
        schema={"_i": pl.Int64, "_first": pl.Int64},
    )


def backwards_reason(tolerance: float) -> pl.Expr:
    """The reject reason of a row whose ``t`` is earlier than ``_prev`` (the latest time before
    it) by more than ``tolerance`` seconds."""
    if tolerance <= 0:
        return pl.format("timestamp goes backwards ({} after {})", pl.col("t"), pl.col("_prev"))
    return pl.format(
        "timestamp goes backwards ({} after {}, more than {} s)", pl.col("t"), pl.col("_prev"), pl.lit(tolerance)
    )


def order_checks(
    ok: pl.DataFrame,
    *,
    key: tuple[str, ...],
    tolerance: float,
    columns: tuple[str, ...],
    source: str,
    path: Path | None,
    field_bad: pl.DataFrame | None = None,
    prior: pl.DataFrame | None = None,
    data: FileLines | None = None,
) -> TypedRows:
    """The ordering checks of :func:`check_rows` on rows whose fields all parsed (``ok``: ``line``
    + typed ``columns``, in file order): duplicates (:func:`duplicate_of`), then rows going
    backwards by more than ``tolerance``. ``field_bad`` (rows rejected by their fields, with
    ``_reason``) and ``prior`` (rejects already made) join the rejects. Reasons are formatted
    for the rejected rows only; rows without ``raw`` get their line's text from ``path``
    (``data``: its :class:`FileLines`, when already read)."""
    parts = [field_bad] if field_bad is not None and field_bad.height else []
    in_order = "t" in ok.columns and in_time_order(ok["t"])  # (dropping rows keeps the order)
    dups = duplicate_rows(ok, key, in_order=in_order)
    if dups.height:
        same = " and ".join(", ".join(key).rsplit(", ", 1))  # ("t", "target") -> "t and target"
        dup_of = (
            pl.Series("_dup", [], dtype=pl.Int64).extend_constant(None, ok.height).scatter(dups["_i"], dups["_first"])
        )
        ok = ok.with_columns(dup_of)
        dup = ok.filter(pl.col("_dup").is_not_null()).rechunk()
        parts.append(
            dup.with_columns(pl.format("duplicate of line {} (same {})", pl.col("_dup"), pl.lit(same)).alias("_reason"))
        )
        ok = ok.filter(pl.col("_dup").is_null()).drop("_dup")
    reordered = 0
    if "t" in ok.columns and not in_order:  # some row is earlier than a row before it (time-free tables: no order)
        ok = ok.sort("line").with_columns(pl.col("t").cum_max().shift(1).alias("_prev"))
        back = (pl.col("t") < pl.col("_prev") - tolerance).fill_null(False)
        late = ok.filter(back).rechunk()  # (polars 2.1 panics formatting a filtered frame's floats otherwise)
        if late.height:
            why = backwards_reason(tolerance)
            parts.append(late.with_columns(why.alias("_reason")))
            ok = ok.filter(~back)
        reordered = int(ok.select((pl.col("t") < pl.col("_prev")).fill_null(False).sum()).item())
        ok = ok.drop("_prev")
    if parts:
        with_raw = all("raw" in p.columns for p in parts)
        bad = pl.concat([p.select("line", "_reason", *(["raw"] if with_raw else [])) for p in parts]).sort("line")
        if path is not None and not with_raw:  # rows of the typed read: their text read back
            text = raw_lines(path, bad["line"].to_list(), limit=None, data=data)
            bad = bad.with_columns(pl.Series("raw", [text.get(i) for i in bad["line"].to_list()], dtype=pl.String))
        made = make_rejects(bad, source, path)
    else:
        made = pl.DataFrame(schema=REJECTS)
    rejects = made if prior is None else pl.concat([prior, made]).sort("line")
    accepted = ok.select("line", *columns)
    if "t" in accepted.columns and not in_order and (reordered or not in_time_order(accepted["t"])):
        accepted = accepted.sort(["t", "line"])
    elif in_order:  # the finite stamps of parsed rows, in order: flagged so, for the reader's next checks
        accepted = mark_in_order(accepted, "t")
    return TypedRows(accepted, rejects, reordered)


def type_rows(
    raw: RawRows,
    parsers: dict[str, tuple[pl.Expr, pl.Expr]],
    *,
    key: tuple[str, ...],
    path: Path | None = None,
    tolerance: float = 0.0,
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """:func:`check_rows` as ``(accepted, rejects)``."""
    res = check_rows(raw, parsers, key=key, path=path, tolerance=tolerance)
    return res.accepted, res.rejects
