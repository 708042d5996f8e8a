"""Reading and printing a run's report (``OUT/report.parquet``, long form: stage, metric, value, unit)."""

from __future__ import annotations

import io
from pathlib import Path

import polars as pl

from onebit.core.errors import InputError


def load_report(out_dir: str | Path) -> pl.DataFrame:
    out = Path(out_dir)
    for name in ("report.parquet", "report.csv"):
        p = out / name
        if p.exists():
            return pl.read_parquet(p) if p.suffix == ".parquet" else pl.read_csv(p)
    raise InputError("no report.parquet or report.csv: is this a finished run folder?", file=out)


def metric(report: pl.DataFrame, key: str) -> float | None:
    """Value of ``stage/metric`` (e.g. ``"beams/assignment_accuracy"``), or None."""
    stage, name = key.split("/", 1)
    hit = report.filter((pl.col("stage") == stage) & (pl.col("metric") == name))
    return None if hit.height == 0 else float(hit["value"][0])


def format_report(report: pl.DataFrame, *, title: str = "onebit report") -> str:
    """The report as a readable table, one row per ``stage/metric``."""
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title)
    table.add_column("metric")
    table.add_column("value", justify="right")
    table.add_column("unit")
    for row in report.iter_rows(named=True):
        v = row["value"]
        text = f"{v:.0f}" if v is not None and float(v).is_integer() and abs(v) < 1e12 else f"{v:.4g}"
        table.add_row(f"{row['stage']}/{row['metric']}", text, row["unit"] or "")
    buf = io.StringIO()
    Console(file=buf, width=100, force_terminal=False, color_system=None).print(table)
    return buf.getvalue()
