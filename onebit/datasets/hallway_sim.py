"""Smart-environment simulator of FindingHuMo (De et al., section IV-C) on the ``hallway`` site.

``walk = "routes"`` (default) follows the paper's experiment (section IV-B: three users "made
to repeatedly move through the space in overlapping paths", Fig. 2): each user paces its own
route back and forth between a west end (printer room 92, busy lab 93, 97) and an east end
(110, 117, 116); every such route runs through the middle corridor 96-95-99-111, where the
routes overlap and users cross one another; users start at staggered times, alternately at
the west and the east end. ``walk = "random"`` (the first version): users enter through the
door (node 104) at staggered times and walk between random destinations alternating between
the wings -- then they mostly walk in file through the door corridor, 10-24 % of user-slots
with two users at one node, which no binary-sensor method can tell apart. Each user has its
own walking speed that also varies from edge to edge, and pauses at route ends /
destinations. With ``exits``, that many users walk to the door and leave before the end.

Sensors: a ceiling PIR at each node with its own coverage radius (``range`` in site.toml:
non-uniform coverage), read through the site's detection regions
(:func:`onebit.core.sensing.detection_regions`). Positions are sampled at 10 Hz; a user inside
a node's region is detected in a sample with probability ``p_detect`` (motion comes in bursts) and a detection
holds the PIR on for ``hold`` seconds. Each node has a clock offset (uniform in
``+-clock_offset`` s) added to its time stamps, and each on-burst's packets are lost with
probability ``drop`` (the hold, the edges and the lost bursts: the PIR's toggle log of
:mod:`onebit.models.pir`). ``motion.csv`` is the raw toggle log (t, sensor, value).

Truth (``truth.csv``): t, target, x, y, node at 10 Hz while a user is inside; ``node`` is the
node whose coverage the user is in (the nearest when several), else the last one it was in
(:func:`current_node`, also used by the scorer).

Planning is sequential per user (each leg starts where the last ended); sampling and
sensing are vectorised over samples, users and nodes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import ConfigError
from onebit.core.lazy import lazy_module
from onebit.core.sensing import covers, current_node, detection_regions
from onebit.core.site import Site, load_site
from onebit.core.writers import write_csv as _atomic_csv
from onebit.core.writers import write_text as _atomic_text
from onebit.datasets.builtin import builtin_site_path
from onebit.datasets.scenario import Scenario
from onebit.models.pir import hold_samples, keep_bursts, pir_on, toggle_edges

nx = lazy_module("networkx")

WEST = ("92", "93", "94", "96", "97", "95")
EAST = ("99", "110", "114", "117", "106", "118", "100", "111", "101")
DOOR = "104"
#: ends of the scripted routes (``walk = "routes"``): every shortest path from a west end to an
#: east end runs through the middle corridor 96-95-99-111, where the routes overlap and cross
ROUTE_WEST = ("92", "93", "97")
ROUTE_EAST = ("110", "117", "116")
WALKS = ("routes", "random")
#: time (s) at which the scripted experiment starts: every route user is at its route's start
START = 1.0


@dataclass(frozen=True, kw_only=True)
class HallwaySimConfig:
    """Simulation parameters (metres, seconds)."""

    duration: float = 150.0
    users: int = 3
    speed: tuple[float, float] = (0.9, 1.6)  #: per-user mean walking speed range (m/s)
    speed_jitter: float = 0.2  #: relative edge-to-edge variation of a user's speed
    pause: tuple[float, float] = (0.0, 4.0)  #: pause at a destination (s)
    enter_gap: tuple[float, float] = (2.0, 8.0)  #: time between two users entering (s)
    exits: int = 0  #: users that leave through the door before the end
    walk: str = (
        "routes"  #: "routes": each user paces its own west-east route; "random": random destinations from the door
    )
    rate_hz: float = 10.0
    p_detect: float = 0.85
    hold: float = 0.6
    clock_offset: float = 0.2
    drop: float = 0.02

    def __post_init__(self) -> None:
        if not (isinstance(self.duration, (int, float)) and self.duration > 0):
            raise ConfigError(f"HallwaySimConfig.duration = {self.duration!r}; must be > 0 seconds")
        if not isinstance(self.users, int) or self.users < 1:
            raise ConfigError(f"HallwaySimConfig.users = {self.users!r}; must be an integer >= 1")
        if not isinstance(self.exits, int) or not 0 <= self.exits <= self.users:
            raise ConfigError(f"HallwaySimConfig.exits = {self.exits!r}; allowed range: [0, users]")
        for name in ("drop", "p_detect"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ConfigError(f"HallwaySimConfig.{name} = {v!r}; allowed range: [0, 1]")
        if self.walk not in WALKS:
            raise ConfigError(f"HallwaySimConfig.walk = {self.walk!r}; allowed: {list(WALKS)}")
        if self.p_detect <= 0:
            raise ConfigError("HallwaySimConfig.p_detect must be > 0")


@dataclass(frozen=True)
class HallwaySimulation:
    samples: pl.DataFrame  # t, target, x, y, node (truth at rate_hz)
    toggles: pl.DataFrame  # t, sensor, value (raw log, with offsets and drops)


def _plan_user(
    g: nx.Graph, pos: dict, cfg: HallwaySimConfig, rng: np.random.Generator, t_in: float, leave_at: float | None
):
    """Waypoints (t, x, y) of one user: enter at the door, alternate wings, maybe leave."""
    speed = rng.uniform(*cfg.speed)
    t = t_in
    node = DOOR
    way = [(t, *pos[node])]
    wing = rng.integers(2)
    end = leave_at if leave_at is not None else cfg.duration + 5.0

    def walk(route):
        nonlocal t, node
        for a, b in zip(route[:-1], route[1:]):
            d = float(np.hypot(*(np.subtract(pos[b], pos[a]))))
            v = speed * (1.0 + rng.uniform(-cfg.speed_jitter, cfg.speed_jitter))
            t += d / v
            way.append((t, *pos[b]))
            node = b

    while t < end:
        choices = WEST if wing == 0 else EAST
        dest = choices[rng.integers(len(choices))]
        wing = 1 - wing
        if dest == node:
            continue
        walk(nx.shortest_path(g, node, dest))
        p = rng.uniform(*cfg.pause)
        t += p
        way.append((t, *pos[node]))
    if leave_at is not None:
        walk(nx.shortest_path(g, node, DOOR))
        t += 1.0
        way.append((t, *pos[DOOR]))
    return np.array(way), (t if leave_at is not None else None)


def _plan_route_user(
    g: nx.Graph,
    pos: dict,
    cfg: HallwaySimConfig,
    rng: np.random.Generator,
    t_in: float,
    leave_at: float | None,
    route: list[str],
):
    """Waypoints (t, x, y) of one user pacing ``route`` back and forth (the paper's scripted
    experiment, section IV-B: users "repeatedly move through the space in overlapping paths"),
    pausing at the ends; a leaver walks to the door at ``leave_at`` and leaves."""
    speed = rng.uniform(*cfg.speed)
    t = t_in
    way = [(min(START, t), *pos[route[0]]), (t, *pos[route[0]])]  # present from the start, leaves at t_in
    end = leave_at if leave_at is not None else cfg.duration + 5.0
    here = route[0]

    def walk(path):
        nonlocal t, here
        for a, b in zip(path[:-1], path[1:]):
            d = float(np.hypot(*(np.subtract(pos[b], pos[a]))))
            t += d / (speed * (1.0 + rng.uniform(-cfg.speed_jitter, cfg.speed_jitter)))
            way.append((t, *pos[b]))
            here = b
            if t >= end:
                return

    leg = route
    while t < end:
        walk(leg)
        t += rng.uniform(*cfg.pause)
        way.append((t, *pos[here]))
        leg = leg[::-1]
    if leave_at is not None:
        walk(nx.shortest_path(g, here, DOOR))
        t += 1.0
        way.append((t, *pos[DOOR]))
    return np.array(way), (t if leave_at is not None else None)


def _routes(g: nx.Graph, users: int, rng: np.random.Generator) -> list[list[str]]:
    """One west-east route per user; ends are dealt without repetition while they last, and
    users alternate the end they start from (so routes are walked in both directions)."""
    west = rng.permutation(ROUTE_WEST).tolist()
    east = rng.permutation(ROUTE_EAST).tolist()
    out = []
    for u in range(users):
        path = nx.shortest_path(g, west[u % len(west)], east[u % len(east)])
        out.append(path if u % 2 == 0 else path[::-1])
    return out


def simulate_hallway(site: Site, cfg: HallwaySimConfig, *, seed: int) -> HallwaySimulation:
    rng = np.random.default_rng(seed)
    g = site.sensor_graph.to_networkx(site)
    pos = {m.id: m.position for m in site.motion_sensors}
    ids = [m.id for m in site.motion_sensors]
    regions = [detection_regions(site)[i] for i in ids]
    times = np.arange(0.0, cfg.duration, 1.0 / cfg.rate_hz)
    leavers = set(rng.choice(cfg.users, size=cfg.exits, replace=False).tolist()) if cfg.exits else set()
    t_in = 1.0
    routes = _routes(g, cfg.users, rng) if cfg.walk == "routes" else []
    frames = []
    for u in range(cfg.users):
        leave_at = cfg.duration - rng.uniform(25.0, 40.0) if u in leavers else None
        if cfg.walk == "routes":
            way, t_out = _plan_route_user(g, pos, cfg, rng, t_in, leave_at, routes[u])
        else:
            way, t_out = _plan_user(g, pos, cfg, rng, t_in, leave_at)
        present = (times >= way[0, 0]) & (times <= (t_out if t_out is not None else np.inf))
        tt = times[present]
        x = np.interp(tt, way[:, 0], way[:, 1])
        y = np.interp(tt, way[:, 0], way[:, 2])
        frames.append(pl.DataFrame({"t": tt, "target": f"user{u + 1}", "x": x, "y": y}))
        t_in += rng.uniform(*cfg.enter_gap)
    samples = pl.concat(frames).sort(["t", "target"])
    xy = samples.select("x", "y").to_numpy()
    cur = current_node(xy, samples["target"].to_numpy(), regions)
    samples = samples.with_columns(
        node=pl.Series(np.asarray(ids + [None], dtype=object)[cur].tolist(), dtype=pl.String)
    )

    # sensing: per sample index and node, any user inside the node's region and detected
    k = np.rint(samples["t"].to_numpy() * cfg.rate_hz).astype(np.int64)
    inside = covers(regions, xy)
    det = inside & (rng.random(inside.shape) < cfg.p_detect)
    on = pir_on(k, det, len(times), hold_samples(cfg.hold, cfg.rate_hz))
    edges = toggle_edges(on)
    keep = keep_bursts(edges.burst, cfg.drop, rng)
    offset = rng.uniform(-cfg.clock_offset, cfg.clock_offset, size=len(ids))
    t_edge = edges.sample / cfg.rate_hz + offset[edges.sensor]
    toggles = (
        pl.DataFrame(
            {
                "t": np.maximum(t_edge, 0.0),
                "sensor": np.asarray(ids, dtype=object)[edges.sensor].tolist(),
                "value": edges.value.astype(np.int8),
            }
        )
        .filter(pl.Series(keep))
        .sort(["t", "sensor"])
        .with_columns(pl.col("t").round(3))
    )
    return HallwaySimulation(samples, toggles)


def write_hallway_dataset(
    out_dir: str | Path,
    *,
    seed: int = 0,
    duration: float = 150.0,
    users: int = 3,
    drop: float = 0.02,
    exits: int = 0,
    walk: str = "routes",
) -> Path:
    """Simulate the ``hallway`` scenario and write ``site.toml``, ``motion.csv``, ``truth.csv``
    (each atomically)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    site_path = builtin_site_path("hallway")
    site = load_site(site_path)
    cfg = HallwaySimConfig(duration=duration, users=users, drop=drop, exits=exits, walk=walk)
    sim = simulate_hallway(site, cfg, seed=seed)
    text = site_path.read_text(encoding="utf-8").replace(
        'units = "m"',
        f'units = "m"\ntargets = {users}                    # users simulated (the most present at once)',
        1,
    )
    _atomic_text(text, out / "site.toml")
    # what a tracker may know: a reading lags the user by the PIR's hold plus a node's clock
    # offset (and a 10 Hz sample); users walk at most speed[1] * (1 + speed_jitter)
    top = math.ceil(cfg.speed[1] * (1.0 + cfg.speed_jitter) * 10) / 10
    _atomic_text(
        "# Written by the simulator: what a tracker may know of these sensors and users.\n"
        f"[istate]\nlatency_s = {cfg.hold + cfg.clock_offset + 1.0 / cfg.rate_hz:g}\nmax_speed = {top:g}\n",
        out / "run.toml",
    )
    _atomic_csv(sim.toggles, out / "motion.csv")
    _atomic_csv(sim.samples.with_columns(pl.col("t").round(3)), out / "truth.csv")
    return out


def _write(dataset, *, seed: int, duration, agents, drop: float, camera: bool, params: dict):
    known = {"exits", "walk"}
    bad = sorted(set(params) - known)
    if bad:
        raise ConfigError(f"scenario 'hallway': unknown --param {bad}; known: {sorted(known)}")
    try:
        exits = int(params.get("exits", 0))
    except ValueError:
        raise ConfigError(f"scenario 'hallway': --param exits={params['exits']!r} is not an integer") from None
    return write_hallway_dataset(
        dataset,
        seed=seed,
        duration=150.0 if duration is None else duration,
        users=3 if agents is None else agents,
        drop=0.02 if drop is None else drop,
        exits=exits,
        walk=params.get("walk", "routes"),
    )


def _specs():

    return {
        "hallway": Scenario(
            "hallway",
            "FindingHuMo Fig. 1 floor: 20 PIR nodes on a hallway graph, 3 users with crossing paths (--param exits=N, walk=routes|random)",
            _write,
        )
    }


SCENARIO_SPECS = _specs()
