"""The ``beams`` stage: crossings + site -> per-agent crossing strings, region paths, tracks,
ambiguity, unexplained crossings and the section IV-F-1 queries."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.errors import ConfigError
from onebit.core.params import param, validate
from onebit.core.region_graph import RegionGraph, build_region_graph
from onebit.core.site import Site
from onebit.core.tables import CROSSINGS, TRACKS, check_schema, conform
from onebit.trackers.base import TrackerSpec
from onebit.trackers.beams import queries
from onebit.trackers.beams.assignment import POLICIES, Assignment, Constraints, ambiguous_crossings, assign_agents

NAME = "beams"

_UNEXPLAINED = {
    "crossing": pl.Int64,
    "t": pl.Float64,
    "beam": pl.String,
    "direction": pl.Int8,
    "source": pl.String,
    "region": pl.String,
    "reason": pl.String,
}


@dataclass(frozen=True, kw_only=True)
class BeamsConfig:
    """Configuration of the ``beams`` tracker (``[beams]`` in ``run.toml``). It works on the
    region graph: no field is a length (times are seconds)."""

    policy: str = param(
        "fifo",
        "queue discipline of the region queues Q_r (Algorithm 1, line 5): fifo assigns the agent that has "
        "waited longest (the paper's experiment), lifo the agent that arrived last (\"agents with momentum "
        'keep moving")',
        choices=POLICIES,
    )
    capacity: dict = param(
        doc="IV-A, {region = u_r} upper bound on the agents in a region; overrides the capacity of the "
        "site's [[regions]]. Empty = unbounded",
        factory=dict,
    )
    max_track_length: int = param(
        0, "IV-B, most regions an agent may visit (its initial region counts); 0 = unbounded", lo=0
    )
    prefer_short_tracks: bool = param(False, "IV-B, region queues ordered by regions visited, shortest first")
    initial_regions: list = param(
        doc="IV-C, the initial region of every agent (n = its length); no other agent is created. Empty = unknown",
        factory=list,
    )
    max_agents: int = param(
        0,
        "when initial_regions is empty, most agents that may be created; 0 = the site's targets (the most "
        "agents present at once), unbounded when it does not say",
        lo=0,
    )
    teams: list = param(
        doc="IV-D, the team of every agent of initial_regions (same length). Empty = none", factory=list
    )
    team_names: list = param(
        doc="IV-D, the m teams, in the order of the team_capacity lists and of the exit priority", factory=list
    )
    team_capacity: dict = param(doc="IV-D, {region = [u^1, .., u^m]} per-team bounds (-1 = unbounded)", factory=dict)
    prefer_team_order: bool = param(
        False,
        "IV-D, the exit policy prefers team_names[0], then [1], ... (e.g. robots before humans), before the "
        "queue order",
    )
    min_traversal_s: dict = param(
        doc='IV-E, {region = seconds} minimum time an agent stays in a region before it may leave; key "*" '
        "sets every other region. Empty = no time rule",
        factory=dict,
    )
    ambiguity: bool = param(True, "run both FIFO and LIFO and mark the crossings whose agent differs")
    traffic_bucket_s: float = param(60.0, "IV-F-1, time bucket of the traffic query", lo=1e-9, hi=1e12, unit="s")
    occupancy_threshold: int = param(
        10, 'IV-F-1, "were there more than N agents in any region" (the paper\'s N = 10)', lo=0
    )

    def __post_init__(self) -> None:
        validate(self)
        for name in ("capacity", "team_capacity", "min_traversal_s"):
            if not isinstance(getattr(self, name), dict):
                raise ConfigError(f"BeamsConfig.{name} = {getattr(self, name)!r}; must be a table {{region = ...}}")
        for name in ("initial_regions", "teams", "team_names"):
            v = getattr(self, name)
            if not isinstance(v, (list, tuple)) or not all(isinstance(x, str) for x in v):
                raise ConfigError(f"BeamsConfig.{name} = {v!r}; must be a list of names")
        for r, u in self.capacity.items():
            if not isinstance(u, int) or isinstance(u, bool) or u < 0:
                raise ConfigError(f"BeamsConfig.capacity.{r} = {u!r}; allowed range: [0, None]")
        for r, s in self.min_traversal_s.items():
            if not isinstance(s, (int, float)) or isinstance(s, bool) or not (0 <= s < float("inf")):
                raise ConfigError(f"BeamsConfig.min_traversal_s.{r} = {s!r}; allowed range: [0, None]")
        if self.teams and len(self.teams) != len(self.initial_regions):
            raise ConfigError(
                f"BeamsConfig.teams has {len(self.teams)} entries; it needs one per agent of "
                f"initial_regions ({len(self.initial_regions)}) -- teams need the known initial condition (IV-C, IV-D)"
            )
        unknown = sorted(set(self.teams) - set(self.team_names))
        if self.team_names and unknown:
            raise ConfigError(f"BeamsConfig.teams names team(s) {unknown} not in team_names {self.team_names}")
        if (self.team_capacity or self.prefer_team_order) and not self.team_names:
            raise ConfigError(
                "BeamsConfig.team_names must list the teams when team_capacity or prefer_team_order is set"
            )
        for r, us in self.team_capacity.items():
            ok = isinstance(us, (list, tuple)) and len(us) == len(self.team_names)
            ok = ok and all(isinstance(u, int) and not isinstance(u, bool) and u >= -1 for u in us)
            if not ok:
                raise ConfigError(
                    f"BeamsConfig.team_capacity.{r} = {us!r}; must be {len(self.team_names)} integers >= -1 "
                    f"(one per team of team_names {self.team_names}, -1 = unbounded)"
                )

    def constraints(self, site: Site, rg: RegionGraph) -> Constraints | None:
        """The section IV variations in index form for :func:`assign_agents` (``None`` = base)."""
        idx = rg.index
        p = len(rg.names)

        def region(name: str, where: str) -> int:
            if name not in idx:
                raise ConfigError(f"BeamsConfig.{where}: unknown region {name!r}; regions are {list(rg.names)}")
            return idx[name]

        cap = np.full(p, -1, np.int64)
        for spec in site.regions:
            if spec.capacity is not None and spec.name in idx:
                cap[idx[spec.name]] = spec.capacity
        for r, u in self.capacity.items():
            cap[region(r, f"capacity.{r}")] = u
        init = (
            np.array([region(r, "initial_regions") for r in self.initial_regions], np.int64)
            if self.initial_regions
            else None
        )
        if init is not None:
            counts = np.bincount(init, minlength=p)
            over = np.flatnonzero((cap >= 0) & (counts > cap))
            if len(over):
                r = rg.names[over[0]]
                raise ConfigError(
                    f"BeamsConfig.initial_regions puts {counts[over[0]]} agents in {r}, over its capacity {cap[over[0]]}"
                )
        tidx = {t: k for k, t in enumerate(self.team_names)}
        team = np.array([tidx[t] for t in self.teams], np.int64) if self.teams else None
        tcap = None
        if self.team_capacity:
            tcap = np.full((p, len(self.team_names)), -1, np.int64)
            for r, us in self.team_capacity.items():
                tcap[region(r, f"team_capacity.{r}")] = us
            if init is not None and team is not None:
                both = np.zeros_like(tcap)
                np.add.at(both, (init, team), 1)
                if np.any((tcap >= 0) & (both > tcap)):
                    raise ConfigError("BeamsConfig.initial_regions and teams exceed a team_capacity bound at the start")
        rank = np.arange(len(self.team_names), dtype=np.int64) if self.prefer_team_order else None
        tau = None
        if self.min_traversal_s:
            tau = np.full(p, float(self.min_traversal_s.get("*", 0.0)))
            for r, s in self.min_traversal_s.items():
                if r != "*":
                    tau[region(r, f"min_traversal_s.{r}")] = float(s)
        c = Constraints(
            capacity=cap if np.any(cap >= 0) else None,
            max_track_length=self.max_track_length,
            prefer_short=self.prefer_short_tracks,
            initial_region=init,
            max_agents=self.max_agents or (site.targets or 0),
            team=team,
            team_capacity=tcap,
            team_rank=rank,
            min_traversal=tau,
            region_names=tuple(rg.names),
        )
        return None if c.trivial else c


def run(inputs: dict, site: Site, config: BeamsConfig) -> dict[str, pl.DataFrame]:
    """Assign every crossing to an agent (Algorithm 1 + variations) and answer the queries.

    Inputs: ``crossings`` (CROSSINGS); optional ``region_graph`` (built from ``site`` otherwise).
    Outputs:

    - ``assignment``: t, beam, direction, track (null = unexplained), source, region,
      ambiguous -- the assignment vector A.
    - ``agents``: track, initial_region, team, crossings (the string y_i, e.g. ``"b^-1 c"``),
      regions (the region path), n_crossings, ambiguous_crossings.
    - ``tracks`` (TRACKS): one row per agent at the first crossing time of the run in its
      initial region, then one row per crossing with the region entered; x/y null.
    - ``unexplained``: crossing (index), t, beam, direction, source, region, reason.
    - ``occupancy`` (t, region, count), ``visits`` (region, visits), ``traffic`` (bucket,
      t_start, region, entries, exits, traffic), ``over_threshold`` (region, t_start, t_end,
      duration_s, peak): the IV-F-1 queries (:mod:`onebit.trackers.beams.queries`).
    """
    crossings = check_schema(inputs["crossings"], CROSSINGS, name="crossings").sort("t", maintain_order=True)
    rg: RegionGraph = inputs.get("region_graph") or build_region_graph(site)
    names = pl.Series("region", list(rg.names), dtype=pl.String)  # gathered by index below
    src, tgt = rg.endpoint_arrays(crossings["beam"], crossings["direction"].to_numpy())
    res, ambiguous = _assign(src, tgt, crossings["t"].to_numpy(), site, rg, config)
    track_ids = (
        pl.select(pl.format("agent{}", pl.int_range(1, res.n_agents + 1, dtype=pl.Int64))).to_series().rename("track")
    )
    labels = pl.when(pl.col("direction") > 0).then(pl.col("beam")).otherwise(pl.col("beam") + "^-1")
    assignment = crossings.with_columns(
        track=_track_column(res, track_ids),
        source=names.gather(src),
        region=names.gather(tgt),
        ambiguous=pl.Series(ambiguous, dtype=pl.Boolean),
        label=labels,
    )
    explained = assignment.filter(pl.col("track").is_not_null())
    starts = _agent_starts(res, track_ids, names, crossings, config)
    occ = queries.occupancy(explained, starts, rg.names)
    return {
        "assignment": assignment.drop("label"),
        "agents": _agents_table(explained, starts),
        "tracks": _tracks_table(explained, starts),
        "unexplained": _unexplained_table(res, assignment),
        "occupancy": occ,
        "visits": queries.visits_per_region(explained, rg.names),
        "traffic": queries.traffic_per_region(explained, config.traffic_bucket_s),
        "over_threshold": queries.intervals_over_threshold(
            occ, config.occupancy_threshold, t_end=float(crossings["t"].max()) if crossings.height else None
        ),
    }


def _assign(src, tgt, times, site: Site, rg: RegionGraph, config: BeamsConfig):
    """Algorithm 1 under the configured policy and constraints, and which crossings the other
    policy (FIFO <-> LIFO) gives to another agent (all False when ``config.ambiguity`` is off)."""
    cons = config.constraints(site, rg)
    res = assign_agents(src, tgt, len(rg.names), policy=config.policy, constraints=cons, times=times)
    if not config.ambiguity:
        return res, np.zeros(len(src), dtype=bool)
    other = "lifo" if config.policy == "fifo" else "fifo"
    alt = assign_agents(src, tgt, len(rg.names), policy=other, constraints=cons, times=times)
    return res, ambiguous_crossings(res.agents, alt.agents)


def _agent_starts(res, track_ids: pl.Series, names: pl.Series, crossings: pl.DataFrame, config: BeamsConfig):
    """Each agent in its initial region (and team) at the first crossing time of the run."""
    t0 = float(crossings["t"].min()) if crossings.height else 0.0
    team_names = pl.Series("team", [*config.team_names, None], dtype=pl.String)  # index -1 = no team
    return pl.DataFrame(
        {
            "track": track_ids,
            "t": pl.Series([t0] * res.n_agents, dtype=pl.Float64),
            "region": names.gather(res.initial_region),
            "team": team_names.gather(np.where(res.team >= 0, res.team, len(config.team_names))),
        }
    )


def _tracks_table(explained: pl.DataFrame, starts: pl.DataFrame) -> pl.DataFrame:
    """TRACKS: each agent's start, then one row per crossing with the region entered."""
    steps = pl.concat(
        [
            starts.select("track", "t", "region").with_columns(order=pl.lit(0)),
            explained.select("track", "t", "region").with_columns(order=pl.lit(1)),
        ]
    )
    return conform(steps.sort(["track", "order", "t"], maintain_order=True).with_columns(tracker=pl.lit(NAME)), TRACKS)


