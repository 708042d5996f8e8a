"""``ceiling-building``: a building floor under a ceiling array of binary sensors, many people walking.

``onebit simulate ceiling-building DIR --agents 40 --duration 120 --seed 0`` writes:

* ``site.toml`` -- a floor of ``cols x rows`` cells ``spacing`` m wide (default 20 x 20 =
  400 sensors, 1.5 m apart: a 30 x 30 m floor), one ceiling sensor over each cell's centre
  (``[[binary_sensors]]``, footprint ``r_inner`` 0.6 m sure, ``r_outer`` 1.0 m in the ring,
  level signal, as the irtracking array), ``targets`` = the agents;
* ``truth.csv`` -- every agent walking straight lines between random points of the floor at
  its own speed (0.8-1.3 m/s), pausing 0-4 s at each, sampled every 0.5 s;
* ``frames.csv`` -- what the array reads at 2 Hz, by ``from-truth``
  (:func:`onebit.datasets.from_truth.simulate_from_truth`: ``p_detect`` 0.9, ``p_ring`` 0.5).

``--param cols=N rows=N spacing=M`` change the array. Deterministic for a seed; written
atomically. The sizes the growth benchmark (``benchmarks/bench_binpf_scale.py``) runs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import ConfigError
from onebit.core.writers import write_csv, write_text
from onebit.datasets.from_truth import FromTruthConfig, simulate_from_truth
from onebit.datasets.scenario import Scenario

NAME = "ceiling-building"
#: Seconds between truth samples.
TRUTH_PERIOD = 0.5


def site_toml(cols: int, rows: int, spacing: float, targets: int) -> str:
    """The floor and its ceiling array (module docstring)."""
    w, h = cols * spacing, rows * spacing
    lines = [
        "# Simulated by 'onebit simulate ceiling-building': a ceiling array over a building floor.",
        f'name = "{NAME}"',
        'units = "m"',
        f"targets = {int(targets)}",
        "",
        "[boundary]",
        f"polygon = [[0.0, 0.0], [{w!r}, 0.0], [{w!r}, {h!r}], [0.0, {h!r}]]",
        "",
        "[sensor_types.ceiling]",
        'signal = "level"',
        "",
        "[sensor_graph]",
        'geometry = "connected"',
    ]
    for j in range(rows):
        for i in range(cols):
            x, y = spacing * (i + 0.5), spacing * (j + 0.5)
            lines += [
                "",
                "[[binary_sensors]]",
                f'id = "c{j:03d}_{i:03d}"',
                f"position = [{x!r}, {y!r}]",
                "r_outer = 1.0",
                "r_inner = 0.6",
                'type = "ceiling"',
            ]
    return "\n".join(lines) + "\n"


def walks(agents: int, duration: float, width: float, height: float, rng: np.random.Generator) -> pl.DataFrame:
    """``truth.csv`` rows (t, target, x, y): every agent's walk (module docstring)."""
    t = np.arange(0.0, duration + 1e-9, TRUTH_PERIOD)
    margin = 0.5
    lo, hi = np.array([margin, margin]), np.array([width - margin, height - margin])
    out = []
    for a in range(agents):
        pos = rng.uniform(lo, hi)
        goal = rng.uniform(lo, hi)
        speed = rng.uniform(0.8, 1.3)
        pause = 0.0
        xy = np.empty((len(t), 2))
        for k in range(len(t)):
            xy[k] = pos
            if pause > 0:
                pause -= TRUTH_PERIOD
                continue
            d = goal - pos
            dist = float(np.hypot(*d))
            step = speed * TRUTH_PERIOD
            if dist <= step:
                pos, goal, pause = goal, rng.uniform(lo, hi), float(rng.uniform(0.0, 4.0))
            else:
                pos = pos + d / dist * step
        out.append(pl.DataFrame({"t": t, "target": f"p{a:03d}", "x": xy[:, 0].round(4), "y": xy[:, 1].round(4)}))
    return pl.concat(out).sort(["t", "target"])


def _int(params: dict, key: str, default: int, lo: int, hi: int) -> int:
    try:
        v = int(params.get(key, default))
    except ValueError:
        raise ConfigError(f"--param {key}={params[key]!r}: not an integer") from None
    if not lo <= v <= hi:
        raise ConfigError(f"--param {key}={v}: allowed range [{lo}, {hi}]")
    return v


def write_building(
    dataset, *, seed: int, duration=None, agents=None, drop: float = 0.0, camera: bool = False, params=None
) -> Path:
    """Write the scenario into ``dataset`` (module docstring)."""
    params = dict(params or {})
    unknown = sorted(set(params) - {"cols", "rows", "spacing"})
    if unknown:
        raise ConfigError(f"scenario {NAME!r}: unknown --param {unknown}; known: ['cols', 'rows', 'spacing']")
    cols = _int(params, "cols", 20, 1, 200)
    rows = _int(params, "rows", 20, 1, 200)
    try:
        spacing = float(params.get("spacing", 1.5))
    except ValueError:
        raise ConfigError(f"--param spacing={params['spacing']!r}: not a number") from None
    if not 0.1 <= spacing <= 100:
        raise ConfigError(f"--param spacing={spacing}: allowed range [0.1, 100] m")
    n = int(agents if agents is not None else 40)
    dur = float(duration if duration is not None else 120.0)
    out = Path(dataset)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    write_text(site_toml(cols, rows, spacing, n), out / "site.toml")
    write_csv(walks(n, dur, cols * spacing, rows * spacing, rng), out / "truth.csv")
    simulate_from_truth(out, seed=seed + 1, cfg=FromTruthConfig(p_detect=0.9, drop=float(drop or 0.0)))
    return out


SCENARIO_SPECS = {
    NAME: Scenario(
        NAME,
        "a building floor: 20 x 20 ceiling sensors (1.5 m apart), 40 people walking (--agents, --param cols/rows/spacing)",
        write_building,
    )
}
