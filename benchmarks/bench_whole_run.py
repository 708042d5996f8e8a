"""Whole runs as a user times them: cold ``onebit run`` processes on 10^4-10^6-row logs of each
sensor kind and on a 24-hour home log, with the time of each stage, of the recordings and of
start-up, beside their floors.

Datasets (built once in a temporary folder, never in the repository):

* **beams**: ``onebit simulate beams-lab`` (seed 7, 180 s, 2 agents), its ``beams.csv``
  repeated end to end (each copy shifted past the last) to N rows; ``--trackers beams``
  (the issue's run: crossings, correct, beams, scores);
* **motion**: ``pir14`` (seed 7) ``motion.csv`` repeated to N rows; ``--trackers intruder``;
* **proximity**: ``proximity-line`` (seed 7) ``proximity.csv`` repeated to N rows;
  ``--trackers clustertrack``;
* **home**: ``onebit simulate home`` (seed 1): 24 hours, 50 PIRs, 2 residents; every
  tracker whose inputs exist (a default ``onebit run``);
* **home-people**: the same log through the trackers of people at home only,
  ``--trackers residents,hmm1,hmm2,findinghumo,findinghumo-flow`` (issue 22's line: a day in
  under 3 minutes on 2 cores).

``--all-trackers``: every kind with a default ``onebit run`` (every tracker whose inputs
exist; the issue's goal: under 2 minutes at 10^6 rows), each stage's time and growth.

Each run is a fresh process (``python -m onebit.cli run DIR --out OUT ...``) timed from
outside (wall); its ``run.toml`` ``[timing]`` gives each stage's work and recording seconds
and the wall clock when the runner was entered, so **start-up** = entry - process start
(imports, argument parsing). **viz** = the recordings: every stage's ``viz_s`` (open the
``.rrd``, log the site, the stage's viz call, close) plus the blueprint. Floors beside each:
the same run with ``--no-rrd`` (the recordings' cost is the difference), and ``pl.read_csv``
of the same log in a fresh process (the read alone, after ``import polars``: the reader
stages' floor). Before the first timed run of a kind, one untimed run of the same command on its smallest log
fills numba's on-disk kernel cache (a checkout's first run compiles every kernel it meets: tens of
seconds that a user's later runs never pay); that run records too, so it also compiles the
Python modules a recorded run imports. Every child process runs with Python's bytecode cache
on (``PYTHONDONTWRITEBYTECODE`` removed, ``PYTHONPYCACHEPREFIX`` in the benchmark's temporary
folder, see :func:`child_env`): an installed onebit has its ``.pyc`` files, and a process that
compiles its own modules from source (a sandbox that sets ``PYTHONDONTWRITEBYTECODE``) pays
~0.25 s of start-up and first-stage time no user meets. A run longer than ``--timeout`` s is killed and reported so (the
``--no-rrd`` run goes first; when it is killed the recorded run is not tried, nor the larger
logs of that kind).

Rows go to ``benchmarks/results.csv`` (row ``whole run``) with the growth exponent over the
sizes. ``python -m benchmarks.bench_whole_run [--sizes 1e4,1e5,1e6] [--kinds beams,motion,...]
[--timeout 600] [--baseline CHECKOUT] [--repeat N] [--config RUN_TOML]`` (``--baseline``: each recorded run also with the
onebit of an earlier commit's checkout, after one run to fill its kernels' cache, and ours
again right after it: the before/after row; ``--repeat N``: the ``--no-rrd`` run, the
recorded run and the ``pl.read_csv`` floor each run ``N`` times in turn, and every time
written is the median of its ``N``: on a shared machine one cold run can be twice another;
``--config``: every run with that ``run.toml``, e.g. lifting a tracker's bound to measure its
growth past it; every tracker stage also gets a CPU row with its growth); ``make bench`` runs it with the defaults. Run it under ``nice`` on a shared
machine; it takes minutes.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import polars as pl

from benchmarks.results import Result, Table, growth

SIZES = (10_000, 100_000, 1_000_000)
KINDS = ("beams", "motion", "proximity", "home", "home-people")
TRACKERS = {
    "beams": "beams",
    "motion": "intruder",
    "proximity": "clustertrack",
    "home": None,
    "home-people": "residents,hmm1,hmm2,findinghumo,findinghumo-flow",
}
LOG = {
    "beams": "beams.csv",
    "motion": "motion.csv",
    "proximity": "proximity.csv",
    "home": "motion.csv",
    "home-people": "motion.csv",
}
READER_STAGE = {
    "beams": "crossings",
    "motion": "motion",
    "proximity": "proximity",
    "home": "motion",
    "home-people": "motion",
}
#: Goals of whole runs, per kind: (rows from which it applies, seconds, label).
GOALS = {"beams": (1_000_000, 10.0, "< 10 s at 1e6 rows"), "home-people": (0, 180.0, "< 3 min (issue 22)")}
ROW = "whole run (cold onebit run)"


#: ``PYTHONPYCACHEPREFIX`` of every child process (set by :func:`main` to its temporary folder).
PYCACHE: dict[str, Path | None] = {"prefix": None}


def child_env(code: Path | None = None) -> dict[str, str]:
    """The environment of a timed child process: this one's, with Python's bytecode cache on
    (``PYTHONDONTWRITEBYTECODE`` removed; ``.pyc`` files under :data:`PYCACHE`'s prefix, never in
    the checkout), and ``PYTHONPATH`` = ``code`` when another checkout's onebit is run."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    if PYCACHE["prefix"] is not None:
        env["PYTHONPYCACHEPREFIX"] = str(PYCACHE["prefix"])
    if code is not None:
        env["PYTHONPATH"] = str(code)
    return env


