"""Rerun logging of the ``findinghumo``, ``hmm1`` and ``hmm2`` stages.

Entity paths (under the tracker's root)::

    <tracker>/eatg/nodes            the sensor graph's nodes with their ids (static)
    <tracker>/eatg/a1               1-hop EATG edges, width by a' (static)
    <tracker>/eatg/a2               2-hop EATG edges, width by a'' (static, hidden by default)
    <tracker>/activations           active nodes of every slot (red halos, one partition per slot)
    <tracker>/tracks/<user>         each decoded track now: a dot in a shade of the tracker's
                                    colour labelled "track k", its trail and hidden path
    <tracker>/decoded/<user>        the whole decoded node sequence (static, hidden by default)
    <tracker>/switches              CPDA switches: node and the tracks re-paired, at their slot
    <tracker>/cpda                  (findinghumo) every CPDA decision at its co-location node and
                                    slot: the pairing chosen and every alternative's probability
    <tracker>/joins                 (findinghumo-flow) the joins chosen by the flow at each
                                    meeting's cut slot, with the alternatives' probabilities
    <tracker>/joint                 every meeting the joint re-decoding changed, at a node of
                                    the pair from the meeting's first slot: tracks, gain in log L

Bulk series go through one ``send_columns`` each.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import bulk, paths
from onebit.viz._series import is_empty, strips_array
from onebit.viz.families import GENERIC, Look
from onebit.viz.frame import log_world_frame
from onebit.viz.tracks import log_point_tracks, track_colors, track_labels

rr = lazy_module("rerun")

NODE = (170, 170, 170, 255)
ACTIVE = (200, 45, 40, 255)
SWITCH = (255, 230, 0, 255)
DECISION = (80, 220, 255, 255)
#: how far (fraction of the site's diagonal) a joint re-decoding mark sits from its node
JOINT_OFFSET = 0.06


def _node_xy(site, nodes) -> np.ndarray:
    pos = {m.id: m.position for m in site.motion_sensors}
    return np.array([pos[n] for n in nodes], dtype=float).reshape(-1, 2)


def log_eatg(rec: rr.RecordingStream, tracker: str, eatg, site) -> None:
    """The sensor graph and the EATG weights as static line strips (width by weight)."""
    root = paths.tracker_root(tracker)
    log_world_frame(rec, root)
    xy = _node_xy(site, eatg.nodes)
    rec.log(
        paths.join(root, "eatg", "nodes"),
        rr.Points2D(
            xy, labels=list(eatg.nodes), radii=rr.Radius.ui_points(3.0), colors=NODE, show_labels=True, draw_order=10.0
        ),
        static=True,
    )
    for kind, mat, col in (("a1", eatg.a1, (120, 150, 190, 200)), ("a2", eatg.a2, (200, 150, 90, 150))):
        w = np.triu(mat + mat.T, k=1) / 2.0
        i, j = np.nonzero(w)
        if i.size == 0:
            continue
        strips = np.stack([xy[i], xy[j]], axis=1)
        radii = -(0.5 + 3.0 * w[i, j] / w[i, j].max())  # UI points, width by weight
        rec.log(
            paths.join(root, "eatg", kind),
            rr.LineStrips2D(strips, radii=radii, colors=col, draw_order=2.0),
            static=True,
        )


def log_activations(
    rec: rr.RecordingStream, tracker: str, active: np.ndarray, site, nodes, t0: float, period: float
) -> None:
    """Active nodes of every slot as points (one partition per slot)."""
    if active.size == 0:
        return
    xy = _node_xy(site, nodes)
    _, j = np.nonzero(active)
    lengths = active.sum(axis=1).astype(np.int64)
    t = t0 + np.arange(active.shape[0]) * period
    entity = paths.join(paths.tracker_root(tracker), "activations")
    log_world_frame(rec, entity)
    rec.log(entity, rr.Points2D.from_fields(radii=rr.Radius.ui_points(8.0), colors=ACTIVE, draw_order=9.0), static=True)
    rec.send_columns(
        entity, indexes=[paths.time_column(t)], columns=rr.Points2D.columns(positions=xy[j]).partition(lengths)
    )


def log_decoded(
    rec: rr.RecordingStream, tracker: str, tracks: pl.DataFrame | None, *, rgb: tuple[int, int, int] | None = None
) -> None:
    """Each decoded track: the dot now with its trail (:func:`log_point_tracks`) and its whole
    node sequence (static, hidden by default in the blueprint)."""
    if is_empty(tracks):
        return
    log_point_tracks(rec, tracker, tracks, rgb=rgb)
    labels = track_labels(tracker, tracks["track"].drop_nulls().unique().to_list())
    shades = track_colors(tracker, labels, rgb=rgb)
    spans = bulk.track_spans(tracks.drop_nulls(["x", "y"]).select("track", "t", "x", "y"), "track")
    if not spans.keys:
        return
    xy = spans.frame.select("x", "y").to_numpy()
    names = [f"{labels[user]}: whole decoded path" for user in spans.keys]
    tints = [shades[user] for user in spans.keys]
    template = rr.LineStrips2D(
        [xy[: spans.bounds[1]]], colors=tints[0], radii=rr.Radius.ui_points(2.0), labels=names[:1]
    )
    per_user = {
        "LineStrips2D:strips": strips_array(xy, spans.lengths),
        "LineStrips2D:colors": bulk.color_array(tints),
        "LineStrips2D:labels": bulk.text_batch(names),
    }
    bulk.log_styles(rec, [paths.decoded(tracker, user) for user in spans.keys], template, per_user)


def _one_based(indices: str) -> str:
    """``"0 1 2"`` (decoder user indices) -> ``"1 2 3"`` (the ``track k`` labels)."""
    return " ".join(str(int(i) + 1) if i.lstrip("-").isdigit() else i for i in str(indices).split())


def log_switches(
    rec: rr.RecordingStream, tracker: str, switches: pl.DataFrame | None, site, nodes, t0: float, period: float
) -> None:
    """CPDA switches as labelled points at the node and slot where they happened (shown for a
    trail window after their slot)."""
    if is_empty(switches):
        return
    pos = {m.id: m.position for m in site.motion_sensors}
    xy = np.array([pos[n] for n in switches["node"].to_list()], dtype=float).reshape(-1, 2)
    t = t0 + (switches["slot"].to_numpy() + 0.5) * period
    labels = [
        f"CPDA switch: tracks {_one_based(u)} -> {_one_based(p)}"
        for u, p in zip(switches["users"].to_list(), switches["pairing"].to_list())
    ]
    entity = paths.join(paths.tracker_root(tracker), "switches")
    log_world_frame(rec, entity)
    rec.log(
        entity,
        rr.Points2D.from_fields(radii=rr.Radius.ui_points(11.0), colors=SWITCH, show_labels=True, draw_order=8.0),
        static=True,
    )
    rec.send_columns(
        entity,
        indexes=[paths.time_column(t)],
        columns=rr.Points2D.columns(positions=xy, labels=labels).partition(np.ones(len(t), dtype=np.int64)),
    )


def _log_labelled_points(
    rec: rr.RecordingStream, entity: str, xy: np.ndarray, t: np.ndarray, labels: list[str], color
) -> None:
    log_world_frame(rec, entity)
    rec.log(
        entity,
        rr.Points2D.from_fields(radii=rr.Radius.ui_points(9.0), colors=color, show_labels=True, draw_order=8.5),
        static=True,
    )
    order = np.argsort(t, kind="stable")
    ts, first = np.unique(t[order], return_index=True)
    lengths = np.diff(np.append(first, len(order)))
    rec.send_columns(
        entity,
        indexes=[paths.time_column(ts)],
        columns=rr.Points2D.columns(positions=xy[order], labels=[labels[i] for i in order]).partition(lengths),
    )


def _cpda_label(users: str, pairing: str, switched: bool, p_chosen: float, alternatives: str, most: int = 3) -> str:
    """A CPDA decision as a short multi-line label: the pairing chosen and its probability,
    then the other pairings, most probable first (at most ``most``; the rest counted)."""
    alts = [(perm, float(prob)) for perm, prob in (a.rsplit(":", 1) for a in alternatives.split("; ") if ":" in a)]
    others = sorted((a for a in alts if a[0] != pairing), key=lambda a: -a[1])
    lines = [
        f"CPDA {'switch' if switched else 'keep'}: tracks {_one_based(users)} -> {_one_based(pairing)} (p={p_chosen:.2f})"
    ]
    lines += [f"  or {_one_based(perm)}: p={prob:.2f}" for perm, prob in others[:most]]
    if len(others) > most:
        rest = others[most][1]
        lines.append(f"  (+{len(others) - most} more, p " + ("< 0.01)" if rest < 0.005 else f"<= {rest:.2f})"))
    return "\n".join(lines)


def log_cpda(
    rec: rr.RecordingStream, tracker: str, decisions: pl.DataFrame | None, site, t0: float, period: float
) -> None:
    """Every CPDA decision (last pass) at its co-location node and slot, labelled with the
    pairing chosen and each alternative's probability."""
    if is_empty(decisions):
        return
    last = decisions.filter(pl.col("pass") == pl.col("pass").max())
    pos = {m.id: m.position for m in site.motion_sensors}
    xy = np.array([pos[n.split()[0]] for n in last["node"].to_list()], dtype=float).reshape(-1, 2)
    t = t0 + (last["slot"].to_numpy() + 0.5) * period
    labels = [
        _cpda_label(u, p, sw, pc, alts)
        for u, p, sw, pc, alts in last.select("users", "pairing", "switched", "p_chosen", "alternatives").iter_rows()
    ]
    _log_labelled_points(rec, paths.join(paths.tracker_root(tracker), "cpda"), xy, t, labels, DECISION)


