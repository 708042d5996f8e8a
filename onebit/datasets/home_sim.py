"""A home of 50 ceiling PIRs and its residents, for days of data (``onebit simulate home``).

The home (metres): a hallway along the bottom (y = 1.5) with 10 PIRs every 3 m, the front
door at its west end (node ``H01``), and five rooms above it -- bedroom, bathroom, kitchen,
living room, office -- each 6 m x 12 m with a 2 x 4 lattice of 8 PIRs (``<room><k>``), joined
to the hallway through a door at its south-west node. The sensor graph links lattice
neighbours inside a room, consecutive hallway nodes and each door node to the hallway node
below it (the only way between rooms). Each PIR sees 1.6 m around it.

Residents follow a day: at each visit a resident picks a room (weights by the hour: the
bedroom at night, the kitchen at meal times, the living room in the evening, the office in
the day), walks there along the graph's shortest path at its own pace (0.6-1.2 m/s), then
**dwells** -- exponential with a room- and hour-dependent mean (hours in bed at night,
minutes in the bathroom) -- moving now and then to a neighbouring spot of the room (every
30-240 s by day, 8 times less often at night). Residents start in the bedroom at midnight.

Sensing, as PIRs do: a sensor sees a resident inside its range only while the resident
moves (probability ``p_detect`` per sample) or, still, with probability ``p_still`` per sample
(breathing, turning over); a detection holds it on for ``hold`` seconds, and a whole on-burst
is lost with probability ``drop`` (the PIR's toggle log of :mod:`onebit.models.pir`). ``motion.csv`` is the
raw toggle log (t, sensor, value), ``truth.csv`` the positions at ``rate_hz`` (t, target, x, y,
node). Sampling and sensing are vectorised over samples, residents and sensors; planning is
sequential per resident. Deterministic for a seed; nothing comes from a real dataset.
"""

from __future__ import annotations

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
from onebit.datasets.scenario import Scenario
from onebit.models.pir import hold_samples, keep_bursts, pir_on, toggle_edges

nx = lazy_module("networkx")

NAME = "home"
ROOMS = ("bedroom", "bathroom", "kitchen", "living", "office")
SPACING = 3.0  #: m between neighbouring PIRs
RANGE = 1.6  #: m: a PIR sees a resident this close
HALL_NODES = 10

#: Weight of each room (ROOMS order) by hour of the day: bedroom at night, kitchen at meals,
#: living room in the evening, office in the day.
_NIGHT = (0.86, 0.1, 0.02, 0.01, 0.01)
_MEAL = (0.05, 0.1, 0.6, 0.2, 0.05)
_DAY = (0.05, 0.1, 0.15, 0.25, 0.45)
_EVENING = (0.1, 0.1, 0.2, 0.55, 0.05)
HOURLY = tuple(
    _NIGHT if h < 7 or h >= 23 else _MEAL if h in (7, 12, 13, 19) else _EVENING if h >= 20 else _DAY for h in range(24)
)
#: Mean dwell (s) per room by day / night.
DWELL_DAY = {"bedroom": 900.0, "bathroom": 300.0, "kitchen": 900.0, "living": 1800.0, "office": 2400.0}
#: At night (23-7 h) moves inside a room come this many times less often.
NIGHT_CALM = 8.0
DWELL_NIGHT = {"bedroom": 10_800.0, "bathroom": 240.0, "kitchen": 300.0, "living": 600.0, "office": 600.0}


