"""Simulations for O'Kane's I-state tracker: the ``istate-room`` dataset and active tracking.

``istate-room`` (``onebit simulate istate-room DIR``): a 12 m x 8 m room with two obstacles,
six motion sensors with square fields of view (``fov`` in ``site.toml``), ``n`` targets
(default 2) walking along shortest paths among the obstacles to random destinations at
0.4-1.2 m/s. Writes ``site.toml``, ``motion.csv`` (t, sensor, value: an edge whenever the set
of targets inside a sensor's square becomes empty or non-empty, sampled at 10 Hz, no chatter;
``--drop p`` removes each on-period with probability p -- false negatives) and ``truth.csv``
(10 Hz). Deterministic for a seed; every file written atomically.

:func:`fig9_environment` and :class:`TargetMotion` also serve the active-tracking study
(section VIII), which runs the trackers and so lives in
:mod:`onebit.experiments.okane_active`: a simulator imports only the base and the models.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import shapely
from shapely.geometry import box

from onebit.core.errors import ConfigError
from onebit.core.writers import write_csv as _atomic_csv
from onebit.core.writers import write_text as _atomic_text
from onebit.datasets.scenario import Scenario
from onebit.models.walking import ShortestPaths, advance

# --------------------------------------------------------------------------- environments


def fig9_environment() -> tuple[shapely.Polygon, list[shapely.Polygon]]:
    """A 100 x 100 square with five rectangular obstacles, after the paper's Fig. 9 (the
    paper gives no coordinates; this is our reconstruction: blocks spread over the square
    leaving corridors between them)."""
    boundary = box(0, 0, 100, 100)
    obstacles = [
        box(18, 18, 38, 34),
        box(60, 12, 74, 42),
        box(22, 60, 44, 80),
        box(62, 64, 86, 76),
        box(44, 44, 54, 54),
    ]
    return boundary, obstacles


def _free(boundary, obstacles):
    return shapely.difference(boundary, shapely.union_all(obstacles)) if obstacles else boundary


def random_free_points(rng: np.random.Generator, free, k: int) -> np.ndarray:
    """``k`` uniform points in ``free`` (rejection sampling, vectorised)."""
    minx, miny, maxx, maxy = free.bounds
    out = np.zeros((0, 2))
    while len(out) < k:
        pts = rng.uniform([minx, miny], [maxx, maxy], size=(4 * k + 8, 2))
        out = np.vstack([out, pts[shapely.contains_xy(free, pts[:, 0], pts[:, 1])]])
    return out[:k]


class TargetMotion:
    """Targets moving along shortest paths to random destinations, ``step`` per stage."""

    def __init__(self, rng, planner: ShortestPaths, start: np.ndarray, step: np.ndarray) -> None:
        self.rng, self.planner, self.pos, self.step = rng, planner, start.copy(), np.asarray(step, float)
        self.routes = [self._new_route(p) for p in self.pos]

    def _new_route(self, p):
        while True:
            q = random_free_points(self.rng, self.planner.free, 1)[0]
            w = self.planner.path(p, q)
            if len(w) > 1:
                return w

    def move(self) -> np.ndarray:
        """Advance every target by its step (per-target: routes differ in length)."""
        for i in range(len(self.pos)):  # n targets, each on its own polyline
            w = self.routes[i]
            L = float(np.hypot(*np.diff(w, axis=0).T).sum())
            s = float(self.step[i])
            if s >= L:
                self.pos[i] = w[-1]
                self.routes[i] = self._new_route(self.pos[i])
            else:
                self.pos[i] = advance(w, s)
                seg_end = np.cumsum(np.r_[0.0, np.hypot(*np.diff(w, axis=0).T)])
                k = int(np.searchsorted(seg_end, s, side="right"))
                self.routes[i] = np.vstack([self.pos[i], w[k:]])
        return self.pos.copy()


# --------------------------------------------------------------------------- istate-room dataset

ROOM = dict(
    boundary=[[0, 0], [12, 0], [12, 8], [0, 8]],
    obstacles=[[[4, 2], [5, 2], [5, 5.5], [4, 5.5]], [[8, 4], [9.5, 4], [9.5, 8], [8, 8]]],
)
ROOM_SENSORS = {
    "m1": (1.5, 1.5),
    "m2": (1.5, 6.0),
    "m3": (6.5, 1.2),
    "m4": (6.5, 5.5),
    "m5": (10.5, 1.5),
    "m6": (10.5, 5.5),
}
ROOM_FOV = 1.0  # half side of each square field of view (m)


def room_site_toml(n: int) -> str:
    """``site.toml`` of the ``istate-room`` scenario."""

    def poly(p):
        return "[" + ", ".join(f"[{x}, {y}]" for x, y in p) + "]"

    lines = [
        'name = "istate-room"',
        'units = "m"',
        f"targets = {n}",
        "",
        "[boundary]",
        f"polygon = {poly(ROOM['boundary'])}",
        "",
    ]
    for i, ob in enumerate(ROOM["obstacles"]):
        lines += ["[[obstacles]]", f'name = "block{i + 1}"', f"polygon = {poly(ob)}", ""]
    for sid, (x, y) in ROOM_SENSORS.items():
        h = ROOM_FOV
        sq = [[x - h, y - h], [x + h, y - h], [x + h, y + h], [x - h, y + h]]
        lines += ["[[motion_sensors]]", f'id = "{sid}"', f"position = [{x}, {y}]", f"fov = {poly(sq)}", ""]
    return "\n".join(lines)


def simulate_room(*, seed: int, duration: float, n: int, drop: float, rate_hz: float = 10.0):
    """Truth (t, target, x, y) and motion edges (t, sensor, value) of the ``istate-room`` scenario."""
    rng = np.random.default_rng(seed)
    bnd = shapely.Polygon(ROOM["boundary"])
    obs = [shapely.Polygon(o) for o in ROOM["obstacles"]]
    free = _free(bnd, obs)
    planner = ShortestPaths(free.buffer(-0.2), margin=0.05)
    K = int(round(duration * rate_hz)) + 1
    speed = rng.uniform(0.4, 1.2, n)
    motion = TargetMotion(rng, planner, random_free_points(rng, planner.free, n), speed / rate_hz)
    pos = np.empty((K, n, 2))
    pos[0] = motion.pos
    for k in range(1, K):  # sequential: each sample follows the last
        pos[k] = motion.move()
    t = np.arange(K) / rate_hz
    truth = pl.DataFrame(
        {
            "t": np.repeat(t, n),
            "target": np.tile([f"target{i + 1}" for i in range(n)], K),
            "x": pos[:, :, 0].ravel(),
            "y": pos[:, :, 1].ravel(),
        }
    )
    ids = list(ROOM_SENSORS)
    c = np.array([ROOM_SENSORS[s] for s in ids])
    inside = (np.abs(pos[:, :, None, 0] - c[None, None, :, 0]) <= ROOM_FOV) & (
        np.abs(pos[:, :, None, 1] - c[None, None, :, 1]) <= ROOM_FOV
    )
    on = inside.any(axis=1)  # (K, sensors)
    # drop whole on-periods with probability `drop` (false negatives)
    start = np.vstack([on[:1], on[1:] & ~on[:-1]])
    period_id = np.cumsum(start, axis=0)
    dropped = rng.random((K + 1, len(ids))) < drop
    on = on & ~np.take_along_axis(dropped, period_id, axis=0)
    prev = np.vstack([np.zeros((1, len(ids)), bool), on[:-1]])
    kk, ss = np.nonzero(on != prev)
    edges = pl.DataFrame({"t": t[kk], "sensor": np.asarray(ids)[ss], "value": on[kk, ss].astype(np.int8)}).sort(
        "t", "sensor"
    )
    return truth, edges


def write_room_dataset(out_dir, *, seed: int = 0, duration: float = 120.0, n: int = 2, drop: float = 0.0) -> Path:
    """Write the ``istate-room`` dataset folder (see the module docstring)."""
    if not 1 <= n <= 6:
        raise ConfigError(f"istate-room: targets = {n}; allowed range: [1, 6]")
    if not 0.0 <= drop < 1.0:
        raise ConfigError(f"istate-room: drop = {drop!r}; allowed range: [0, 1)")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    truth, edges = simulate_room(seed=seed, duration=duration, n=n, drop=drop)
    _atomic_text(room_site_toml(n), out / "site.toml")
    _atomic_csv(edges, out / "motion.csv")
    _atomic_csv(truth, out / "truth.csv")
    return out


# --------------------------------------------------------------------------- registry


def _write_room(dataset, *, seed: int, duration, agents, drop: float, camera: bool, params: dict) -> Path:
    if params:
        raise ConfigError(f"scenario 'istate-room' takes no --param options, got {sorted(params)}")
    return write_room_dataset(
        dataset, seed=seed, duration=120.0 if duration is None else duration, n=agents or 2, drop=drop
    )


def _specs():

    return {
        "istate-room": Scenario(
            "istate-room",
            "O'Kane I-states: 12 x 8 m room, 2 obstacles, 6 square motion-sensor fields of view, 2 targets on shortest paths",
            _write_room,
        )
    }


SCENARIO_SPECS = _specs()
