"""Stage ``findinghumo-flow``: the sensor-graph HMM, then a global association of path
fragments by a minimum-cost flow (:mod:`onebit.trackers.findinghumo_flow.association`).

Decode the users as the HMM trackers do (:func:`onebit.models.graph_hmm.decoding.decode_motion`;
``decoder`` picks the second-order full-state HMM or the Adaptive-HMM), cut the decoded paths
at every meeting, chain the fragments over the whole run by a minimum-cost flow, and report
one track per chain (at most the site's ``targets`` at a time, as the HMM trackers).

Outputs (tables ``findinghumo-flow_<key>``): ``tracks`` (TRACKS), ``fragments`` (fragment,
track, start, end, identity), ``joins`` (every allowed join at a meeting's cut slot: slot,
node, from / to fragment, cost, chosen, and the pairing's posterior among the joins of its
incoming fragment), ``eatg``, ``windows``, ``decoder``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.frames import outside_silence
from onebit.core.params import param
from onebit.core.site import Site
from onebit.models.graph_hmm.decoding import (
    JOINT,
    HmmConfig,
    available,
    cap_users,
    decode_key,
    decode_motion,
    tracks_table,
    windows_table,
)
from onebit.models.graph_hmm.joint import joint_table, redecode_meetings
from onebit.models.graph_hmm.viterbi import log_safe
from onebit.trackers.attribution import attribute_events
from onebit.trackers.base import ARTIFACTS, PROGRESS, TrackerSpec, home_count_bound
from onebit.trackers.findinghumo_flow.association import (
    BIRTH,
    Fragment,
    assemble,
    dwell_means,
    fragments,
    join_cost,
    meeting_joins,
    meetings,
    min_cost_cover,
    pace,
    visits,
)

NAME = "findinghumo-flow"

FRAGMENTS = pl.Schema(
    {"fragment": pl.Int64, "track": pl.Int64, "start": pl.Int64, "end": pl.Int64, "identity": pl.Int64}
)
JOINS = pl.Schema(
    {
        "slot": pl.Int64,
        "node": pl.String,
        "src": pl.Int64,
        "dst": pl.Int64,
        "cost": pl.Float64,
        "chosen": pl.Boolean,
        "probability": pl.Float64,
    }
)


@dataclass(frozen=True, kw_only=True)
class FlowConfig(HmmConfig):
    """``[findinghumo-flow]``: the shared HMM options plus the association's."""

    joint: str = param(
        "before-cpda",
        "re-decode every meeting of two users jointly (as in the shared HMM options); here on the HMM's "
        "paths, before the association, by default (0.464 vs 0.501 after it, seeds 0-19); after-cpda "
        "re-decodes the associated paths; off: none",
        choices=JOINT,
    )
    decoding: str = param(
        "batch", "batch only: a global min-cost flow over the whole run is never lagged", choices=("batch",)
    )
    decoder: str = param(
        "full2",
        "full2 (second-order full-state HMM) or adaptive (the Adaptive-HMM)",
        choices=("full2", "adaptive"),
    )
    pace_sigma: float = param(
        0.35, "spread of the log pace (slots per node) of one user across a meeting", lo=1e-3, hi=1e9
    )
    max_gap: int = param(
        10, "slots a track may vanish before it continues on a track that starts", lo=0, hi=10_000, unit="slots"
    )
    switch_cost: float = param(
        1.0,
        "cost of a join that changes the decoded track: the HMM's own pairing is kept unless the evidence "
        "against it is stronger (and among equals)",
        lo=0.0,
        hi=1e3,
        unit="nats",
    )
    turn_dwell: bool = param(
        False,
        "add the turn/pass dwell term -log Geom(n; mu_turn | mu_pass) to the join cost (off by default: on "
        "the issue's 20 seeds it made the association worse, 0.75 vs 0.60 hops -- users here also pause "
        "where they do not turn, see docs/findinghumo.md)",
    )


