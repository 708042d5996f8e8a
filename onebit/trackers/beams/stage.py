"""The ``beams`` stage: crossings + site -> per-agent crossing strings, region paths and tracks."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.datasets.region_graph import RegionGraph, build_region_graph
from onebit.datasets.site import Site
from onebit.tables import CROSSINGS, TRACKS, check_schema, conform
from onebit.trackers.base import TrackerSpec, check_choice, register
from onebit.trackers.beams.assignment import POLICIES, assign_agents

NAME = "beams"


@dataclass(frozen=True, kw_only=True)
class BeamsConfig:
    """Configuration of the ``beams`` tracker.

    policy : queue discipline of the region queues Q_r (Algorithm 1, line 5): ``"fifo"``
        assigns the agent that has waited longest (the paper's experiment), ``"lifo"`` the
        agent that arrived last ("agents with momentum keep moving").
    """

    policy: str = "fifo"

    def __post_init__(self) -> None:
        check_choice(self, "policy", POLICIES)


def run(inputs: dict, site: Site, config: BeamsConfig, log=None) -> dict[str, pl.DataFrame]:
    """Assign every crossing to an agent (Algorithm 1) and build tracks.

    Inputs: ``crossings`` (CROSSINGS); optional ``region_graph`` (built from ``site`` otherwise).
    Outputs:

    - ``assignment``: t, beam, direction, track -- the assignment vector A.
    - ``agents``: track, initial_region, crossings (the string y_i, e.g. ``"b^-1 c"``),
      regions (the region path), n_crossings.
    - ``tracks`` (TRACKS): one row per agent at the first crossing time of the run in its
      initial region, then one row per crossing with the region entered; x/y null.
    - ``occupancy``: t, region, count -- agents per region after every crossing.
    """
    crossings = check_schema(inputs["crossings"], CROSSINGS, name="crossings").sort("t", maintain_order=True)
    rg: RegionGraph = inputs.get("region_graph") or build_region_graph(site)
    names = np.asarray(rg.names, dtype=object)
    src, tgt = rg.endpoint_arrays(crossings["beam"], crossings["direction"].to_numpy())
    res = assign_agents(src, tgt, len(rg.names), policy=config.policy)
    track_ids = pl.Series("track", [f"agent{k + 1}" for k in range(res.n_agents)], dtype=pl.String)

    labels = pl.when(pl.col("direction") > 0).then(pl.col("beam")).otherwise(pl.col("beam") + "^-1")
    assignment = crossings.with_columns(
        track=track_ids.gather(res.agents) if res.n_agents else pl.Series("track", [], dtype=pl.String),
        source=pl.Series(names[src].tolist() if len(src) else [], dtype=pl.String),
        region=pl.Series(names[tgt].tolist() if len(tgt) else [], dtype=pl.String),
        label=labels,
    )
    t0 = float(crossings["t"].min()) if crossings.height else 0.0
    starts = pl.DataFrame(
        {
            "track": track_ids,
            "t": pl.Series([t0] * res.n_agents, dtype=pl.Float64),
            "region": pl.Series(names[res.initial_region].tolist() if res.n_agents else [], dtype=pl.String),
        }
    )
    steps = pl.concat([starts.with_columns(order=pl.lit(0)), assignment.select("track", "t", "region").with_columns(order=pl.lit(1))])
    tracks = conform(
        steps.sort(["track", "order", "t"], maintain_order=True).with_columns(tracker=pl.lit(NAME)), TRACKS
    )
    agents = (
        assignment.group_by("track", maintain_order=True)
        .agg(crossings=pl.col("label").str.join(" "), path=pl.col("region").str.join(" "), n_crossings=pl.len())
        .join(starts.select("track", initial_region="region"), on="track", how="right")
        .select(
            "track",
            "initial_region",
            pl.col("crossings").fill_null(""),
            regions=pl.concat_str([pl.col("initial_region"), pl.col("path")], separator=" ", ignore_nulls=True),
            n_crossings=pl.col("n_crossings").fill_null(0).cast(pl.Int64),
        )
    )
    occ = occupancy(assignment, starts, rg)
    out = {"assignment": assignment.drop("label"), "agents": agents, "tracks": tracks, "occupancy": occ}
    if log is not None:
        log.region_tracks(NAME, tracks, rg)
        log.occupancy(NAME, occ)
    return out


def occupancy(assignment: pl.DataFrame, starts: pl.DataFrame, rg: RegionGraph) -> pl.DataFrame:
    """Agents per region over time: initial counts at the first time, then after each crossing.

    ``count_r(t) = n_r(0) + entries_r(<= t) - exits_r(<= t)``; one row per region at the
    start and one per (crossing, endpoint region), computed with cumulative sums per region.
    """
    t0 = starts["t"].min() if starts.height else 0.0
    init = (
        pl.DataFrame({"region": list(rg.names)})
        .join(starts.group_by("region").agg(delta=pl.len().cast(pl.Int64)), on="region", how="left")
        .with_columns(t=pl.lit(t0, pl.Float64), delta=pl.col("delta").fill_null(0), order=pl.lit(0))
    )
    moves = pl.concat(
        [
            assignment.select("t", region="source", delta=pl.lit(-1, pl.Int64)).with_row_index("order", offset=1),
            assignment.select("t", region="region", delta=pl.lit(1, pl.Int64)).with_row_index("order", offset=1),
        ]
    ).select("t", "region", "delta", pl.col("order").cast(pl.Int32))
    allm = pl.concat([init.select("t", "region", "delta", pl.col("order").cast(pl.Int32)), moves])
    return (
        allm.sort(["order", "delta"])
        .with_columns(count=pl.col("delta").cum_sum().over("region"))
        .select("t", "region", "count")
    )


SPEC = register(TrackerSpec(name=NAME, needs=("crossings",), config=BeamsConfig, run=run))
