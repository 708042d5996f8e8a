"""Scoring of CLUSTERTRACK (Singh et al. section 6): error in units of R, targets found."""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.site import Site
from onebit.core.tables import SCORES, conform
from onebit.scoring.association import associate, cost_table, matched_pairs, pair_samples

NAME = "clustertrack"

# --------------------------------------------------------------------------- scoring


def track_pairs(truth: pl.DataFrame, tracks: pl.DataFrame) -> pl.DataFrame:
    """Every track row paired with the truth of every target at the nearest truth time (no
    tolerance: the paper interpolates its truth to every instant), with ``err`` =
    :math:`|\\hat P_k(t) - X_g(t)|` (1D tracks have ``y`` null, taken as 0)."""
    tr = tracks.select("track", "t", "x", pl.col("y").fill_null(0.0))
    return pair_samples(tr, truth, tolerance=None).with_columns(
        err=((pl.col("x") - pl.col("true_x")) ** 2 + (pl.col("y") - pl.col("true_y")) ** 2).sqrt()
    )


def match_tracks(truth: pl.DataFrame, tracks: pl.DataFrame) -> tuple[list[str], list[str], np.ndarray, pl.DataFrame]:
    """Mean distance (over the track's instants) between every target and every track.

    Returns ``(targets, tracks, D (Q, N), pairs)``: :math:`D_{gk} = C_{kg}` of
    :func:`~onebit.scoring.association.cost_table` (``reduce="mean"``) on :func:`track_pairs`,
    ``inf`` where a target and a track share no instant.
    """
    targets = sorted(truth["target"].unique().to_list())
    names = sorted(tracks["track"].unique().to_list())
    if not targets or not names:
        return targets, names, np.zeros((len(targets), len(names))), pl.DataFrame()
    pairs = track_pairs(truth, tracks)
    m = cost_table(pairs, cost="err", reduce="mean")
    D = np.full((len(targets), len(names)), np.inf)
    gi = {g: i for i, g in enumerate(targets)}
    ti = {t: i for i, t in enumerate(names)}
    D[[gi[g] for g in m["target"]], [ti[t] for t in m["track"]]] = m["cost"].to_numpy()
    return targets, names, D, pairs


def score(
    tracker: str, tables: dict, site: Site, region_graph=None
) -> tuple[list[tuple[str, str, float, str]], dict[str, pl.DataFrame]]:
    """Report rows: mean_error_R, targets_true, targets_found, spurious_tracks,
    count_lower_bound, count_consensus; table ``clustertrack_scores`` (SCORES).

    ``mean_error_R`` is the paper's error: per target the mean distance (over the instants)
    to the *nearest* track, :math:`\\frac{1}{Q R} \\sum_g \\min_k D_{gk}`. ``targets_found``
    are the targets the one association
    (:func:`~onebit.scoring.association.associate`, mean error, gate :math:`D_0`) matches.
    """
    rows: list[tuple[str, str, float, str]] = []
    params = tables.get(f"{NAME}_params")
    if params is None or params.height == 0:
        return rows, {}
    R, D0 = float(params["R"][0]), float(params["D0"][0])
    rows.append((NAME, "count_lower_bound", float(params["count_lower_bound"][0]), "targets"))
    if int(params["count_consensus"][0]) >= 0:
        rows.append((NAME, "count_consensus", float(params["count_consensus"][0]), "targets"))
    rows.append((NAME, "tracks", float(params["tracks"][0]), "tracks"))
    rows.append((NAME, "reruns", float(params["reruns"][0]), "reruns"))
    truth, tracks = tables.get("truth"), tables.get(f"{NAME}_tracks")
    if truth is None or truth.height == 0 or tracks is None:
        return rows, {}
    targets, names, D, pairs = match_tracks(truth, tracks)
    rows.append((NAME, "targets_true", float(len(targets)), "targets"))
    if not names:
        rows += [(NAME, "targets_found", 0.0, "targets"), (NAME, "spurious_tracks", 0.0, "tracks")]
        return rows, {}
    nearest = D.min(axis=1)
    rows.append((NAME, "mean_error_R", float(nearest.mean() / R), "R"))
    # one association: minimum summed mean error, a pair matched only within D0 (a target "found")
    matched = associate(pairs, cost="err", reduce="mean", gate=D0)
    found = matched.height
    rows += [
        (NAME, "targets_found", float(found), "targets"),
        (NAME, "spurious_tracks", float(len(names) - found), "tracks"),
    ]
    sc = matched_pairs(pairs, matched).with_columns(tracker=pl.lit(NAME), error=pl.col("err"))
    sc = conform(sc, SCORES).sort(["t", "track"])
    rows.append((NAME, "error_mean_matched", float(sc["error"].mean()) if sc.height else float("nan"), site.units))
    return rows, {f"{NAME}_scores": sc}
