"""``onebit experiment correct OUT``: the counting-automaton correction over many seeds.

The study behind ``docs/beams-correct.md`` ("`correct/recovered`: definition and measured
numbers"): for each seed, the Fig. 1 building (``beams-building``), 3 agents, drop 0.05,
300 s, no camera -- with the dataset's own ``run.toml`` (n = 3, known eta_0) -- is run through
the pipeline twice, as ``onebit run --trackers beams`` would: with the ``correct`` stage, and
with it disabled (``[correct] enabled = false``). Per seed: dropped, inserted and restored
crossings, ``correct/recovered``, and the assignment accuracy with and without the correction.

Default: 20 seeds (``seed`` .. ``seed + 19``; ``--trials`` sets the count); ``quick``: 3 seeds
of 120 s. Every seed is an independent task on the executor given (``--executor
serial|local|ray``, see :mod:`onebit.experiments.trials`), simulated and run in a temporary
folder of the worker (no shared file system needed); the tables are the same on every
executor. Writes ``results.parquet`` / ``results.csv`` (one row per seed), ``summary.csv``
(means; ``recovered`` over the seeds with drops, as in the doc) and ``timings.csv``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import polars as pl

from onebit.core import writers
from onebit.datasets.beams_sim import write_beams_dataset
from onebit.experiments.trials import StudyError, format_table, run_trials, write_timings
from onebit.pipeline.executors import Executor
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline

SEEDS = 20
DURATION = 300.0
DROP = 0.05
QUICK = dict(seeds=3, duration=120.0)

RESULT_SCHEMA = pl.Schema(
    {
        "seed": pl.Int64,
        "dropped": pl.Float64,
        "inserted": pl.Float64,
        "restored": pl.Float64,
        "recovered": pl.Float64,
        "accuracy_corrected": pl.Float64,
        "accuracy_uncorrected": pl.Float64,
    }
)


def one_seed(job: tuple[int, float, float]) -> dict:
    """A task: simulate one seed, run the beams pipeline with and without ``correct``."""
    seed, duration, drop = job
    with tempfile.TemporaryDirectory(prefix="onebit-correct-") as tmp:
        root = Path(tmp)
        data = write_beams_dataset(
            root / "data", "beams-building", seed=seed, duration=duration, drop=drop, camera=False
        )
        on = run_pipeline(data, root / "on", trackers=("beams",), progress=False)
        off = run_pipeline(
            data, root / "off", trackers=("beams",), config={"correct": {"enabled": False}}, progress=False
        )
    if not (on.ok and off.ok):
        raise StudyError(f"seed {seed}: a stage failed: with correct {on.status}, without {off.status}")
    return {
        "seed": seed,
        "dropped": metric(on.report, "correct/dropped"),
        "inserted": metric(on.report, "correct/inserted"),
        "restored": metric(on.report, "correct/restored"),
        "recovered": metric(on.report, "correct/recovered"),
        "accuracy_corrected": metric(on.report, "beams/assignment_accuracy"),
        "accuracy_uncorrected": metric(off.report, "beams/assignment_accuracy"),
    }


def summarise(results: pl.DataFrame) -> pl.DataFrame:
    with_drops = pl.col("dropped") > 0
    return results.select(
        seeds=pl.len().cast(pl.Int64),
        seeds_with_drops=with_drops.sum().cast(pl.Int64),
        dropped=pl.col("dropped").sum(),
        inserted=pl.col("inserted").sum(),
        restored=pl.col("restored").sum(),
        recovered=pl.col("recovered").filter(with_drops).mean(),
        accuracy_corrected=pl.col("accuracy_corrected").mean(),
        accuracy_uncorrected=pl.col("accuracy_uncorrected").mean(),
    )


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
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    n = trials or (QUICK["seeds"] if quick else SEEDS)
    duration = QUICK["duration"] if quick else DURATION
    jobs = [(seed + k, duration, DROP) for k in range(n)]
    rows, timings = run_trials(
        one_seed, jobs, executor=executor, label=lambda j: f"seed {j[0]}", echo=echo, study="correct"
    )
    results = pl.DataFrame(rows, schema=RESULT_SCHEMA)
    summary = summarise(results)
    writers.write_parquet(results, out / "results.parquet")
    writers.write_csv(results, out / "results.csv")
    writers.write_csv(summary, out / "summary.csv")
    write_timings(timings, out)
    echo(format_table(summary))
    return out
