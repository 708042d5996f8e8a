"""Stage ``residents``: who is who at home, from the motion log's events.

Every motion ``ON`` edge at a sensor with a position is an event; the decoder
(:mod:`onebit.trackers.residents.decode`) attributes the events to people by minimising eq. (1)
of :mod:`onebit.trackers.residents.model` (dwell-aware motion on the sensor graph, penalised
births): the number of people is its answer, at most ``targets`` of ``site.toml`` when given
(the decoder's own bound), else at most ``max_people``. An ``OFF`` edge goes to the person of
its sensor's last ``ON``. With ``habits`` (off by default: no gain measured on the real
sessions, docs/residents.md), two decoded people are then re-oriented between their meetings
by their sensor habits, learned without labels (:mod:`onebit.trackers.residents.habits`).

Known residents: when the run has a ``residents_profile`` (``residents_profile.csv`` in the
dataset, learned from labelled days by ``onebit learn residents``) and ``profile`` is on, the
events are decoded instead by the exact known-residents HMM of
:mod:`onebit.trackers.residents.known` (each event to its most probable resident; people named
by the profile's residents, ``resident<id>``).

Outputs (tables ``residents_<key>``):

* ``events`` -- t, sensor, track: which person each motion edge was attributed to (null for an
  ``OFF`` with no ``ON`` before it);
* ``tracks`` (TRACKS) -- each person every ``period`` seconds while present, at the node (and
  x, y) of their latest event: present while silent; gone ``exit_after_s`` after an event at an
  exit node that is followed by a longer silence (they left), back at their next event;
* ``people`` -- t, present: the number of people present over time: the home's count model's
  (stage ``occupancy``, :mod:`onebit.models.occupancy`) when the run has it, which also bounds
  the decoder's people when ``site.toml`` has no ``targets``; else the decoded people's presence;
* ``decoder`` -- events, people, cost, beam, states (mean kept per event).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.config import MAX_STEPS, check_size
from onebit.core.params import param, validate
from onebit.core.site import Site
from onebit.core.tables import MOTION, TRACKS, check_schema, conform
from onebit.core.units import length
from onebit.trackers.base import ARTIFACTS, TrackerSpec, home_count_bound, progress_of
from onebit.trackers.residents.decode import (
    Attribution,
    attribution_cost,
    decode_events,
    preds_from_tracks,
    tracks_from_pred,
)
from onebit.trackers.residents.habits import meeting_cuts, reorient
from onebit.trackers.residents.known import chains, clock_bonus, habit_log_probs, posteriors, turn_posteriors
from onebit.trackers.residents.model import birth_cost, move_cost, node_distances

NAME = "residents"

EVENTS = pl.Schema({"t": pl.Float64, "sensor": pl.String, "track": pl.String})
PEOPLE = pl.Schema({"t": pl.Float64, "present": pl.Int64})
DECODER = pl.Schema(
    {"events": pl.Int64, "people": pl.Int64, "cost": pl.Float64, "beam": pl.Int64, "states": pl.Float64}
)


@dataclass(frozen=True, kw_only=True)
class ResidentsConfig:
    """``[residents]``: the model's constants (eq. 2-5 of the model module) and the search's."""

    l0: float = length(1.0, "spread of the next sensor a person fires (about a sensor's footprint)", lo=1e-9)
    speed: float = length(
        0.0,
        "walking speed at which the spread grows with silence. Default 0: on the real two-resident sessions "
        "a person's next event is no farther after a long silence than after a short one (docs/residents.md, "
        '"what the data says")',
        unit="m/s",
        lo=0.0,
    )
    l_max: float = length(4.0, "largest spread (a room), used when speed > 0", lo="l0")
    silence_weight: float = param(0.0, "w of the silence term of eq. (3) (0: off)", lo=0.0, hi=100.0)
    silence_tau_s: float = param(10.0, "tau of the silence term of eq. (3)", lo=1e-9, unit="s")
    stay: float = param(0.0, "rho of the who-fires term (5) (0: off)", lo=0.0, hi=0.999)
    birth_door: float = param(6.0, "cost of a new person at a door or at the log's start", lo=0.0, hi=1e6, unit="nats")
    birth_inside: float = param(15.0, "cost of a new person anywhere else", lo=0.0, hi=1e6, unit="nats")
    start_window_s: float = param(
        60.0, "time from the first event during which people already home appear", lo=0.0, unit="s"
    )
    max_people: int = param(4, "bound on the people when site.toml has no targets", lo=1, hi=16)
    beam: int = param(
        1,
        "states kept per event (0 = all: the exact minimum of (1)). Default 1 (each event committed to its "
        "cheapest continuation): measured better than the exact minimum on the real sessions (docs/residents.md)",
        lo=0,
        hi=1_000_000,
    )
    distance: str = param(
        "graph",
        "graph (shortest paths over the site's sensor graph, each edge as long as the straight line between "
        "its sensors) or straight (between sensor positions)",
        choices=("graph", "straight"),
    )
    period: float = param(1.0, "time between two rows of a person in tracks", lo=1e-6, unit="s")
    exit_after_s: float = param(
        60.0, "silence after a last event at an exit node after which the person has left", lo=0.0, unit="s"
    )
    habits: bool = param(
        False,
        "re-orient two decoded people between their meetings by their sensor habits, learned without labels "
        "(onebit.trackers.residents.habits; only when two people are decoded)",
    )
    meet: float = length(2.5, "two people this close (the decoder's distance) may have swapped (eq. H1)", lo=0.0)
    habit_margin: float = param(
        0.0,
        "also a possible swap where the two people's motion costs for an event differ by at most this "
        "(0: off) (eq. H1)",
        lo=0.0,
        unit="nats",
    )
    habit_alpha: float = param(1.0, "Dirichlet pseudo-count per sensor of the habits (eq. H3)", lo=1e-6)
    habit_switch: float = param(0.0, "cost of a swap at a meeting (lambda of eq. H2)", lo=0.0, unit="nats")
    habit_restarts: int = param(8, "random starting orientations of the hard EM besides the decoder's", lo=0, hi=1000)
    profile: bool = param(
        True,
        "decode with the run's residents_profile when it has one (known residents, "
        "onebit.trackers.residents.known); off: always the unsupervised decoder",
    )
    profile_spread: float = length(
        3.0, "l of eq. (K1): the kernel that transitions never seen in the profile fall back to", lo=1e-9
    )
    profile_prior: float = param(
        2.0, "beta of eq. (K1): the weight of that kernel against the learned counts", lo=1e-9, hi=1e9
    )
    profile_clock_weight: float = param(
        1.0,
        "w of eq. (K3): the weight of the residents' habits by time when the profile has a clock (0: ignore it)",
        lo=0.0,
        hi=100.0,
    )
    profile_model: str = param(
        "chains",
        "chains (eq. K1-K3: both residents present, firing in turn) or turns (eq. K4: runs of one "
        "resident's events weighed by their habits by sensor and time; a home over days, where one is "
        "often out or asleep)",
        choices=("chains", "turns"),
    )
    profile_tau_s: float = param(
        300.0, "tau of (K4): the silence after which the next event may be anyone's", lo=1e-3, hi=1e7, unit="s"
    )

    def __post_init__(self) -> None:
        validate(self)


def available(site: Site) -> str | None:
    """Why the tracker cannot run on ``site`` (``None``: it can)."""
    return None if site.motion_sensors else "site has no motion sensors"


@dataclass(frozen=True)
class Home:
    """What the model needs of the site: node ids, positions, distances, entry nodes."""

    nodes: tuple[str, ...]
    xy: np.ndarray
    dist: np.ndarray
    entry: np.ndarray
    exit: np.ndarray


def home_of(site: Site, distance: str) -> Home:
    """The site's motion sensors as the model's nodes (module docstring of the model)."""
    pos = {m.id: m.position for m in site.motion_sensors}
    nodes = tuple(pos)
    g = site.sensor_graph
    edges = list(g.edges) if g is not None else []
    dist = node_distances(list(nodes), pos, edges, how=distance)
    entries = set(g.entries) if g is not None else set()
    exits = set(g.exits) if g is not None else set()
    xy = np.array([pos[n] for n in nodes], dtype=float).reshape(-1, 2)
    return Home(nodes, xy, dist, np.array([n in entries for n in nodes]), np.array([n in exits for n in nodes]))


def people_bound(site: Site, cfg: ResidentsConfig, counted: int = 0) -> int:
    """``K`` of eq. (1): ``targets`` when the site gives it (0 people -> 1: events need a cause),
    else the most people the home's count model says are in at once (``counted``, stage
    ``occupancy``), else ``max_people``."""
    if site.targets is not None:
        return max(1, int(site.targets))
    return max(1, min(counted, cfg.max_people)) if counted > 0 else cfg.max_people


def attribute(
    t: np.ndarray, node: np.ndarray, home: Home, cfg: ResidentsConfig, *, people: int, progress=None
) -> Attribution:
    """Decode the events ``(t[i], node[i])`` (node indices into ``home.nodes``; sorted by t)."""
    birth = birth_cost(
        t,
        home.entry[node],
        t_first=float(t[0]) if len(t) else 0.0,
        start_window_s=cfg.start_window_s,
        door=cfg.birth_door,
        inside=cfg.birth_inside,
    )

    def move_row(J: np.ndarray, i: int) -> np.ndarray:
        return move_cost(
            home.dist,
            node[J],
            np.full(len(J), node[i]),
            t[i] - t[J],
            l0=cfg.l0,
            v=cfg.speed,
            l_max=cfg.l_max,
            w=cfg.silence_weight,
            tau=cfg.silence_tau_s,
        )

    res = decode_events(move_row, birth, people=people, beam=cfg.beam or None, stay=cfg.stay or None, progress=progress)
    if not cfg.habits or res.people != 2:
        return res

    def move_to(src: np.ndarray, i: int) -> np.ndarray:
        return move_cost(
            home.dist,
            src,
            np.full(len(src), node[i]),
            np.zeros(len(src)),
            l0=cfg.l0,
            v=cfg.speed,
            l_max=cfg.l_max,
            w=0.0,
            tau=cfg.silence_tau_s,
        )

    cut = meeting_cuts(node, res.track, home.dist, meet=cfg.meet, margin=cfg.habit_margin, move_cost=move_to)
    track = reorient(
        node,
        res.track,
        cut,
        len(home.nodes),
        alpha=cfg.habit_alpha,
        switch=cfg.habit_switch,
        restarts=cfg.habit_restarts,
    )
    pred = preds_from_tracks(track)

    def move_one(j: int, i: int) -> float:
        return float(move_row(np.array([j]), i)[0])

    cost = attribution_cost(pred, move_one, birth, stay=cfg.stay or None)
    return Attribution(pred, tracks_from_pred(pred), cost, int((pred < 0).sum()), res.states)


def attribute_known(
    t: np.ndarray, node: np.ndarray, home: Home, profile: pl.DataFrame, cfg: ResidentsConfig, *, epoch: str | None
) -> tuple[Attribution, list[str]]:
    """Each event to its most probable resident under the profile (eq. K1-K3 of
    :mod:`onebit.trackers.residents.known`). Returns the attribution (people numbered in the
    order of the profile's residents, only those given an event) and their resident ids."""
    ch = chains(profile, home.nodes, home.dist, spread=cfg.profile_spread, prior=cfg.profile_prior)
    if cfg.profile_model == "turns":  # (K4): runs of one resident's events, weighed by their habits
        log_e = habit_log_probs(profile, ch.residents, home.nodes, node, t, epoch=epoch)
        post = turn_posteriors(log_e, t, cfg.profile_tau_s)
        log_z = 0.0
    else:
        bonus = clock_bonus(profile, ch.residents, home.nodes, node, t, epoch=epoch, weight=cfg.profile_clock_weight)
        post, log_z = posteriors(node, ch, bonus)
    who = post.argmax(axis=1) if len(node) else np.zeros(0, dtype=np.int64)
    fired = np.unique(who)
    track = np.searchsorted(fired, who).astype(np.int64)
    K, S = len(ch.residents), len(home.nodes)
    states = np.full(len(node), float(K * (S + 1) ** (K - 1)))
    att = Attribution(preds_from_tracks(track), track, -log_z, int(fired.size), states)
    return att, [ch.residents[k] for k in fired]


def run(inputs: dict, site: Site, config: ResidentsConfig) -> dict[str, pl.DataFrame]:
    """Attribute the motion events to people (module docstring)."""
    motion = check_schema(inputs["motion"], MOTION, name="motion").select(MOTION.names())
    home = home_of(site, config.distance)
    index = {n: k for k, n in enumerate(home.nodes)}
    motion = motion.with_row_index("row").filter(pl.col("sensor").is_in(list(home.nodes)))
    on = motion.filter(pl.col("on"))
    t = on["t"].to_numpy().astype(float)
    node = np.array([index[s] for s in on["sensor"].to_list()], dtype=np.int64)
    profile = inputs.get("residents_profile")
    if config.profile and profile is not None and profile.height:
        res, labels = attribute_known(t, node, home, profile, config, epoch=site.epoch)
        names = np.array([f"resident{r}" for r in labels], dtype=object)
    else:
        K = people_bound(site, config, home_count_bound(inputs))
        res = attribute(t, node, home, config, people=K, progress=progress_of(inputs))
        names = np.array([f"person{k + 1}" for k in range(max(res.people, 1))], dtype=object)
    on_tracks = on.select("row", "t", "sensor").with_columns(
        track=pl.Series(names[res.track].tolist() if len(t) else [], dtype=pl.String)
    )
    off = motion.filter(~pl.col("on")).select("row", "t", "sensor")
    off = off.sort("t").join_asof(  # an OFF edge: the person of its sensor's last ON (both sorted by t here)
        on_tracks.select("t", "sensor", "track").sort("t"),
        on="t",
        by="sensor",
        strategy="backward",
        check_sortedness=False,
    )
    events = pl.concat([on_tracks, off.select(on_tracks.columns)]).sort("row").select(EVENTS.names())
    tracks = tracks_table(t, node, res, names, home, config)
    decoder = pl.DataFrame(
        {
            "events": [len(t)],
            "people": [res.people],
            "cost": [res.cost],
            "beam": [config.beam],
            "states": [float(res.states.mean()) if len(t) else 0.0],
        },
        schema=DECODER,
    )
    return {
        "events": conform(events, EVENTS),
        "tracks": tracks,
        "people": counted_people(inputs, t, node, res, home, config),
        "decoder": decoder,
        ARTIFACTS: {"t": t, "node": node, "track": res.track, "nodes": home.nodes, "xy": home.xy},
    }


def presence(t: np.ndarray, node: np.ndarray, res: Attribution, home: Home, cfg: ResidentsConfig) -> list[np.ndarray]:
    """Each person's presence intervals, ``(n, 2)`` arrays of ``[start, end]`` times: from their
    first event on; a person whose event at an exit node is followed by more than
    ``exit_after_s`` of silence left ``exit_after_s`` after it and is back at their next event;
    present to the log's end otherwise (dwelling while silent)."""
    t_end = float(t[-1]) if len(t) else 0.0
    out = []
    for p in range(res.people):
        mine = np.flatnonzero(res.track == p)
        tp, gone = t[mine], home.exit[node[mine]]
        gap = np.diff(np.append(tp, np.inf))  # silence after each event (inf after the last)
        leaves = gone & (gap > cfg.exit_after_s)
        leaves[-1] = gone[-1]  # after the last event: they left if it was at an exit
        ends = np.flatnonzero(leaves)
        starts = np.r_[0, ends[:-1] + 1] if ends.size else np.array([0])
        seg_end = np.minimum(tp[ends] + cfg.exit_after_s, t_end)
        if not leaves[-1]:  # still in at the end of the log
            starts = np.r_[starts, ends[-1] + 1] if ends.size else starts
            seg_end = np.r_[seg_end, t_end]
        out.append(np.column_stack([tp[starts], seg_end]))
    return out


def tracks_table(
    t: np.ndarray, node: np.ndarray, res: Attribution, names: np.ndarray, home: Home, cfg: ResidentsConfig
) -> pl.DataFrame:
    """Every person on one grid of ``period`` s from the first event, while present, at the
    node of their latest event at or before the grid time."""
    frames = []
    if len(t):
        check_size(
            (t[-1] - t[0]) / cfg.period * max(res.people, 1),
            MAX_STEPS,
            what=f"track rows ({res.people} people every {cfg.period:g} s)",
            field=f"[residents] period = {cfg.period:g}",
            hint="a longer period",
        )
    grid = (
        float(t[0]) + cfg.period * np.arange(int(np.floor((t[-1] - t[0]) / cfg.period)) + 1) if len(t) else np.zeros(0)
    )
    for p, spans in enumerate(presence(t, node, res, home, cfg)):
        mine = np.flatnonzero(res.track == p)
        inside = np.zeros(grid.size, bool)
        for a, b in spans:
            inside |= (grid >= a - 1e-9) & (grid <= b + 1e-9)
        ts = grid[inside]
        if ts.size == 0:  # present between two grid times: its first one after the start
            ts = grid[np.searchsorted(grid, spans[0, 0]) :][:1]
        k = node[mine[np.maximum(np.searchsorted(t[mine], ts + 1e-9, side="right") - 1, 0)]]
        frames.append(
            pl.DataFrame(
                {
                    "track": names[p],
                    "t": ts,
                    "x": home.xy[k, 0],
                    "y": home.xy[k, 1],
                    "node": np.asarray(home.nodes, dtype=object)[k].tolist(),
                },
                schema_overrides={"node": pl.String, "track": pl.String},
            )
        )
    df = pl.concat(frames) if frames else pl.DataFrame(schema={"track": pl.String, "t": pl.Float64})
    return conform(df.with_columns(tracker=pl.lit(NAME)), TRACKS).sort(["t", "track"])


def counted_people(inputs: dict, t, node, res: Attribution, home: Home, cfg: ResidentsConfig) -> pl.DataFrame:
    """``people``: the home's count model's (stage ``occupancy``: doors, silence, which sensors
    fire, a count learned from labelled days) when the run has it, else the decoded people's
    presence (:func:`people_table`)."""
    counted = inputs.get("occupancy_people")
    if counted is not None:
        return counted.select(PEOPLE.names()).cast(dict(PEOPLE))
    return people_table(t, node, res, home, cfg)


def people_table(t: np.ndarray, node: np.ndarray, res: Attribution, home: Home, cfg: ResidentsConfig) -> pl.DataFrame:
    """The number of people present at each event's time (their presence intervals)."""
    present = np.zeros(len(t), dtype=np.int64)
    for spans in presence(t, node, res, home, cfg):
        inside = np.zeros(len(t), bool)
        for a, b in spans:
            inside |= (t >= a) & (t <= b)
        present += inside
    return pl.DataFrame({"t": t, "present": present}, schema=PEOPLE)


SPEC = TrackerSpec(
    name=NAME,
    needs=("motion",),
    wants=("residents_profile", "occupancy_people"),
    counts_people=True,
    config=ResidentsConfig,
    run=run,
    available=available,
    help="who is who at home: motion events attributed to people by a dwell-aware motion model on the sensor graph",
)
