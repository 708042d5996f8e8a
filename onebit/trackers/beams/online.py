"""The ``beams`` tracker run online: each crossing assigned once, as soon as it is final.

Algorithm 1 of Bobadilla et al. is crossing by crossing: the agent of crossing ``j`` depends
only on the queue operations of the crossings before it. :class:`OnlineBeams` keeps the queues
(:class:`~onebit.trackers.beams.assignment.AssignmentState`, the same pass the batch reference
runs, with the configured policy and section IV variations) between calls; :func:`advance` feeds
it the crossings that became final since the last call and returns the new ``tracks`` rows:
the crossing's row (track, t, region entered) and, for an agent created by it, the agent's
start row (its initial region at the run's first crossing time, as the batch stage dates it;
agents of a known initial condition get theirs with the first crossing). The rows equal the
batch stage's ``tracks`` (:func:`onebit.trackers.beams.stage.run`) on the whole string.

Only the ``tracks`` are online: the queries (occupancy, traffic, over-threshold intervals),
the FIFO/LIFO ambiguity marks and the ``agents`` strings are the final batch run's. When the
false-negative correction runs (``[correct]``: the number of agents is known), the tracker's
input is the corrected string, which the correction's dynamic programme chooses over the
whole string (an insertion is placed between observed crossings, possibly far back): it is not
sequential, and ``onebit follow`` re-runs the tracker on the settled prefix instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.region_graph import RegionGraph
from onebit.core.site import Site
from onebit.core.tables import CROSSINGS, TRACKS, check_schema, conform
from onebit.trackers.beams.assignment import AssignmentState
from onebit.trackers.beams.stage import NAME, BeamsConfig


@dataclass
class OnlineBeams:
    """What :func:`advance` keeps between calls."""

    rg: RegionGraph
    state: AssignmentState
    names: list[str]
    t0: float | None = None  # the first crossing's time: every agent's start row is dated there
    started: int = 0  # agents whose start row is out
    fed: int = 0  # crossings fed
    ended: bool = False


def start(site: Site, config: BeamsConfig, rg: RegionGraph) -> OnlineBeams:
    """A fresh online assignment for ``site`` (queues empty, or the known initial condition)."""
    return OnlineBeams(rg, AssignmentState(len(rg.names), config.policy, config.constraints(site, rg)), list(rg.names))


def advance(state: OnlineBeams, crossings: pl.DataFrame, *, final: bool = False) -> pl.DataFrame:
    """Assign the crossings of ``crossings`` not fed yet (every final crossing so far, in the
    reader's order: by ``t``) and return the new TRACKS rows. ``final``: the log has ended (a
    run without crossings still has its known agents' start rows, at ``t = 0``)."""
    out = pl.DataFrame(schema=TRACKS)
    if state.ended:
        return out
    crossings = check_schema(crossings, CROSSINGS, name="crossings")
    new = crossings.slice(state.fed)
    rows: list[tuple[str, float, str]] = []
    if new.height:
        if state.t0 is None:
            state.t0 = float(new["t"][0])
        src, tgt = state.rg.endpoint_arrays(new["beam"], new["direction"].to_numpy())
        t = new["t"].to_numpy()
        for j in range(new.height):  # one crossing at a time: an agent's start row before its first crossing
            agent = int(state.state.feed(src[j : j + 1], tgt[j : j + 1], t[j : j + 1])[0])
            rows += _starts(state)
            if agent >= 0:
                rows.append((f"agent{agent + 1}", float(t[j]), state.names[int(tgt[j])]))
        state.fed = crossings.height
    if final:
        if state.t0 is None:
            state.t0 = 0.0
        rows += _starts(state)
        state.ended = True
    if not rows:
        return out
    df = pl.DataFrame(rows, schema={"track": pl.String, "t": pl.Float64, "region": pl.String}, orient="row")
    return conform(df.with_columns(tracker=pl.lit(NAME)), TRACKS)


def _starts(state: OnlineBeams) -> list[tuple[str, float, str]]:
    """Start rows of the agents that have none out yet (all dated at the first crossing)."""
    if state.t0 is None or math.isnan(state.t0):
        return []
    n = state.state.n_agents
    initial = np.asarray(state.state.initial, dtype=np.int64)
    rows = [(f"agent{a + 1}", state.t0, state.names[int(initial[a])]) for a in range(state.started, n)]
    state.started = n
    return rows
