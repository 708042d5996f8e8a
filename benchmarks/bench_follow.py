"""The cost of one ``onebit follow`` poll against the run's length (issue 25).

``python -m benchmarks.bench_follow [--case hallway|beams|reader|all] [--tiles N] [--speed S]
[--decoding lagged|batch] [--no-incremental] [--write]``. Every case prints the CPU time
(``time.process_time``: other users of the machine do not count) of a poll as the mean over
each fifth of the run. A poll that costs the same in the last fifth as in the second is flat
(linear over the run); one that grows is quadratic over the run.

* ``hallway`` -- the hallway demo (seed 7, 3 users, 150 s), its ``motion.csv`` repeated every
  160 s ``--tiles`` times, followed as a replay at ``--speed`` with a simulated clock (one poll
  per simulated second) and the findinghumo tracker (``eatg = "layout"``); also the readers'
  share of a poll (the incremental readers and the reader stages still re-run) and whether the
  published rows equal the batch run's.
* ``beams`` -- the beams-lab demo (seed 3, 2 agents, 150 s), its ``beams.csv`` repeated
  ``--tiles`` times, followed with the ``beams`` tracker (``[correct] enabled = false``: its
  input is the reader's crossings, so it runs crossing by crossing).
* ``istate`` -- the istate-room demo (seed 2, 150 s), its ``motion.csv`` repeated ``--tiles``
  times, followed with the ``istate`` tracker (``latency_auto = false``: stage by stage).
* ``reader`` -- the motion reader alone on a long log (hallway tiled to ~10^6 edges): the
  incremental reader (:class:`onebit.readers.tail.ToggleTail`) fed 1 000 s of log per poll,
  beside what a poll paid before, the batch reader (``read_motion_csv``) on the whole prefix
  at the end of each fifth.

``--no-incremental`` runs the follow cases the earlier way (``FollowConfig(incremental=False)``:
the snapshot re-read, ``beams`` and ``istate`` re-run on the prefix at every poll);
``--compare`` runs each follow case both ways. ``--write`` adds the rows to
``benchmarks/results.csv`` (row ``follow poll``: one row per case and fifth, ours = CPU ms per
poll, peer = the earlier way where measured).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import polars as pl


def tiled(root: Path, scenario: str, log: str, tiles: int, *, seed: int, agents: int) -> Path:
    """``scenario``'s ``log`` repeated every 160 s ``tiles`` times (site.toml and run.toml kept)."""
    from onebit.datasets.catalogue import get_scenario

    src = get_scenario(scenario).write(
        root / f"{scenario}-one", seed=seed, duration=150.0, agents=agents, drop=0.0, camera=False, params={}
    )
    out = root / f"{scenario}-x{tiles}"
    out.mkdir()
    for name in ("site.toml", "run.toml"):
        if (src / name).exists():
            (out / name).write_text((src / name).read_text())
    m = pl.read_csv(src / log)
    pl.concat([m.with_columns(pl.col("t") + i * 160.0) for i in range(tiles)]).write_csv(out / log)
    return out


def tiled_hallway(root: Path, tiles: int) -> Path:
    return tiled(root, "hallway", "motion.csv", tiles, seed=7, agents=3)


