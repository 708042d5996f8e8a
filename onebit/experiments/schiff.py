"""``onebit experiment schiff OUT``: Schiff & Goldberg's simulation study (section VIII).

Every sensor set (``beams22``, ``pir14``, ``pir14-imperfect``, ``pir4``, ``pir8``) with
refractory periods 0, 4, 8 and 16 s, over the same 10 three-minute trajectories (trajectory
``k`` is drawn from seed ``seed + k`` whatever the sensor set, as the paper reuses its 10
paths across tests). Each run goes through the same code as ``onebit run``: the simulator's
raw toggle log -> the motion reader with its debounce rules -> the ``intruder`` tracker (1000
particles) and the ``intruder-naive`` baseline -> errors against truth at every iteration.

Writes ``results.parquet`` / ``results.csv`` (scenario, refractory, estimator, mean and
median error, fraction within 1..4 cells, iterations), ``errors.parquet`` (every iteration's
error) and PNG plots: ``fig3_naive_error_over_time.png``, ``fig4-7_<scenario>.png`` (error
distributions per refractory period), ``fig8_sensor_count.png`` and
``fig9_imperfect_error_over_time.png``. Every (sensor set, refractory period, trajectory) is
an independent task on the executor given (``--executor serial|local|ray``, see
:mod:`onebit.experiments.trials`); the tables are the same on every executor, the seconds per
task go to ``timings.csv``.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core import writers as outputs
from onebit.core.site import site_from_dict
from onebit.core.tables import REJECTS
from onebit.datasets.pir_sim import simulate
from onebit.experiments.trials import run_trials, write_timings
from onebit.pipeline.executors import Executor
from onebit.readers.motion import MotionConfig, read_motion, site_rules
from onebit.readers.rows import RawRows
from onebit.scoring.intruder import match_errors
from onebit.trackers.intruder.stage import IntruderConfig, NaiveConfig, run_naive
from onebit.trackers.intruder.stage import run as run_intruder

SCENARIOS = ("beams22", "pir14", "pir14-imperfect", "pir4", "pir8")
REFRACTORY = (0.0, 4.0, 8.0, 16.0)
TRIALS = 10
DURATION = 180.0

RESULT_SCHEMA = pl.Schema(
    {
        "scenario": pl.String,
        "refractory": pl.Float64,
        "estimator": pl.String,
        "mean_error": pl.Float64,
        "median_error": pl.Float64,
        "within_1": pl.Float64,
        "within_2": pl.Float64,
        "within_3": pl.Float64,
        "within_4": pl.Float64,
        "iterations": pl.Int64,
    }
)


def toggles_as_rows(toggles: pl.DataFrame) -> RawRows:
    """An in-memory toggle log as the string rows a CSV reader would give (line = row + 2)."""
    frame = (
        toggles.select(pl.col("t").cast(pl.String), "sensor", pl.col("value").cast(pl.String))
        .with_row_index("line", offset=2)
        .with_columns(pl.col("line").cast(pl.Int64), raw=pl.lit(None, pl.String))
    )
    return RawRows("motion.csv", frame, pl.DataFrame(schema=REJECTS))


def one_run(
    scenario: str, refractory: float, trial: int, *, seed: int, duration: float, particles: int
) -> pl.DataFrame:
    """Errors (cells) of the filter and the baseline on one simulated trajectory."""
    d, sim = simulate(
        scenario, seed=seed + 1000 * trial + 7, path_seed=seed + trial, duration=duration, refractory=refractory
    )
    site = site_from_dict(d, source=f"{scenario}/site.toml")
    ids = [m.id for m in site.motion_sensors]
    read = read_motion(toggles_as_rows(sim.toggles), ids, rules=site_rules(site, MotionConfig()))
    if read.rejects.height:
        raise RuntimeError(f"simulated log of {scenario} has rejects: {read.rejects.head(3)}")
    inputs = {"motion": read.motion}
    out = []
    for name, tracks in (
        (
            "intruder",
            run_intruder(inputs, site, IntruderConfig(particles=particles, seed=seed + trial, start=0.0, end=duration))[
                "tracks"
            ],
        ),
        ("naive", run_naive(inputs, site, NaiveConfig(start=0.0, end=duration))["tracks"]),
    ):
        sc = match_errors(tracks, sim.truth, tolerance=1.0)
        out.append(
            sc.select("t", "error").with_columns(
                scenario=pl.lit(scenario), refractory=pl.lit(refractory), estimator=pl.lit(name), trial=pl.lit(trial)
            )
        )
    return pl.concat(out)


def _one_run_task(job: tuple) -> pl.DataFrame:
    """A task: :func:`one_run` on ``(scenario, refractory, trial, seed, duration, particles)``."""
    scenario, refractory, trial, seed, duration, particles = job
    return one_run(scenario, refractory, trial, seed=seed, duration=duration, particles=particles)


def _label(job: tuple) -> str:
    return f"{job[0]} refractory {job[1]:g} s trajectory {job[2]}"


def summarise(errors: pl.DataFrame) -> pl.DataFrame:
    e = pl.col("error")
    return (
        errors.group_by("scenario", "refractory", "estimator", maintain_order=True)
        .agg(
            mean_error=e.mean(),
            median_error=e.median(),
            **{f"within_{k}": (e <= k).mean() for k in (1, 2, 3, 4)},
            iterations=pl.len().cast(pl.Int64),
        )
        .select(RESULT_SCHEMA.names())
        .cast(dict(RESULT_SCHEMA))
    )


def plot(errors: pl.DataFrame, out: Path) -> list[Path]:
    """The paper's figures as PNGs (matplotlib, Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    made = []
    bins = np.arange(0, 11.5, 0.5)

    def save(fig, name):
        p = out / name
        tmp = p.with_name(f".{p.name}.tmp.png")
        fig.savefig(tmp, dpi=90)
        plt.close(fig)
        tmp.replace(p)
        made.append(p)

    def over_time(sel, title, name):
        fig, ax = plt.subplots(figsize=(7, 3))
        g = sel.filter(pl.col("trial") == sel["trial"].min()).sort("t")
        ax.plot(g["t"], g["error"], ".-")
        ax.set(xlabel="time (s)", ylabel="error (cells)", title=title)
        save(fig, name)

    naive = errors.filter(pl.col("estimator") == "naive")
    if naive.height:
        over_time(naive, "naive estimator: error over time (Fig. 3)", "fig3_naive_error_over_time.png")
    for fig_no, sc in (("fig5", "beams22"), ("fig6", "pir14"), ("fig7", "pir14-imperfect"), ("fig4", "naive")):
        sel = (
            naive if sc == "naive" else errors.filter((pl.col("scenario") == sc) & (pl.col("estimator") == "intruder"))
        )
        if sel.height == 0:
            continue
        fig, ax = plt.subplots(figsize=(6, 3.5))
        if sc == "naive":
            ax.hist(sel["error"].to_numpy(), bins=bins, density=True, alpha=0.7, label="naive")
        else:
            for f in sorted(sel["refractory"].unique().to_list()):
                g = sel.filter(pl.col("refractory") == f)["error"].to_numpy()
                ax.hist(g, bins=bins, histtype="step", density=True, label=f"refractory {f:g} s")
        ax.set(xlabel="error (cells)", ylabel="density", title=f"{sc}: distribution of error values")
        ax.legend()
        save(fig, f"{fig_no}_{sc}.png")
    sel = errors.filter(
        pl.col("scenario").is_in(["pir4", "pir8", "pir14"])
        & (pl.col("refractory") == 8.0)
        & (pl.col("estimator") == "intruder")
    )
    if sel.height:
        fig, ax = plt.subplots(figsize=(6, 3.5))
        for sc in ("pir4", "pir8", "pir14"):
            g = sel.filter(pl.col("scenario") == sc)["error"].to_numpy()
            if len(g):
                ax.hist(g, bins=bins, histtype="step", density=True, label=f"{sc[3:]} sensors")
        ax.set(xlabel="error (cells)", ylabel="density", title="number of motion sensors, 8 s refractory (Fig. 8)")
        ax.legend()
        save(fig, "fig8_sensor_count.png")
    sel = errors.filter(
        (pl.col("scenario") == "pir14-imperfect") & (pl.col("refractory") == 4.0) & (pl.col("estimator") == "intruder")
    )
    if sel.height:
        over_time(
            sel, "14 imperfect sensors, 4 s refractory: error over time (Fig. 9)", "fig9_imperfect_error_over_time.png"
        )
    return made