def _simulate(scenario: str, out: Path, *args: str) -> Path:
    subprocess.run(
        [sys.executable, "-m", "onebit.cli", "simulate", scenario, str(out), *args],
        check=True,
        capture_output=True,
        text=True,
    )
    return out


def tile_log(src: Path, dst: Path, log: str, rows: int) -> Path:
    """``dst``: ``src``'s ``site.toml`` and its ``log`` repeated end to end to ``rows`` rows
    (copy ``i`` shifted by ``i`` times the log's span rounded up to whole seconds, plus one)."""
    dst.mkdir(parents=True, exist_ok=True)
    shutil.copy(src / "site.toml", dst / "site.toml")
    df = pl.read_csv(src / log)
    period = float(int(df["t"].max()) + 2)
    copies = -(-rows // df.height)
    pl.concat([df.with_columns(pl.col("t") + i * period) for i in range(copies)]).head(rows).write_csv(dst / log)
    return dst


def datasets(root: Path, kinds, sizes) -> list[tuple[str, int, Path]]:
    """``(kind, rows, folder)`` of every dataset of the benchmark, built under ``root``."""
    out = []
    base = {
        "beams": lambda: _simulate(
            "beams-lab", root / "src-beams", "--seed", "7", "--duration", "180", "--agents", "2", "--no-camera"
        ),
        "motion": lambda: _simulate("pir14", root / "src-motion", "--seed", "7", "--no-camera"),
        "proximity": lambda: _simulate("proximity-line", root / "src-proximity", "--seed", "7", "--no-camera"),
    }
    home = None
    for kind in kinds:
        if kind.startswith("home"):
            home = home or _simulate("home", root / "home-24h", "--seed", "1")
            out.append((kind, pl.read_csv(home / "motion.csv").height, home))
            continue
        src = base[kind]()
        for n in sizes:
            out.append((kind, n, tile_log(src, root / f"{kind}-{n}", LOG[kind], n)))
    return out


def read_csv_cold(path: Path) -> tuple[float, float]:
    """Seconds of ``pl.read_csv(path)`` in a fresh process (after ``import polars``): wall and CPU."""
    code = (
        "import time, polars as pl\nt, c = time.perf_counter(), time.process_time(); pl.read_csv("
        f"{str(path)!r})\nprint(time.perf_counter() - t, time.process_time() - c)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], check=True, capture_output=True, text=True, env=child_env()
    ).stdout.split()
    return float(out[0]), float(out[1])


def cold_run(
    dataset: Path,
    out: Path,
    trackers: str | None,
    *,
    rrd: bool,
    timeout: float,
    code: Path | None = None,
    config: Path | None = None,
) -> dict:
    """One ``onebit run`` process: wall, start-up, per-stage work and viz seconds, or ``killed``;
    ``code``: run the onebit of that checkout (``PYTHONPATH``) instead of this one; ``config``:
    its ``--config`` (a ``run.toml``)."""
    cmd = [sys.executable, "-m", "onebit.cli", "run", str(dataset), "--out", str(out)]
    cmd += ["--trackers", trackers] if trackers else []
    cmd += ["--config", str(config)] if config is not None else []
    cmd += [] if rrd else ["--no-rrd"]
    shutil.rmtree(out, ignore_errors=True)
    spawned = time.time()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    try:
        env = child_env(code)
        proc = subprocess.run(
            cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=code
        )  # -m imports from the cwd first
    except subprocess.TimeoutExpired:
        return {"killed": True, "wall": timeout, "cmd": cmd}
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if not (out / "run.toml").exists():
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    record = tomllib.loads((out / "run.toml").read_text())
    timing = record.get("timing", {})
    cpu += timing.get("worker_cpu_s", 0.0)  # a stage's worker processes (forked by a fork server, not waited for here)
    stages = {k: v for k, v in timing.items() if isinstance(v, dict)}
    viz = sum(v.get("viz_s", 0.0) for v in stages.values()) + timing.get("blueprint_s", 0.0)
    viz_cpu = sum(v.get("viz_cpu_s", 0.0) for v in stages.values()) + timing.get("blueprint_cpu_s", 0.0)
    return {
        "killed": False,
        "wall": wall,
        "cpu": cpu,
        "startup": timing.get("entered_unix", spawned) - spawned,
        "viz": viz,
        "viz_cpu": viz_cpu,
        "stages": stages,
        "status": record.get("stages", {}),
        "cmd": cmd,
    }


def median_run(runs: list[dict]) -> dict:
    """One run's record from ``runs`` of the same command: the median of each time (wall, cpu,
    start-up, viz, every stage's seconds), ``killed`` if any was; the first run's status."""
    if len(runs) == 1 or any(r["killed"] for r in runs):
        return next((r for r in runs if r["killed"]), runs[0])
    out = dict(runs[0])
    for key in ("wall", "cpu", "startup", "viz", "viz_cpu"):
        out[key] = float(statistics.median(r[key] for r in runs))
    stages = {}
    for stage, first in runs[0]["stages"].items():
        stages[stage] = {
            k: float(statistics.median(r["stages"].get(stage, {}).get(k, v) for r in runs)) for k, v in first.items()
        }
    out["stages"] = stages
    out["runs"] = len(runs)
    return out


def _commit_of(checkout: Path) -> str:
    try:
        return subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=checkout, capture_output=True, text=True, timeout=10
        ).stdout.strip() or str(checkout)
    except (OSError, subprocess.SubprocessError):
        return str(checkout)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_whole_run")
    ap.add_argument(
        "--sizes", default=",".join(f"{s:g}" for s in SIZES), help="rows of the tiled logs (comma-separated)"
    )
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--timeout", type=float, default=600.0, help="s; a run taking longer is killed and reported so")
    ap.add_argument(
        "--all-trackers",
        action="store_true",
        help="a default onebit run (every tracker whose inputs exist) on every kind, not its one tracker",
    )
    ap.add_argument(
        "--baseline",
        type=Path,
        default=None,
        metavar="CHECKOUT",
        help="also run each recorded run with the onebit of this checkout (an earlier commit): the before/after rows",
    )
    ap.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="RUN_TOML",
        help="pass --config RUN_TOML to every run (e.g. lifting [clustertrack] max_instants to measure a "
        "tracker's growth past its bound); the rows name the file",
    )
    ap.add_argument(
        "--repeat",
        type=int,
        default=1,
        help="run each command (--no-rrd, recorded, pl.read_csv) this many times in turn and keep the medians",
    )
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error(f"--repeat {args.repeat}: at least 1")
    sizes = tuple(int(float(s)) for s in args.sizes.split(","))
    kinds = tuple(k.strip() for k in args.kinds.split(","))
    print(f"load average {os.getloadavg()}", flush=True)
    table = Table()
    with tempfile.TemporaryDirectory(prefix="onebit-whole-run-") as tmp:
        root = Path(tmp)
        PYCACHE["prefix"] = root / "pycache"
        runs: dict[str, list] = {}
        killed: set[str] = set()
        warmed: set[str] = set()
        for kind, n, data in datasets(root, kinds, sizes):
            if kind not in warmed:  # numba's on-disk cache and the bytecode filled, as a user's second run finds them
                warmed.add(kind)
                cold_run(
                    data,
                    root / "out-warm",
                    TRACKERS[kind] if not args.all_trackers else None,
                    rrd=True,
                    timeout=args.timeout,
                    config=args.config,
                )
            if kind in killed:  # a smaller log of this kind already ran past the timeout
                print(f"  {kind} {n} rows: not run (a smaller log was killed at the timeout)", flush=True)
                continue
            trackers = None if args.all_trackers else TRACKERS[kind]
            if kind.startswith("home"):
                what = f"home (24 h, 50 PIRs, 2 residents), {f'--trackers {trackers}' if trackers else 'every tracker'}"
            else:
                what = f"{kind} --trackers {trackers}" if trackers else f"{kind}, every tracker"
            what += f" (--config {args.config.name})" if args.config is not None else ""
            offs, ons, floors = [], [], []
            for _ in range(args.repeat):  # in turn: the three measured in the same minute each time
                offs.append(
                    cold_run(data, root / "out-norrd", trackers, rrd=False, timeout=args.timeout, config=args.config)
                )
                if offs[-1]["killed"]:
                    break
                ons.append(cold_run(data, root / "out", trackers, rrd=True, timeout=args.timeout, config=args.config))
                floors.append(read_csv_cold(data / LOG[kind]))
            off = median_run(offs)
            on = off if off["killed"] else median_run(ons)
            if not floors:
                floors.append(read_csv_cold(data / LOG[kind]))
            floor = float(statistics.median(f[0] for f in floors))
            floor_cpu = float(statistics.median(f[1] for f in floors))
            if args.baseline is not None and not on["killed"]:
                warm = cold_run(
                    data,
                    root / "out-base",
                    trackers,
                    rrd=True,
                    timeout=args.timeout,
                    code=args.baseline,
                    config=args.config,
                )  # its kernels' cache
                base = (
                    warm
                    if warm["killed"]
                    else cold_run(
                        data,
                        root / "out-base",
                        trackers,
                        rrd=True,
                        timeout=args.timeout,
                        code=args.baseline,
                        config=args.config,
                    )
                )
                again = cold_run(
                    data, root / "out", trackers, rrd=True, timeout=args.timeout, config=args.config
                )  # right after, in the same conditions
                ours = min(on["wall"], again["wall"])
                print(
                    f"  {kind} {n} rows: baseline {base['wall']:.1f} s{' (killed)' if base['killed'] else ''}, ours {ours:.1f} s",
                    flush=True,
                )
                table.add(
                    Result(
                        ROW,
                        f"{what}, {n:.0e} rows: wall, this commit vs {_commit_of(args.baseline)}",
                        n,
                        "s wall",
                        ours,
                        base["wall"],
                        f"the same run at {_commit_of(args.baseline)}" + (" (killed)" if base["killed"] else ""),
                    )
                )
            runs.setdefault(kind, []).append((n, what, on, off, (floor, floor_cpu)))
            if on["killed"]:
                killed.add(kind)
            print(
                f"  {kind} {n} rows: wall {on['wall']:.1f} s{' (killed)' if on['killed'] else ''}, --no-rrd "
                f"{off['wall']:.1f} s, read_csv {floor:.3f} s",
                flush=True,
            )
        for kind, items in runs.items():
            ns = [n for n, *_ in items]
            walls = [on["wall"] for _, _, on, _, _ in items if not on["killed"]]
            g_wall = growth([n for n, _, on, _, _ in items if not on["killed"]], walls)
            for n, what, on, off, (floor, floor_cpu) in items:
                killed = " (killed at the timeout)" if on["killed"] else ""
                if "every tracker" in what and not kind.startswith("home"):
                    from_rows, limit, goal = 1_000_000, 120.0, "< 120 s at 1e6 rows"
                else:
                    from_rows, limit, goal = GOALS.get(kind, (0, None, ""))
                met = (on["wall"] < limit and not on["killed"]) if limit is not None and n >= from_rows else None
                table.add(
                    Result(
                        ROW,
                        f"{what}, {n:.0e} rows: wall{killed}",
                        n,
                        "s wall",
                        on["wall"],
                        off["wall"],
                        "the same run --no-rrd",
                        g_wall,
                        goal,
                        met,
                    )
                )
                if on["killed"]:
                    continue
                table.add(
                    Result(
                        ROW,
                        f"{what}, {n:.0e} rows: cpu (user + sys)",
                        n,
                        "s cpu",
                        on["cpu"],
                        off.get("cpu"),
                        "the same run --no-rrd",
                        growth(
                            [n for n, _, o, _, _ in items if not o["killed"]],
                            [o["cpu"] for _, _, o, _, _ in items if not o["killed"]],
                        ),
                        "the run's CPU seconds: what a loaded machine does not inflate",
                    )
                )
                table.add(
                    Result(
                        ROW,
                        f"{what}, {n:.0e} rows: start-up",
                        n,
                        "s wall",
                        on["startup"],
                        on["wall"],
                        "the whole run",
                        None,
                        "imports and checks before the first stage",
                    )
                )
                share = on["viz"] / on["wall"] if on["wall"] else None
                table.add(
                    Result(
                        ROW,
                        f"{what}, {n:.0e} rows: viz (recordings)",
                        n,
                        "s wall",
                        on["viz"],
                        on["wall"],
                        "the whole run",
                        growth(ns, [r[2].get("viz", 0) for r in items if not r[2]["killed"]]),
                        "<= 20 % of the run",
                        share is not None and share <= 0.20,
                    )
                )
                share_cpu = on["viz_cpu"] / on["cpu"] if on["cpu"] else None
                table.add(
                    Result(
                        ROW,
                        f"{what}, {n:.0e} rows: viz (recordings), cpu",
                        n,
                        "s cpu",
                        on["viz_cpu"],
                        on["cpu"],
                        "the whole run's cpu",
                        growth(ns, [r[2].get("viz_cpu", 0) for r in items if not r[2]["killed"]]),
                        "<= 20 % of the run",
                        share_cpu is not None and share_cpu <= 0.20,
                    )
                )
                for stage, t in on["stages"].items():
                    reader = stage == READER_STAGE[kind]
                    table.add(
                        Result(
                            ROW,
                            f"{what}, {n:.0e} rows: stage {stage}",
                            n,
                            "s wall",
                            t["work_s"],
                            floor if reader else None,
                            "pl.read_csv of the log (fresh process)" if reader else "",
                            growth(
                                ns,
                                [r[2]["stages"].get(stage, {}).get("work_s", 0) for r in items if not r[2]["killed"]],
                            ),
                            "<= 2x pl.read_csv (cold)" if reader else "",
                            (t["work_s"] <= 2 * floor) if reader else None,
                        )
                    )
                    if not reader and "work_cpu_s" in t:  # a tracker's CPU: what the load does not inflate
                        table.add(
                            Result(
                                ROW,
                                f"{what}, {n:.0e} rows: stage {stage}, cpu",
                                n,
                                "s cpu",
                                t["work_cpu_s"],
                                None,
                                "",
                                growth(
                                    [r[0] for r in items if stage in r[2].get("stages", {})],
                                    [
                                        r[2]["stages"][stage]["work_cpu_s"]
                                        for r in items
                                        if stage in r[2].get("stages", {})
                                    ],
                                ),
                                "",
                                None,
                            )
                        )
                    if reader and "work_cpu_s" in t:
                        table.add(
                            Result(
                                ROW,
                                f"{what}, {n:.0e} rows: stage {stage}, cpu",
                                n,
                                "s cpu",
                                t["work_cpu_s"],
                                floor_cpu,
                                "pl.read_csv of the log (fresh process), cpu",
                                None,
                                "<= 2x pl.read_csv (cold)",
                                t["work_cpu_s"] <= 2 * floor_cpu,
                            )
                        )
    table.write()


if __name__ == "__main__":
    main()