def associate_paths(
    paths: np.ndarray,
    hops: np.ndarray,
    a1: np.ndarray,
    a2: np.ndarray,
    feature: np.ndarray,
    entries: np.ndarray,
    exits: np.ndarray,
    *,
    pace_sigma: float = 0.35,
    max_gap: int = 10,
    switch_cost: float = 1.0,
    turn_dwell: bool = False,
    run_start: int = 0,
) -> tuple[np.ndarray, list[Fragment], np.ndarray, list[tuple]]:
    """Chain the fragments of ``paths`` (U, D) into identities (association module docstring).

    Returns the identities' paths (K, D), the fragments, the identity of each fragment and the
    joins ``(slot, node, f, g, cost, chosen)``.
    """
    n_u, d = paths.shape
    if n_u == 0:
        return paths, [], np.zeros(0, np.int64), []
    log_a2 = log_safe(a2)
    meets = meetings(paths, hops, feature)
    frags = fragments(paths, meets)
    mu = dwell_means(paths, meets) if turn_dwell else None
    vis = [visits(paths[f.track, f.start : f.end]) for f in frags]
    paces = [pace(*v) for v in vis]
    joins: dict[tuple[int, int], float] = {}
    where: dict[tuple[int, int], tuple[int, int]] = {}
    for f, g, cut, last in meeting_joins(paths, frags, meets, hops):
        c = join_cost(vis[f], vis[g], log_a2, mu, pace_sigma, paces[f], paces[g])
        if np.isfinite(c):  # a'' = 0: the EATG says the joined path cannot happen
            joins[(f, g)] = c + switch_cost * (frags[f].track != frags[g].track)
            where[(f, g)] = (cut, last)
    first_slot = np.array([f.start for f in frags])
    last_slot = np.array([f.end for f in frags])
    first_node = np.array([paths[f.track, f.start] for f in frags])
    last_node = np.array([paths[f.track, f.end - 1] for f in frags])
    has_in = np.zeros(len(frags), bool)
    has_out = np.zeros(len(frags), bool)
    for f, g in joins:
        has_out[f] = True
        has_in[g] = True
    # births / deaths: free at the run's ends and at the doors (entry / exit signatures)
    birth = np.where((first_slot <= run_start) | entries[first_node], 0.0, BIRTH)
    death = np.where((last_slot >= d) | exits[last_node], 0.0, BIRTH)
    # a track that ends away from the doors may go on as one that starts later, within reach
    ends = np.flatnonzero(~has_out & (last_slot < d))
    starts = np.flatnonzero(~has_in & (first_slot > run_start))
    steps = [np.eye(a1.shape[0])]  # steps[k] = A'^k: reaching a node in k slots
    for _ in range(max_gap + 1):
        steps.append(steps[-1] @ a1)
    log_steps = log_safe(np.stack(steps))
    for f in ends:
        gap = first_slot[starts] - last_slot[f]
        ok = (gap >= 0) & (gap <= max_gap) & (hops[last_node[f], first_node[starts]] <= gap + 1)
        for g in starts[ok]:
            k = int(first_slot[g] - last_slot[f]) + 1
            # no a'' terms across a gap: the nodes walked in it are not known
            c = -float(log_steps[k, last_node[f], first_node[g]]) + join_cost(
                (vis[f][0][:0], vis[f][1][:0]), vis[g], log_a2, None, pace_sigma, paces[f], paces[g]
            )
            if np.isfinite(c):
                joins[(int(f), int(g))] = c
                where[(int(f), int(g))] = (int(first_slot[g]), int(last_node[f]))
    succ, _ = min_cost_cover(len(frags), birth, death, joins)
    out, ident = assemble(paths, frags, succ)
    rows = [(s, j, f, g, c, bool(succ[f] == g)) for (f, g), c in joins.items() for s, j in [where[(f, g)]]]
    return out, frags, ident, rows


