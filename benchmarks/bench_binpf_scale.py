"""binpf online at building scale: the CPU time of a frame against the sensors and the people
(issue #37 item 3).

``python -m benchmarks.bench_binpf_scale [--arrays 10x10,20x20,30x30] [--people 10,40]
[--seconds 40] [--follow] [--no-write]``. Each case is ``onebit simulate ceiling-building``
(:mod:`onebit.datasets.building_sim`: a ceiling array of ``C x R`` binary sensors 1.5 m apart,
``P`` people walking, frames at 2 Hz) run through the online driver
(:mod:`onebit.trackers.binpf.online`, the default ``[binpf]`` config with ``commit_lag = 6``
and the site's ``targets`` = ``P``), one frame at a time as ``onebit follow`` steps it; the
time per frame is the median over the frames after the first 20 (the people's tracks born),
on one core (the compiled loop is single-threaded). The 2 Hz frame period, 500 ms, is the
real-time budget beside it: ``ratio`` < 1 is faster than real time. The growth exponent is
over the array sizes at each number of people (0 = independent of the array).

A frame costs ``O(tracks x particles x sensors near the tracks)``: a sensor is skipped for a
track when it is farther than ``R + 38 w`` from every particle (its footprint below
``2^-54``, where it cannot change a double: :mod:`onebit.trackers.binpf.kernels`) -- with the
default soft edge ``w = 0.3`` m that is 12.4 m, so on a floor much wider than that the cost
stops growing with the array.

``--follow`` also replays the 20 x 20, 40-person floor through ``onebit follow --replay 4x`` on
the wall clock (60 s of log in 15 s) and prints its delay p50 / p99: a follow that keeps up
has a p99 that does not grow with the log.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.results import Result, Table

BUDGET_MS = 500.0  # the array's 2 Hz frame period


def levels(dataset: Path):
    """``(site, times, on (T, S))`` of a simulated floor's ``frames.csv``."""
    import polars as pl

    from onebit.core.site import load_site

    site = load_site(dataset / "site.toml")
    ids = [s.id for s in site.proximity_sensors]
    idx = {s: i for i, s in enumerate(ids)}
    fr = pl.read_csv(dataset / "frames.csv", schema_overrides={"active": pl.String})
    on = np.zeros((fr.height, len(ids)), dtype=bool)
    for k, active in enumerate(fr["active"].fill_null("").to_list()):
        for s in active.split():
            on[k, idx[s]] = True
    return site, fr["t"].to_numpy(), on


def frame_costs(site, times: np.ndarray, on: np.ndarray, *, warm: int = 20) -> tuple[np.ndarray, int]:
    """Seconds of each frame after the first ``warm``, stepped one at a time; the tracks live at the end."""
    from onebit.trackers.binpf import online
    from onebit.trackers.binpf.stage import BinPFConfig, filter_params, site_arrays

    cfg = BinPFConfig(commit_lag=6, log_particles=0)
    _, sensors, radii, lo, hi = site_arrays(site, cfg)
    st = online.start(filter_params(cfg, site, period=0.5), sensors, radii, lo, hi, lag=cfg.commit_lag)
    online.step(st, times[:warm], on[:warm], final=False)
    cost = []
    for k in range(warm, len(times)):
        t0 = time.perf_counter()
        online.step(st, times[k : k + 1], on[k : k + 1], final=False)
        cost.append(time.perf_counter() - t0)
    return np.array(cost), int(st.arrays["state"][0])


def follow_delay(dataset: Path, speed: float) -> tuple[float, float, float]:
    """``onebit follow --replay`` on the wall clock: (delay p50, p99, wall seconds)."""
    from onebit.pipeline.follow import FollowConfig, follow
    from onebit.pipeline.report import metric

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = follow(
            dataset,
            Path(tmp) / "out",
            trackers=("binpf",),
            config={"binpf": {"commit_lag": 6, "log_particles": 0}},
            options=FollowConfig(replay=speed, poll=0.25),
        )
        wall = time.perf_counter() - t0
        return metric(res.report, "binpf/delay_p50"), metric(res.report, "binpf/delay_p99"), wall


def main(*argv: str) -> None:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_binpf_scale", description=__doc__.split("\n")[0])
    ap.add_argument(
        "--arrays", default="10x10,20x20,30x30", help="ceiling arrays, columns x rows (default 10x10,20x20,30x30)"
    )
    ap.add_argument("--people", default="10,40", help="people walking (default 10,40)")
    ap.add_argument("--seconds", type=float, default=40.0, help="seconds of log per case (default 40: 80 frames)")
    ap.add_argument(
        "--follow", action="store_true", help="also replay the 20 x 20, 40-person floor through onebit follow at 4x"
    )
    ap.add_argument("--no-write", action="store_true", help="print only, do not update results.csv")
    args = ap.parse_args(list(argv) or None)
    from onebit.datasets.building_sim import write_building

    arrays = [tuple(int(v) for v in a.split("x")) for a in args.arrays.split(",")]
    people = [int(p) for p in args.people.split(",")]
    table = Table()
    grid: dict[tuple[int, int], float] = {}
    print(f"{'sensors':>8} {'people':>7} {'tracks':>7} {'ms/frame p50':>13} {'p90':>8} {'x real time':>12}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in people:
            sizes, ms = [], []
            for cols, rows in arrays:
                ds = write_building(
                    Path(tmp) / f"b{cols}x{rows}_{n}",
                    seed=1,
                    duration=args.seconds,
                    agents=n,
                    params={"cols": cols, "rows": rows},
                )
                site, times, on = levels(ds)
                cost, tracks = frame_costs(site, times, on)
                p50, p90 = float(np.median(cost)) * 1e3, float(np.percentile(cost, 90)) * 1e3
                grid[(cols * rows, n)] = p50
                sizes.append(cols * rows)
                ms.append(p50)
                print(f"{cols * rows:>8} {n:>7} {tracks:>7} {p50:>13.1f} {p90:>8.1f} {BUDGET_MS / p50:>12.1f}")
            growth = float(np.log(ms[-1] / ms[0]) / np.log(sizes[-1] / sizes[0])) if len(ms) > 1 else None
            for s, m in zip(sizes, ms):
                table.add(
                    Result(
                        row="binpf online frame (building scale)",
                        case=f"{n} people",
                        size=s,
                        unit="ms/frame",
                        ours=m,
                        peer=BUDGET_MS,
                        peer_name="2 Hz frame period",
                        growth=growth,
                        goal="faster than real time on one core",
                        met=m < BUDGET_MS,
                    )
                )
        if args.follow:
            ds = write_building(Path(tmp) / "follow", seed=2, duration=60.0, agents=40, params={})
            p50, p99, wall = follow_delay(ds, 4.0)
            print(
                f"follow --replay 4x, 400 sensors, 40 people, 60 s: delay p50 {p50:.2f} s, p99 {p99:.2f} s ({wall:.0f} s wall)"
            )
    if not args.no_write:
        print(f"wrote {table.write()}")


if __name__ == "__main__":
    main()
