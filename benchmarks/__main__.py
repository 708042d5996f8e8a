"""``python -m benchmarks`` (what ``make bench`` runs): every benchmark in turn, each under a header.

A benchmark that fails (including a failed equality check against its peer) is reported and
the run goes on; the exit status is 1 if any failed. ``bench_camera`` is skipped with a note
when it cannot be imported.
"""

from __future__ import annotations

import importlib
import sys
import time
import traceback

BENCHMARKS = (
    ("bench_table", "issue #16 table: every row, ours vs peer or floor, ratio, growth -> benchmarks/results.csv"),
    ("bench_reader", "raw beam log reader"),
    ("bench_assignment", "Algorithm 1 agent assignment"),
    ("bench_camera", "camera reader"),
    ("bench_counting", "counting-automaton error correction"),
    ("bench_clustertrack", "CLUSTERTRACK Algorithm 1 scan vs direct per-particle"),
    ("bench_intruder", "intruder SIR particle filter vs Stone Soup particle predictor/updater"),
    ("bench_findinghumo", "FindingHuMo Viterbi vs hmmlearn, decoder time per slot, 2nd-order memory"),
    (
        "bench_hmm_growth",
        "hmm2 / hmm1 / findinghumo windows: decoder time per slot vs graph size (25-800 nodes) at the same activity",
        ["--sizes", "25,50,100,200,400,800", "--modes", "full2,full1,adaptive"],
    ),
    (
        "bench_hmm_growth",
        "hmm2 / hmm1 on the 24-hour home log, on its 50 nodes and on 200",
        ["--scenario", "home", "--minutes", "1440", "--start-hour", "0", "--sizes", "50,200", "--modes", "full2,full1"]
        + ["--repeat", "1", "--no-reference"],
    ),
    ("bench_istate", "O'Kane I-state filter step, matching vs direct communication update"),
    (
        "bench_binpf_scale",
        "binpf online at building scale: ms per frame vs ceiling sensors (100-900) and people (10, 40), 2 Hz budget",
    ),
    ("bench_runmany", "run-many over 16 datasets and the O'Kane study: serial vs local pool vs Ray"),
    (
        "bench_whole_run",
        "cold onebit run on 1e4-1e6-row beams/motion/proximity logs and a 24-h home log: stages, viz, start-up vs --no-rrd and pl.read_csv",
    ),
    (
        "bench_whole_run",
        "a default onebit run (every tracker) on 1e4-1e6-row beams/motion/proximity logs: each stage's growth, < 2 min at 1e6",
        ["--all-trackers", "--kinds", "beams,motion,proximity"],
    ),
    (
        "bench_home_month",
        "a generated ARAS-format home, 1/7/30 days: cold import + default run beside a pl.read_csv floor, < 2 min and 2 GB at 30",
        ["--days", "1,7,30"],
    ),
)
OPTIONAL = {"bench_camera"}


def main() -> int:
    failed: list[str] = []
    t_all = time.perf_counter()
    for name, title, *argv in BENCHMARKS:
        print(f"\n=== {name}: {title} ===", flush=True)
        try:
            module = importlib.import_module(f"benchmarks.{name}")
        except ImportError as exc:
            if name in OPTIONAL and (getattr(exc, "name", None) or "").startswith(f"benchmarks.{name}"):
                print(f"(skipped: benchmarks/{name}.py is not there)")
                continue
            traceback.print_exc()
            failed.append(name)
            continue
        t0 = time.perf_counter()
        try:
            module.main(*argv)  # a benchmark given arguments (argv) runs with them
        except Exception:  # report and go on with the next benchmark
            traceback.print_exc()
            failed.append(name)
        print(f"({name}: {time.perf_counter() - t0:.1f} s)", flush=True)
    print(
        f"\nall benchmarks: {time.perf_counter() - t_all:.1f} s" + (f"; FAILED: {', '.join(failed)}" if failed else "")
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
