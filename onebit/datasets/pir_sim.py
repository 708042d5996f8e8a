"""Simulated PIR intruder datasets: the 10 x 10 cell room of Schiff & Goldberg, section VIII.

Units: world units are metres and one cell is 1 m (the tracker's ``cell = 1.0``), so the room
is ``[0, 10] x [0, 10]`` and speeds in cells/s are m/s.

The intruder follows the paper's motion model (the tracker's own
:func:`onebit.trackers.intruder.filter.propagate` with one particle): ``t_P = 2`` s,
``v_max = 4`` cells/s, speed noise 1.5 cells/s, orientation noise ``sigma_theta = v_max / v``
(capped at pi), rejection against the walls; a uniformly random start. The paper gives the
orientation noise only as "inversely proportional to the current speed"; the constant
``v_max`` (1 rad at top speed) is the one that reproduces the paper's only statistic of the
path distribution alone, the naive baseline's 55 % within 4 cells of the centre (Fig. 4):
``1 / v`` gives 39 %, ``2 / v`` 46 %, ``4 / v`` 55 %, ``8 / v`` 58 %, a uniform position 50 %.
``truth.csv`` holds its position at every iteration ``t_tau = tau * t_P`` (``tau = 0 .. duration / t_P``).

Sensors fire from the intruder's position at each iteration, as in the paper: sensor ``i``
out of its refractory period fires with ``P(S_i = 1 | x_tau)`` of the deployed sensor model
(the same one the tracker uses), and with ``P(S | B = 1) = 1e-6`` while refractory;
``beta_i`` follows the paper's recursion. Firings are written as a **raw toggle log**
(``motion.csv``: t, sensor, value): an on edge inside the iteration (``t_tau - U(0.25, 0.75)
t_P``) and an off edge ``0.2 t_P`` later, with relay chatter (an off/on pair inside the
on-period, at most 0.09 s apart; probability ``chatter``) and short glitches in idle time
(pulses shorter than the minimum on-time; probability ``glitch`` per sensor and iteration).
``site.toml`` declares ``chatter_window = 0.1`` and ``min_on = 0.1`` for the sensor types,
so the reader recovers exactly the firings. ``--drop`` loses a firing's message (the sensor
still goes refractory).

Scenarios (``--param refractory=F`` sets every sensor's refractory period, default 0 s)::

    beams22          22 perfect optical beams (10 x 1 cells) in a criss-cross
    pir14            14 perfect PIR sensors around the walls
    pir14-imperfect  the same 14 sensors, detection falling with distance, false-positive rate 0.25
    pir4, pir8       the first 4 (corners) or 8 (corners + wall centres) of the 14
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core import writers
from onebit.core.errors import ConfigError
from onebit.core.site import site_from_dict
from onebit.datasets.scenario import Scenario
from onebit.models.motion import Motion, Room, prior, propagate
from onebit.models.pir import deploy, log_p_silent

ROOM = 10.0
PERIOD = 2.0
V_MAX = 4.0
SPEED_SIGMA = 1.5
TURN_SCALE = V_MAX  # sigma_theta = v_max / v: 1 rad at top speed (the paper: 'inversely proportional')
BOX = 2.0
P_FIRE_REFRACTORY = 1e-6
CHATTER_WINDOW = 0.1
MIN_ON = 0.1

#: 14 PIR poses (x, y, heading deg): the 4 corners looking at the centre, the 4 wall centres
#: looking across, then 6 more along the walls. ``pirN`` takes the first N.
PIR_POSES: tuple[tuple[float, float, float], ...] = (
    (0.0, 0.0, 45.0),
    (10.0, 0.0, 135.0),
    (10.0, 10.0, 225.0),
    (0.0, 10.0, 315.0),
    (5.0, 0.0, 90.0),
    (10.0, 5.0, 180.0),
    (5.0, 10.0, 270.0),
    (0.0, 5.0, 0.0),
    (2.5, 0.0, 90.0),
    (10.0, 2.5, 180.0),
    (7.5, 10.0, 270.0),
    (0.0, 7.5, 0.0),
    (7.5, 0.0, 90.0),
    (2.5, 10.0, 270.0),
)

PIR_TYPE = {"kind": "pir-triangle", "range": 10.0, "fov": 60.0, "resolution": 2.0}
PIR_IMPERFECT = {**PIR_TYPE, "falloff": 0.6, "false_positive": 0.25}
BEAM_TYPE = {"kind": "beam", "length": 10.0, "resolution": 1.0}

SCENARIOS = ("beams22", "pir14", "pir14-imperfect", "pir4", "pir8")


def site_dict(scenario: str, refractory: float = 0.0) -> dict:
    """The ``site.toml`` contents of a scenario (a dict, as TOML would load it)."""
    debounce = {"chatter_window": CHATTER_WINDOW, "min_on": MIN_ON, "p_fire_refractory": P_FIRE_REFRACTORY}
    if scenario == "beams22":
        # 11 beams per direction, evenly spaced across the 10 cells (22 in all, as in the paper)
        pos = [(k + 0.5) * ROOM / 11 for k in range(11)]
        sensors = [{"id": f"bx{k:02d}", "position": [0.0, y], "heading": 0.0} for k, y in enumerate(pos)]
        sensors += [{"id": f"by{k:02d}", "position": [x, 0.0], "heading": 90.0} for k, x in enumerate(pos)]
        typ, table = "beam", {**BEAM_TYPE, **debounce}
    elif scenario.startswith("pir"):
        imperfect = scenario.endswith("-imperfect")
        n = int(scenario[3:].removesuffix("-imperfect"))
        if n < 1 or n > len(PIR_POSES):
            raise ConfigError(f"scenario {scenario!r}: at most {len(PIR_POSES)} PIR sensors")
        sensors = [{"id": f"pir{k:02d}", "position": [x, y], "heading": h} for k, (x, y, h) in enumerate(PIR_POSES[:n])]
        typ, table = (
            ("pir-imperfect", {**PIR_IMPERFECT, **debounce}) if imperfect else ("pir", {**PIR_TYPE, **debounce})
        )
    else:
        raise ConfigError(f"unknown PIR scenario {scenario!r}; known: {list(SCENARIOS)}")
    for s in sensors:
        s["type"] = typ
        s["refractory"] = float(refractory)
    return {
        "name": f"schiff-{scenario}",
        "units": "m",
        "boundary": {"polygon": [[0.0, 0.0], [ROOM, 0.0], [ROOM, ROOM], [0.0, ROOM]]},
        "targets": 1,
        "motion_sensors": sensors,
        "sensor_types": {typ: table},
    }


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return "[" + ", ".join(_toml_value(x) for x in v) + "]"


def site_toml(d: dict) -> str:
    """Serialise :func:`site_dict` as TOML (top-level scalars, tables, arrays of tables)."""
    out = ["# Schiff & Goldberg's simulated room: 10 x 10 cells, one cell = 1 m (tracker cell = 1.0)"]
    out += [f"{k} = {_toml_value(v)}" for k, v in d.items() if not isinstance(v, (dict, list))]
    out += ["", "[boundary]", f"polygon = {_toml_value(d['boundary']['polygon'])}"]
    for s in d["motion_sensors"]:
        out += ["", "[[motion_sensors]]"] + [f"{k} = {_toml_value(v)}" for k, v in s.items()]
    for name, t in d["sensor_types"].items():
        out += ["", f'[sensor_types."{name}"]'] + [f"{k} = {_toml_value(v)}" for k, v in t.items()]
    return "\n".join(out) + "\n"


@dataclass(frozen=True)
class Simulation:
    truth: pl.DataFrame  # t, target, x, y
    firings: pl.DataFrame  # t (iteration end), sensor, slot
    toggles: pl.DataFrame  # t, sensor, value: the raw log


def path_motion():
    """The intruder model of the simulated paths (:class:`~onebit.trackers.intruder.filter.Motion`)."""

    return Motion(PERIOD, V_MAX, SPEED_SIGMA, TURN_SCALE, 1000)


def intruder_path(rng: np.random.Generator, n_steps: int, site) -> np.ndarray:
    """``(n_steps + 1, 2)`` positions at t_tau from the paper's intruder model (sequential in time)."""

    room = Room(site.free_space)
    motion = path_motion()
    p = prior(1, room, motion, rng)
    xy = np.empty((n_steps + 1, 2))
    xy[0] = p.x[0], p.y[0]
    for k in range(1, n_steps + 1):
        p, _, _ = propagate(p, room, motion, rng)
        xy[k] = p.x[0], p.y[0]
    return xy


