"""Stages ``findinghumo`` (Adaptive-HMM + CPDA) and the baselines ``hmm1`` / ``hmm2``.

``findinghumo`` (paper Algorithm 1): slot the motion log at ``period`` T, learn the EATG,
decode the users window by window with the Adaptive-HMM (first order on non-overlapping
motion over the active nodes and their 1-hop neighbours, second order over up to 2-hop
neighbours on overlapping motion), then disambiguate crossovers with CPDA over the last ``C``
windows. ``hmm1`` / ``hmm2`` (section IV-B): full-state first / second-order HMMs decoded
online on the same windows (or ``offline = true``: one window over the whole run), no CPDA.

Outputs (tables ``<tracker>_<key>``): ``tracks`` (TRACKS; one row per user and slot at the
slot's mid time, ``node`` and its x/y), ``eatg`` (kind, src, dst, weight, hops), ``windows``
(per HMM window: slot, K, K_now, Sig_in, Sig_out, order, states, overlap), ``decoder``
(slots, seconds), ``events`` (TRACKER_EVENTS: the track each ON edge went to,
:func:`onebit.trackers.attribution.attribute_events`), and for ``findinghumo`` ``switches`` (CPDA switches: slot, node, users,
pairing) and ``cpda`` (every co-location event CPDA decided, with the alternatives'
posteriors, :func:`~onebit.trackers.findinghumo.cpda.decisions_table`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.frames import outside_silence, silent_stretches
from onebit.core.params import param
from onebit.core.site import Site
from onebit.core.tables import MOTION, check_schema
from onebit.models.graph_hmm.decoding import (
    JOINT,
    WINDOWS,
    HmmConfig,
    available,
    build_eatg,
    cap_users,
    decode_key,
    decode_motion,
    door_signatures,
    slot_activity,
    tracks_table,
    user_bound,
    windows_table,
)
from onebit.models.graph_hmm.joint import joint_table, redecode_meetings
from onebit.trackers.attribution import attribute_events
from onebit.trackers.base import ARTIFACTS, PROGRESS, TrackerSpec, home_count_bound
from onebit.trackers.findinghumo.cpda import cpda, decisions_table, switches_table
from onebit.trackers.findinghumo.lagged import lagged_paths

__all__ = [
    "WINDOWS",
    "HmmConfig",
    "FindingHumoConfig",
    "SPECS",
    "build_eatg",
    "cap_users",
    "door_signatures",
    "slot_activity",
    "run_findinghumo",
    "run_hmm1",
    "run_hmm2",
]


@dataclass(frozen=True, kw_only=True)
class FindingHumoConfig(HmmConfig):
    """``[findinghumo]``: the shared HMM options plus CPDA's."""

    c_windows: int = param(
        2, "C, the number of HMM windows CPDA looks back and ahead over (paper example: 2)", lo=1, hi=1000
    )
    cpda_passes: int = param(5, 'maximum number of CPDA passes ("repeat until stable")', lo=1, hi=100)
    joint: str = param(
        "before-cpda",
        "as in the shared HMM options, here before-cpda by default: the paper leaves open how the K users' "
        "paths are decoded jointly; re-decoding each meeting of two users exactly is part of that decoding, "
        "and CPDA then runs on its output as on the HMM's in the paper. Measured (docs/findinghumo.md): "
        "seeds 0-59 0.536 vs 0.570 after-cpda",
        choices=JOINT,
    )


def _run(name: str, mode: str, inputs: dict, site: Site, cfg: HmmConfig) -> dict[str, pl.DataFrame]:
    if cfg.decoding == "lagged":
        return _run_lagged(name, mode, inputs, site, cfg)
    run = decode_motion(mode, inputs, site, cfg, progress=inputs.get(PROGRESS))
    g = site.sensor_graph
    nodes = g.nodes
    active, t0, eatg, res, silent = run.active, run.t0, run.eatg, run.result, run.silent
    paths = res.paths
    out: dict[str, pl.DataFrame] = {}
    cap = cfg.max_users or (site.targets or 0) or home_count_bound(inputs)
    joint_log: list[dict] = []
    if cfg.joint == "before-cpda" or (cfg.joint == "after-cpda" and not isinstance(cfg, FindingHumoConfig)):
        paths, joint_log = redecode_meetings(
            paths, active, eatg, p_hit=cfg.p_hit, p_false=cfg.p_false, pad=cfg.joint_pad, reach=cfg.joint_hops
        )
    cpda_input = paths
    if isinstance(cfg, FindingHumoConfig):
        feature = np.isin(np.asarray(nodes), list(g.entries) + list(g.exits))
        cp = cpda(
            paths,
            eatg.a2,
            horizon=cfg.c_windows * cfg.d_max,
            feature=feature,
            hops=eatg.hops,
            max_passes=cfg.cpda_passes,
        )
        decoded = cap_users(res.paths, active, eatg.hops, cap)
        out["decoded_hmm"] = outside_silence(tracks_table(name, decoded, nodes, site, t0, cfg.period), silent).drop(
            "tracker"
        )
        paths = cp.paths
        out["switches"] = switches_table(cp, nodes)
        out["cpda"] = decisions_table(cp, nodes)
        if cfg.joint == "after-cpda":
            paths, joint_log = redecode_meetings(
                paths, active, eatg, p_hit=cfg.p_hit, p_false=cfg.p_false, pad=cfg.joint_pad, reach=cfg.joint_hops
            )
    if cfg.joint != "off":
        out["joint"] = joint_table(joint_log, nodes, t0, cfg.period)
    paths = cap_users(paths, active, eatg.hops, cap)
    tracks = outside_silence(tracks_table(name, paths, nodes, site, t0, cfg.period), silent)  # the empty room: no track
    out["tracks"] = tracks
    out["events"] = attribute_events(inputs["motion"], tracks, nodes, eatg.hops, t0=t0, period=cfg.period)
    out["eatg"] = eatg.table()
    out["windows"] = windows_table(res)
    out["decoder"] = pl.DataFrame({"slots": [int(active.shape[0])], "users": [int(paths.shape[0])]})
    out[ARTIFACTS] = {"eatg": eatg, "active": active, "nodes": nodes, "t0": t0, "period": cfg.period, "paths": paths}
    if isinstance(cfg, FindingHumoConfig):
        out[ARTIFACTS]["decoded_paths"] = (
            cpda_input  # what CPDA started from (the Adaptive-HMM's, re-decoded at meetings)
        )
    return out


