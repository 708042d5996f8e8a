"""Simulator of agents moving among directional beams: writes a complete dataset folder.

Agents move continuously and at random through the free space of a site: from a point in
their region they wander to one or two random points, walk to an approach point in front
of a randomly chosen beam of that region, and cross it at walking speed to the other side.
Sometimes they hesitate: walk into the beam far enough to block the nearer pair, then go
back (a start-and-return, paper Fig. 5). Every leg is a straight segment that stays inside
the region shrunk by the agent's radius, so agents never pass through obstacles.

Raw events are produced the way the hardware sees them: pair ``p`` of beam ``beta`` is
blocked while the distance from an agent's centre to the pair's segment is below the agent
radius. Agents are planned one after another; an agent waits before entering a beam while
an earlier agent is using it, so two bodies never occupy one beam at once (the paper's
source of false negatives is then modelled explicitly by ``drop``: each crossing's raw
events are removed with probability ``drop``).

Motion planning is sequential per agent (each leg depends on where the last one ended);
the sampling of positions and the beam/pair blocking are vectorised over samples.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl
import shapely
from shapely.geometry import LineString, Point

from onebit.core.errors import ConfigError
from onebit.core.region_graph import RegionGraph, build_region_graph
from onebit.core.sensing import body_radius
from onebit.core.site import Site, load_site
from onebit.core.writers import write_csv as _atomic_csv
from onebit.core.writers import write_text as _atomic_text
from onebit.datasets.builtin import builtin_site_path
from onebit.datasets.camera_render import render_overhead_video
from onebit.datasets.scenario import Scenario

#: Built-in scenarios: site, default agent count, speed range (units/s). An agent's radius is
#: the site's ``body_radius`` (lab 0.15 ft, building 0.25 m): the one value the beam reader's
#: geometry and the trackers use too.
SCENARIOS = {
    "beams-lab": dict(site="lab", agents=2, speed=(0.6, 1.2), start="same"),
    "beams-building": dict(site="building", agents=3, speed=(0.8, 1.5), start="random"),
}


@dataclass(frozen=True, kw_only=True)
class BeamsSimConfig:
    """Simulation parameters (units of the site)."""

    duration: float = 180.0
    agents: int = 2
    drop: float = 0.0
    speed: tuple[float, float] = (0.6, 1.2)
    radius: float = 0.15
    hesitate: float = 0.12
    pause: tuple[float, float] = (0.0, 1.5)
    rate_hz: float = 200.0
    start: str = "random"

    def __post_init__(self) -> None:

        if self.duration <= 0:
            raise ConfigError(f"duration = {self.duration!r}; must be > 0 seconds")
        if not isinstance(self.agents, int) or self.agents < 1:
            raise ConfigError(f"agents = {self.agents!r}; must be an integer >= 1")
        if not 0.0 <= self.drop < 1.0:
            raise ConfigError(f"drop = {self.drop!r}; allowed range: [0, 1)")
        if not 0.0 <= self.hesitate < 1.0:
            raise ConfigError(f"hesitate = {self.hesitate!r}; allowed range: [0, 1)")


@dataclass(frozen=True)
class BeamsSimulation:
    """Everything a simulation produced, before it is written to disk."""

    samples: pl.DataFrame  # t, target, x, y at rate_hz
    beam_events: pl.DataFrame  # t, beam, pair, blocked (raw, after drops)
    true_crossings: pl.DataFrame  # t, beam, direction, target (all crossings, dropped or not)
    dropped: pl.DataFrame  # t, beam, direction, target of the dropped crossings
    start_regions: dict[str, str] | None = None  # target -> region name at t = 0


class _Planner:
    """Plans one agent's piecewise-linear path as waypoints (t, x, y)."""

    def __init__(self, site: Site, rg: RegionGraph, cfg: BeamsSimConfig, rng: np.random.Generator, reserved: dict):
        self.site, self.rg, self.cfg, self.rng, self.reserved = site, rg, cfg, rng, reserved
        self.shrunk = [p.buffer(-cfg.radius) for p in rg.polygons]
        self.beams = {b.id: b for b in site.beams}
        self.edges = {i: [] for i in range(len(rg.names))}
        idx = rg.index
        for bid in rg.beam_source:
            s, t = idx[rg.beam_source[bid]], idx[rg.beam_target[bid]]
            self.edges[s].append((bid, 1, t))
            self.edges[t].append((bid, -1, s))

    def random_points(self, region: int, k: int = 64) -> np.ndarray:
        poly = self.shrunk[region]
        minx, miny, maxx, maxy = poly.bounds
        for _ in range(50):
            pts = self.rng.uniform([minx, miny], [maxx, maxy], size=(k, 2))
            ok = shapely.contains_xy(poly, pts[:, 0], pts[:, 1])
            if ok.any():
                return pts[ok]
        raise RuntimeError("region too small for the agent radius")

    def route(self, region: int, p: np.ndarray, q: np.ndarray) -> list[np.ndarray] | None:
        """Waypoints from p to q inside the shrunk region: direct, or through one random point."""
        poly = self.shrunk[region].buffer(1e-9)
        if poly.contains(LineString([p, q])):
            return [q]
        cand = self.random_points(region, 256)
        a = shapely.linestrings(np.stack([np.broadcast_to(p, cand.shape), cand], axis=1))
        b = shapely.linestrings(np.stack([cand, np.broadcast_to(q, cand.shape)], axis=1))
        ok = shapely.contains(poly, a) & shapely.contains(poly, b)
        if ok.any():
            return [cand[np.flatnonzero(ok)[0]], q]
        return None

    def plan(self, target: str, region: int, p: np.ndarray) -> tuple[list, list]:
        cfg, rng = self.cfg, self.rng
        t = 0.0
        way = [(t, *p)]
        crossings = []

        def walk(to: np.ndarray) -> None:
            nonlocal t, p
            d = float(np.hypot(*(to - p)))
            t += d / rng.uniform(*cfg.speed)
            p = np.asarray(to, float)
            way.append((t, *p))

        def wait(dt: float) -> None:
            nonlocal t
            if dt > 0:
                t += dt
                way.append((t, *p))

        while t < cfg.duration:
            for _ in range(rng.integers(0, 3)):
                nxt = self.random_points(region, 16)[0]
                r = self.route(region, p, nxt)
                if r:
                    for w in r:
                        walk(w)
                    wait(rng.uniform(*cfg.pause))
            options = self.edges[region]
            bid, direction, dest = options[rng.integers(len(options))]
            beam = self.beams[bid]
            n = beam.forward_normal * direction
            u = rng.uniform(0.3, 0.7)
            q = np.asarray(beam.line.interpolate(u, normalized=True).coords[0])
            clear = cfg.radius + beam.spacing / 2 + 0.6 * cfg.radius
            approach, exit_ = q - n * clear, q + n * clear
            if not self.shrunk[dest].buffer(1e-9).contains(Point(exit_)):
                continue
            r = self.route(region, p, approach)
            if r is None:
                continue
            for w in r:
                walk(w)
            hesitate = rng.random() < cfg.hesitate
            leg = (2 * clear) / cfg.speed[0] + (2 * clear) / cfg.speed[0] * (2 if hesitate else 1) + 0.5
            start = self._free_after(bid, t, leg)
            wait(start - t)
            t_enter = t
            if hesitate:
                depth = rng.uniform(0.2, 0.9) * cfg.radius
                walk(q - n * depth)
                walk(approach)
            walk(q)
            t_cross = t
            walk(exit_)
            self.reserved.setdefault(bid, []).append((t_enter - 0.25, t + 0.25))
            crossings.append((t_cross, bid, direction, target))
            region, p = dest, exit_
        return way, crossings

    def _free_after(self, bid: str, t: float, leg: float) -> float:
        """Earliest time >= t at which beam ``bid`` is free for ``leg`` seconds."""
        busy = sorted(self.reserved.get(bid, []))
        start = t
        for a, b in busy:
            if start + leg <= a or start >= b:
                continue
            start = b
        # a second pass catches intervals skipped over by the first shift
        for a, b in sorted(busy):
            if not (start + leg <= a or start >= b):
                start = b
        return start


