"""Reading and printing a run's report (``OUT/report.parquet``, long form: stage, metric, value, unit)."""

from __future__ import annotations

import io
import re
from collections.abc import Sequence
from pathlib import Path

import polars as pl

from onebit.core import writers
from onebit.core.errors import InputError
from onebit.pipeline.context import Stage


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


#: The measures a run summary shows per stage beside the count and MOT columns: each tracker's
#: paper's own measure (docs/metrics.md), the readers' share of the log they decoded.
HEADLINE: dict[str, tuple[str, ...]] = {
    "crossings": ("decoded",),
    "motion": ("edges",),
    "proximity": ("edges",),
    "frames": ("frames",),
    "correct": ("recovered",),
    "beams": ("assignment_accuracy", "agent_count_error"),
    "intruder": ("mean_error_cells", "within_2"),
    "intruder-naive": ("mean_error_cells", "within_2"),
    "clustertrack": ("mean_error_R", "targets_found"),
    "findinghumo": ("hop_error",),
    "findinghumo-flow": ("hop_error",),
    "hmm1": ("hop_error",),
    "hmm2": ("hop_error",),
    "istate": ("containment", "area_share"),
    "residents": ("people_decoded", "identity_accuracy"),
    "rejects": ("rows",),
}
#: Columns every positional tracker has (docs/metrics.md, "Standard MOT metrics").
SUMMARY_COLUMNS: tuple[tuple[str, str], ...] = (
    ("count_error", "count err"),
    ("mota@1m", "MOTA@1m"),
    ("idf1@1m", "IDF1@1m"),
)


def _number(v: float | None) -> str:
    if v is None:
        return ""
    return f"{v:.0f}" if float(v).is_integer() and abs(v) < 1e12 else f"{v:.3g}"


def format_run_summary(report: pl.DataFrame, status: dict[str, str], *, title: str = "onebit run") -> str:
    """One table for a finished run: a row per stage that ran (ok or failed) with its seconds,
    its count error, MOTA and IDF1 at 1 m, and its paper's measures (:data:`HEADLINE`).

    The whole report stays in ``report.csv`` and ``onebit report``; skipped stages are said
    by :func:`skipped_groups`."""
    from rich.console import Console
    from rich.table import Table

    values = {(r["stage"], r["metric"]): r["value"] for r in report.iter_rows(named=True)}
    table = Table(title=title)
    table.add_column("stage")
    table.add_column("s", justify="right")
    for _, label in SUMMARY_COLUMNS:
        table.add_column(label, justify="right")
    table.add_column("paper's measures (docs/metrics.md)")
    ran = [(name, state) for name, state in status.items() if not state.startswith("skipped") and "/" not in name]
    if any(stage == "rejects" for stage, _ in values) and "rejects" not in status:
        ran.append(("rejects", ""))
    for name, state in ran:
        seconds = ""
        if state.startswith("ok (") and state.endswith(" s)"):
            seconds = state[len("ok (") : -len(" s)")]
        elif state.startswith("failed"):
            seconds = "FAILED"
        cols = [_number(values.get((name, key))) for key, _ in SUMMARY_COLUMNS]
        measures = ", ".join(
            f"{key} {_number(values[(name, key)])}" for key in HEADLINE.get(name, ()) if (name, key) in values
        )
        table.add_row(name, seconds, *cols, measures)
    buf = io.StringIO()
    Console(file=buf, width=110, force_terminal=False, color_system=None).print(table)
    return buf.getvalue()


def skipped_groups(status: dict[str, str], stage_list: Sequence[Stage] = ()) -> list[str]:
    """One line per group of skipped stages: the stages skipped for one reason, e.g.
    ``skipped (site has no [sensor_graph] with edges): findinghumo, hmm1, hmm2``.

    A stage skipped because an earlier stage did not make its input (``input table 'crossings'
    not produced by an earlier stage``) joins the group of the stage of ``stage_list`` that
    makes that table, when that stage was skipped too: the reason is said once, at its root."""
    reasons = {name: state[len("skipped: ") :] for name, state in status.items() if state.startswith("skipped: ")}

    def root(name: str, seen: frozenset[str] = frozenset()) -> str:
        why = reasons[name]
        if "not produced by an earlier stage" not in why:
            return name
        for table in re.findall(r"'([^']+)'", why):
            maker = next((st.name for st in stage_list if st.declares(table)), None)
            if maker is not None and maker in reasons and maker not in seen:
                return root(maker, seen | {name})
        return name

    def said(name: str) -> str:  # the reason without the stage's own name: "tracker 'hmm1' not selected"
        return reasons[name].replace(f"tracker '{name}' ", "").replace(f" '{name}'", "")

    groups: dict[str, list[str]] = {}
    for name in reasons:
        groups.setdefault(said(root(name)), []).append(name)
    lines: dict[str, str] = {}
    for title, pattern in (("inputs not in the dataset", ABSENT), ("the site lacks what they need", SITE)):
        hits = [r for r in groups if pattern.match(r)]
        if len(hits) > 1:  # one line for the kind, each stage with what it lacks
            what = [next(g for g in pattern.match(r).groups() if g) for r in hits]
            lines[title] = "; ".join(f"{', '.join(groups[r])} ({w})" for r, w in zip(hits, what))
            groups = {r: n for r, n in groups.items() if r not in hits}
    lines.update({reason: ", ".join(names) for reason, names in groups.items()})
    return [f"skipped ({reason}): {what}" for reason, what in lines.items()]


#: A stage skipped because an input file is not in the dataset ("no truth_count.csv in the
#: dataset", "no frames.csv or /frames MCAP channel in the dataset"): group 1 names the file.
ABSENT = re.compile(r"^no (\S+?\.\w+)\b.* in the dataset$")
#: A stage skipped because the site lacks what it needs ("site has no beams", "site.toml has
#: no proximity sensors", "no sensor has ignore = true in site.toml"): group 1 says what.
SITE = re.compile(r"^(?:site(?:\.toml)? has (no .+)|(no sensor has .+) in site\.toml)$")
