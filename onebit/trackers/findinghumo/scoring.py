"""Scoring of the HMM trackers in hops on the sensor graph (paper section IV-B).

The true node of a user at a slot is the node whose coverage it is in (nearest when several),
else the last one it was in (:func:`onebit.datasets.hallway_sim.current_node`, computed from
the truth positions and the site's sensor ranges -- the truth reader does not carry the
simulator's ``node`` column). For every slot a user is present, the truth sample nearest to
the slot's mid time is compared with each decoded track's node at that slot.

Matching: decoded tracks to true users one-to-one, minimising the summed hop error over the
whole run (``scipy.optimize.linear_sum_assignment``); a slot where the user is present and
the track is not counts as the graph diameter. ``hop_error`` is the mean over users and
slots of the shortest-path hop count between the true and the matched track's node
(the paper's metric, measured on the physical 1-hop graph).
"""

from __future__ import annotations

import numpy as np
import polars as pl
from scipy.optimize import linear_sum_assignment

from onebit.datasets.hallway_sim import current_node
from onebit.datasets.site import Site
from onebit.tables import SCORES, conform
from onebit.trackers.findinghumo.eatg import hop_matrix


def truth_nodes(truth: pl.DataFrame, site: Site) -> pl.DataFrame:
    """Truth with ``node`` filled from positions and sensor ranges where it is null."""
    ids = [m.id for m in site.motion_sensors]
    xy = np.array([m.position for m in site.motion_sensors])
    rng = np.array([m.range or 2.5 for m in site.motion_sensors])
    tr = truth.sort(["target", "t"])
    cur = current_node(tr.select("x", "y").to_numpy(), tr["target"].to_numpy(), xy, rng)
    names = pl.Series(np.asarray(ids + [None], dtype=object)[cur].tolist(), dtype=pl.String)
    if "node" in tr.columns:
        return tr.with_columns(node=pl.col("node").fill_null(names))
    return tr.with_columns(node=names)


def hop_scores(name: str, tables: dict, site: Site, log=None):
    """Report rows and ``<name>_scores`` (SCORES) for one HMM tracker."""
    rows: list[tuple[str, str, float, str]] = []
    tracks = tables.get(f"{name}_tracks")
    dec = tables.get(f"{name}_decoder")
    if dec is not None and dec.height and dec["slots"][0] > 0:
        per_slot = float(dec["seconds"][0]) / float(dec["slots"][0])
        rows.append((name, "decoder_seconds_per_slot", per_slot, "s"))
    truth = tables.get("truth")
    if tracks is None:
        return rows, {}
    n_dec = tracks["track"].n_unique()
    rows.append((name, "users_decoded", float(n_dec), "users"))
    if truth is None or truth.height == 0:
        return rows, {}
    g = site.sensor_graph
    nodes = g.nodes
    hops = hop_matrix(nodes, g.edges)
    diameter = int(hops[hops <= len(nodes)].max())
    idx = {n: i for i, n in enumerate(nodes)}
    tr = truth_nodes(truth, site).drop_nulls("node")
    targets = sorted(tr["target"].unique().to_list())
    rows.append((name, "users_true", float(len(targets)), "users"))
    if tracks.height == 0:
        rows.append((name, "hop_error", float(diameter), "hops"))
        return rows, {}
    # slot times of the run and the truth at each (slot, target)
    slot_t = tracks["t"].unique().sort()
    period = float(np.median(np.diff(slot_t.to_numpy()))) if slot_t.len() > 1 else 1.0
    grid = pl.DataFrame({"t": slot_t}).join(pl.DataFrame({"target": targets}), how="cross").sort("t")
    tr = tr.select("t", "target", "x", "y", "node").sort("t")
    true_at = grid.join_asof(
        tr, on="t", by="target", strategy="nearest", tolerance=period / 2 + 1e-9, check_sortedness=False  # both sorted by t
    ).drop_nulls("node")
    trk = sorted(tracks["track"].unique().to_list())
    tk = {t: i for i, t in enumerate(trk)}
    tg = {t: i for i, t in enumerate(targets)}
    est = tracks.select("t", "track", est=pl.col("node"))
    # hop error of every (slot, target) x track; missing track node = diameter
    pairs = true_at.join(pl.DataFrame({"track": trk}), how="cross").join(est, on=["t", "track"], how="left")
    ti = np.array([idx[n] for n in pairs["node"].to_list()])
    ei = np.array([idx.get(n, -1) if n is not None else -1 for n in pairs["est"].to_list()])
    h = np.where(ei >= 0, hops[ti, np.maximum(ei, 0)], diameter)
    pairs = pairs.with_columns(hop=pl.Series(h, dtype=pl.Int64))
    cost = np.zeros((len(trk), len(targets)))
    agg = pairs.group_by("track", "target").agg(pl.col("hop").sum())
    cost[[tk[t] for t in agg["track"]], [tg[t] for t in agg["target"]]] = agg["hop"].to_numpy()
    r, c = linear_sum_assignment(cost)
    mapping = {trk[a]: targets[b] for a, b in zip(r, c)}
    matched = pairs.filter(
        pl.struct("track", "target").is_in(pl.DataFrame({"track": list(mapping), "target": list(mapping.values())}).to_struct().implode())
    )
    # true users without a matched track count the diameter on every slot
    unmatched = [t for t in targets if t not in mapping.values()]
    per_user = matched.group_by("target").agg(pl.col("hop").mean().alias("m"), pl.len().alias("n"))
    total = float(matched["hop"].sum()) + diameter * true_at.filter(pl.col("target").is_in(unmatched)).height
    n_all = true_at.height
    rows.append((name, "hop_error", total / n_all if n_all else 0.0, "hops"))
    for tgt in targets:
        sel = per_user.filter(pl.col("target") == tgt)
        rows.append((name, f"hop_error/{tgt}", float(sel["m"][0]) if sel.height else float(diameter), "hops"))
    rows.append((name, "slots_exact", float((matched["hop"] == 0).mean()) if matched.height else 0.0, "fraction"))
    pos = {m.id: m.position for m in site.motion_sensors}
    exy = np.array([pos[n] if n is not None else (np.nan, np.nan) for n in matched["est"].to_list()]).reshape(-1, 2)
    err = np.hypot(exy[:, 0] - matched["x"].to_numpy(), exy[:, 1] - matched["y"].to_numpy())
    scores = conform(
        matched.with_columns(tracker=pl.lit(name), error=pl.Series(err, dtype=pl.Float64), hop_error=pl.col("hop")),
        SCORES,
    ).sort(["t", "track"])
    if log is not None:
        log.scores(name, scores)
    return rows, {f"{name}_scores": scores}