def sample_path(way: list, times: np.ndarray) -> np.ndarray:
    """Positions (len(times), 2) on a piecewise-linear path given as (t, x, y) waypoints."""
    w = np.asarray(way, float)
    tt, keep = np.unique(w[:, 0], return_index=True)
    # where the agent waits, several waypoints share a time: keep the last position at that time
    last = np.searchsorted(w[:, 0], tt, side="right") - 1
    return np.c_[np.interp(times, tt, w[last, 1]), np.interp(times, tt, w[last, 2])]


def _dist_to_segment(pts: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    u = np.clip(((pts - a) @ ab) / (ab @ ab), 0.0, 1.0)
    # per coordinate, not ``pts - (a + u[:, None] * ab)``: numpy broadcasts over a length-2 axis slowly
    return np.hypot(pts[:, 0] - (a[0] + u * ab[0]), pts[:, 1] - (a[1] + u * ab[1]))


def simulate_beams(site: Site, cfg: BeamsSimConfig, *, seed: int) -> BeamsSimulation:
    """Simulate ``cfg.agents`` agents on ``site`` for ``cfg.duration`` seconds (deterministic per seed)."""
    rng = np.random.default_rng(seed)
    rg = build_region_graph(site)
    reserved: dict[str, list] = {}
    planner = _Planner(site, rg, cfg, rng, reserved)
    times = np.arange(0.0, cfg.duration, 1.0 / cfg.rate_hz)
    start_region = int(rng.integers(len(rg.names)))
    paths, crossings, starts = {}, [], {}
    for k in range(cfg.agents):
        target = f"agent{k + 1}"
        region = start_region if cfg.start == "same" else int(rng.integers(len(rg.names)))
        starts[target] = rg.names[region]
        p0 = planner.random_points(region, 16)[0]
        way, cr = planner.plan(target, region, p0)
        paths[target] = sample_path(way, times)
        crossings += [c for c in cr if c[0] < cfg.duration]
    true_cross = pl.DataFrame(
        crossings, schema={"t": pl.Float64, "beam": pl.String, "direction": pl.Int8, "target": pl.String}, orient="row"
    ).sort("t")
    dropped_mask = rng.random(true_cross.height) < cfg.drop
    dropped = true_cross.filter(pl.Series(dropped_mask))

    # raw events: pair blocked while an agent's centre is within its radius of the pair segment
    events = []
    for beam in site.beams:
        drops = dropped.filter(pl.col("beam") == beam.id)
        for pair, (a, b) in beam.pair_segments().items():
            blocked = np.zeros(len(times), dtype=bool)
            for target, pos in paths.items():
                near = _dist_to_segment(pos, a, b) < cfg.radius
                if drops.height:
                    near &= ~_within_dropped(times, near, drops.filter(pl.col("target") == target)["t"].to_numpy())
                blocked |= near
            edges = np.flatnonzero(np.diff(np.r_[False, blocked].astype(np.int8)) != 0)
            events.append(
                pl.DataFrame(
                    {
                        "t": times[edges],
                        "beam": [beam.id] * len(edges),
                        "pair": [pair] * len(edges),
                        "blocked": blocked[edges],
                    },
                    schema={"t": pl.Float64, "beam": pl.String, "pair": pl.String, "blocked": pl.Boolean},
                )
            )
    beam_events = pl.concat(events).sort(["t", "beam", "pair"]) if events else pl.DataFrame()
    samples = pl.concat(
        [pl.DataFrame({"t": times, "target": tgt, "x": pos[:, 0], "y": pos[:, 1]}) for tgt, pos in paths.items()]
    ).sort(["t", "target"])
    return BeamsSimulation(samples, beam_events, true_cross, dropped, starts)


def _within_dropped(times: np.ndarray, near: np.ndarray, drop_t: np.ndarray) -> np.ndarray:
    """Mask of the blocked runs of ``near`` that contain a dropped crossing time."""
    if len(drop_t) == 0:
        return np.zeros_like(near)
    run_id = np.cumsum(np.r_[True, near[1:] != near[:-1]])
    hit = np.zeros(run_id[-1] + 1, dtype=bool)
    k = np.clip(np.searchsorted(times, drop_t), 0, len(times) - 1)
    hit[run_id[k][near[k]]] = True
    return hit[run_id] & near


def write_beams_dataset(
    out_dir: str | Path,
    scenario: str = "beams-lab",
    *,
    seed: int = 0,
    duration: float = 180.0,
    agents: int | None = None,
    drop: float = 0.0,
    camera: bool = True,
) -> Path:
    """Simulate a built-in scenario and write a dataset folder.

    Writes ``site.toml``, ``beams.csv`` (raw pair events), ``truth.csv`` (at the camera frame
    rate), ``truth_crossings.csv`` (every true crossing, with its agent and a ``dropped``
    flag), ``run.toml`` (the known initial condition for the ``correct`` stage: ``[correct]``
    ``n`` and ``initial`` counts per region, the paper's known eta_0 of section V) and, with
    ``camera``, an overhead ``camera.mp4``. Every file is written atomically.
    """
    if scenario not in SCENARIOS:
        raise ConfigError(f"unknown scenario {scenario!r}; known: {sorted(SCENARIOS)}")
    sc = SCENARIOS[scenario]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    site_path = builtin_site_path(sc["site"])
    site = load_site(site_path)
    cfg = BeamsSimConfig(
        duration=duration,
        agents=agents or sc["agents"],
        drop=drop,
        speed=sc["speed"],
        radius=body_radius(site),
        start=sc["start"],
    )
    sim = simulate_beams(site, cfg, seed=seed)
    _atomic_text(with_targets(site_path.read_text(encoding="utf-8"), cfg.agents), out / "site.toml")
    _atomic_csv(sim.beam_events.with_columns(pl.col("blocked").cast(pl.Int8)), out / "beams.csv")
    cam = site.camera
    fps = cam.fps if cam else 10.0
    step = max(1, int(round(cfg.rate_hz / fps)))
    frames = sim.samples.filter((pl.col("t") * cfg.rate_hz).round().cast(pl.Int64) % step == 0)
    _atomic_csv(frames.select("t", "target", "x", "y"), out / "truth.csv")
    dropped_keys = sim.dropped.with_columns(dropped=pl.lit(True))
    tc = sim.true_crossings.join(dropped_keys, on=["t", "beam", "direction", "target"], how="left").with_columns(
        pl.col("dropped").fill_null(False).cast(pl.Int8)
    )
    _atomic_csv(tc, out / "truth_crossings.csv")
    _atomic_text(initial_condition_toml(sim.start_regions or {}), out / "run.toml")
    if camera and cam is not None:
        render_overhead_video(out / "camera.mp4", site, frames, seed=seed, radius=cfg.radius)
    return out


def with_targets(site_text: str, n: int) -> str:
    """``site.toml`` text with ``targets = n`` (the simulated agents: the most present at once)."""
    lines = site_text.splitlines()
    k = next((i for i, ln in enumerate(lines) if ln.startswith("units")), 0)
    return (
        "\n".join(
            lines[: k + 1]
            + [f"targets = {n}                    # agents simulated (the most present at once)"]
            + lines[k + 1 :]
        )
        + "\n"
    )


def initial_condition_toml(start_regions: dict[str, str]) -> str:
    """The dataset's ``run.toml``: ``[correct] n`` and ``initial`` (agents per start region)."""
    counts: dict[str, int] = {}
    for region in start_regions.values():
        counts[region] = counts.get(region, 0) + 1
    table = ", ".join(f'"{r}" = {c}' for r, c in sorted(counts.items()))
    return (
        "# Written by the simulator: the known initial condition (Bobadilla et al. V, IV-C).\n"
        "[correct]\n"
        f"n = {len(start_regions)}\n"
        f"initial = {{{table}}}\n"
    )


def _scenario_writer(name: str):
    def write(dataset, *, seed: int, duration: float, agents: int | None, drop: float, camera: bool, params: dict):
        if params:
            raise ConfigError(f"scenario {name!r} takes no --param options, got {sorted(params)}")
        return write_beams_dataset(
            dataset,
            name,
            seed=seed,
            duration=180.0 if duration is None else duration,
            agents=agents,
            drop=drop,
            camera=camera,
        )

    return write


def _specs():

    helps = {
        "beams-lab": "paper Fig. 8 lab: 4 directional beams, 5 regions in a chain, 2 agents, camera",
        "beams-building": "paper Fig. 1 building: 7 beams, 6 regions, 3 agents, camera",
    }
    return {n: Scenario(n, helps[n], _scenario_writer(n)) for n in SCENARIOS}


SCENARIO_SPECS = _specs()