def run_flow(inputs: dict, site: Site, config: FlowConfig) -> dict:
    """``findinghumo-flow`` (module docstring)."""
    cfg = config
    run = decode_motion(cfg.decoder, inputs, site, cfg, progress=inputs.get(PROGRESS))
    g = site.sensor_graph
    nodes = g.nodes
    eatg = run.eatg
    arr = np.asarray(nodes)
    feature = np.isin(arr, list(g.entries) + list(g.exits))
    entries = np.isin(arr, list(g.entries))
    exits = np.isin(arr, list(g.exits))
    decoded = run.result.paths
    joint_log: list[dict] = []
    if cfg.joint == "before-cpda":  # on the HMM's paths, before the association
        decoded, joint_log = redecode_meetings(
            decoded, run.active, eatg, p_hit=cfg.p_hit, p_false=cfg.p_false, pad=cfg.joint_pad, reach=cfg.joint_hops
        )
    paths, frags, ident, joins = associate_paths(
        decoded,
        eatg.hops,
        eatg.a1,
        eatg.a2,
        feature,
        entries,
        exits,
        pace_sigma=cfg.pace_sigma,
        max_gap=cfg.max_gap,
        run_start=cfg.d_max,
    )
    if cfg.joint == "after-cpda":  # on the associated paths
        paths, joint_log = redecode_meetings(
            paths, run.active, eatg, p_hit=cfg.p_hit, p_false=cfg.p_false, pad=cfg.joint_pad, reach=cfg.joint_hops
        )
    cap = cfg.max_users or (site.targets or 0) or home_count_bound(inputs)
    paths = cap_users(paths, run.active, eatg.hops, cap)
    tracks = outside_silence(tracks_table(NAME, paths, nodes, site, run.t0, cfg.period), run.silent)
    frag_table = pl.DataFrame(
        [(i, f.track, f.start, f.end, int(ident[i])) for i, f in enumerate(frags)], schema=FRAGMENTS, orient="row"
    )
    join_table = _joins_table(joins, nodes)
    return {
        "tracks": tracks,
        "events": attribute_events(inputs["motion"], tracks, nodes, eatg.hops, t0=run.t0, period=cfg.period),
        "fragments": frag_table,
        "joins": join_table,
        "eatg": eatg.table(),
        **({"joint": joint_table(joint_log, nodes, run.t0, cfg.period)} if cfg.joint != "off" else {}),
        "windows": windows_table(run.result),
        "decoder": pl.DataFrame({"slots": [int(run.active.shape[0])], "users": [int(paths.shape[0])]}),
        ARTIFACTS: {
            "eatg": eatg,
            "active": run.active,
            "nodes": nodes,
            "t0": run.t0,
            "period": cfg.period,
            "paths": paths,
            "decoded_paths": decoded,  # what the association started from
        },
    }


def _joins_table(joins: list[tuple], nodes) -> pl.DataFrame:
    """Joins with the posterior of each among the joins of its incoming fragment (softmax of -cost)."""
    if not joins:
        return pl.DataFrame(schema=JOINS)
    df = pl.DataFrame(
        [(s, nodes[j], f, g, c, ch) for s, j, f, g, c, ch in joins],
        schema={k: v for k, v in JOINS.items() if k != "probability"},
        orient="row",
    )
    return df.with_columns(
        probability=(-(pl.col("cost") - pl.col("cost").min().over("src"))).exp()
        / (-(pl.col("cost") - pl.col("cost").min().over("src"))).exp().sum().over("src")
    ).sort("slot", "src", "dst")


def shared_decode(cfg: FlowConfig) -> tuple:
    """The decoded run this tracker shares with the HMM trackers of the same decoder and
    fields (``hmm2`` with the default ``decoder = "full2"``)."""
    return ("graph-hmm decode", decode_key(cfg.decoder, cfg))


SPEC = TrackerSpec(
    name=NAME,
    needs=("motion",),
    config=FlowConfig,
    run=run_flow,
    available=available,
    wants=("occupancy_people",),
    counts_people=True,
    shares=shared_decode,
    help="beyond FindingHuMo: HMM paths cut at every meeting, fragments joined over the whole run by a minimum-cost flow",
)