def _agents_table(explained: pl.DataFrame, starts: pl.DataFrame) -> pl.DataFrame:
    """One row per agent: its crossing string y_i, region path and counts."""
    return (
        explained.group_by("track", maintain_order=True)
        .agg(
            crossings=pl.col("label").str.join(" "),
            path=pl.col("region").str.join(" "),
            n_crossings=pl.len(),
            ambiguous_crossings=pl.col("ambiguous").sum(),
        )
        .join(starts.select("track", "team", initial_region="region"), on="track", how="right")
        .select(
            "track",
            "initial_region",
            "team",
            pl.col("crossings").fill_null(""),
            regions=pl.concat_str([pl.col("initial_region"), pl.col("path")], separator=" ", ignore_nulls=True),
            n_crossings=pl.col("n_crossings").fill_null(0).cast(pl.Int64),
            ambiguous_crossings=pl.col("ambiguous_crossings").fill_null(0).cast(pl.Int64),
        )
    )


def _unexplained_table(res, assignment: pl.DataFrame) -> pl.DataFrame:
    """The crossings no agent could make, with the reason and the crossing's columns."""
    unexplained = pl.DataFrame(
        {"crossing": res.unexplained, "reason": list(res.reasons)}, schema={"crossing": pl.Int64, "reason": pl.String}
    ).join(
        assignment.with_row_index("crossing").with_columns(pl.col("crossing").cast(pl.Int64)), on="crossing", how="left"
    )
    return unexplained.select(list(_UNEXPLAINED)).cast(_UNEXPLAINED)


def _track_column(res: Assignment, track_ids: pl.Series) -> pl.Series:
    """Track id of every crossing, null for the unexplained ones (``A[j] = -1``)."""
    if len(res.agents) == 0 or res.n_agents == 0:
        return pl.Series("track", [None] * len(res.agents), dtype=pl.String)
    ok = res.agents >= 0
    col = track_ids.gather(np.where(ok, res.agents, 0))
    return pl.select(pl.when(pl.Series(ok)).then(col).otherwise(None)).to_series().rename("track")


def occupancy(assignment: pl.DataFrame, starts: pl.DataFrame, rg: RegionGraph) -> pl.DataFrame:
    """Agents per region over time (kept for callers of the first version; see
    :func:`onebit.trackers.beams.queries.occupancy`)."""
    return queries.occupancy(assignment, starts, rg.names)


SPEC = TrackerSpec(
    name=NAME,
    needs=("crossings",),
    counts_people=True,
    config=BeamsConfig,
    run=run,
    help="Bobadilla et al.: region-graph agent assignment from directional beams",
)
