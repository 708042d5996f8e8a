"""``onebit logs info``: what a raw log holds -- channels, sensors, time span, rates, rejects.

Works on any raw-log CSV or Parquet file, on an ``.mcap`` recording (one row per channel),
on a CASAS smart-home log ``*.txt`` or pymrt ``events.csv`` (:mod:`onebit.readers.casas`: one
row for the whole log, then one per kind of sensor -- motion, contact, temperature, ... -- then
the resident-labelled events, the annotation problems and the lost OFFs) and on a folder (every
``*.csv``, ``*.parquet``, ``*.mcap`` and ``*.txt`` in it).
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.readers.casas import CSV_COLUMNS, TOGGLE_KINDS, read_casas, repair_lost_offs
from onebit.readers.mcap_io import read_mcap
from onebit.readers.rows import header_names, read_csv_rows

#: Schema of the :func:`log_info` frame.
LOG_INFO = pl.Schema(
    {
        "source": pl.String,
        "rows": pl.Int64,
        "sensors": pl.Int64,
        "sensor_ids": pl.String,
        "t_min": pl.Float64,
        "t_max": pl.Float64,
        "span_s": pl.Float64,
        "rate_hz": pl.Float64,
        "rejects": pl.Int64,
    }
)

#: Columns that name a sensor (or target), in order of preference.
ID_COLUMNS = ("beam", "sensor", "target")
#: How many ids :func:`log_info` lists before eliding the rest.
MAX_IDS = 10

_SUFFIXES = (".csv", ".parquet", ".mcap", ".txt")


def _parse_t(values: pl.Series) -> pl.Series:
    """``t`` as Float64 seconds: numbers as they are, ISO wall-clock as Unix seconds; else null."""
    s = values.str.strip_chars()
    num = s.cast(pl.Float64, strict=False)
    todo = num.is_null() & s.is_not_null() & (s != "")
    if todo.any():
        try:
            iso = (
                s.filter(todo)
                .str.to_datetime(time_unit="us", time_zone="UTC", strict=False)
                .dt.epoch("us")
                .cast(pl.Float64)
                / 1e6
            )
        except pl.exceptions.PolarsError:
            iso = pl.Series([None] * int(todo.sum()), dtype=pl.Float64)
        num = num.scatter(todo.arg_true(), iso)
    return num.fill_nan(None)


def _summarise(source: str, df: pl.DataFrame, bad_rows: int, extra_rejects: int = 0) -> dict:
    """One summary row for string rows ``df`` (already stripped of ``bad_rows`` malformed rows)."""
    rejects = bad_rows + extra_rejects
    if "t" in df.columns:
        t = _parse_t(df["t"])
        ok = t.is_not_null() & t.is_finite()
        rejects += int((~ok).sum())
        df = df.filter(ok)
        t = t.filter(ok)
    else:
        t = pl.Series([], dtype=pl.Float64)
    id_col = next((c for c in ID_COLUMNS if c in df.columns), None)
    sensors = ids = None
    if id_col is not None:
        uniq = df[id_col].drop_nulls().unique().sort().to_list()
        sensors = len(uniq)
        ids = ",".join(uniq[:MAX_IDS]) + (f",… (+{len(uniq) - MAX_IDS})" if len(uniq) > MAX_IDS else "")
    t_min = t.min() if t.len() else None
    t_max = t.max() if t.len() else None
    span = None if t_min is None else float(t_max - t_min)
    rate = df.height / span if span else None
    return {
        "source": source,
        "rows": df.height,
        "sensors": sensors,
        "sensor_ids": ids,
        "t_min": t_min,
        "t_max": t_max,
        "span_s": span,
        "rate_hz": rate,
        "rejects": rejects,
    }


def _csv_rows(path: Path) -> list[dict]:
    """One summary of a CSV log, read by the CSV layer of :mod:`onebit.readers.rows` (a bad
    line counts as a reject, it never fails the file)."""
    header = header_names(path)[0]
    if not header:
        return [_summarise(path.name, pl.DataFrame(), 0)]
    names = tuple(dict.fromkeys(h for h in header if h))
    raw = read_csv_rows(path, names)
    return [_summarise(path.name, raw.frame.drop("line", "raw"), raw.rejects.height)]


def _parquet_rows(path: Path) -> list[dict]:
    try:
        df = pl.read_parquet(path)
    except (pl.exceptions.PolarsError, OSError) as exc:
        raise InputError(f"cannot read Parquet: {exc}", file=path) from None
    return [_summarise(path.name, df.with_columns(pl.all().cast(pl.String)), 0)]


def _mcap_rows(path: Path) -> list[dict]:
    contents = read_mcap(path)
    per_source = dict(contents.rejects.group_by("source").len().iter_rows())
    rows = []
    for topic, df in contents.channels.items():
        source = f"{path.name}:{topic}"
        rows.append(_summarise(source, df.drop("line", "raw"), 0, per_source.pop(source, 0)))
    for source, n in sorted(per_source.items()):  # unknown topics, the file itself (truncation)
        rows.append(_summarise(source, pl.DataFrame(), 0, n))
    return rows


def _is_casas_csv(path: Path) -> bool:
    """A pymrt ``events.csv`` (:func:`onebit.readers.casas.read_casas_csv`): no ``t`` column and
    either a header naming a time, a sensor and a message column, or none (a date-time first)."""
    try:
        header = [h.lower() for h in header_names(path)[0]]
    except InputError:
        return False
    if not header or "t" in header:
        return False
    if re.match(r"^\d{4}-\d{1,2}-\d{1,2}[ Tt_]\d", header[0]):
        return True
    return all(any(n in header for n in CSV_COLUMNS[c]) for c in ("time", "sensor", "message"))


def _casas_rows(path: Path) -> list[dict]:
    """The whole log (with its rejected lines), then one row per kind of sensor, then
    ``:resident-labelled`` (events annotated with their resident(s); ``sensors`` = distinct
    residents' sets), ``:annotation-problems`` (events kept whose annotation did not read) and
    ``:lost-off`` (the OFFs :func:`~onebit.readers.casas.repair_lost_offs` would insert, at
    their times) when there are any; times are seconds since the log's first second."""
    log = read_casas(path)
    ev = log.events.with_columns(t=pl.col("t").cast(pl.String))
    rows = [_summarise(path.name, ev.select("t", "sensor"), 0, log.rejects.height)]
    for kind in sorted(ev["kind"].unique().to_list()):
        rows.append(_summarise(f"{path.name}:{kind}", ev.filter(pl.col("kind") == kind).select("t", "sensor"), 0))
    labelled = ev.filter(pl.col("residents").is_not_null())
    if labelled.height:
        rows.append(
            _summarise(f"{path.name}:resident-labelled", labelled.select("t", pl.col("residents").alias("sensor")), 0)
        )
    if log.annotation_problems.height:
        probs = log.events.join(log.annotation_problems.select("line"), on="line").with_columns(
            t=pl.col("t").cast(pl.String)
        )
        rows.append(_summarise(f"{path.name}:annotation-problems", probs.select("t", "sensor"), 0))
    _, lost = repair_lost_offs(log.events.filter(pl.col("kind").is_in(list(TOGGLE_KINDS))))
    if lost.height:
        rows.append(
            _summarise(f"{path.name}:lost-off", lost.select(pl.col("t_off").cast(pl.String).alias("t"), "sensor"), 0)
        )
    return rows


def log_info(path: str | Path) -> pl.DataFrame:
    """Summarise a raw log: one row per file (CSV/Parquet) or per channel (MCAP).

    Parameters
    ----------
    path
        A ``*.csv`` or ``*.parquet`` raw log, an ``.mcap`` recording, a CASAS log ``*.txt``,
        or a folder of them.

    Returns
    -------
    pl.DataFrame
        In the :data:`LOG_INFO` schema: ``source`` (file name, or ``"<file>:<topic>"``),
        ``rows`` (rows that parse), ``sensors`` / ``sensor_ids`` (distinct values of the first
        of ``beam``, ``sensor``, ``target`` present; null without one; at most
        :data:`MAX_IDS` ids listed), ``t_min`` / ``t_max`` / ``span_s`` (seconds; ISO times
        as Unix seconds), ``rate_hz`` (rows / span; null for a zero span) and ``rejects``.

    Notes
    -----
    A row is a reject when it has too many or too few fields (an empty last field counts as
    missing) or its ``t`` is neither a number nor an ISO time; for MCAP also every message
    the reader rejected. Rejects with no channel (an unknown topic, a truncated file) get
    their own row named like the reader's reject ``source``, with ``rows = 0``.

    Raises
    ------
    InputError
        A missing file, an unsupported suffix, a file that cannot be read at all, or non-MCAP
        bytes in a ``.mcap``.
    """
    path = Path(path)
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in _SUFFIXES)
        if not files:
            raise InputError("no *.csv, *.parquet or *.mcap files in this folder", file=path)
        return pl.concat([log_info(p) for p in files])
    if not path.is_file():
        raise InputError("no such file", file=path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        rows = _casas_rows(path) if _is_casas_csv(path) else _csv_rows(path)
    elif suffix == ".parquet":
        rows = _parquet_rows(path)
    elif suffix == ".mcap":
        rows = _mcap_rows(path)
    elif suffix == ".txt":
        rows = _casas_rows(path)
    else:
        raise InputError(
            f"unsupported file type '{path.suffix}'; expected .csv, .parquet, .mcap or .txt (CASAS)", file=path
        )
    return pl.DataFrame(rows, schema=LOG_INFO, orient="row") if rows else pl.DataFrame(schema=LOG_INFO)


def _fmt(value: object, spec: str = ".3f") -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return format(value, spec)
    return str(value)


def format_log_info(df: pl.DataFrame, *, width: int = 120) -> str:
    """Render a :func:`log_info` frame as a plain-text table (rich, no colour codes).

    Parameters
    ----------
    df
        A frame in the :data:`LOG_INFO` schema.
    width
        Console width in characters the table is fitted to.

    Returns
    -------
    str
        The table, ending with a newline.
    """
    from rich.console import Console
    from rich.table import Table

    table = Table(title="raw logs", title_justify="left")
    numeric = {"rows", "sensors", "t_min", "t_max", "span_s", "rate_hz", "rejects"}
    for col in LOG_INFO:
        table.add_column(col, justify="right" if col in numeric else "left", overflow="fold")
    for row in df.select(list(LOG_INFO)).iter_rows(named=True):
        table.add_row(*(_fmt(row[c], ".4g" if c == "rate_hz" else ".3f") for c in LOG_INFO))
    buf = io.StringIO()
    Console(file=buf, width=width, color_system=None, force_terminal=False).print(table)
    return buf.getvalue()
