"""The ``scores`` stage's work: crossings against the truth, then every tracker that ran.

Declared in :mod:`onebit.pipeline.stages` (``scores_stage(TRACKERS, METRICS)``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import polars as pl

from onebit.core.config import config_from_mapping
from onebit.core.errors import OnebitError
from onebit.core.tables import REJECTS
from onebit.pipeline.context import ReportRow, RunContext, Stage
from onebit.pipeline.homes import count_rows
from onebit.scoring.crossings import ScoresConfig, score_crossings
from onebit.scoring.identity import baseline_rows, graph_hops, identity_scores
from onebit.scoring.mot import mot_rows
from onebit.scoring.serve import CannotServe
from onebit.viz.tracks import log_scores

if TYPE_CHECKING:
    from onebit.pipeline.stages import TrackerEntry

#: ``metric(tracker, tables, site, region_graph) -> report rows``: a metric the scores stage
#: adds for every tracker that ran (``[]`` when the run lacks what it needs)
MetricFn = Callable[[str, dict[str, pl.DataFrame], Any, Any], list[ReportRow]]


def identity_metric(tracker: str, tables: dict[str, pl.DataFrame], site, region_graph) -> list[ReportRow]:
    """Identity per event (:func:`onebit.scoring.identity.identity_scores`, docs/metrics.md) of a
    tracker that wrote ``<tracker>_events``, when the dataset has ``truth_events``."""
    te, ev = tables.get("truth_events"), tables.get(f"{tracker}_events")
    if te is None or not te.height or ev is None:
        return []
    return identity_scores(te, ev, tracks=tables.get(f"{tracker}_tracks")).rows(tracker)


def _ran(entry: TrackerEntry, ctx: RunContext) -> bool:
    return entry.name in ctx.trackers and ctx.status.get(entry.name, "").startswith("ok")


def _score_tracker(entry: TrackerEntry, ctx: RunContext, tables: dict, cfg: ScoresConfig) -> dict | None:
    """A tracker's own metrics (``entry.score``) and its MOT rows into the report; the tables
    its scoring made, or ``None`` when it failed or cannot serve the data (said in its status)."""
    site = ctx.site.tracked  # the trackers' view: no ignored sensor
    try:  # one tracker's scoring failing (say, a sensor without a region) keeps the others'
        rows, made = entry.score(entry.name, tables, site, ctx.region_graph)
        rows = rows + mot_rows(entry.name, entry.gate, tables, site, ctx.region_graph, gates_m=cfg.gates_m)
    except CannotServe as exc:  # the tracker's model does not fit the data: a flag, no number
        ctx.status[f"scores/{entry.name}"] = f"cannot serve the data: {exc}"
        ctx.report.append((entry.name, "cannot_serve", 1.0, "flag"))
        return None
    except OnebitError as exc:
        ctx.status[f"scores/{entry.name}"] = f"failed: {exc}"
        return None
    ctx.report += rows
    return made


def scores_work(ctx: RunContext, trackers: tuple[TrackerEntry, ...], metrics: tuple[MetricFn, ...]) -> dict:
    """The work of the ``scores`` stage (:func:`scores_stage`)."""
    cfg = config_from_mapping(ScoresConfig, ctx.section("scores"), section="scores")
    ctx.record("scores", cfg)
    tables = dict(ctx.tables)
    tables["timings"] = pl.DataFrame(
        {"stage": list(ctx.seconds), "seconds": list(ctx.seconds.values())},
        schema={"stage": pl.String, "seconds": pl.Float64},
    )
    rows, out = score_crossings(tables, cfg)
    ctx.report += rows
    site = ctx.site.tracked  # the trackers' view: no ignored sensor
    tables.update(out)
    for entry in trackers:
        made = _score_tracker(entry, ctx, tables, cfg) if _ran(entry, ctx) else None
        if made is not None:
            out.update(made)
            tables.update(made)
    for entry in filter(lambda e: _ran(e, ctx), trackers):  # the metrics of every tracker (METRICS)
        for fn in metrics:
            try:
                ctx.report += fn(entry.name, tables, site, ctx.region_graph)
            except OnebitError as exc:
                ctx.status[f"scores/{entry.name}"] = f"failed: {exc}"
    te = tables.get("truth_events")
    if te is not None and te.height:  # what a tracker's identity per event is compared with
        ctx.report += baseline_rows(te, graph_hops(site), profile=tables.get("residents_profile"), epoch=ctx.site.epoch)
    ctx.report += count_rows(tables)  # the count model's and the count baselines' scores
    rej = ctx.tables.get("rejects", pl.DataFrame(schema=REJECTS))
    ctx.report.append(("rejects", "rows", float(rej.height), "rows"))
    out["timings"] = tables["timings"]
    return out


def scores_viz(rec, ctx: RunContext, made: dict, trackers: tuple[TrackerEntry, ...]) -> None:
    """Every tracker's error over time (``<tracker>_scores``), by track."""
    for entry in trackers:
        sc = made.get(f"{entry.name}_scores")
        if sc is not None:
            tracks = ctx.tables.get(f"{entry.name}_tracks")
            ids = (
                tracks["track"].drop_nulls().unique().to_list()
                if tracks is not None and "track" in tracks.columns
                else None
            )
            log_scores(rec, entry.name, sc, track_ids=ids, look=entry.drawn)


def scores_stage(trackers: tuple[TrackerEntry, ...], metrics: tuple[MetricFn, ...]) -> Stage:
    """The ``scores`` stage: crossings against the truth, then every tracker that ran ok: its
    paper's metrics (``entry.score``), the standard MOT metrics (:func:`onebit.scoring.mot.mot_rows`)
    and every metric of ``metrics``, then the identity baselines."""
    makes = (
        "crossing_matches",
        "corrected_targets",
        "correct_recovered",
        "timings",
        *(f"{e.name}_*" for e in trackers),
    )
    return Stage(
        "scores",
        (),
        makes,
        lambda ctx: None,
        lambda ctx: scores_work(ctx, trackers, metrics),
        lambda rec, ctx, made: scores_viz(rec, ctx, made, trackers),
        config=ScoresConfig,
    )
