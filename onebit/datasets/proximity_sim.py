"""Simulated binary-proximity datasets (Singh et al., sections 5 and 6).

Scenarios (``onebit simulate NAME DIR --seed N [--targets Q] [--param k=v]``):

* ``proximity-line``: 1-D, sensors every R (rho R = 1), 5 targets over 20 instants whose
  velocity at each instant is uniform within +-20% of the target's mean (section 5.1).
  ``--param variant=crossing`` (default, Fig. 4a: targets start well separated, come close
  and separate again), ``variant=together`` (Fig. 4b: start within R of each other and
  separate), ``variant=separated`` (parallel, 6R apart, the same mean speed);
  ``--param rho_r=0.5`` changes the sensor density (Fig. 6a), ``--param scale=0.25`` scales
  the target positions (Fig. 7).
* ``proximity-line-accel``: constant acceleration (Fig. 5b).
* ``proximity-line-nonideal``: as ``crossing`` with the two-radius model R_i = alpha R,
  R_o = beta R (``--param alpha=0.7 --param beta=1.3`` default; 0.5 / 1.5 the other
  setting); a target in the ring R_i < d <= R_o is detected with probability
  ``p_ring`` = 0.5 per sensor and instant.
* ``proximity-grid``: 2-D, sensors on a grid of pitch R (rho R^2 = 1), two targets that
  approach each other and separate (Fig. 10).
* ``pir-line``: the lab experiment (section 6): 5 PIR sensors 4 ft apart (R_i = 3 ft,
  R_o = 7 ft), two people starting at opposite ends and crossing, the sensor at 16 ft
  never sees person T1, detection probability in the ring 0.5, and relay chatter in the raw
  toggle log (every rising edge is followed by short 1->0->1 flickers) that the reader's
  ``chatter_window`` must undo.

1-D sites are a thin strip ``[x_lo, x_hi] x [-0.5, 0.5]`` with every sensor at ``y = 0``;
the tracker treats a site whose proximity sensors all have ``y == 0`` as 1-D. Units: R = 1
(metres) for the simulations, feet for ``pir-line``.

Files: ``site.toml``, ``proximity.csv`` (t, sensor, value: the toggle log, one row per state
change; every sensor starts off), ``truth.csv`` (t, target, x, y at every instant) and
``run.toml`` with the ``[proximity]`` sampling instants. Everything is deterministic from
the seed and written atomically.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import ConfigError
from onebit.core.writers import write_csv as _atomic_csv
from onebit.core.writers import write_text as _atomic_text
from onebit.datasets.scenario import Scenario

#: Seconds between instants (the sampling period of the frames).
PERIOD = 1.0


@dataclass(frozen=True)
class ProximityWorld:
    """A simulated deployment: sensors, targets' positions at every instant and readings."""

    name: str
    units: str
    boundary: tuple[float, float, float, float]  # minx, miny, maxx, maxy
    sensor_xy: np.ndarray  # (n, 2)
    r_inner: np.ndarray
    r_outer: np.ndarray
    truth: np.ndarray  # (Q, T, 2)
    on: np.ndarray  # (T, n) bool readings at the instants
    chatter: float = 0.0  # s; relay chatter written into the log (0 = none)


# --------------------------------------------------------------------------- trajectories


def jittered_constant_velocity(
    x0: np.ndarray, v: np.ndarray, T: int, rng: np.random.Generator, jitter: float = 0.2
) -> np.ndarray:
    """``(Q, T)``: x[t+1] = x[t] + v_q * U(1 - jitter, 1 + jitter) (section 5.1)."""
    steps = v[:, None] * rng.uniform(1 - jitter, 1 + jitter, size=(v.size, T - 1))
    return np.c_[x0, x0[:, None] + np.cumsum(steps, axis=1)]


