"""The cost of one ``onebit follow`` poll against the run's length (issue 25 item 2).

``python -m benchmarks.bench_follow [--tiles 200] [--speed 100] [--decoding lagged|batch]``:
simulates the hallway demo (seed 7, 3 users, 150 s), repeats its ``motion.csv`` every 160 s
``--tiles`` times, and follows it as a replay at ``--speed`` with a simulated clock (one poll
per simulated second) and the findinghumo tracker (``eatg = "layout"``). Prints the CPU time
of a poll (``time.process_time``, so other users of the machine do not count) as the mean over
each fifth of the run, the reader stages' share of it, and whether the published rows equal
the batch run's. A poll that costs the same in the last fifth as in the second grows
linearly over the run; one that grows is quadratic.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import polars as pl


def tiled_hallway(root: Path, tiles: int) -> Path:
    from onebit.datasets.catalogue import get_scenario

    src = get_scenario("hallway").write(
        root / "one", seed=7, duration=150.0, agents=3, drop=0.0, camera=False, params={}
    )
    out = root / f"hallway-x{tiles}"
    out.mkdir()
    (out / "site.toml").write_text((src / "site.toml").read_text())
    m = pl.read_csv(src / "motion.csv")
    pl.concat([m.with_columns(pl.col("t") + i * 160.0) for i in range(tiles)]).write_csv(out / "motion.csv")
    return out


def poll_costs(data: Path, out: Path, *, speed: float, decoding: str) -> dict:
    import onebit.pipeline.follow as follow_module
    from onebit.pipeline.follow import FollowConfig, follow

    spent = {"read": 0.0}
    original = follow_module._read_prefix

    def timed(*a, **k):
        t = time.process_time()
        try:
            return original(*a, **k)
        finally:
            spent["read"] += time.process_time() - t

    marks: list[tuple[float, float]] = []
    now = [1000.0]

    def sleep(dt: float) -> None:
        marks.append((time.process_time(), spent["read"]))
        now[0] += dt

    follow_module._read_prefix = timed
    try:
        res = follow(
            data,
            out,
            trackers=("findinghumo",),
            config={"findinghumo": {"eatg": "layout", "decoding": decoding}},
            options=FollowConfig(replay=speed, poll=1.0),
            clock=lambda: now[0],
            sleep=sleep,
        )
    finally:
        follow_module._read_prefix = original
    m = np.array(marks)
    work, read = np.diff(m[:, 0]), np.diff(m[:, 1])
    q = max(len(work) // 5, 1)

    def fifths(a):
        return [round(float(np.mean(a[i * q : (i + 1) * q])) * 1000, 1) for i in range(5)]

    equal = res.report.filter((pl.col("stage") == "findinghumo") & (pl.col("metric") == "online_equals_batch"))
    return {
        "polls": len(work),
        "cpu_s": round(float(work.sum()), 1),
        "ms_per_poll_by_fifth": fifths(work),
        "reader_ms_by_fifth": fifths(read),
        "equal": bool(equal["value"][0] == 1.0) if equal.height else None,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tiles", type=int, default=200)
    ap.add_argument("--speed", type=float, default=100.0)
    ap.add_argument("--decoding", choices=("lagged", "batch"), default="lagged")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        data = tiled_hallway(Path(tmp), args.tiles)
        edges = pl.read_csv(data / "motion.csv").height
        print(f"hallway x {args.tiles} ({edges} edges), replay {args.speed}x, findinghumo decoding = {args.decoding}")
        print(poll_costs(data, Path(tmp) / "out", speed=args.speed, decoding=args.decoding))


if __name__ == "__main__":
    main()
