"""Rerun logging of the ``findinghumo``, ``hmm1`` and ``hmm2`` stages.

Entity paths (under the tracker's root)::

    <tracker>/eatg/nodes            the sensor graph's nodes with their ids (static)
    <tracker>/eatg/a1               1-hop EATG edges, width by a' (static)
    <tracker>/eatg/a2               2-hop EATG edges, width by a'' (static)
    <tracker>/activations           active nodes of every slot (Points2D per slot)
    <tracker>/tracks/<user>         decoded user position (node) and its path so far
    <tracker>/decoded/<user>        the whole decoded node sequence as a line strip (static)
    <tracker>/switches              CPDA switches: node and the users re-paired, at their slot

Bulk series go through one ``send_columns`` each.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import rerun as rr

from onebit.viz import colors, paths
from onebit.viz._series import groups, is_empty
from onebit.viz.tracks import log_point_tracks


def _node_xy(site, nodes) -> np.ndarray:
    pos = {m.id: m.position for m in site.motion_sensors}
    return np.array([pos[n] for n in nodes], dtype=float).reshape(-1, 2)


def log_eatg(rec: rr.RecordingStream, tracker: str, eatg, site) -> None:
    """The sensor graph and the EATG weights as static line strips (width by weight)."""
    root = paths.tracker_root(tracker)
    xy = _node_xy(site, eatg.nodes)
    rec.log(paths.join(root, "eatg", "nodes"), rr.Points2D(xy, labels=list(eatg.nodes), radii=0.35, colors=(200, 200, 200)), static=True)
    for kind, mat, col in (("a1", eatg.a1, (90, 160, 255)), ("a2", eatg.a2, (255, 170, 60))):
        w = np.triu(mat + mat.T, k=1) / 2.0
        i, j = np.nonzero(w)
        if i.size == 0:
            continue
        strips = np.stack([xy[i], xy[j]], axis=1)
        radii = 0.03 + 0.25 * w[i, j] / w[i, j].max()
        rec.log(paths.join(root, "eatg", kind), rr.LineStrips2D(strips, radii=radii, colors=col), static=True)


def log_activations(rec: rr.RecordingStream, tracker: str, active: np.ndarray, site, nodes, t0: float, period: float) -> None:
    """Active nodes of every slot as points (one partition per slot)."""
    if active.size == 0:
        return
    xy = _node_xy(site, nodes)
    s, j = np.nonzero(active)
    lengths = active.sum(axis=1).astype(np.int64)
    t = t0 + np.arange(active.shape[0]) * period
    rec.send_columns(
        paths.join(paths.tracker_root(tracker), "activations"),
        indexes=[paths.time_column(t)],
        columns=rr.Points2D.columns(positions=xy[j], radii=np.full(j.size, 0.9, np.float32), colors=np.tile([255, 60, 60, 90], (j.size, 1))).partition(lengths),
    )


def log_decoded(rec: rr.RecordingStream, tracker: str, tracks: pl.DataFrame | None) -> None:
    """Each decoded user: moving point + path so far, and its whole node sequence (static)."""
    if is_empty(tracks):
        return
    log_point_tracks(rec, tracker, tracks)
    for user, g in groups(tracks.drop_nulls(["x", "y"]), "track"):
        xy = g.select("x", "y").to_numpy()
        rec.log(paths.decoded(tracker, user), rr.LineStrips2D([xy], colors=colors.color_of(user), radii=0.12), static=True)


def log_switches(rec: rr.RecordingStream, tracker: str, switches: pl.DataFrame | None, site, nodes, t0: float, period: float) -> None:
    """CPDA switches as labelled points at the node and slot where they happened."""
    if is_empty(switches):
        return
    pos = {m.id: m.position for m in site.motion_sensors}
    xy = np.array([pos[n] for n in switches["node"].to_list()], dtype=float).reshape(-1, 2)
    t = t0 + (switches["slot"].to_numpy() + 0.5) * period
    labels = [f"CPDA {u} -> {p}" for u, p in zip(switches["users"].to_list(), switches["pairing"].to_list())]
    rec.send_columns(
        paths.join(paths.tracker_root(tracker), "switches"),
        indexes=[paths.time_column(t)],
        columns=rr.Points2D.columns(positions=xy, labels=labels, radii=np.full(len(t), 1.2, np.float32), colors=np.tile([255, 230, 0, 200], (len(t), 1))).partition(np.ones(len(t), dtype=np.int64)),
    )


def log_run(rec: rr.RecordingStream, tracker: str, out: dict, *, site, region_graph, config, tables: dict) -> None:
    """Everything an HMM tracker produced: the EATG, active nodes per slot, decoded paths and
    (FindingHuMo) the CPDA switches."""
    art = out["artifacts"]
    log_eatg(rec, tracker, art["eatg"], site)
    log_activations(rec, tracker, art["active"], site, art["nodes"], art["t0"], art["period"])
    log_decoded(rec, tracker, out["tracks"])
    if "switches" in out:
        log_switches(rec, tracker, out["switches"], site, art["nodes"], art["t0"], art["period"])