def log_joins(
    rec: rr.RecordingStream, tracker: str, joins: pl.DataFrame | None, site, t0: float, period: float
) -> None:
    """The flow's chosen joins at each meeting's cut slot and node, labelled with the
    probability of every alternative join of the same incoming fragment."""
    if is_empty(joins):
        return
    chosen = joins.filter(pl.col("chosen"))
    if chosen.height == 0:
        return
    alts = joins.group_by("src").agg(
        pl.format("{}: {}", "dst", pl.col("probability").round(2)).str.join("; ").alias("alts")
    )
    chosen = chosen.join(alts, on="src", how="left")
    pos = {m.id: m.position for m in site.motion_sensors}
    xy = np.array([pos[n] for n in chosen["node"].to_list()], dtype=float).reshape(-1, 2)
    t = t0 + (chosen["slot"].to_numpy() + 0.5) * period
    labels = [
        f"join fragment {a} -> {b} (p={p:.2f}); alternatives {al}"
        for a, b, p, al in chosen.select("src", "dst", "probability", "alts").iter_rows()
    ]
    _log_labelled_points(rec, paths.join(paths.tracker_root(tracker), "joins"), xy, t, labels, DECISION)


def log_joint(rec: rr.RecordingStream, tracker: str, joint: pl.DataFrame | None, site) -> None:
    """The meetings the joint re-decoding changed (gain > 0), labelled with the two tracks,
    the gain in the joint log-likelihood and whether their tails were exchanged."""
    if is_empty(joint):
        return
    changed = joint.filter(pl.col("gain") > 0)
    if changed.height == 0:
        return
    pos = {m.id: m.position for m in site.motion_sensors}
    xy = np.array([pos[n] for n in changed["node"].to_list()], dtype=float).reshape(-1, 2)
    # CPDA labels its decisions at the same nodes and slots: the joint mark sits a little off
    # the node (JOINT_OFFSET of the site's diagonal) so the two labels do not overprint
    xy = xy + np.array([0.0, -JOINT_OFFSET * site.diagonal])
    t = changed["t"].to_numpy()
    labels = [
        f"joint: users {a[4:]},{b[4:]} +{g:.1f} nats{' (exchanged)' if ex else ''}"
        for a, b, g, ex in changed.select("track_a", "track_b", "gain", "exchanged").iter_rows()
    ]
    _log_labelled_points(rec, paths.join(paths.tracker_root(tracker), "joint"), xy, t, labels, DECISION)


def log_run(
    rec: rr.RecordingStream, tracker: str, out: dict, *, site, region_graph, config, tables: dict, look: Look = GENERIC
) -> None:
    """Everything an HMM tracker produced: the EATG, active nodes per slot, decoded paths and
    (FindingHuMo) the CPDA switches."""
    art = out["artifacts"]
    log_eatg(rec, tracker, art["eatg"], site)
    log_activations(rec, tracker, art["active"], site, art["nodes"], art["t0"], art["period"])
    log_decoded(rec, tracker, out["tracks"], rgb=look.rgb)
    if "switches" in out:
        log_switches(rec, tracker, out["switches"], site, art["nodes"], art["t0"], art["period"])
    if "cpda" in out:
        log_cpda(rec, tracker, out["cpda"], site, art["t0"], art["period"])
    if "joins" in out:
        log_joins(rec, tracker, out["joins"], site, art["t0"], art["period"])
    if "joint" in out:
        log_joint(rec, tracker, out["joint"], site)