def _run_lagged(name: str, mode: str, inputs: dict, site: Site, cfg: HmmConfig) -> dict[str, pl.DataFrame]:
    """``decoding = "lagged"``: the live algorithm on the whole log at once
    (:mod:`onebit.trackers.findinghumo.lagged`; ``onebit follow`` publishes the same rows)."""
    motion = check_schema(inputs["motion"], MOTION, name="motion")
    g = site.sensor_graph
    nodes = g.nodes
    active, t0 = slot_activity(motion, nodes, cfg.period, cfg.sampling)
    eatg = build_eatg(site, active, cfg)  # layout or file: never learned from this log (config check)
    fh = isinstance(cfg, FindingHumoConfig)
    paths, lag = lagged_paths(mode, active, site, cfg, eatg, cpda_windows=cfg.c_windows if fh else None)
    silent = silent_stretches([motion.filter(pl.col("sensor").is_in(list(nodes)))], min_s=cfg.absent_after)
    out: dict[str, pl.DataFrame] = {}
    res = lag.dec.result()
    cap = user_bound(site, cfg)
    if fh:
        decoded = cap_users(res.paths, active, eatg.hops, cap)
        out["decoded_hmm"] = outside_silence(tracks_table(name, decoded, nodes, site, t0, cfg.period), silent).drop(
            "tracker"
        )
        cp = lag.cpda_result()
        out["switches"] = switches_table(cp, nodes)
        out["cpda"] = decisions_table(cp, nodes)
    if cfg.joint != "off":
        out["joint"] = joint_table(lag.joint_log, nodes, t0, cfg.period)
    tracks = outside_silence(tracks_table(name, paths, nodes, site, t0, cfg.period), silent)
    out["tracks"] = tracks
    out["events"] = attribute_events(inputs["motion"], tracks, nodes, eatg.hops, t0=t0, period=cfg.period)
    out["eatg"] = eatg.table()
    out["windows"] = windows_table(res)
    out["decoder"] = pl.DataFrame({"slots": [int(active.shape[0])], "users": [int(paths.shape[0])]})
    out[ARTIFACTS] = {"eatg": eatg, "active": active, "nodes": nodes, "t0": t0, "period": cfg.period, "paths": paths}
    if fh:
        out[ARTIFACTS]["decoded_paths"] = res.paths
    return out


def run_findinghumo(inputs: dict, site: Site, config: FindingHumoConfig):
    """FindingHuMo: Adaptive-HMM + CPDA (module docstring)."""
    return _run("findinghumo", "adaptive", inputs, site, config)


def run_hmm1(inputs: dict, site: Site, config: HmmConfig):
    """Full-state first-order HMM baseline (online windows, or offline)."""
    return _run("hmm1", "full1", inputs, site, config)


def run_hmm2(inputs: dict, site: Site, config: HmmConfig):
    """Full-state second-order HMM baseline (online windows, or offline)."""
    return _run("hmm2", "full2", inputs, site, config)


def _shares(mode: str):
    """The decoded run a tracker of ``mode`` shares (:func:`decode_key`), unless it decodes lagged."""

    def key(cfg: HmmConfig):
        return None if cfg.decoding == "lagged" else ("graph-hmm decode", decode_key(mode, cfg))

    return key


SPECS = [
    TrackerSpec(
        name="findinghumo",
        needs=("motion",),
        config=FindingHumoConfig,
        run=run_findinghumo,
        available=available,
        wants=("occupancy_people",),
        counts_people=True,
        shares=_shares("adaptive"),
        help="FindingHuMo (De et al.): Adaptive-HMM on a PIR sensor graph + CPDA path disambiguation",
    ),
    TrackerSpec(
        name="hmm1",
        needs=("motion",),
        config=HmmConfig,
        run=run_hmm1,
        available=available,
        wants=("occupancy_people",),
        counts_people=True,
        shares=_shares("full1"),
        help="baseline: full-state first-order HMM on the PIR sensor graph (FindingHuMo section IV-B)",
    ),
    TrackerSpec(
        name="hmm2",
        needs=("motion",),
        config=HmmConfig,
        run=run_hmm2,
        available=available,
        wants=("occupancy_people",),
        counts_people=True,
        shares=_shares("full2"),
        help="baseline: full-state second-order HMM on the PIR sensor graph (FindingHuMo section IV-B)",
    ),
]
