"""Row-level reading shared by every CSV/MCAP reader: raw string rows -> typed rows + rejects.

A reader first gets its rows as all-string columns with a ``line`` column (CSV: the file's
line number, header = line 1; MCAP: the message's index in its channel), then types and
checks them with polars expressions. A row that fails any check goes to ``rejects`` with the
first reason that applies; nothing is dropped silently.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.core.tables import REJECTS

EXTRA = "__extra__"


@dataclass(frozen=True)
class RawRows:
    """String rows of one source: ``frame`` has the wanted columns (String), ``line`` and ``raw``."""

    source: str
    frame: pl.DataFrame
    rejects: pl.DataFrame


def read_csv_rows(path: str | Path, columns: tuple[str, ...]) -> RawRows:
    """Read a CSV whose header names at least ``columns`` (any order, extra columns ignored).

    Rows with too few or too many fields are rejected (polars reads them with
    ``truncate_ragged_lines`` and an extra sentinel column); blank lines are skipped.
    """
    path = Path(path)
    source = path.name
    try:
        header = pl.read_csv(path, n_rows=0, infer_schema=False).columns
    except pl.exceptions.NoDataError:
        return RawRows(source, _empty_rows(columns), pl.DataFrame(schema=REJECTS))
    except (pl.exceptions.ComputeError, OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read CSV header: {exc}", file=path, line=1) from None
    header = [h.strip() for h in header]
    for col in columns:
        if col not in header:
            raise InputError(f"missing column; the header has {header}", file=path, line=1, field=col)
    names = [h if h not in (EXTRA, "line", "raw") else f"{h}_" for h in header] + [EXTRA]
    try:
        df = pl.read_csv(
            path,
            has_header=False,
            skip_rows=1,
            schema={n: pl.String for n in names},
            missing_columns="insert",
            truncate_ragged_lines=True,
        )
    except (pl.exceptions.ComputeError, OSError) as exc:
        raise InputError(f"cannot parse CSV: {exc}", file=path) from None
    df = df.with_row_index("line", offset=2).with_columns(pl.col("line").cast(pl.Int64))
    fields = [n for n in names if n != EXTRA]
    blank = pl.all_horizontal([pl.col(n).is_null() for n in names])
    df = df.filter(~blank)
    n_fields = pl.sum_horizontal([pl.col(n).is_not_null().cast(pl.Int32) for n in fields])
    reason = (
        pl.when(pl.col(EXTRA).is_not_null())
        .then(pl.lit(f"too many fields (expected {len(fields)})"))
        .when(pl.col(fields[-1]).is_null() & (n_fields < len(fields)))
        .then(pl.format("too few fields ({} of {})", n_fields, pl.lit(len(fields))))
        .otherwise(None)
    )
    df = df.with_columns(reason.alias("_reason"))
    bad = df.filter(pl.col("_reason").is_not_null())
    good = df.filter(pl.col("_reason").is_null()).select("line", *columns)
    rejects = make_rejects(bad, source, path)
    return RawRows(source, good.with_columns(pl.lit(None, pl.String).alias("raw")), rejects)


def _empty_rows(columns) -> pl.DataFrame:
    return pl.DataFrame(schema={"line": pl.Int64, **{c: pl.String for c in columns}, "raw": pl.String})


def raw_lines(path: Path, lines: list[int]) -> dict[int, str]:
    """The text of the given 1-based line numbers (read only when there are rejects)."""
    want = set(lines)
    out: dict[int, str] = {}
    if not want:
        return out
    last = max(want)
    with open(path, encoding="utf-8", errors="replace") as fh:
        for i, text in enumerate(fh, start=1):
            if i in want:
                out[i] = text.rstrip("\r\n")
            if i >= last:
                break
    return out


def make_rejects(bad: pl.DataFrame, source: str, path: Path | None) -> pl.DataFrame:
    """Build ``rejects`` rows from a frame with ``line``, ``_reason`` and optionally ``raw``."""
    if bad.height == 0:
        return pl.DataFrame(schema=REJECTS)
    if "raw" in bad.columns and bad["raw"].null_count() < bad.height:
        raw = bad["raw"]
    elif path is not None and path.suffix.lower() == ".csv":
        text = raw_lines(path, bad["line"].to_list())
        raw = pl.Series([text.get(i) for i in bad["line"].to_list()], dtype=pl.String)
    else:
        raw = pl.Series([None] * bad.height, dtype=pl.String)
    return pl.DataFrame(
        {
            "source": pl.Series([source] * bad.height, dtype=pl.String),
            "line": bad["line"].cast(pl.Int64),
            "reason": bad["_reason"].cast(pl.String),
            "raw": raw,
        },
        schema=REJECTS,
    )


# --------------------------------------------------------------------------- typing rows


def parse_time(col: str, epoch: str | None, frame: pl.DataFrame | None = None) -> tuple[pl.Expr, pl.Expr]:
    """Expression for ``t`` (seconds since the epoch) from numbers or ISO wall-clock strings.

    Returns ``(t, reason)``; ``reason`` is null where the value parsed. ISO strings are
    measured from the site's ``epoch``; without one, from midnight UTC of the earliest stamp.
    """
    s = pl.col(col).str.strip_chars()
    num = s.cast(pl.Float64, strict=False)
    if frame is not None and frame.height and not frame.select((num.is_null() & pl.col(col).is_not_null()).any()).item():
        # every value is a number: leave out ISO parsing, the costly part
        reason = (
            pl.when(pl.col(col).is_null() | (s == ""))
            .then(pl.lit(f"field '{col}': missing"))
            .when(~num.is_finite())
            .then(pl.format("field '{}': not finite: '{}'", pl.lit(col), s))
            .otherwise(None)
        )
        return num, reason
    iso = s.str.to_datetime(time_unit="us", time_zone="UTC", strict=False)
    if epoch is not None:
        ep = datetime.fromisoformat(str(epoch).replace("Z", "+00:00"))
        if ep.tzinfo is None:
            ep = ep.replace(tzinfo=timezone.utc)
        ep_expr = pl.lit(ep).cast(pl.Datetime("us", "UTC"))
    else:
        ep_expr = iso.min().dt.truncate("1d")
    from_iso = (iso - ep_expr).dt.total_microseconds().cast(pl.Float64) / 1e6
    t = pl.coalesce(num, from_iso)
    reason = (
        pl.when(pl.col(col).is_null() | (s == ""))
        .then(pl.lit(f"field '{col}': missing"))
        .when(t.is_null())
        .then(pl.format("field '{}': not a number or ISO time: '{}'", pl.lit(col), s))
        .when(~t.is_finite())
        .then(pl.format("field '{}': not finite: '{}'", pl.lit(col), s))
        .otherwise(None)
    )
    return t, reason


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


def parse_choice(col: str, mapping: dict[str, object], dtype: pl.DataType) -> tuple[pl.Expr, pl.Expr]:
    """Map string values through ``mapping``; anything else is rejected naming the allowed values."""
    s = pl.col(col).str.strip_chars()
    v = s.replace_strict(list(mapping), list(mapping.values()), default=None, return_dtype=dtype)
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
        reason = reason.when(~s.is_in(list(known))).then(pl.format("field '{}': unknown {} '{}'", pl.lit(col), pl.lit(what), s))
    return s, reason.otherwise(None)


def type_rows(
    raw: RawRows,
    parsers: dict[str, tuple[pl.Expr, pl.Expr]],
    *,
    key: tuple[str, ...],
    path: Path | None = None,
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """Apply ``parsers`` (column -> (value, reason)), then the ordering checks, and split.

    Checks, in order: each field's own reason; a row identical in ``key`` to an earlier row
    is a duplicate; a row whose ``t`` is earlier than an accepted row before it goes backwards.
    Returns ``(accepted, rejects)``; ``accepted`` is sorted by ``t`` (stable in file order)
    and keeps ``line``.
    """
    df = raw.frame
    value_exprs = [v.alias(c) for c, (v, _) in parsers.items()]
    reasons = [r for _, r in parsers.values()]
    typed = df.with_columns(pl.coalesce(reasons).alias("_reason")).with_columns(value_exprs)
    ok = typed.filter(pl.col("_reason").is_null())
    first_line = pl.col("line").min().over(list(key))
    ok = ok.with_columns(
        pl.when(pl.col("line") != first_line).then(pl.format("duplicate of line {}", first_line)).otherwise(None).alias("_reason")
    )
    dup = ok.filter(pl.col("_reason").is_not_null())
    ok = ok.filter(pl.col("_reason").is_null()).sort("line")
    prev_max = pl.col("t").cum_max().shift(1)
    ok = ok.with_columns(
        pl.when(pl.col("t") < prev_max)
        .then(pl.format("timestamp goes backwards ({} after {})", pl.col("t"), prev_max))
        .otherwise(None)
        .alias("_reason")
    )
    back = ok.filter(pl.col("_reason").is_not_null())
    ok = ok.filter(pl.col("_reason").is_null())
    bad = pl.concat([typed.filter(pl.col("_reason").is_not_null()), dup, back], how="vertical_relaxed").sort("line")
    rejects = pl.concat([raw.rejects, make_rejects(bad, raw.source, path)]).sort("line")
    accepted = ok.select("line", *parsers.keys())
    return accepted, rejects
