"""Scoring of the ``beams`` tracker (Bobadilla et al.): assignment accuracy against the true
agents, region-level localisation error, and the rows that need no truth (IV-F-1 queries)."""

from __future__ import annotations

import polars as pl

from onebit.core.region_graph import RegionGraph
from onebit.core.site import Site
from onebit.scoring.crossings import assignment_scores, error_summary, region_scores


def query_rows(tables: dict) -> list[tuple[str, str, float, str]]:
    """Report rows of the beams stage that need no truth: ambiguity, unexplained crossings and
    the IV-F-1 query summaries (most visited region, peak occupancy, time over threshold)."""
    rows: list[tuple[str, str, float, str]] = []
    a = tables.get("beams_assignment")
    if a is None:
        return rows
    rows.append(
        ("beams", "ambiguous_crossings", float(a["ambiguous"].sum()) if "ambiguous" in a.columns else 0.0, "crossings")
    )
    un = tables.get("beams_unexplained")
    rows.append(("beams", "unexplained_crossings", float(un.height) if un is not None else 0.0, "crossings"))
    visits = tables.get("beams_visits")
    if visits is not None and visits.height:
        top = visits.row(0, named=True)
        rows.append(("beams", "most_visited_visits", float(top["visits"]), f"visits of {top['region']}"))
    occ = tables.get("beams_occupancy")
    if occ is not None and occ.height:
        best = occ.sort(["count", "t"], descending=[True, False]).row(0, named=True)
        rows.append(("beams", "peak_occupancy", float(best["count"]), f"agents in {best['region']}"))
    over = tables.get("beams_over_threshold")
    if over is not None:
        rows.append(("beams", "over_threshold_intervals", float(over.height), "intervals"))
        rows.append(("beams", "over_threshold_s", float(over["duration_s"].sum()) if over.height else 0.0, "s"))
    return rows


def score(
    tracker: str, tables: dict, site: Site, region_graph: RegionGraph
) -> tuple[list[tuple[str, str, float, str]], dict]:
    """Report rows and ``scores`` of the beams tracker.

    With truth: the agents are matched to the true agents by the crossings they share
    (:func:`~onebit.scoring.crossings.assignment_scores`; the crossings come with their true
    target from ``crossing_matches``, or ``corrected_targets`` when the correction ran), then
    ``assignment_accuracy``, ``agent_count_error``, ``agents`` and the region-level error of
    every matched agent (:func:`~onebit.scoring.crossings.region_scores`).
    """
    rows = query_rows(tables)
    out: dict[str, pl.DataFrame] = {}
    matches = tables.get("corrected_targets", tables.get("crossing_matches"))
    if matches is not None and "beams_assignment" in tables and "truth" in tables:
        acc, mapping = assignment_scores(matches, tables["beams_assignment"])
        n_true = tables["truth"]["target"].n_unique()
        n_rec = tables["beams_agents"].height
        rows += [
            ("beams", "assignment_accuracy", acc, "fraction"),
            ("beams", "agent_count_error", float(n_rec - n_true), "agents"),
            ("beams", "agents", float(n_rec), "agents"),
        ]
        sc = region_scores(tables["beams_tracks"], tables["truth"], mapping, region_graph, tracker="beams")
        rows += error_summary(sc, stage="beams", unit=site.units)
        out["beams_scores"] = sc
    return rows, out