def _fifths(a: np.ndarray) -> list[float]:
    q = max(len(a) // 5, 1)
    return [round(float(np.mean(a[i * q : (i + 1) * q])) * 1000, 1) for i in range(5)]


def poll_costs(data: Path, out: Path, *, speed: float, tracker: str, config: dict, incremental: bool = True) -> dict:
    """Follow ``data`` as a replay with a simulated clock; CPU per poll and the readers' share, by fifth."""
    import onebit.pipeline.follow as follow_module
    from onebit.pipeline.follow import FollowConfig, follow

    spent = {"read": 0.0}
    read_original = follow_module.Follow.read  # the readers: incremental ones and the polled stages

    def timed(fn):
        def run(*a, **k):
            t = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                spent["read"] += time.process_time() - t

        return run

    marks: list[tuple[float, float]] = []
    now = [1000.0]

    def sleep(dt: float) -> None:
        marks.append((time.process_time(), spent["read"]))
        now[0] += dt

    follow_module.Follow.read = timed(read_original)
    try:
        res = follow(
            data,
            out,
            trackers=(tracker,),
            config=config,
            options=FollowConfig(replay=speed, poll=1.0, incremental=incremental),
            clock=lambda: now[0],
            sleep=sleep,
        )
    finally:
        follow_module.Follow.read = read_original
    m = np.array(marks)
    work, read = np.diff(m[:, 0]), np.diff(m[:, 1])
    equal = res.report.filter((pl.col("stage") == tracker) & (pl.col("metric") == "online_equals_batch"))
    return {
        "polls": len(work),
        "cpu_s": round(float(work.sum()), 1),
        "ms_per_poll_by_fifth": _fifths(work),
        "reader_ms_by_fifth": _fifths(read),
        "equal": bool(equal["value"][0] == 1.0) if equal.height else None,
    }


def reader_costs(data: Path, *, step: float = 1000.0) -> dict:
    """The motion reader on a long log: incremental (per ``step`` s of log) vs a batch re-read of the prefix."""
    from onebit.core.config import config_from_mapping
    from onebit.core.site import load_site
    from onebit.readers.motion import MotionConfig, read_motion_csv, site_rules
    from onebit.readers.tail import ToggleTail
    from onebit.readers.timebase import TimeOrigin

    site = load_site(data / "site.toml")
    ids = [s.id for s in site.motion_sensors]
    rules = site_rules(site, config_from_mapping(MotionConfig, {}, section="motion"))
    raw = (data / "motion.csv").read_bytes()
    head, _, body = raw.partition(b"\n")
    lines = body.splitlines(keepends=True)
    t = np.array([float(ln.split(b",", 1)[0]) for ln in lines])
    cuts = np.searchsorted(t, np.arange(step, t[-1] + step, step), side="right")
    origin = TimeOrigin(origin=0.0, numeric=0.0, source="data")
    tail = ToggleTail("motion.csv", ids, origin=origin, rules=rules, held=site.level_sensors)
    tail.feed(head + b"\n")
    costs, emitted, lo = [], 0, 0
    for hi in cuts:
        chunk = b"".join(lines[lo:hi])
        c0 = time.process_time()
        emitted += tail.feed(chunk).motion.height
        costs.append(time.process_time() - c0)
        lo = hi
    emitted += tail.finish().motion.height
    costs = np.array(costs)
    q = max(len(costs) // 5, 1)
    batch, sizes = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(5):  # what a poll paid before: the whole prefix re-read, at the end of each fifth
            n = int(cuts[min((i + 1) * q, len(cuts)) - 1])
            p = Path(tmp) / "motion.csv"
            p.write_bytes(head + b"\n" + b"".join(lines[:n]))
            best = np.inf
            for _ in range(3):
                c0 = time.process_time()
                ref = read_motion_csv(p, ids, epoch=origin, rules=rules, held=site.level_sensors)
                best = min(best, time.process_time() - c0)
            batch.append(round(best * 1000, 1))
            sizes.append(n)
        ref = read_motion_csv(data / "motion.csv", ids, epoch=origin, rules=rules, held=site.level_sensors)
    return {
        "edges": len(lines),
        "polls": len(costs),
        "ms_per_poll_by_fifth": _fifths(costs),
        "batch_reread_ms_by_fifth": batch,
        "lines_at_fifth_ends": sizes,
        "equal": emitted == ref.motion.height,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("hallway", "beams", "istate", "reader", "all"), default="all")
    ap.add_argument("--tiles", type=int, default=0, help="0: 200 (hallway), 400 (beams), 40 (istate), 7250 (reader)")
    ap.add_argument("--speed", type=float, default=100.0)
    ap.add_argument("--decoding", choices=("lagged", "batch"), default="lagged")
    ap.add_argument("--no-incremental", action="store_true")
    ap.add_argument("--write", action="store_true", help="add the rows to benchmarks/results.csv")
    ap.add_argument("--compare", action="store_true", help="also run the earlier way: the peer of each row")
    args = ap.parse_args()
    inc = not args.no_incremental
    rows = []

    def both(*a, **k):
        """(this way's costs, the earlier way's when --compare) of one follow case."""
        r = poll_costs(*a, **k, incremental=inc)
        print(r)
        if not (args.compare and inc):
            return r, None, None
        out = a[1].with_name(a[1].name + "-before")
        b = poll_costs(a[0], out, **k, incremental=False)
        print("earlier way:", b)
        return r, b["ms_per_poll_by_fifth"], b["reader_ms_by_fifth"]

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        if args.case in ("hallway", "all"):
            tiles = args.tiles or 200
            data = tiled_hallway(root, tiles)
            edges = pl.read_csv(data / "motion.csv").height
            print(
                f"hallway x {tiles} ({edges} edges), replay {args.speed}x, findinghumo {args.decoding}, incremental {inc}"
            )
            r, peer, peer_read = both(
                data,
                root / "out-h",
                speed=args.speed,
                tracker="findinghumo",
                config={"findinghumo": {"eatg": "layout", "decoding": args.decoding}},
            )
            rows.append((f"hallway x{tiles} findinghumo {args.decoding}, poll", edges, r["ms_per_poll_by_fifth"], peer))
            rows.append((f"hallway x{tiles} readers, poll", edges, r["reader_ms_by_fifth"], peer_read))
        if args.case in ("beams", "all"):
            tiles = args.tiles or 400
            data = tiled(root, "beams-lab", "beams.csv", tiles, seed=3, agents=2)
            events = pl.read_csv(data / "beams.csv").height
            print(f"beams-lab x {tiles} ({events} beam events), replay {args.speed}x, beams, incremental {inc}")
            r, peer, peer_read = both(
                data, root / "out-b", speed=args.speed, tracker="beams", config={"correct": {"enabled": False}}
            )
            rows.append((f"beams-lab x{tiles} beams, poll", events, r["ms_per_poll_by_fifth"], peer))
            rows.append((f"beams-lab x{tiles} beam reader, poll", events, r["reader_ms_by_fifth"], peer_read))
        if args.case in ("istate", "all"):
            tiles = args.tiles or 40
            data = tiled(root, "istate-room", "motion.csv", tiles, seed=2, agents=None)
            edges = pl.read_csv(data / "motion.csv").height
            print(f"istate-room x {tiles} ({edges} edges), replay {args.speed}x, istate, incremental {inc}")
            r, peer, _ = both(
                data,
                root / "out-i",
                speed=args.speed,
                tracker="istate",
                config={"istate": {"latency_auto": False, "max_stages": 0}},
            )
            rows.append((f"istate-room x{tiles} istate, poll", edges, r["ms_per_poll_by_fifth"], peer))
        if args.case in ("reader", "all"):
            tiles = args.tiles or 7250
            data = tiled_hallway(root, tiles)
            r = reader_costs(data)
            print(f"motion reader, hallway x {tiles}: {r}")
            rows.append(
                (
                    f"motion reader, hallway x{tiles}, 1000 s per poll",
                    r["edges"],
                    r["ms_per_poll_by_fifth"],
                    r["batch_reread_ms_by_fifth"],
                )
            )
    if args.write and inc:
        from benchmarks.results import Result, Table

        table = Table()
        for case, size, ours, peer in rows:
            for k, v in enumerate(ours, start=1):
                table.add(
                    Result(
                        row="follow poll",
                        case=f"{case} ms, fifth {k} of the run",
                        size=size,
                        unit="ms cpu per poll",
                        ours=v,
                        peer=None if peer is None else peer[k - 1],
                        peer_name=""
                        if peer is None
                        else (
                            "batch re-read of the prefix (the earlier poll)"
                            if case.startswith("motion reader")
                            else "--no-incremental: re-read and re-run on the prefix (the earlier poll)"
                        ),
                        goal="flat: fifth 5 <= 1.5x fifth 2" if k == 5 else "",
                        met=(v <= 1.5 * ours[1]) if k == 5 else None,
                    )
                )
        print(f"wrote {table.write()}")


if __name__ == "__main__":
    main()
