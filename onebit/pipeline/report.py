"""Reading and printing a run's report (``OUT/report.parquet``, long form: stage, metric, value, unit)."""

from __future__ import annotations

import io
from pathlib import Path

import polars as pl

from onebit.core import writers
from onebit.core.errors import InputError


def check_run_folder(out_dir: str | Path) -> Path:
    """``out_dir`` is a folder and not marked ``INCOMPLETE`` (a run killed while swapping its
    results in, so it may mix two runs); else an :class:`InputError` naming it."""
    out = Path(out_dir)
    if not out.is_dir():
        raise InputError("no such run folder" if not out.exists() else "is a file, not a run folder", file=out)
    if writers.is_incomplete(out):
        raise InputError(
            "incomplete run folder: a run was interrupted while it replaced the folder's content, so "
            "it may mix two runs; run 'onebit run DATASET --out' into it again",
            file=out,
        )
    return out


def load_report(out_dir: str | Path) -> pl.DataFrame:
    """The report of a finished run folder; refuses a folder whose run was cut short.

    Raises :class:`InputError` naming the folder when it is not a folder, is marked
    ``INCOMPLETE`` (a run killed while swapping its results in), or has no report (no run
    finished there; a run may be writing it now, or was killed before it finished).
    """
    out = check_run_folder(out_dir)
    for name in ("report.parquet", "report.csv"):
        p = out / name
        if p.exists():
            try:
                return pl.read_parquet(p) if p.suffix == ".parquet" else pl.read_csv(p)
            except (pl.exceptions.PolarsError, OSError) as exc:
                raise InputError(f"cannot read the report: {type(exc).__name__}", file=p) from None
    if writers.in_progress(out):
        raise InputError(
            "no finished run here yet: a run is writing this folder now, or was killed before it "
            "finished (then run it again)",
            file=out,
        )
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