@dataclass(frozen=True, kw_only=True)
class HomeSimConfig:
    """Simulation parameters (metres, seconds)."""

    duration: float = 86_400.0  #: s (a day)
    residents: int = 2
    speed: tuple[float, float] = (0.6, 1.2)  #: per-resident walking speed range (m/s)
    fidget: tuple[float, float] = (30.0, 240.0)  #: s between two moves inside a room while dwelling
    rate_hz: float = 2.0
    p_detect: float = 0.9  #: detection probability per sample of a moving resident in range
    p_still: float = 0.01  #: per sample, of a resident standing or lying still in range
    hold: float = 2.0  #: s a detection keeps the PIR on
    drop: float = 0.0  #: probability that a whole on-burst is lost

    def __post_init__(self) -> None:
        if not (isinstance(self.duration, (int, float)) and 0 < self.duration <= 31 * 86_400):
            raise ConfigError(f"HomeSimConfig.duration = {self.duration!r}; allowed range: (0, 31 days]")
        if not isinstance(self.residents, int) or not 1 <= self.residents <= 8:
            raise ConfigError(f"HomeSimConfig.residents = {self.residents!r}; allowed range: [1, 8]")
        for name in ("p_detect", "p_still", "drop"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ConfigError(f"HomeSimConfig.{name} = {v!r}; allowed range: [0, 1]")
        if not 0 < self.rate_hz <= 20:
            raise ConfigError(f"HomeSimConfig.rate_hz = {self.rate_hz!r}; allowed range: (0, 20]")
        if self.hold <= 0:
            raise ConfigError(f"HomeSimConfig.hold = {self.hold!r}; must be > 0 s")


def layout() -> tuple[dict[str, tuple[float, float]], list[tuple[str, str]], dict[str, list[str]]]:
    """``(positions, edges, nodes of each room)`` of the home (module docstring); 50 nodes."""
    pos: dict[str, tuple[float, float]] = {}
    edges: list[tuple[str, str]] = []
    rooms: dict[str, list[str]] = {}
    hall = [f"H{k + 1:02d}" for k in range(HALL_NODES)]
    for k, h in enumerate(hall):
        pos[h] = (SPACING * k + 1.5, 1.5)
    edges += list(zip(hall[:-1], hall[1:]))
    rooms["hallway"] = hall
    for r, room in enumerate(ROOMS):
        ids = {}
        for i in range(2):  # columns
            for j in range(4):  # rows, from the hallway up
                node = f"{room[:3].upper()}{j * 2 + i + 1}"
                pos[node] = (SPACING * (2 * r + i) + 1.5, 1.5 + SPACING * (j + 1))
                ids[i, j] = node
        for (i, j), node in ids.items():
            if (i + 1, j) in ids:
                edges.append((node, ids[i + 1, j]))
            if (i, j + 1) in ids:
                edges.append((node, ids[i, j + 1]))
        edges.append((hall[2 * r], ids[0, 0]))  # the room's door
        rooms[room] = list(ids.values())
    return pos, edges, rooms


def site_toml(residents: int) -> str:
    """``site.toml`` of the home (boundary, 50 PIRs with their range, the sensor graph)."""
    pos, edges, _ = layout()
    width, height = SPACING * HALL_NODES, SPACING * 5
    lines = [
        "# The 'home' scenario of onebit simulate: a hallway of 10 PIRs and five rooms of 8 PIRs",
        "# (bedroom, bathroom, kitchen, living room, office), doors at each room's south-west node.",
        f'name = "{NAME}"',
        'units = "m"',
        f"targets = {residents}                    # residents simulated (the most present at once)",
        "",
        "[boundary]",
        f"polygon = [[0, 0], [{width:g}, 0], [{width:g}, {height:g}], [0, {height:g}]]",
        "",
    ]
    for node, (x, y) in pos.items():
        lines += ["[[motion_sensors]]", f'id = "{node}"', f"position = [{x:g}, {y:g}]", f"range = {RANGE:g}"]
    lines += ["", "[sensor_graph]", "edges = [", *(f'  ["{a}", "{b}"],' for a, b in edges), "]"]
    lines += ['entries = ["H01"]', 'exits = ["H01"]', ""]
    return "\n".join(lines)


def _plan(g, pos: dict, rooms: dict, cfg: HomeSimConfig, rng: np.random.Generator) -> np.ndarray:
    """Waypoints ``(t, x, y, moving)`` of one resident over the day (module docstring);
    ``moving`` is 1 on the segment that ends at a waypoint when the resident walked it."""
    speed = rng.uniform(*cfg.speed)
    here = rooms["bedroom"][rng.integers(len(rooms["bedroom"]))]
    t = 0.0
    way = [(0.0, *pos[here], 0.0)]
    paths = dict(nx.all_pairs_shortest_path(g))

    def walk(dest: str) -> None:
        nonlocal t, here
        for a, b in zip(paths[here][dest][:-1], paths[here][dest][1:]):
            t += float(np.hypot(*np.subtract(pos[b], pos[a]))) / (speed * rng.uniform(0.85, 1.15))
            way.append((t, *pos[b], 1.0))
            here = b

    while t < cfg.duration:
        hour = int(t // 3600) % 24
        room = ROOMS[rng.choice(len(ROOMS), p=np.asarray(HOURLY[hour]) / sum(HOURLY[hour]))]
        walk(rooms[room][rng.integers(len(rooms[room]))])
        night = hour < 7 or hour >= 23
        mean = (DWELL_NIGHT if night else DWELL_DAY)[room]
        until = t + rng.exponential(mean)
        while t < until and t < cfg.duration:  # dwell: still, with a move to a neighbouring spot now and then
            t = min(until, t + rng.uniform(*cfg.fidget) * (NIGHT_CALM if night else 1.0))
            way.append((t, *pos[here], 0.0))
            near = [n for n in g.neighbors(here) if n in rooms[room]]
            if near and t < until:
                walk(near[rng.integers(len(near))])
    return np.array(way)


@dataclass(frozen=True)
class HomeSimulation:
    samples: pl.DataFrame  # t, target, x, y, node (truth at rate_hz)
    toggles: pl.DataFrame  # t, sensor, value (raw PIR log)


def simulate_home(site: Site, cfg: HomeSimConfig, *, seed: int) -> HomeSimulation:
    """Residents' paths (:func:`_plan`) sampled at ``rate_hz`` and sensed by the site's PIRs."""
    rng = np.random.default_rng(seed)
    g = site.sensor_graph.to_networkx(site)
    pos = {m.id: m.position for m in site.motion_sensors}
    _, _, rooms = layout()
    ids = [m.id for m in site.motion_sensors]
    regions = [detection_regions(site)[i] for i in ids]
    times = np.arange(0.0, cfg.duration, 1.0 / cfg.rate_hz)
    frames, moving = [], []
    for u in range(cfg.residents):
        way = _plan(g, pos, rooms, cfg, rng)
        x = np.interp(times, way[:, 0], way[:, 1])
        y = np.interp(times, way[:, 0], way[:, 2])
        seg = np.clip(np.searchsorted(way[:, 0], times, side="right"), 1, len(way) - 1)
        moving.append(way[seg, 3] > 0)  # the segment that ends at waypoint seg was walked
        frames.append(pl.DataFrame({"t": times, "target": f"resident{u + 1}", "x": x, "y": y}))
    samples = pl.concat(frames)
    move = np.concatenate(moving)
    xy = samples.select("x", "y").to_numpy()
    cur = current_node(xy, samples["target"].to_numpy(), regions)
    samples = samples.with_columns(
        node=pl.Series(np.asarray(ids + [None], dtype=object)[cur].tolist(), dtype=pl.String)
    )
    k = np.tile(np.arange(len(times)), cfg.residents)
    p = np.where(move, cfg.p_detect, cfg.p_still)[:, None]
    det = covers(regions, xy) & (rng.random((len(xy), len(ids))) < p)
    edges = toggle_edges(pir_on(k, det, len(times), hold_samples(cfg.hold, cfg.rate_hz)))
    keep = keep_bursts(edges.burst, cfg.drop, rng)  # the last draw: the stream after it is not used
    toggles = (
        pl.DataFrame(
            {
                "t": edges.sample / cfg.rate_hz,
                "sensor": np.asarray(ids, dtype=object)[edges.sensor].tolist(),
                "value": edges.value.astype(np.int8),
            }
        )
        .filter(pl.Series(keep))
        .sort(["t", "sensor"])
        .with_columns(pl.col("t").round(3))
    )
    return HomeSimulation(samples.sort(["t", "target"]), toggles)


def write_home_dataset(
    out_dir: str | Path, *, seed: int = 0, duration: float = 86_400.0, residents: int = 2, drop: float = 0.0
) -> Path:
    """Simulate the ``home`` scenario and write ``site.toml``, ``motion.csv``, ``truth.csv``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _atomic_text(site_toml(residents), out / "site.toml")
    site = load_site(out / "site.toml")
    sim = simulate_home(site, HomeSimConfig(duration=duration, residents=residents, drop=drop), seed=seed)
    _atomic_csv(sim.toggles, out / "motion.csv")
    _atomic_csv(sim.samples.with_columns(pl.col("t").round(3)), out / "truth.csv")
    return out


def _write(dataset, *, seed: int, duration, agents, drop: float, camera: bool, params: dict):
    if params:
        raise ConfigError(f"scenario 'home': unknown --param {sorted(params)}; it takes none")
    return write_home_dataset(
        dataset,
        seed=seed,
        duration=86_400.0 if duration is None else duration,
        residents=2 if agents is None else agents,
        drop=0.0 if drop is None else drop,
    )


SCENARIO_SPECS = {
    NAME: Scenario(
        NAME,
        "a home of 50 PIRs (hallway + 5 rooms), 2 residents over a day with dwell times (--duration s, --agents N)",
        _write,
    )
}
