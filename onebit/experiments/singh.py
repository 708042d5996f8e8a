"""``onebit experiment singh OUT``: Singh et al.'s study (Fig. 6a, section 5.2, section 6).

Settings, each over ``trials`` seeds (default 20; the seed fixes the target trajectories,
which are the same for every sensor density, as in the paper's Fig. 6a):

* ``ideal`` on ``proximity-line`` (crossing variant, Fig. 4a) at rho R in {0.5, 1, 2, 4};
* ``nonideal`` at rho R = 1 with (alpha, beta) = (0.7, 1.3) and (0.5, 1.5);
* ``pir-line``: both people caught (each matched to a track within D_0 on average).

Per trial: mean localisation error in R (mean over targets of the mean distance to the
nearest track), targets found (tracks matched one-to-one to targets within D_0 on average),
spurious tracks, tracks, reruns. Writes ``results.parquet`` / ``results.csv`` (one row per
trial), ``summary.csv`` (per setting, with the paper's numbers) and ``error_vs_density.png``,
``found_spurious.png``, and ``timings.csv``. ``quick`` runs 3 trials on fewer settings. Every
(setting, seed) is an independent task on the executor given (``--executor
serial|local|ray``, see :mod:`onebit.experiments.trials`); the tables are the same on every
executor.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
from shapely.geometry import box

from onebit.core import writers as outputs
from onebit.core.lazy import lazy_module
from onebit.datasets.proximity_sim import make_world
from onebit.experiments.trials import run_trials, write_timings
from onebit.pipeline.executors import Executor
from onebit.trackers.clustertrack.algorithm import clustertrack, rules_of_thumb, trajectory_distance
from onebit.trackers.clustertrack.feasible import SensorArray
from onebit.trackers.clustertrack.space import FeasibleSpace

_optimize = lazy_module("scipy.optimize")

#: The paper's numbers (mean error in R; fraction of pir-line runs catching both people).
PAPER = {
    ("ideal", 1.0): 0.238,
    ("nonideal 0.7/1.3", 1.0): 0.287,
    ("nonideal 0.5/1.5", 1.0): 0.377,
    ("pir-line", 1.25): 0.7162,
}
PAPER_PIR_BOTH = 0.65


def one_trial(name: str, seed: int, params: dict, *, H: int = 25, m_o_r: float = 15.0) -> dict:
    """Simulate, run CLUSTERTRACK (with Appendix B) and score one trial."""
    w = make_world(name, seed=seed, params=params)
    sa = SensorArray(tuple(f"p{i}" for i in range(len(w.sensor_xy))), w.sensor_xy, w.r_inner, w.r_outer)
    sp = FeasibleSpace.build(w.on, np.arange(w.on.shape[0], dtype=float), sa, box(*w.boundary), dim=1, cell=0.1)
    R = sa.radius
    p = rules_of_thumb(sp, H=H, m_o=m_o_r / R)
    res = clustertrack(sp, p, np.random.default_rng(seed))
    D = trajectory_distance(w.truth[:, :, :1], res.tracks)
    a, b = _optimize.linear_sum_assignment(D)
    found = int(np.sum(D[a, b] <= p.D0))
    return {
        "error_R": float(D.min(axis=1).mean() / R),
        "targets": int(w.truth.shape[0]),
        "found": found,
        "tracks": int(res.tracks.shape[0]),
        "spurious": int(res.tracks.shape[0] - found),
        "reruns": int(res.reruns),
        "lower_bound": int(sp.max_lower_bound),
    }


def _trial_task(job: tuple) -> dict:
    """A task: one trial of a setting, ``(label, scenario, rho_R, params, seed)`` -> its row."""
    label, scen, rho, params, s = job
    return {"setting": label, "scenario": scen, "rho_R": rho, "seed": s, **one_trial(scen, s, params)}


def _label(job: tuple) -> str:
    return f"{job[0]} rho R = {job[2]:g} seed {job[4]}"


def run(
    out: Path,
    *,
    seed: int = 0,
    trials: int | None = None,
    quick: bool = False,
    echo=print,
    executor: Executor | None = None,
) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    n = trials or (3 if quick else 20)
    densities = (1.0, 2.0) if quick else (0.5, 1.0, 2.0, 4.0)
    settings = [("ideal", "proximity-line", rho, {"variant": "crossing", "rho_r": str(rho)}) for rho in densities]
    settings += [
        (f"nonideal {a}/{b}", "proximity-line-nonideal", 1.0, {"alpha": str(a), "beta": str(b)})
        for a, b in ((0.7, 1.3), (0.5, 1.5))
    ]
    settings.append(("pir-line", "pir-line", 1.25, {}))
    # per setting and trial: independent simulations
    jobs = [(label, scen, rho, params, seed + k) for label, scen, rho, params in settings for k in range(n)]
    rows, timings = run_trials(_trial_task, jobs, executor=executor, label=_label, echo=echo, study="singh")
    res = pl.DataFrame(rows)
    outputs.write_parquet(res, out / "results.parquet")
    outputs.write_csv(res, out / "results.csv")
    write_timings(timings, out)
    summary = (
        res.group_by("setting", "rho_R", maintain_order=True)
        .agg(
            trials=pl.len(),
            error_R=pl.col("error_R").mean(),
            error_R_sd=pl.col("error_R").std(),
            found=pl.col("found").mean(),
            all_found=(pl.col("found") == pl.col("targets")).mean(),
            spurious=pl.col("spurious").mean(),
            tracks=pl.col("tracks").mean(),
        )
        .with_columns(
            paper_error_R=pl.struct("setting", "rho_R").map_elements(
                lambda s: PAPER.get((s["setting"], s["rho_R"])), return_dtype=pl.Float64
            )
        )
    )
    outputs.write_csv(summary, out / "summary.csv")
    echo(str(summary))

    _figures(summary, out, plt)
    return out


def _figures(summary: pl.DataFrame, out: Path, plt) -> None:
    """The study's two figures: error against sensor density (Fig. 6a) and the share of runs
    finding every target beside the spurious tracks."""
    ideal = summary.filter(pl.col("setting") == "ideal")
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.errorbar(ideal["rho_R"], ideal["error_R"], yerr=ideal["error_R_sd"], marker="o", label="ideal (ours)")
    for lab, mk in (("nonideal 0.7/1.3", "s"), ("nonideal 0.5/1.5", "^")):
        s = summary.filter(pl.col("setting") == lab)
        if s.height:
            ax.plot(s["rho_R"], s["error_R"], mk, label=f"{lab} (ours)")
    for (lab, rho), v in PAPER.items():
        if lab != "pir-line":
            ax.plot([rho], [v], "kx")
    ax.plot([], [], "kx", label="paper")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("rho R (sensors per R)")
    ax.set_ylabel("mean localisation error (R)")
    ax.set_title("CLUSTERTRACK: error vs sensor density (Fig. 6a)")
    ax.legend()
    fig.tight_layout()
    with outputs.atomic_path(out / "error_vs_density.png", suffix=".tmp.png") as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 4))
    lab = [f"{a}\nrho R={b:g}" for a, b in zip(summary["setting"], summary["rho_R"])]
    xs = np.arange(summary.height)
    ax.bar(xs - 0.2, summary["all_found"], 0.4, label="fraction of runs finding all targets")
    ax.bar(xs + 0.2, summary["spurious"] / 5.0, 0.4, label="spurious tracks / 5")
    ax.axhline(PAPER_PIR_BOTH, color="k", ls=":", lw=1, label="paper: pir-line both caught (65%)")
    ax.set_xticks(xs, lab, fontsize=7)
    ax.legend(fontsize=7)
    fig.tight_layout()
    with outputs.atomic_path(out / "found_spurious.png", suffix=".tmp.png") as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
