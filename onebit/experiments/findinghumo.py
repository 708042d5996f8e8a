"""``onebit experiment findinghumo OUT``: FindingHuMo against its baselines over seeds.

The seed sweep behind ``docs/findinghumo.md`` (the issue's acceptance setting): for each seed
the hallway (``onebit simulate hallway``), 3 users, 150 s, drop 0.02, is run through the
pipeline with the ``findinghumo``, ``findinghumo-flow``, ``hmm1`` and ``hmm2`` trackers, as
``onebit run --trackers findinghumo,findinghumo-flow,hmm1,hmm2`` would. Per seed and tracker: the hop error (whole-run matching of
decoded users to true users), users decoded and true, exact slots, IDF1 and identity switches.

Default: 20 seeds (``seed`` .. ``seed + 19``, the issue's setting; ``--trials`` sets the count); ``quick``: 2 seeds
of 60 s. Every seed is an independent task on the executor given (``--executor
serial|local|ray``, see :mod:`onebit.experiments.trials`), simulated and run in a temporary
folder of the worker; the tables are the same on every executor. Writes ``results.parquet``
/ ``results.csv`` (one row per seed and tracker), ``summary.csv`` (per tracker, with the
paper's hop errors for 3 users) and ``timings.csv``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import polars as pl

from onebit.core import writers
from onebit.datasets.hallway_sim import write_hallway_dataset
from onebit.experiments.trials import StudyError, format_table, run_trials, write_timings
from onebit.pipeline.executors import Executor
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline

TRACKERS = ("findinghumo", "findinghumo-flow", "hmm1", "hmm2")
SEEDS = 20
DURATION = 150.0
USERS = 3
DROP = 0.02
QUICK = dict(seeds=2, duration=60.0)
#: The paper's hop errors with 3 users (De et al., the runs it reports).
PAPER = {"findinghumo": "0.00", "hmm2": "0.08-0.35", "hmm1": "0.75-2.74", "findinghumo-flow": "-"}
METRICS = ("hop_error", "users_true", "users_decoded", "slots_exact", "idf1", "id_switches")

RESULT_SCHEMA = pl.Schema({"seed": pl.Int64, "tracker": pl.String, **{m: pl.Float64 for m in METRICS}})


def one_seed(job: tuple[int, float, int, float]) -> list[dict]:
    """A task: simulate one seed of the hallway, run the three trackers, one row per tracker."""
    seed, duration, users, drop = job
    with tempfile.TemporaryDirectory(prefix="onebit-findinghumo-") as tmp:
        root = Path(tmp)
        data = write_hallway_dataset(root / "data", seed=seed, duration=duration, users=users, drop=drop)
        res = run_pipeline(data, root / "run", trackers=TRACKERS, progress=False)
    if not res.ok:
        raise StudyError(f"seed {seed}: a stage failed: {res.status}")
    return [{"seed": seed, "tracker": tr, **{m: metric(res.report, f"{tr}/{m}") for m in METRICS}} for tr in TRACKERS]


def summarise(results: pl.DataFrame) -> pl.DataFrame:
    return (
        results.group_by("tracker", maintain_order=True)
        .agg(
            seeds=pl.len().cast(pl.Int64),
            hop_error=pl.col("hop_error").mean(),
            hop_error_sd=pl.col("hop_error").std(),
            users_decoded=pl.col("users_decoded").mean(),
            slots_exact=pl.col("slots_exact").mean(),
            idf1=pl.col("idf1").mean(),
            id_switches=pl.col("id_switches").mean(),
        )
        .with_columns(paper_hop_error=pl.col("tracker").replace_strict(PAPER, default=None, return_dtype=pl.String))
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
    jobs = [(seed + k, duration, USERS, DROP) for k in range(n)]
    per_seed, timings = run_trials(
        one_seed, jobs, executor=executor, label=lambda j: f"seed {j[0]}", echo=echo, study="findinghumo"
    )
    results = pl.DataFrame([row for rows in per_seed for row in rows], schema=RESULT_SCHEMA)
    summary = summarise(results)
    writers.write_parquet(results, out / "results.parquet")
    writers.write_csv(results, out / "results.csv")
    writers.write_csv(summary, out / "summary.csv")
    write_timings(timings, out)
    echo(format_table(summary))
    return out
