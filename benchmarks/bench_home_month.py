"""A month of a home in the ARAS format (issue 34, item 5): ``onebit import aras`` then a default
``onebit run``, each a cold process as a user meets them, on 1, 7 and 30 generated days, beside
a floor; the goal: 30 days under 2 minutes and 2 GB on 2 cores.

The house (generated in a temporary folder, never real data; :func:`write_house`): a README in
the ARAS format (its sensor table and activity table laid out as the published houses' READMEs)
naming 20 sensor columns of the published kinds (contact, one of them the house door; force;
photocell; sonar; distance; IR; pressure; temperature) and ``DAY_1.txt`` ... ``DAY_N.txt``,
86 400 lines each: the 20 levels then the two residents' activity ids. Each day (seeded,
numpy): both residents sleep from about 23:00 to 07:00 (activity 11, each one's bed force
sensor on); on about 60 % of days one resident or both go out (activity 2) for 2-5 hours, the
door contact on for a few seconds at leaving and at coming back; while someone is home and
awake, 200-450 sensor activations of 3-120 s are spread over the waking hours (a few hundred to
about a thousand level changes a day); the temperature sensor switches a few times a day.

Before the timed runs, one untimed import and run of another generated day fills numba's
on-disk kernel cache and the ``.pyc`` files (a checkout's first run compiles every kernel it
meets, seconds that a user's later runs never pay); its times are printed as the warm-up.

What is timed, per N: ``python -m onebit.cli import aras HOUSE DS`` (it writes ``run.toml``:
the residents tracker) and ``python -m onebit.cli run DS --out RUN``, each a fresh process
under ``/usr/bin/time -v`` (wall, user + sys CPU of the process and its waited-for children,
peak RSS; a run's forked workers' CPU from its ``run.toml`` ``worker_cpu_s`` when any). The
floor: reading the N day files with ``polars.read_csv(f, separator=" ", has_header=False)`` in
a fresh process (``import polars`` included: a user's process pays it too). Printed: days,
import s, run s, total s, peak RSS MB (the larger of the two processes), floor s, total /
floor, CPU s, and the growth total(N max) / total(N min) beside N max / N min.

``python -m benchmarks.bench_home_month [--days 1,7,30] [--seed 1] [--timeout 600]``. Run it
under ``nice`` on a shared machine; 30 days take a minute or two.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
import polars as pl

DAY_S = 86_400
GOAL_S, GOAL_MB, GOAL_DAYS = 120.0, 2048.0, 30

#: (id, README type, place) of the 20 sensor columns, in column order.
SENSORS = (
    ("Co1", "Contact Sensor", "House door"),
    ("Co2", "Contact Sensor", "Wardrobe"),
    ("Co3", "Contact Sensor", "Fridge"),
    ("Co4", "Contact Sensor", "Kitchen cupboard"),
    ("Co5", "Contact Sensor", "Shower cabinet door"),
    ("Fo1", "Force Sensor", "Bed resident 1"),
    ("Fo2", "Force Sensor", "Bed resident 2"),
    ("Fo3", "Force Sensor", "Couch"),
    ("Fo4", "Force Sensor", "Armchair"),
    ("Ph1", "Photocell", "Bathroom drawer"),
    ("Ph2", "Photocell", "Kitchen drawer"),
    ("Ph3", "Photocell", "Wardrobe"),
    ("So1", "Sonar Distance", "Kitchen"),
    ("So2", "Sonar Distance", "Hall"),
    ("Di1", "Distance", "Bathroom door"),
    ("Ir1", "IR", "TV receiver"),
    ("Ir2", "IR", "Kitchen"),
    ("Pr1", "Pressure Mat", "Bathroom"),
    ("Pr2", "Pressure Mat", "Couch"),
    ("Te1", "Temperature Sensor", "Kitchen"),
)
DOOR, BED1, BED2, TEMP = 0, 5, 6, 19
#: Columns a resident awake at home activates.
AWAKE = np.array([i for i in range(len(SENSORS)) if i not in (DOOR, BED1, BED2, TEMP)])
ACTIVITIES = {1: "Other", 2: "Going Out", 11: "Sleeping", 12: "Watching TV", 16: "Napping"}
SLEEPING, GOING_OUT = 11, 2


def readme() -> str:
    """A README in the ARAS format: its sensor table and its activity table."""
    lines = ["ARAS Human Activity Recognition Dataset -- House G (generated for a benchmark)", ""]
    lines += ["Sensor Explanations", "-------------------", "Column\tSensor ID\tSensor Type\tPlace"]
    lines += [f"{i}\t{sid}\t{typ}\t{place}" for i, (sid, typ, place) in enumerate(SENSORS, start=1)]
    lines += ["", "Activity Explanations", "---------------------", "ID\tACTIVITY"]
    lines += [f"{k}\t{v}" for k, v in ACTIVITIES.items()]
    return "\n".join(lines) + "\n"


def _paint(n: int, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """A boolean (n,) that is True inside any [start, end) interval (clipped to [0, n))."""
    starts, ends = np.clip(starts, 0, n), np.clip(ends, 0, n)
    d = np.zeros(n + 1, dtype=np.int32)
    np.add.at(d, starts, 1)
    np.add.at(d, ends, -1)
    return np.cumsum(d[:n]) > 0


def day(rng: np.random.Generator) -> np.ndarray:
    """One day: (86 400, 22) int8, the 20 levels then the two residents' activities."""
    s = len(SENSORS)
    a = np.zeros((DAY_S, s + 2), dtype=np.int8)
    act = a[:, s:]
    act[:] = 1
    t = np.arange(DAY_S)
    home = np.ones((DAY_S, 2), dtype=bool)
    awake = np.ones((DAY_S, 2), dtype=bool)
    for r, bed in enumerate((BED1, BED2)):
        wake = int(rng.normal(7.0, 0.4) * 3600)
        sleep = int(rng.normal(23.0, 0.4) * 3600)
        asleep = (t < wake) | (t >= sleep)
        act[asleep, r] = SLEEPING
        a[asleep, bed] = 1
        awake[asleep, r] = False
        if rng.random() < 0.3:  # an afternoon nap on the couch
            n0 = int(rng.uniform(13, 16) * 3600)
            nap = (t >= n0) & (t < n0 + int(rng.uniform(1200, 3600)))
            act[nap, r] = 16
            awake[nap, r] = False
    if rng.random() < 0.6:  # going out: one resident or both, 2-5 hours
        who = (0, 1) if rng.random() < 0.4 else (int(rng.integers(2)),)
        t0 = int(rng.uniform(9, 16) * 3600)
        t1 = t0 + int(rng.uniform(2, 5) * 3600)
        for r in who:
            out = (t >= t0) & (t < t1)
            act[out, r] = GOING_OUT
            home[out, r] = awake[out, r] = False
        for edge in (t0, t1):  # the door opens at leaving and at coming back
            a[edge - 3 : edge + int(rng.integers(3, 9)), DOOR] = 1
    # activations while someone is home and awake
    k = int(rng.integers(200, 450))
    start = rng.integers(0, DAY_S, size=3 * k)
    start = start[(home & awake).any(axis=1)[start]][:k]
    dur = np.clip(rng.exponential(25.0, size=start.size), 3, 120).astype(np.int64)
    col = rng.choice(AWAKE, size=start.size)
    for c in np.unique(col):
        sel = col == c
        a[_paint(DAY_S, start[sel], start[sel] + dur[sel]), c] = 1
    # the temperature sensor: a few switches a day
    switches = np.sort(rng.integers(0, DAY_S, size=2 * int(rng.integers(1, 4))))
    a[_paint(DAY_S, switches[0::2], switches[1::2]), TEMP] = 1
    return a


