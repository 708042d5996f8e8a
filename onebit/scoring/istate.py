"""Scoring of the I-state filter (O'Kane): does the I-state contain the true joint state?"""

from __future__ import annotations

import numpy as np
import polars as pl
import shapely

from onebit.core.site import Site
from onebit.trackers.istate.core import IState, contains

NAME = "istate"

# --------------------------------------------------------------------------- scoring


def score(tracker: str, tables: dict, site: Site, region_graph=None) -> tuple[list[tuple[str, str, float, str]], dict]:
    """``istate/containment``: fraction of scored stages whose I-state contains the true joint
    state (truth at the stage time, all n targets present); ``elements_mean``/``_max``;
    ``area_mean`` (mean area of the union of the regions within the free space);
    ``scored_stages``."""
    summ = tables.get(f"{NAME}_summary")
    regs = tables.get(f"{NAME}_regions")
    if summ is None or regs is None:
        return [], {}
    rows = [
        (NAME, "elements_mean", float(summ["elements"].mean()) if summ.height else 0.0, "elements"),
        (NAME, "elements_max", float(summ["elements"].max()) if summ.height else 0.0, "elements"),
        (NAME, "area_mean", float(summ["area"].mean()) if summ.height else 0.0, f"{site.units}^2"),
    ]
    truth = tables.get("truth")
    if truth is None or truth.height == 0 or summ.height == 0:
        return rows, {}
    n = int(regs["k"].max()) + 1 if regs.height else 0
    targets = truth["target"].unique().sort().to_list()
    if n and len(targets) != n:
        rows.append((NAME, "target_count_mismatch", float(len(targets) - n), "targets"))
        return rows, {}
    tol = 1e-6 + 0.05 * (float(summ["t"].diff().median() or 1.0))
    stages = summ.select("t", "stage").sort("t")
    pos = []
    for tgt in targets:  # one as-of join per target (n is small)
        tt = truth.filter(pl.col("target") == tgt).select("t", "x", "y").sort("t")
        pos.append(stages.join_asof(tt, on="t", strategy="nearest", tolerance=tol).select("x", "y").to_numpy())
    pos = np.stack(pos, axis=1)  # (K, n, 2)
    ok_truth = ~np.isnan(pos).any(axis=(1, 2))
    geoms = shapely.from_wkb(regs["wkb"].to_numpy())
    st_idx = regs["stage"].to_numpy()
    bounds = np.searchsorted(st_idx, stages["stage"].to_numpy())
    bounds = np.r_[bounds, len(st_idx)]
    inside = np.zeros(len(stages), dtype=bool)
    for s in np.flatnonzero(ok_truth):  # one I-state per stage
        g = geoms[bounds[s] : bounds[s + 1]]
        inside[s] = len(g) > 0 and contains(IState(g.reshape(-1, n)), pos[s])
    scored = int(ok_truth.sum())
    rows += [
        (NAME, "containment", float(inside[ok_truth].mean()) if scored else float("nan"), "fraction"),
        (NAME, "scored_stages", float(scored), "stages"),
    ]
    out = stages.with_columns(contains=pl.Series(inside), scored=pl.Series(ok_truth))
    return rows, {f"{NAME}_containment": out}
