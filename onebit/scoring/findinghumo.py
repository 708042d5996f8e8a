"""Scoring of the HMM trackers in hops on the sensor graph (paper section IV-B).

The true node of a user at a slot is the node whose coverage it is in (nearest when several),
else the last one it was in (:func:`onebit.core.sensing.current_node`, computed from
the truth positions and the site's detection regions -- the truth reader does not carry the
simulator's ``node`` column). For every slot a user is present, the truth sample nearest to
the slot's mid time is compared with each decoded track's node at that slot.

Matching: decoded tracks to true users one-to-one, minimising the summed hop error over the
whole run, no gate (:func:`onebit.scoring.association.associate`, ``reduce="sum"``); a slot
where the user is present and the track is not counts as the graph diameter. ``hop_error``
is the mean over users and slots of the shortest-path hop count between the true and the
matched track's node (the paper's metric, measured on the physical 1-hop graph).
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.sensing import current_node, detection_regions
from onebit.core.site import Site
from onebit.core.tables import SCORES, conform
from onebit.models.graph_hmm.eatg import hop_matrix
from onebit.scoring.association import associate, matched_pairs, pair_samples

#: The last ``(truth, site, result)`` of :func:`truth_nodes`: the scores stage asks for the same
#: truth and site once per node tracker and per scorer (9 times in a five-tracker home run, 1 s
#: each on a day of 2 Hz truth); the same objects (``is``) give the same answer.
_LAST_TRUTH_NODES: list[tuple[pl.DataFrame, Site, pl.DataFrame]] = []


def truth_nodes(truth: pl.DataFrame, site: Site) -> pl.DataFrame:
    """Truth with ``node`` filled where it is null: the motion sensor whose detection region
    (:func:`onebit.core.sensing.detection_regions`) holds the position, nearest when several,
    else the last one the target was in (:func:`~onebit.core.sensing.current_node`)."""
    if _LAST_TRUTH_NODES and _LAST_TRUTH_NODES[0][0] is truth and _LAST_TRUTH_NODES[0][1] is site:
        return _LAST_TRUTH_NODES[0][2]
    out = _truth_nodes(truth, site)
    _LAST_TRUTH_NODES[:] = [(truth, site, out)]
    return out


def _truth_nodes(truth: pl.DataFrame, site: Site) -> pl.DataFrame:
    tr = truth.sort(["target", "t"])
    if "node" in tr.columns and tr["node"].null_count() == 0:
        return tr
    regions = detection_regions(site)
    ids = [m.id for m in site.motion_sensors]
    cur = current_node(tr.select("x", "y").to_numpy(), tr["target"].to_numpy(), [regions[i] for i in ids])
    names = pl.Series(np.asarray(ids + [None], dtype=object)[cur].tolist(), dtype=pl.String)
    if "node" in tr.columns:
        return tr.with_columns(node=pl.col("node").fill_null(names))
    return tr.with_columns(node=names)


def score(name: str, tables: dict, site: Site, region_graph=None):
    """Report rows and ``<name>_scores`` (SCORES) for one HMM tracker."""
    rows: list[tuple[str, str, float, str]] = []
    tracks = tables.get(f"{name}_tracks")
    dec = tables.get(f"{name}_decoder")
    timings = tables.get("timings")
    secs = (
        timings.filter(pl.col("stage") == name)["seconds"] if timings is not None else pl.Series([], dtype=pl.Float64)
    )
    if dec is not None and dec.height and dec["slots"][0] > 0 and secs.len():
        per_slot = float(secs[0]) / float(dec["slots"][0])  # the whole stage, timed by the runner
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
    # every (slot, user present, track): the truth sample nearest to the slot, the track's node
    slot_t = tracks["t"].unique().sort()
    period = float(np.median(np.diff(slot_t.to_numpy()))) if slot_t.len() > 1 else 1.0
    pairs = pair_samples(
        tracks.select("track", "t", est="node"),
        tr,
        tolerance=period / 2 + 1e-9,
        columns=("est",),
        truth_columns=("x", "y", "node"),
        complete=True,
    ).rename({"true_x": "x", "true_y": "y", "true_node": "node"})
    true_at = pairs.select("t", "target").unique()
    # hop error of every pair; a slot the track misses (or a node off the graph) = diameter
    ti = pairs["node"].replace_strict(list(idx), list(idx.values()), return_dtype=pl.Int64).to_numpy()
    ei = (
        pairs["est"]
        .replace_strict(list(idx), list(idx.values()), default=-1, return_dtype=pl.Int64)
        .fill_null(-1)
        .to_numpy()
    )
    h = np.where(ei >= 0, hops[ti, np.maximum(ei, 0)], diameter)
    pairs = pairs.with_columns(hop=pl.Series(h, dtype=pl.Int64))
    # one association: minimum summed hop error over the run, no gate (the paper's metric)
    matching = associate(pairs, cost="hop", reduce="sum", gate=None)
    mapping = dict(zip(matching["track"], matching["target"]))
    matched = matched_pairs(pairs, matching)
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
    ids = [m.id for m in site.motion_sensors]
    px, py = ([float(m.position[k]) for m in site.motion_sensors] for k in (0, 1))
    ex = matched["est"].replace_strict(ids, px, default=None, return_dtype=pl.Float64).to_numpy()
    ey = matched["est"].replace_strict(ids, py, default=None, return_dtype=pl.Float64).to_numpy()
    err = np.hypot(ex - matched["x"].to_numpy(), ey - matched["y"].to_numpy())
    scores = conform(
        matched.with_columns(tracker=pl.lit(name), error=pl.Series(err, dtype=pl.Float64), hop_error=pl.col("hop")),
        SCORES,
    ).sort(["t", "track"])
    return rows, {f"{name}_scores": scores}
