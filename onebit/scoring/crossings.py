"""Scores: truth -> true regions and crossings; reconstructed agents matched to true agents.

* :func:`true_crossings_from_truth` -- truth positions -> the region each target is in at each
  sample -> a crossing wherever the region changes (the beam is the one joining the two
  regions, nearest to the two samples when several do, as b and c in the building).
* :func:`match_crossings` -- observed crossings matched one-to-one to true crossings with the
  same beam and direction, nearest in time within a tolerance.
* :func:`assignment_scores` -- reconstructed agents matched one-to-one to true agents by
  maximising the number of shared crossings (the one association,
  :func:`onebit.scoring.association.associate`, with cost minus one per shared crossing).
* :func:`region_scores` -- the region-level localisation error of every matched agent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import polars as pl
import shapely

from onebit.core.errors import ConfigError
from onebit.core.params import param, validate
from onebit.core.region_graph import RegionGraph
from onebit.core.site import Site
from onebit.core.tables import SCORES, TRUE_CROSSINGS, conform
from onebit.scoring.association import associate
from onebit.scoring.correction import score_correction

#: The most MOT gates of ``[scores] gates_m``: each is one association of every tracker's tracks.
MAX_GATES = 32


@dataclass(frozen=True, kw_only=True)
class ScoresConfig:
    """``run.toml`` ``[scores]``: scoring parameters."""

    crossing_tolerance_s: float = param(
        1.0,
        "largest time difference between an observed crossing and the true crossing it is matched to",
        lo=0.0,
        unit="s",
    )
    gates_m: tuple[float, ...] = param(
        (1.0,),
        "the metric gates, in metres (onebit.scoring.mot converts them to the site's units itself, so the "
        "field carries no unit to convert), at which every tracker with positions gets MOTA, IDF1, HOTA, ... "
        "(rows mota@1m); the irtracking authors score at 1.5 m",
    )

    def __post_init__(self) -> None:
        validate(self)
        g = self.gates_m
        if isinstance(g, (int, float)) and not isinstance(g, bool):
            g = (g,)
        if not isinstance(g, (list, tuple)) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0 for v in g
        ):
            raise ConfigError(
                f"ScoresConfig.gates_m = {self.gates_m!r}; expected a list of positive distances in metres, e.g. [1.0, 1.5]"
            )
        if len(g) > MAX_GATES:  # each gate is one MOT association of every tracker
            raise ConfigError(f"ScoresConfig.gates_m: {len(g)} gates, more than the {MAX_GATES} allowed")
        object.__setattr__(self, "gates_m", tuple(float(v) for v in dict.fromkeys(g)))


def truth_regions(truth: pl.DataFrame, rg: RegionGraph) -> pl.DataFrame:
    """Fill ``region`` of a truth table from the region graph (vectorised point-in-polygon)."""
    names = np.asarray(list(rg.names) + [None], dtype=object)
    idx = rg.region_index_of(truth["x"].to_numpy(), truth["y"].to_numpy())
    return truth.with_columns(region=pl.Series(names[idx].tolist(), dtype=pl.String))


def true_crossings_from_truth(truth: pl.DataFrame, site: Site, rg: RegionGraph) -> pl.DataFrame:
    """Crossings implied by the truth positions (TRUE_CROSSINGS schema).

    A sample outside every region (inside a wall, exactly on a beam) keeps the region of the
    sample before it. Consecutive samples of one target in regions ``i != j`` give a crossing
    at the mid time, on the beam ``beta`` with an edge ``i -> j`` nearest to the mid point.
    """
    if truth.height == 0:
        return pl.DataFrame(schema=TRUE_CROSSINGS)
    idx = rg.region_index_of(truth["x"].to_numpy(), truth["y"].to_numpy())
    tr = truth.select("t", "target", "x", "y").with_columns(ridx=pl.Series(idx).replace(-1, None)).sort(["target", "t"])
    tr = tr.with_columns(pl.col("ridx").forward_fill().over("target"))
    prev = [pl.col(c).shift(1).over("target").alias(f"p_{c}") for c in ("t", "x", "y", "ridx")]
    ch = tr.with_columns(prev).filter(pl.col("p_ridx").is_not_null() & (pl.col("ridx") != pl.col("p_ridx")))
    if ch.height == 0:
        return pl.DataFrame(schema=TRUE_CROSSINGS)
    beams = list(rg.beam_source)
    bidx = rg.index
    fs = np.array([bidx[rg.beam_source[b]] for b in beams])
    ft = np.array([bidx[rg.beam_target[b]] for b in beams])
    i = ch["p_ridx"].to_numpy()[:, None]
    j = ch["ridx"].to_numpy()[:, None]
    fwd = (fs[None, :] == i) & (ft[None, :] == j)
    bwd = (fs[None, :] == j) & (ft[None, :] == i)
    mid = np.c_[(ch["x"] + ch["p_x"]).to_numpy() / 2, (ch["y"] + ch["p_y"]).to_numpy() / 2]
    lines = np.array([site.beam(b).line for b in beams], dtype=object)
    dist = shapely.distance(shapely.points(mid)[:, None], lines[None, :])
    dist = np.where(fwd | bwd, dist, np.inf)
    k = np.argmin(dist, axis=1)
    found = np.isfinite(dist[np.arange(len(k)), k])
    direction = np.where(fwd[np.arange(len(k)), k], 1, -1)
    out = pl.DataFrame(
        {
            "t": ((ch["t"] + ch["p_t"]) / 2).to_numpy(),
            "beam": np.asarray(beams, dtype=object)[k].tolist(),
            "direction": direction.astype(np.int8),
            "target": ch["target"],
        }
    ).filter(pl.Series(found))
    return conform(out, TRUE_CROSSINGS).sort("t")


def match_crossings(observed: pl.DataFrame, true: pl.DataFrame, tolerance: float) -> pl.DataFrame:
    """Observed crossings with ``target`` and ``dt`` of the true crossing each one recovers.

    Each observed crossing takes the nearest true crossing of the same beam and direction
    within ``tolerance`` seconds; when two observed crossings take the same true one, the
    nearer keeps it and the other stays unmatched (target null).
    """
    obs = observed.with_row_index("obs").sort("t")
    tru = (
        true.select("t", "beam", "direction", "target")
        .with_row_index("true_id")
        .with_columns(t_true=pl.col("t"))
        .sort("t")
    )
    j = obs.join_asof(
        tru.drop("target"),
        on="t",
        by=["beam", "direction"],
        strategy="nearest",
        tolerance=tolerance,
        check_sortedness=False,
    )
    j = j.with_columns(dt=(pl.col("t") - pl.col("t_true")).abs())
    best = pl.col("dt") == pl.col("dt").min().over("true_id")
    first = pl.col("obs") == pl.col("obs").filter(best).min().over("true_id")
    j = j.with_columns(
        pl.when(pl.col("true_id").is_not_null() & best & first).then(pl.col("true_id")).otherwise(None).alias("true_id")
    )
    j = j.join(tru.select("true_id", "target"), on="true_id", how="left")
    return j.sort("obs").drop("obs", "t_true")


def assignment_scores(matched: pl.DataFrame, assignment: pl.DataFrame) -> tuple[float, dict[str, str]]:
    """Fraction of observed crossings attributed to the matched true agent, and the matching.

    ``matched``: observed crossings in order with ``target`` (null when no true crossing
    matched); ``assignment``: the same crossings in the same order with ``track``.
    The agents are matched by the one association
    (:func:`~onebit.scoring.association.associate`) with the per-crossing cost
    :math:`c_s = -1` for every crossing a (track, target) pair shares, summed: minimum
    :math:`\\sum C_{kg} = -` maximum number of shared crossings, gate :math:`\\gamma = 0`
    (an agent sharing no crossing with a true agent stays unmatched). The accuracy is
    :math:`-\\sum_{matched} C_{kg} / N_{crossings}`.
    """
    if assignment.height == 0:
        return 1.0, {}
    pairs = pl.DataFrame({"track": assignment["track"], "target": matched["target"].cast(pl.String)}).drop_nulls()
    if pairs.height == 0:
        return 0.0, {}
    matching = associate(pairs.with_columns(cost=pl.lit(-1.0)), cost="cost", reduce="sum", gate=0.0)
    mapping = dict(zip(matching["track"], matching["target"]))
    return float(-matching["cost"].sum() / assignment.height), mapping


def region_scores(
    tracks: pl.DataFrame, truth: pl.DataFrame, mapping: dict[str, str], rg: RegionGraph, *, tracker: str
) -> pl.DataFrame:
    """Per truth sample of every matched target: the matched track's region against the truth.

    ``error`` (world units) = distance from the true position to the track's region polygon
    (0 when the true agent is inside the estimated region); ``hop_error`` = hops between the
    estimated and the true region in the undirected region graph.

    Vectorised: regions travel as indices (names mapped once by polars), the hops are one
    gather, and a shapely distance is computed only for samples outside the estimated region
    (a sample inside its true region, when that is the estimated one, is at distance 0 --
    exactly what shapely returns), without making point geometries
    (:func:`polygon_distance_xy`). Same output as :func:`onebit._testing.oracles.region_scores_reference`.
    """
    if not mapping or truth.height == 0 or tracks.height == 0:
        return pl.DataFrame(schema=SCORES)
    idx = rg.index
    m = pl.DataFrame({"track": list(mapping), "target": list(mapping.values())})
    est = (
        tracks.select("track", "t", "region")
        .join(m, on="track")
        .with_columns(e=pl.col("region").replace_strict(list(idx), list(idx.values()), return_dtype=pl.Int64))
        .drop("region")
        .sort("t")
    )
    tru = truth.select("t", "target", "x", "y")
    g = rg.region_index_of(tru["x"].to_numpy(), tru["y"].to_numpy())
    tru = tru.with_columns(g=pl.Series(g, dtype=pl.Int64)).filter(pl.col("g") >= 0).sort("t")
    j = tru.join_asof(est, on="t", by="target", strategy="backward", check_sortedness=False).drop_nulls("e")
    if j.height == 0:
        return pl.DataFrame(schema=SCORES)
    e = j["e"].to_numpy()
    g = j["g"].to_numpy()
    hops = rg.hop_distance()[e, g]
    err = np.zeros(j.height)
    away = np.flatnonzero(e != g)
    if away.size:
        polys = np.asarray(rg.polygons, dtype=object)
        err[away] = polygon_distance_xy(polys, e[away], j["x"].to_numpy()[away], j["y"].to_numpy()[away])
    out = j.select("track", "target", "t").with_columns(
        tracker=pl.lit(tracker), error=pl.Series(err, dtype=pl.Float64), hop_error=pl.Series(hops, dtype=pl.Int64)
    )
    return conform(out, SCORES)


def polygon_distance_xy(polys: np.ndarray, which: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``shapely.distance(polys[which], shapely.points(x, y))``, the same bits, without making a
    point geometry per sample (making them cost most of :func:`region_scores`).

    For a polygon GEOS's distance to a point is 0 when the point is in or on it, else the least
    distance to a segment of its rings, each by ``Distance::pointToSegment``; both are done
    here in numpy, vectorised over the points, the segment formula written as GEOS writes it
    (same operations in the same order, so the same rounding). A loop over the distinct
    polygons (regions: few) and their segments. Anything but a non-empty polygon or
    multipolygon goes to shapely.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    which = np.asarray(which, dtype=np.int64)
    out = np.empty(len(x))
    order = np.argsort(which, kind="stable")
    ks, starts = np.unique(which[order], return_index=True)
    for k, sel in zip(ks.tolist(), np.split(order, starts[1:])):
        poly = polys[k]
        px, py = x[sel], y[sel]
        if shapely.get_type_id(poly) not in (3, 6) or shapely.is_empty(poly):
            out[sel] = shapely.distance(poly, shapely.points(px, py))
            continue
        d = np.full(len(sel), np.inf)
        for ring in shapely.get_rings(shapely.get_parts(poly)).tolist():
            c = shapely.get_coordinates(ring)
            for (ax, ay), (bx, by) in zip(c[:-1].tolist(), c[1:].tolist()):
                d = np.minimum(d, _point_segment_distance(px, py, ax, ay, bx, by))
        d[shapely.intersects_xy(poly, px, py)] = 0.0
        out[sel] = d
    return out


def _point_segment_distance(px: np.ndarray, py: np.ndarray, ax: float, ay: float, bx: float, by: float) -> np.ndarray:
    """GEOS's ``Distance::pointToSegment(p, A, B)`` for arrays of points ``p``."""
    ux, uy = px - ax, py - ay
    da = np.sqrt(ux * ux + uy * uy)  # p.distance(A)
    if ax == bx and ay == by:
        return da
    dx, dy = bx - ax, by - ay
    len2 = dx * dx + dy * dy
    r = (ux * dx + uy * dy) / len2
    vx, vy = px - bx, py - by
    db = np.sqrt(vx * vx + vy * vy)  # p.distance(B)
    s = ((ay - py) * dx - (ax - px) * dy) / len2
    mid = np.abs(s) * np.sqrt(len2)
    return np.where(r <= 0.0, da, np.where(r >= 1.0, db, mid))