def line_targets(variant: str, Q: int, T: int, rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    """1-D target positions ``(Q, T)`` in units of R for a ``proximity-line`` variant."""
    if variant == "separated":
        v = np.full(Q, rng.uniform(0.3, 0.5))
        x0 = np.arange(Q) * 6.0 + rng.uniform(-0.3, 0.3, Q)
        x = jittered_constant_velocity(x0, v, T, rng)
    elif variant == "crossing":
        # start 4R apart; neighbours move towards each other (alternating directions), meet
        # near the middle of the run, cross and separate again
        gap = 4.0
        x0 = np.arange(Q) * gap + rng.uniform(-0.3, 0.3, Q)
        sign = np.where(np.arange(Q) % 2 == 0, 1.0, -1.0)
        v = sign * gap / (T - 1) * rng.uniform(0.8, 1.2, Q)
        x = jittered_constant_velocity(x0, v, T, rng)
    elif variant == "together":
        v = np.linspace(0.1, 1.3, Q) + rng.uniform(-0.05, 0.05, Q)
        x0 = rng.uniform(0.0, 1.0, Q)
        x = jittered_constant_velocity(x0, v, T, rng)
    elif variant == "accel":
        v0 = np.linspace(-0.6, 0.6, Q) + rng.uniform(-0.1, 0.1, Q)
        a = rng.uniform(-0.06, 0.06, Q)
        x0 = np.arange(Q) * 4.0 - 2.0 * Q + rng.uniform(-0.5, 0.5, Q)
        t = np.arange(T)
        x = x0[:, None] + v0[:, None] * t + 0.5 * a[:, None] * t**2
    else:
        raise ConfigError(f"--param variant={variant!r}; allowed: crossing, together, separated")
    return x * scale


def detect(d: np.ndarray, r_in: np.ndarray, r_out: np.ndarray, p_ring: float, rng: np.random.Generator) -> np.ndarray:
    """Readings from distances ``d (T, n, Q)``: on if any target is within R_i, or in the
    ring R_i < d <= R_o and detected (probability ``p_ring`` per target, sensor, instant)."""
    sure = d <= r_in[None, :, None]
    ring = (d > r_in[None, :, None]) & (d <= r_out[None, :, None])
    return np.any(sure | (ring & (rng.random(d.shape) < p_ring)), axis=2)


def line_world(
    name: str,
    x: np.ndarray,
    *,
    rho_r: float,
    alpha: float,
    beta: float,
    p_ring: float,
    rng: np.random.Generator,
    margin: float = 2.0,
) -> ProximityWorld:
    """Sensors every 1/rho along the strip covering the targets (R = 1)."""
    lo = float(np.floor(x.min() - margin))
    hi = float(np.ceil(x.max() + margin))
    pitch = 1.0 / rho_r
    sx = np.arange(lo, hi + 1e-9, pitch)
    n = sx.size
    r_in, r_out = np.full(n, alpha), np.full(n, beta)
    xy = np.c_[sx, np.zeros(n)]
    d = np.abs(x.T[:, None, :] - sx[None, :, None])  # (T, n, Q)
    on = detect(d, r_in, r_out, p_ring, rng)
    truth = np.stack([x, np.zeros_like(x)], axis=-1)
    return ProximityWorld(name, "m", (lo, -0.5, hi, 0.5), xy, r_in, r_out, truth, on)


def grid_world(rng: np.random.Generator, T: int = 20) -> ProximityWorld:
    """Fig. 10: a 10R x 10R field, sensors every R, two targets passing each other."""
    g = np.arange(0.5, 10.0, 1.0)
    gx, gy = np.meshgrid(g, g)
    xy = np.c_[gx.ravel(), gy.ravel()]
    n = len(xy)
    t = np.arange(T)
    a = np.c_[np.linspace(1.0, 9.0, T), np.full(T, 4.2)]
    b = np.c_[np.linspace(9.0, 1.0, T), np.full(T, 5.8)]
    jit = rng.uniform(0.8, 1.2, size=(2, T - 1))
    truth = []
    for base, j in zip((a, b), jit):
        step = np.diff(base, axis=0) * j[:, None]
        truth.append(np.r_[base[:1], base[:1] + np.cumsum(step, axis=0)])
    truth = np.stack(truth) + rng.uniform(-0.2, 0.2, size=(2, 1, 2))
    del t
    d = np.linalg.norm(truth.transpose(1, 0, 2)[:, None, :, :] - xy[None, :, None, :], axis=-1)  # (T, n, Q)
    on = detect(d, np.ones(n), np.ones(n), 0.5, rng)
    return ProximityWorld("proximity-grid", "m", (0.0, 0.0, 10.0, 10.0), xy, np.ones(n), np.ones(n), truth, on)


def pir_world(rng: np.random.Generator, T: int = 20) -> ProximityWorld:
    """Section 6: 5 PIR sensors at 4, 8, ..., 20 ft; T1 walks 0 -> 24 ft, T2 24 -> 0 ft."""
    sx = np.arange(4.0, 21.0, 4.0)
    n = sx.size
    r_in, r_out = np.full(n, 3.0), np.full(n, 7.0)
    v = np.array([24.0, -24.0]) / (T - 1)
    x = jittered_constant_velocity(np.array([0.5, 23.5]), v, T, rng, jitter=0.15)
    x = np.clip(x, 0.0, 24.0)
    d = np.abs(x.T[:, None, :] - sx[None, :, None])
    blind = np.zeros(d.shape, dtype=bool)
    blind[:, 3, 0] = True  # the sensor at 16 ft misses T1 completely
    d = np.where(blind, np.inf, d)
    on = detect(d, r_in, r_out, 0.5, rng)
    truth = np.stack([x, np.zeros_like(x)], axis=-1)
    xy = np.c_[sx, np.zeros(n)]
    return ProximityWorld("pir-line", "ft", (0.0, -0.5, 24.0, 0.5), xy, r_in, r_out, truth, on, chatter=0.3)


# --------------------------------------------------------------------------- writing


def toggle_log(world: ProximityWorld, ids: list[str], rng: np.random.Generator) -> pl.DataFrame:
    """The raw toggle log: one row per state change at the instants; with ``chatter`` every
    rising edge is followed by 1-3 flickers (off then on again within ``chatter`` seconds)."""
    on = world.on.astype(np.int8)
    T, n = on.shape
    prev = np.r_[np.zeros((1, n), np.int8), on[:-1]]
    ti, si = np.nonzero(on != prev)
    t = ti * PERIOD
    val = on[ti, si]
    rows = [pl.DataFrame({"t": t.astype(float), "s": si, "value": val.astype(np.int8)})]
    if world.chatter > 0:
        rise = val == 1
        k = rng.integers(1, 4, size=int(rise.sum()))
        base = np.repeat(t[rise], k)
        sen = np.repeat(si[rise], k)
        j = np.concatenate([np.arange(kk) for kk in k]) if k.size else np.zeros(0, int)
        t_off = base + 0.05 + j * 0.15 + rng.uniform(0.0, 0.03, size=base.size)
        t_on = t_off + rng.uniform(0.02, world.chatter * 0.3, size=base.size)
        rows.append(pl.DataFrame({"t": t_off, "s": sen, "value": np.zeros(base.size, np.int8)}))
        rows.append(pl.DataFrame({"t": t_on, "s": sen, "value": np.ones(base.size, np.int8)}))
    log = pl.concat(rows).sort(["t", "s"])
    names = pl.Series("sensor", ids, dtype=pl.String)
    return log.with_columns(sensor=names.gather(log["s"])).select(pl.col("t").round(4), "sensor", "value")


def site_toml(world: ProximityWorld, ids: list[str]) -> str:
    lo, lo_y, hi, hi_y = world.boundary
    lines = [
        f'name = "{world.name}"',
        f'units = "{world.units}"',
        f"targets = {world.truth.shape[0]}",
        "",
        "[boundary]",
        f"polygon = [[{lo}, {lo_y}], [{hi}, {lo_y}], [{hi}, {hi_y}], [{lo}, {hi_y}]]",
    ]
    for i, sid in enumerate(ids):
        x, y = (float(v) for v in world.sensor_xy[i])
        lines += ["", "[[proximity_sensors]]", f'id = "{sid}"', f"position = [{x!r}, {y!r}]"]
        if world.r_inner[i] == world.r_outer[i]:
            lines.append(f"radius = {float(world.r_outer[i])!r}")
        else:
            lines += [f"r_inner = {float(world.r_inner[i])!r}", f"r_outer = {float(world.r_outer[i])!r}"]
    return "\n".join(lines) + "\n"


def write_world(world: ProximityWorld, out: str | Path, rng: np.random.Generator) -> Path:
    """Write ``site.toml``, ``proximity.csv``, ``truth.csv`` and ``run.toml`` atomically."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ids = [f"p{i + 1:02d}" for i in range(len(world.sensor_xy))]
    _atomic_text(site_toml(world, ids), out / "site.toml")
    _atomic_csv(toggle_log(world, ids, rng), out / "proximity.csv")
    Q, T, _ = world.truth.shape
    truth = pl.DataFrame(
        {
            "t": np.tile(np.arange(T) * PERIOD, Q).astype(float),
            "target": np.repeat([f"T{q + 1}" for q in range(Q)], T),
            "x": world.truth[:, :, 0].ravel().round(6),
            "y": world.truth[:, :, 1].ravel().round(6),
        }
    ).sort(["t", "target"])
    _atomic_csv(truth, out / "truth.csv")
    run = [
        "[proximity]",
        f"period = {PERIOD!r}",
        "start = 0.0",
        f"instants = {T}",
    ]
    if world.chatter > 0:
        run.append(f"chatter_window = {world.chatter!r}")
    _atomic_text("\n".join(run) + "\n", out / "run.toml")
    return out


# --------------------------------------------------------------------------- scenarios

_PARAMS = {
    "proximity-line": {"variant", "rho_r", "scale", "instants"},
    "proximity-line-accel": {"rho_r", "instants"},
    "proximity-line-nonideal": {"alpha", "beta", "p_ring", "rho_r", "variant", "instants"},
    "proximity-grid": {"instants"},
    "pir-line": {"instants"},
}


def _float(params: dict, key: str, default: float, lo: float | None = None) -> float:
    if key not in params:
        return default
    try:
        v = float(params[key])
    except ValueError:
        raise ConfigError(f"--param {key}={params[key]!r}: not a number") from None
    if not np.isfinite(v) or (lo is not None and v <= lo):
        raise ConfigError(f"--param {key}={params[key]!r}: must be a number > {lo}")
    return v


def make_world(name: str, *, seed: int, targets: int | None = None, params: dict | None = None) -> ProximityWorld:
    """Simulate scenario ``name`` (see the module docstring) without writing anything."""
    params = dict(params or {})
    unknown = sorted(set(params) - _PARAMS[name])
    if unknown:
        raise ConfigError(f"scenario {name!r}: unknown --param {unknown}; allowed: {sorted(_PARAMS[name])}")
    rng = np.random.default_rng(seed)
    T = int(_float(params, "instants", 20.0, lo=2.0))
    if name == "proximity-grid":
        return grid_world(rng, T)
    if name == "pir-line":
        return pir_world(rng, T)
    Q = int(targets or 5)
    rho_r = _float(params, "rho_r", 1.0, lo=0.0)
    if name == "proximity-line-accel":
        x = line_targets("accel", Q, T, rng)
        return line_world(name, x, rho_r=rho_r, alpha=1.0, beta=1.0, p_ring=0.5, rng=rng)
    variant = params.get("variant", "crossing")
    alpha = _float(params, "alpha", 0.7 if name.endswith("nonideal") else 1.0, lo=-1e-12)
    beta = _float(params, "beta", 1.3 if name.endswith("nonideal") else 1.0, lo=0.0)
    if alpha > 1.0 or beta < 1.0:
        raise ConfigError(f"--param alpha={alpha}, beta={beta}: need alpha <= 1 <= beta")
    x = line_targets(variant, Q, T, rng, scale=_float(params, "scale", 1.0, lo=0.0))
    return line_world(
        name, x, rho_r=rho_r, alpha=alpha, beta=beta, p_ring=_float(params, "p_ring", 0.5, lo=-1e-12), rng=rng
    )


def _writer(name: str):
    def write(dataset, *, seed: int, duration=None, agents=None, drop: float = 0.0, camera: bool = False, params=None):
        if duration is not None:
            params = {**(params or {}), "instants": str(int(round(duration / PERIOD)))}
        world = make_world(name, seed=seed, targets=agents, params=params)
        if drop > 0:  # a lost reading: the sensor reports off at that instant
            rng = np.random.default_rng(seed + 7919)
            world = ProximityWorld(**{**world.__dict__, "on": world.on & (rng.random(world.on.shape) >= drop)})
        return write_world(world, dataset, np.random.default_rng(seed + 1))

    return write


def _specs():

    helps = {
        "proximity-line": "Singh 5.1: 5 targets, 20 instants, sensors every R; --param variant=crossing|together|separated",
        "proximity-line-accel": "Singh Fig. 5b: 5 targets with constant acceleration",
        "proximity-line-nonideal": "Singh 5.2: two-radius sensing, --param alpha=0.7 --param beta=1.3 (or 0.5 / 1.5)",
        "proximity-grid": "Singh Fig. 10: 2-D grid (rho R^2 = 1), two targets approach and separate",
        "pir-line": "Singh section 6: 5 PIR sensors 4 ft apart, two people crossing, one blind sensor, relay chatter",
    }
    return {n: Scenario(n, h, _writer(n)) for n, h in helps.items()}


SCENARIO_SPECS = _specs()