def run_study(
    out: Path,
    *,
    seed: int = 0,
    trials: int | None = None,
    quick: bool = False,
    echo=print,
    scenarios: tuple[str, ...] | None = None,
    refractory: tuple[float, ...] | None = None,
    executor: Executor | None = None,
) -> Path:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if quick:
        scenarios = scenarios or ("beams22", "pir8")
        refractory = refractory or (0.0, 8.0)
        trials = trials or 2
        duration, particles = 40.0, 300
    else:
        scenarios = scenarios or SCENARIOS
        refractory = refractory or REFRACTORY
        trials = trials or TRIALS
        duration, particles = DURATION, 1000
    started = time.time()
    jobs = [(sc, f, k, seed, duration, particles) for sc in scenarios for f in refractory for k in range(trials)]
    parts, timings = run_trials(_one_run_task, jobs, executor=executor, label=_label, echo=echo, study="schiff")
    errors = pl.concat(parts)
    # the naive baseline does not depend on the sensors: keep one copy per trajectory
    naive = errors.filter(pl.col("estimator") == "naive").unique(["trial", "t"], keep="first", maintain_order=True)
    naive = naive.with_columns(scenario=pl.lit("any"), refractory=pl.lit(None, pl.Float64))
    errors = pl.concat([errors.filter(pl.col("estimator") == "intruder"), naive])
    results = summarise(errors)
    outputs.write_parquet(errors, out / "errors.parquet")
    outputs.write_parquet(results, out / "results.parquet")
    outputs.write_csv(results, out / "results.csv")
    write_timings(timings, out)
    plot(errors, out)
    echo(f"schiff study: {results.height} rows in {time.time() - started:.0f} s -> {out}/results.csv")
    return out


def run(
    out: Path,
    *,
    seed: int = 0,
    trials: int | None = None,
    quick: bool = False,
    echo=print,
    executor: Executor | None = None,
) -> Path:
    """The registered entry point (see :mod:`onebit.experiments`)."""
    return run_study(out, seed=seed, trials=trials, quick=quick, echo=echo, executor=executor)
