"""run-many and the studies on executors: serial vs a local process pool vs Ray, on this machine.

1. **run-many over 16 simulated datasets** -- a building's day of logs: 4 each of
   ``beams-building`` (600 s, drop 0.02), ``pir14`` (180 s, refractory 4 s), ``hallway``
   (3 users, 150 s) and ``proximity-line``, simulated once into a temporary folder. Timed,
   each writing its own OUT: :func:`run_many` on the serial executor (this process), the local
   pool with 1 and with ``cores`` workers, and Ray with ``cores`` CPUs (a local instance
   started and stopped inside the timing, as ``onebit run-many --executor ray`` does). The
   summaries must be equal (every metric but the wall-clock ones, unit ``s``); the benchmark
   asserts it. Printed: wall time, speed-up over serial, and the *busy* time (sum of the task
   times measured in the workers) -- busy / wall is how many cores were kept working.
2. **The O'Kane study at the paper's settings on Ray** (m = 1..4, n = 1..5, 1000 stages,
   M = 10): wall time, the sum of the trial times, and their ratio. The paper's 10 trials per
   setting take ~23 min on 2 cores; by default the benchmark runs 1 trial per setting (20
   trials, the same per-trial work) and extrapolates; ``--okane-trials 10`` runs it all,
   ``--okane-trials 0`` skips it.

The machine's load average is printed before and after: the numbers mean little when other
work shares the cores.

Run with ``python -m benchmarks.bench_runmany [--okane-trials N] [--cores N]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import polars as pl

from onebit.datasets.catalogue import get_scenario
from onebit.experiments import okane
from onebit.pipeline.executors import LocalPoolExecutor, RayExecutor, SerialExecutor
from onebit.pipeline.runmany import RunManyResult, run_many

#: (scenario, duration s, drop, params) of the 16 datasets, 4 seeds each.
DATASETS = (
    ("beams-building", 600.0, 0.02, {}),
    ("pir14", 180.0, 0.0, {"refractory": "4"}),
    ("hallway", 150.0, 0.0, {}),
    ("proximity-line", None, 0.0, {}),
)
SEEDS = (0, 1, 2, 3)
PAPER_OKANE_TRIALS = 10


def simulate_datasets(root: Path) -> list[Path]:
    out = []
    for name, duration, drop, params in DATASETS:
        for seed in SEEDS:
            sc = get_scenario(name)
            out.append(
                sc.write(
                    root / f"{name}-{seed}",
                    seed=seed,
                    duration=duration,
                    agents=None,
                    drop=drop,
                    camera=False,
                    params=params,
                )
            )
    return out


def _deterministic(res: RunManyResult) -> pl.DataFrame:
    return res.summary.filter(pl.col("unit").is_null() | (pl.col("unit") != "s"))


def _load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.1f} (1 min), {five:.1f} (5 min) on {os.cpu_count()} cores"


def bench_run_many(cores: int) -> None:
    with tempfile.TemporaryDirectory(prefix="bench-runmany-") as tmp:
        root = Path(tmp)
        t0 = time.perf_counter()
        folders = simulate_datasets(root / "data")
        print(f"simulated {len(folders)} datasets in {time.perf_counter() - t0:.1f} s")
        runs = []
        for label, ex in (
            ("serial (this process)", SerialExecutor()),
            ("local pool, 1 worker", LocalPoolExecutor(workers=1)),
            (f"local pool, {cores} workers", LocalPoolExecutor(workers=cores)),
            (f"ray local, {cores} CPUs (start + stop)", RayExecutor(workers=cores)),
        ):
            t0 = time.perf_counter()
            with ex:
                res = run_many([str(root / "data" / "*")], root / f"out-{ex.kind}-{len(runs)}", executor=ex)
            wall = time.perf_counter() - t0
            busy = float(res.datasets["seconds"].sum())
            runs.append((label, wall, busy, res))
        ref = runs[0][3]
        assert ref.datasets["status"].to_list() == ["ok"] * len(folders), ref.datasets
        for label, _, _, res in runs[1:]:
            assert _deterministic(res).equals(_deterministic(ref)), f"{label}: summary differs from the serial one"
        serial = runs[0][1]
        print(f"\nrun-many, {len(folders)} datasets ({_load()}); summaries equal on every executor")
        print(f"{'executor':40s} {'wall s':>8s} {'speed-up':>9s} {'busy s':>8s} {'busy/wall':>10s}")
        for label, wall, busy, _ in runs:
            print(f"{label:40s} {wall:8.1f} {serial / wall:8.2f}x {busy:8.1f} {busy / wall:10.2f}")
        longest = ref.datasets.sort("seconds", descending=True).row(0, named=True)
        print(
            f"longest single dataset (serial): {longest['dataset']} {longest['seconds']:.1f} s "
            f"-- no executor finishes before it"
        )


def bench_okane(trials: int, cores: int) -> None:
    with tempfile.TemporaryDirectory(prefix="bench-okane-") as tmp:
        t0 = time.perf_counter()
        with RayExecutor(workers=cores) as ex:
            out = okane.run(Path(tmp) / "okane", trials=trials, echo=lambda s: None, executor=ex)
        wall = time.perf_counter() - t0
        secs = pl.read_csv(out / "timings.csv")["seconds"]
        busy, longest = float(secs.sum()), float(secs.max())
        n = pl.read_parquet(out / "results.parquet").height
    print(
        f"\nO'Kane study, paper settings (1000 stages, M = 10), {trials} trial(s) per setting = {n} trials, "
        f"ray local {cores} CPUs ({_load()})"
    )
    print(
        f"wall {wall:.0f} s (incl. Ray start and the Rerun recording of one trial); busy {busy:.0f} s; "
        f"busy/wall {busy / wall:.2f}; trial mean {busy / n:.1f} s, longest {longest:.1f} s"
    )
    if trials < PAPER_OKANE_TRIALS:
        scale = PAPER_OKANE_TRIALS / trials
        print(
            f"the paper's {PAPER_OKANE_TRIALS} trials per setting: ~{wall * scale / 60:.0f} min on {cores} cores "
            f"(~{busy * scale / 60:.0f} min on one)"
        )


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python -m benchmarks.bench_runmany")
    p.add_argument(
        "--okane-trials", type=int, default=1, help="trials per setting of the O'Kane study (0: skip; paper: 10)"
    )
    p.add_argument("--cores", type=int, default=os.cpu_count() or 1, help="workers of the pool / CPUs of Ray")
    p.add_argument("--skip-run-many", action="store_true")
    args = p.parse_args(argv or [])
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    print(_load())
    if not args.skip_run_many:
        bench_run_many(args.cores)
    if args.okane_trials > 0:
        bench_okane(args.okane_trials, args.cores)


if __name__ == "__main__":
    main(sys.argv[1:])