def error_summary(scores: pl.DataFrame, *, stage: str, unit: str) -> list[tuple[str, str, float, str]]:
    """Mean, median, p90 error and the fraction within 1..4 hops, as report rows."""
    if scores.height == 0:
        return []
    e = scores["error"]
    rows = [
        (stage, "error_mean", float(e.mean()), unit),
        (stage, "error_median", float(e.median()), unit),
        (stage, "error_p90", float(e.quantile(0.9, "linear")), unit),
    ]
    h = scores["hop_error"].drop_nulls()
    if h.len():
        rows.append((stage, "region_accuracy", float((h == 0).mean()), "fraction"))
        rows.append((stage, "hop_error_mean", float(h.mean()), "hops"))
        rows += [(stage, f"within_{k}_hops", float((h <= k).mean()), "fraction") for k in (1, 2, 3, 4)]
    return rows


def score_crossings(
    tables: dict, cfg: ScoresConfig
) -> tuple[list[tuple[str, str, float, str]], dict[str, pl.DataFrame]]:
    """Decoded crossings against the truth, and the correction's restored crossings.

    Report: ``crossings/decoded_match`` (fraction of true crossings some observed crossing
    recovers), ``crossings/true``, ``crossings/spurious``; with the ``correct`` stage, its
    :func:`~onebit.scoring.correction.score_correction` rows; in simulation
    ``truth/crossings_from_positions`` (fraction of the simulator's own crossing list that the
    truth positions reproduce). Tables: ``crossing_matches`` (observed crossings with the true
    target they recover), ``corrected_targets`` (per corrected crossing, its true target).
    """
    rows: list[tuple[str, str, float, str]] = []
    out: dict[str, pl.DataFrame] = {}
    t = tables
    if "crossings" in t and "true_crossings" in t:
        m = match_crossings(t["crossings"], t["true_crossings"], cfg.crossing_tolerance_s)
        n_true = t["true_crossings"].height
        recovered = m["true_id"].drop_nulls().n_unique()
        rows.append(("crossings", "decoded_match", recovered / n_true if n_true else 1.0, "fraction"))
        rows.append(("crossings", "true", float(n_true), "crossings"))
        rows.append(("crossings", "spurious", float(m["true_id"].null_count()), "crossings"))
        out["crossing_matches"] = m
        if "corrected_crossings" in t:
            c_rows, c_tables, targets = score_correction(t, m)
            rows += c_rows
            out.update(c_tables)
            out["corrected_targets"] = targets
    if "sim_crossings" in t and "true_crossings" in t:
        m2 = match_crossings(t["true_crossings"], t["sim_crossings"], cfg.crossing_tolerance_s)
        n = t["sim_crossings"].height
        rows.append(
            ("truth", "crossings_from_positions", m2["true_id"].drop_nulls().n_unique() / n if n else 1.0, "fraction")
        )
    return rows, out
