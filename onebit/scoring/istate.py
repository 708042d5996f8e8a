"""Scoring of the I-state filter (O'Kane): does the I-state contain the true joint state?"""

from __future__ import annotations

import numpy as np
import polars as pl
import shapely

from onebit.core.site import Site
from onebit.core.wkb import geometries
from onebit.scoring.serve import CannotServe
from onebit.trackers.istate.core import has_perfect_matching

NAME = "istate"


def _summary_rows(summ: pl.DataFrame, site: Site) -> list[tuple[str, str, float, str]]:
    """The rows of the I-state's own summary: its elements, its area and share of the free
    space, the readings it rejected and the stages left empty."""
    free_area = float(site.free_space.area)
    rows = [
        (NAME, "elements_mean", float(summ["elements"].mean()) if summ.height else 0.0, "elements"),
        (NAME, "elements_max", float(summ["elements"].max()) if summ.height else 0.0, "elements"),
        (NAME, "area_mean", float(summ["area"].mean()) if summ.height else 0.0, f"{site.units}^2"),
        # the I-state's size beside its containment: a filter that keeps the truth by covering
        # the whole room says little (containment 1.0 at area_share 1.0 is the trivial I-state)
        (
            NAME,
            "area_share",
            float(summ["area"].mean()) / free_area if summ.height and free_area > 0 else float("nan"),
            "fraction of free space",
        ),
    ]
    if (
        "area_share" in summ.columns
    ):  # how much of the room the I-state leaves open: containment is only as good as this
        rows.append(
            (
                NAME,
                "area_share_mean",
                float(summ["area_share"].mean()) if summ.height else 0.0,
                "fraction of free space",
            )
        )
    if "rejected" in summ.columns:
        rows.append((NAME, "rejected_readings", float(summ["rejected"].sum()), "readings"))
        rows.append((NAME, "stages_with_rejects", float((summ["rejected"] > 0).sum()), "stages"))
    empty = summ.filter(pl.col("elements") == 0).height
    if empty:  # the readings contradict n targets under the sensing model (a wrong n, a lagging sensor)
        rows.append((NAME, "empty_stages", empty / summ.height, "fraction"))
    return rows


def _contained(regs: pl.DataFrame, stages: pl.DataFrame, pos: np.ndarray, present: np.ndarray, ok_truth, n: int):
    """Per stage, whether its I-state contains the present targets' true positions (``pos (K,
    T, 2)``): a perfect matching of the targets into one element's regions, the absent
    targets' regions free."""
    geoms = geometries(regs["wkb"])  # each distinct region parsed once
    st_idx = regs["stage"].to_numpy()
    bounds = np.searchsorted(st_idx, stages["stage"].to_numpy())
    bounds = np.r_[bounds, len(st_idx)]
    inside = np.zeros(len(stages), dtype=bool)
    for s in np.flatnonzero(ok_truth):  # one I-state per stage
        g = geoms[bounds[s] : bounds[s + 1]].reshape(-1, n)
        if len(g) == 0:
            continue
        pts = pos[s, present[s]]  # (m, 2), m <= n
        adj = shapely.intersects_xy(g[:, :, None], pts[None, None, :, 0], pts[None, None, :, 1])  # (E, n, m)
        free = np.ones(adj.shape[:2] + (n - pts.shape[0],), dtype=bool)  # absent targets fit any region
        inside[s] = bool(has_perfect_matching(np.concatenate([adj, free], axis=2)).any())
    return inside


# --------------------------------------------------------------------------- scoring


def score(tracker: str, tables: dict, site: Site, region_graph=None) -> tuple[list[tuple[str, str, float, str]], dict]:
    """``istate/containment``: fraction of scored stages whose I-state contains the true joint
    state; ``elements_mean``/``_max``; ``area_mean`` (mean area of the union of the regions
    within the free space) and ``area_share`` (that area over the free space's: always beside
    the containment); ``scored_stages``.

    ``targets`` is the most targets present at once (:mod:`onebit.scoring.serve`), so the
    truth may hold more ids than ``n`` over the run and fewer than ``n`` at a stage: a stage
    is scored when at least one target is present (truth within a twentieth of a period of
    the stage time), and contains the present ones when they lie in distinct regions of one
    element (the absent targets' regions are free: a matching that saturates the present
    targets). A stage with more targets present than ``n`` cannot be held by the I-state:
    :class:`~onebit.scoring.serve.CannotServe`, naming the first such time."""
    summ = tables.get(f"{NAME}_summary")
    regs = tables.get(f"{NAME}_regions")
    if summ is None or regs is None:
        return [], {}
    rows = _summary_rows(summ, site)
    truth = tables.get("truth")
    if truth is None or truth.height == 0 or summ.height == 0:
        return rows, {}
    tracks = tables.get(f"{NAME}_tracks")
    if regs.height:
        n = int(regs["k"].max()) + 1
    elif tracks is not None and tracks.height:
        n = int(tracks["track"].n_unique())
    else:
        n = int(site.targets or 0)
    if n == 0:
        return rows, {}
    targets = truth["target"].unique().sort().to_list()
    tol = 1e-6 + 0.05 * (float(summ["t"].diff().median() or 1.0))
    stages = summ.select("t", "stage").sort("t")
    pos = []
    for tgt in targets:  # one as-of join per target (a few)
        tt = truth.filter(pl.col("target") == tgt).select("t", "x", "y").sort("t")
        pos.append(stages.join_asof(tt, on="t", strategy="nearest", tolerance=tol).select("x", "y").to_numpy())
    pos = np.stack(pos, axis=1)  # (K, T, 2), NaN where a target is absent
    present = ~np.isnan(pos).any(axis=2)  # (K, T)
    count = present.sum(axis=1)
    over = np.flatnonzero(count > n)
    if over.size:
        k = int(over[0])
        raise CannotServe(
            f"the truth has {int(count[k])} targets at t = {float(stages['t'][k]):g} s but the I-state holds n = {n} "
            f"('targets' in site.toml, or [istate] targets): it must be the most targets present at once"
        )
    ok_truth = count > 0
    inside = _contained(regs, stages, pos, present, ok_truth, n)
    scored = int(ok_truth.sum())
    rows += [
        (NAME, "containment", float(inside[ok_truth].mean()) if scored else float("nan"), "fraction"),
        (NAME, "scored_stages", float(scored), "stages"),
    ]
    if "area_share" in summ.columns and scored:  # containment next to the share of the room it takes
        share = summ.sort("t")["area_share"].to_numpy()[ok_truth]
        rows.append((NAME, "area_share_scored", float(share.mean()), "fraction of free space"))
    out = stages.with_columns(contains=pl.Series(inside), scored=pl.Series(ok_truth))
    return rows, {f"{NAME}_containment": out}