def write_house(folder: Path, days: int, seed: int = 1) -> Path:
    """``folder``: the README and ``DAY_1.txt`` ... ``DAY_<days>.txt`` (module docstring)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "README").write_text(readme())
    rng = np.random.default_rng(seed)
    for d in range(1, days + 1):
        a = day(rng)
        df = pl.DataFrame(a, schema=[f"c{i}" for i in range(a.shape[1])], orient="row")
        df.write_csv(folder / f"DAY_{d}.txt", separator=" ", include_header=False)
    return folder


def level_changes(folder: Path, days: int) -> float:
    """Mean level changes per day of the house's sensor columns."""
    total = 0
    for d in range(1, days + 1):
        a = pl.read_csv(folder / f"DAY_{d}.txt", separator=" ", has_header=False).to_numpy()[:, : len(SENSORS)]
        total += int((np.diff(a, axis=0) != 0).sum())
    return total / days


def child_env() -> dict[str, str]:
    """This process's environment with Python's bytecode cache on (an installed onebit has its
    ``.pyc`` files; a sandbox's ``PYTHONDONTWRITEBYTECODE`` would add compile time no user pays)."""
    return {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def timed(cmd: list[str], timeout: float) -> dict:
    """``cmd`` under ``/usr/bin/time -v``: wall s, user + sys CPU s, peak RSS MB, or killed."""
    with tempfile.NamedTemporaryFile("r", suffix=".time") as rep:
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(
                ["/usr/bin/time", "-v", "-o", rep.name, *cmd],
                capture_output=True,
                text=True,
                timeout=timeout,
                env=child_env(),
            )
        except subprocess.TimeoutExpired:
            return {"killed": True, "wall": timeout, "cpu": float("nan"), "rss_mb": float("nan")}
        wall = time.perf_counter() - t0
        text = Path(rep.name).read_text()
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")

    def field(name: str) -> float:
        m = re.search(rf"{re.escape(name)}: *([\d.:]+)", text)
        if not m:
            raise RuntimeError(f"/usr/bin/time -v gave no {name!r}:\n{text}")
        return float(m.group(1))

    return {
        "killed": False,
        "wall": wall,
        "cpu": field("User time (seconds)") + field("System time (seconds)"),
        "rss_mb": field("Maximum resident set size (kbytes)") / 1024.0,
        "stdout": proc.stdout,
    }


def floor(folder: Path, days: int, timeout: float) -> dict:
    """``pl.read_csv`` of the ``days`` day files in a fresh process (its import of polars included)."""
    files = [str(folder / f"DAY_{d}.txt") for d in range(1, days + 1)]
    code = (
        "import sys, polars as pl\n"
        "n = sum(pl.read_csv(f, separator=' ', has_header=False).height for f in sys.argv[1:])\n"
        "print(n)"
    )
    return timed([sys.executable, "-c", code, *files], timeout)


def measure(root: Path, days: int, seed: int, timeout: float) -> dict:
    """Generate ``days`` days, then time the import, the run and the floor (module docstring)."""
    house = write_house(root / f"house-{days}", days, seed)
    ds, run = root / f"ds-{days}", root / f"run-{days}"
    cli = [sys.executable, "-m", "onebit.cli"]
    imp = timed([*cli, "import", "aras", str(house), str(ds)], timeout)
    res = {"days": days, "changes": level_changes(house, days), "import": imp}
    if imp["killed"]:
        res["run"] = {"killed": True, "wall": float("nan"), "cpu": float("nan"), "rss_mb": float("nan")}
    else:
        res["run"] = timed([*cli, "run", str(ds), "--out", str(run)], timeout)
        if not res["run"]["killed"]:
            record = tomllib.loads((run / "run.toml").read_text())
            res["run"]["cpu"] += record.get("timing", {}).get("worker_cpu_s", 0.0)
            res["stages"] = dict(record.get("stages", {}))
            bad = {k: v for k, v in res["stages"].items() if not str(v).startswith(("ok", "skipped"))}
            if bad:
                raise RuntimeError(f"onebit run on {days} day(s): stages not ok: {bad}")
    res["floor"] = floor(house, days, timeout)
    shutil.rmtree(house, ignore_errors=True)
    shutil.rmtree(ds, ignore_errors=True)
    shutil.rmtree(run, ignore_errors=True)
    return res


def table(results: list[dict]) -> str:
    """The printed table and its verdict (module docstring)."""
    head = (
        f"{'days':>4} {'changes/day':>11} {'import s':>9} {'run s':>8} {'total s':>8} {'CPU s':>7} "
        f"{'peak RSS MB':>11} {'floor s':>8} {'total/floor':>11}"
    )
    rows = [head]
    for r in results:
        imp, run, fl = r["import"], r["run"], r["floor"]
        total = imp["wall"] + run["wall"]
        kill = " (killed)" if imp["killed"] or run["killed"] else ""
        rows.append(
            f"{r['days']:>4} {r['changes']:>11.0f} {imp['wall']:>9.1f} {run['wall']:>8.1f} {total:>8.1f} "
            f"{imp['cpu'] + run['cpu']:>7.1f} {max(imp['rss_mb'], run['rss_mb']):>11.0f} {fl['wall']:>8.2f} "
            f"{total / fl['wall']:>11.1f}{kill}"
        )
    if len(results) > 1:
        lo, hi = results[0], results[-1]
        t_lo = lo["import"]["wall"] + lo["run"]["wall"]
        t_hi = hi["import"]["wall"] + hi["run"]["wall"]
        rows.append(
            f"growth: total at {hi['days']} days / total at {lo['days']} day(s) = {t_hi / t_lo:.1f} "
            f"(days x{hi['days'] / lo['days']:.0f}; exponent {np.log(t_hi / t_lo) / np.log(hi['days'] / lo['days']):.2f})"
        )
    for r in results:
        if r["days"] == GOAL_DAYS:
            total = r["import"]["wall"] + r["run"]["wall"]
            rss = max(r["import"]["rss_mb"], r["run"]["rss_mb"])
            ok = total < GOAL_S and rss < GOAL_MB and not (r["import"]["killed"] or r["run"]["killed"])
            rows.append(
                f"goal ({GOAL_DAYS} days < {GOAL_S:.0f} s and < {GOAL_MB / 1024:.0f} GB): "
                f"{total:.1f} s, {rss:.0f} MB -> {'MET' if ok else 'NOT MET'}"
            )
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_home_month")
    ap.add_argument("--days", default="1,7,30", help="comma-separated numbers of days (default 1,7,30)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds before a process is killed")
    args = ap.parse_args(argv)
    days = sorted({int(x) for x in args.days.split(",") if x.strip()})
    if not days or days[0] < 1:
        ap.error("--days: positive numbers of days, e.g. 1,7,30")
    results = []
    with tempfile.TemporaryDirectory(prefix="onebit-home-month-") as tmp:
        warm = measure(Path(tmp) / "warm-up", 1, args.seed + 1000, args.timeout)
        print(
            f"  warm-up (1 day, untimed: fills numba's kernel cache and the .pyc files): import "
            f"{warm['import']['wall']:.1f} s, run {warm['run']['wall']:.1f} s",
            flush=True,
        )
        for n in days:
            results.append(measure(Path(tmp), n, args.seed, args.timeout))
            r = results[-1]
            print(
                f"  {n} day(s): import {r['import']['wall']:.1f} s, run {r['run']['wall']:.1f} s, "
                f"floor {r['floor']['wall']:.2f} s",
                flush=True,
            )
    print(f"{os.cpu_count()} cores; cold processes (python -m onebit.cli), /usr/bin/time -v; floor = pl.read_csv")
    print(table(results))


if __name__ == "__main__":
    main()