def fire(rng: np.random.Generator, xy: np.ndarray, dep, *, drop: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``(T, n)`` firings S and delivered messages for iterations 1..T at positions ``xy[1:]``.

    Probabilities for every iteration and sensor are computed at once; only the refractory
    recursion beta_tau = f if S else max(0, beta_{tau-1} - t_P) runs over iterations.
    """

    pos = xy[1:]
    T, n = len(pos), len(dep.ids)
    p_fire = -np.expm1(log_p_silent(pos[:, 0], pos[:, 1], dep, BOX / 2, BOX / 2)).T  # (T, n)
    u = rng.random((T, n))
    lost = rng.random((T, n)) < drop
    S = np.zeros((T, n), bool)
    beta = np.zeros(n)
    for k in range(T):
        blind = beta > 0
        S[k] = np.where(blind, u[k] < dep.rho, u[k] < p_fire[k])
        beta = np.where(S[k], dep.refractory, np.maximum(0.0, beta - PERIOD))
    return S, S & ~lost


def toggle_log(
    rng: np.random.Generator, sent: np.ndarray, ids: tuple[str, ...], *, chatter: float, glitch: float
) -> pl.DataFrame:
    """The raw toggle log of the delivered firings ``sent`` (T, n), with chatter and glitches."""
    T, n = sent.shape
    k, i = np.nonzero(sent)
    t_end = (k + 1) * PERIOD
    on = t_end - rng.uniform(0.25, 0.75, len(k)) * PERIOD
    off = on + 0.2 * PERIOD
    rows_t = [on, off]
    rows_i = [i, i]
    rows_v = [np.ones(len(k), np.int8), np.zeros(len(k), np.int8)]
    ch = rng.random(len(k)) < chatter
    c_off = on[ch] + rng.uniform(0.2, 0.6, ch.sum()) * 0.2 * PERIOD
    c_on = c_off + rng.uniform(0.0, 0.9, ch.sum()) * CHATTER_WINDOW
    rows_t += [c_off, c_on]
    rows_i += [i[ch], i[ch]]
    rows_v += [np.zeros(ch.sum(), np.int8), np.ones(ch.sum(), np.int8)]
    gk, gi = np.nonzero(rng.random((T, n)) < glitch)
    g_on = (gk + 1) * PERIOD + 0.1 * PERIOD
    g_off = g_on + rng.uniform(0.1, 0.5, len(gk)) * MIN_ON
    rows_t += [g_on, g_off]
    rows_i += [gi, gi]
    rows_v += [np.ones(len(gk), np.int8), np.zeros(len(gk), np.int8)]
    t = np.round(np.concatenate(rows_t), 6)
    names = np.asarray(ids, dtype=object)[np.concatenate(rows_i)]
    return pl.DataFrame(
        {"t": t, "sensor": pl.Series(names.tolist(), dtype=pl.String), "value": np.concatenate(rows_v)}
    ).sort("t", "sensor")


def simulate(
    scenario: str,
    *,
    seed: int,
    duration: float = 180.0,
    refractory: float = 0.0,
    drop: float = 0.0,
    chatter: float = 0.3,
    glitch: float = 0.02,
    path_seed: int | None = None,
) -> tuple[dict, Simulation]:
    """Simulate one scenario. ``path_seed`` (default ``seed``) draws the path, so several sensor
    sets can share the paper's 10 trajectories."""

    d = site_dict(scenario, refractory)
    site = site_from_dict(d, source=f"{scenario}/site.toml")
    n_steps = int(round(duration / PERIOD))
    xy = intruder_path(np.random.default_rng([path_seed if path_seed is not None else seed, 1]), n_steps, site)
    dep = deploy(site, 1.0)
    rng = np.random.default_rng([seed, 2])
    S, sent = fire(rng, xy, dep, drop=drop)
    toggles = toggle_log(rng, sent, dep.ids, chatter=chatter, glitch=glitch)
    truth = pl.DataFrame({"t": np.arange(n_steps + 1) * PERIOD, "target": "intruder", "x": xy[:, 0], "y": xy[:, 1]})
    k, i = np.nonzero(S)
    firings = pl.DataFrame(
        {
            "t": (k + 1) * PERIOD,
            "sensor": pl.Series(np.asarray(dep.ids, dtype=object)[i].tolist(), dtype=pl.String),
            "slot": k,
        }
    )
    return d, Simulation(truth, firings, toggles)


def run_toml() -> str:
    """The dataset's ``run.toml``: what the simulation knows that a tracker's defaults do not.

    ``[istate]``: the simulated intruder moves at up to ``V_MAX`` cells/s (cells of 1 m, so
    m/s), and a sensor's state is the firing of the last iteration, so a reading may lag the
    intruder by up to one period ``t_P`` (``latency_s``); with the I-state filter's defaults
    (a walker, no lag) the I-state would lose the intruder.
    """
    return f"[istate]\nmax_speed = {V_MAX}\nlatency_s = {PERIOD}\n"


def write_pir_dataset(
    dataset: str | Path, scenario: str, *, seed: int, duration: float = 180.0, refractory: float = 0.0, **kwargs
) -> Path:
    """Write ``site.toml``, ``motion.csv``, ``truth.csv``, ``truth_firings.csv`` and ``run.toml`` (atomically)."""
    dataset = Path(dataset)
    dataset.mkdir(parents=True, exist_ok=True)
    d, sim = simulate(scenario, seed=seed, duration=duration, refractory=refractory, **kwargs)
    writers.write_text(site_toml(d), dataset / "site.toml")
    writers.write_csv(sim.toggles, dataset / "motion.csv")
    writers.write_csv(sim.truth, dataset / "truth.csv")
    writers.write_csv(sim.firings, dataset / "truth_firings.csv")
    writers.write_text(run_toml(), dataset / "run.toml")
    return dataset


def _float_param(params: dict, key: str, default: float, lo: float, hi: float | None = None) -> float:
    if key not in params:
        return default
    try:
        v = float(params[key])
    except ValueError:
        raise ConfigError(f"--param {key}={params[key]!r}: not a number") from None
    if not math.isfinite(v) or v < lo or (hi is not None and v > hi):
        raise ConfigError(f"--param {key}={v!r}: allowed range [{lo}, {hi if hi is not None else 'inf'}]")
    return v


def _writer(name: str):
    def write(
        dataset, *, seed: int, duration: float | None, agents: int | None, drop: float, camera: bool, params: dict
    ):
        unknown = set(params) - {"refractory", "chatter", "glitch"}
        if unknown:
            raise ConfigError(
                f"scenario {name!r}: unknown --param {sorted(unknown)}; known: refractory, chatter, glitch"
            )
        if agents not in (None, 1):
            raise ConfigError(f"scenario {name!r} has exactly one intruder, got --agents {agents}")
        if not 0.0 <= drop <= 1.0:
            raise ConfigError(f"--drop {drop!r}: allowed range [0, 1]")
        return write_pir_dataset(
            dataset,
            name,
            seed=seed,
            duration=180.0 if duration is None else float(duration),
            refractory=_float_param(params, "refractory", 0.0, 0.0),
            drop=drop,
            chatter=_float_param(params, "chatter", 0.3, 0.0, 1.0),
            glitch=_float_param(params, "glitch", 0.02, 0.0, 1.0),
        )

    return write


_HELP = {
    "beams22": "Schiff & Goldberg: 22 perfect optical beams, 10x10-cell room, one intruder (--param refractory=F)",
    "pir14": "Schiff & Goldberg: 14 perfect PIR sensors (Fig. 1 style), one intruder (--param refractory=F)",
    "pir14-imperfect": "Schiff & Goldberg: 14 PIR sensors losing detection with distance, false-positive rate 0.25",
    "pir4": "Schiff & Goldberg: 4 perfect PIR sensors in the corners",
    "pir8": "Schiff & Goldberg: 8 perfect PIR sensors (corners + wall centres)",
}

SCENARIO_SPECS = {n: Scenario(n, _HELP[n] + " (no camera)", _writer(n)) for n in SCENARIOS}
