"""Scoring of the ``intruder`` and ``intruder-naive`` trackers in cells (Schiff & Goldberg VIII)."""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.site import Site
from onebit.core.tables import SCORES, conform
from onebit.scoring.association import associate, matched_pairs, pair_samples
from onebit.scoring.serve import CannotServe, targets_at_once

# --------------------------------------------------------------------------- scoring


def match_errors(tracks: pl.DataFrame, truth: pl.DataFrame, *, tolerance: float) -> pl.DataFrame:
    """Per-sample error of every track against the target it is matched to (SCORES).

    Each track sample is paired with each target's truth sample nearest in time (within
    ``tolerance`` s, :func:`~onebit.scoring.association.pair_samples`); the per-sample cost is
    the Euclidean error :math:`e_s = \\lVert \\hat p_k(t_s) - p_g(t_s) \\rVert` and tracks are
    matched one-to-one to targets by minimum mean error over the run, no gate
    (:func:`~onebit.scoring.association.associate` with ``reduce="mean"``).
    """
    if tracks.height == 0 or truth.height == 0:
        return pl.DataFrame(schema=SCORES)
    tr = tracks.select("tracker", "track", "t", "x", "y").drop_nulls(["x", "y"])
    pairs = pair_samples(tr, truth, tolerance=tolerance, columns=("tracker", "x", "y")).with_columns(
        error=((pl.col("x") - pl.col("true_x")) ** 2 + (pl.col("y") - pl.col("true_y")) ** 2).sqrt()
    )
    if pairs.height == 0:
        return pl.DataFrame(schema=SCORES)
    matching = associate(pairs, cost="error", reduce="mean", gate=None)
    return conform(matched_pairs(pairs, matching).sort("t", maintain_order=True), SCORES)


def error_rows(scores: pl.DataFrame, *, stage: str, cell: float) -> list[tuple[str, str, float, str]]:
    """Mean, median, p90 error in cells and the fraction within 1, 2, 3, 4 cells."""
    if scores.height == 0:
        return []
    e = scores["error"] / cell
    rows = [
        (stage, "mean_error_cells", float(e.mean()), "cells"),
        (stage, "median_error_cells", float(e.median()), "cells"),
        (stage, "p90_error_cells", float(e.quantile(0.9, "linear")), "cells"),
    ]
    rows += [(stage, f"within_{k}", float((e <= k).mean()), "fraction") for k in (1, 2, 3, 4)]
    rows.append((stage, "scored_iterations", float(scores.height), "iterations"))
    return rows


def score(tracker: str, tables: dict, site: Site, region_graph=None) -> tuple[list[tuple[str, str, float, str]], dict]:
    """Report rows (:func:`error_rows`) and ``<tracker>_scores`` of ``intruder`` / ``intruder-naive``.

    Raises :class:`~onebit.scoring.serve.CannotServe` when the truth has more than one target
    at once: a single-target filter's error against several people means nothing."""
    tracks = tables.get(f"{tracker}_tracks")
    truth = tables.get("truth")
    if tracks is None or truth is None:
        return [], {}
    at_once = targets_at_once(truth)
    if at_once > 1:
        raise CannotServe(
            f"the truth has {at_once} targets at once; the filter tracks a single intruder (Schiff & Goldberg) -- "
            "declare 'targets' in site.toml to skip it, and use findinghumo or istate for several people"
        )
    it = tables.get(f"{tracker}_iterations")
    cell = float(it["cell"][0]) if it is not None and it.height else 1.0
    t = tracks["t"].sort().to_numpy()
    tol = float(np.median(np.diff(t))) / 2 if len(t) > 1 else 1.0
    sc = match_errors(tracks, truth, tolerance=tol)
    return error_rows(sc, stage=tracker, cell=cell), {f"{tracker}_scores": sc}
