"""Raw beam-log reader speed, side by side with the physical floor and a plain Python peer.

For ``N`` in (10^4, 10^5, 10^6) rows a raw beam log of the building site's 7 beams (a..g) is
generated (numpy, seeded, vectorised) and written to a temporary CSV with polars. Each beam
sees a sequence of passes; passes on different beams overlap in time, passes on one beam do
not. A pass is 4 edges:

* crossing (~98%): first pair blocked, other pair blocked, first pair cleared, other pair
  cleared (forward: first = ``a``; backward: first = ``b``);
* start-and-return (~2%): first blocked, other blocked, other cleared, first cleared.

Timed on the same file:

* **ours**: :func:`onebit.readers.beams.decode_beam_log` (read, type and check every row,
  reject no-change edges, decode passes, vectorised with polars);
* **read_csv**: ``pl.read_csv(path)`` -- the physical floor, parsing only;
* **peer**: a plain per-row Python implementation of the Fig. 7 machine (``csv`` module and a
  dict of per-beam states: IDLE -a-> A -b-> AB -a clear-> B -b clear-> IDLE + emit forward,
  the mirror for backward; AB -other clear-> back to the first state and first clear from
  there = start-and-return; any other transition goes back to IDLE).

Ours and the peer must give the same crossings (t, beam, direction) and the same number of
start-and-return passes; the benchmark asserts it. Peak memory is the growth of the resident
set's high-water mark during one call in a fresh interpreter (Linux: ``VmHWM`` after resetting
it through ``/proc/self/clear_refs``): polars allocates outside Python's allocator, so
``tracemalloc`` would miss it; ``ru_maxrss`` cannot be reset; and in this long-running process
freed pages kept by the allocator would hide the growth.

Timing: best of 3 (2 at 10^6 rows), fewer when a size takes more than ~10 s.

Run with ``python -m benchmarks.bench_reader``.
"""

from __future__ import annotations

import csv
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import polars as pl

from onebit.datasets.builtin import builtin_site
from onebit.readers.beams import decode_beam_log

SIZES = (10_000, 100_000, 1_000_000)
ABORT_FRACTION = 0.02
SEED = 0
MEM_MAX_S = 10.0


def generate_beam_log(n_rows: int, beam_ids: tuple[str, ...], *, seed: int = SEED) -> tuple[pl.DataFrame, int, int]:
    """Raw beam rows (t, beam, pair, blocked), sorted by t; returns (frame, crossings, aborted).

    ``n_rows`` is rounded down to a multiple of 4 (4 edges per pass). Vectorised: no loop per row.
    """
    rng = np.random.default_rng(seed)
    n_pass = n_rows // 4
    beam = rng.integers(0, len(beam_ids), n_pass)
    forward = rng.random(n_pass) < 0.5
    abort = rng.random(n_pass) < ABORT_FRACTION
    # durations: idle gap before the pass, then 3 inter-edge gaps (>= 0.05 s so one beam never ties)
    gap = 0.05 + rng.exponential(2.0, n_pass)
    steps = 0.05 + rng.exponential(0.1, (n_pass, 3))
    length = gap + steps.sum(axis=1)
    # passes on the same beam follow one another: start = per-beam cumulative length + gap
    per_beam = (
        pl.DataFrame({"beam": beam, "length": length})
        .select((pl.col("length").cum_sum().over("beam") - pl.col("length")).alias("start"))["start"]
        .to_numpy()
    )
    start = per_beam + gap
    offsets = np.concatenate([np.zeros((n_pass, 1)), np.cumsum(steps, axis=1)], axis=1)
    t = (start[:, None] + offsets).ravel()

    first = np.where(forward, 0, 1)  # 0 = a, 1 = b
    other = 1 - first
    # crossing: first, other, first, other; start-and-return: first, other, other, first
    pair = np.stack([first, other, np.where(abort, other, first), np.where(abort, first, other)], axis=1).ravel()
    blocked = np.tile(np.array([1, 1, 0, 0], dtype=np.int8), n_pass)
    beams = np.repeat(beam, 4)

    order = np.argsort(t, kind="stable")
    frame = pl.DataFrame(
        {
            "t": np.round(t[order], 6),
            "beam": np.asarray(beam_ids)[beams[order]],
            "pair": np.array(["a", "b"])[pair[order]],
            "blocked": blocked[order],
        }
    )
    n_abort = int(abort.sum())
    return frame, n_pass - n_abort, n_abort


# --------------------------------------------------------------------------- the peer


def peer_decode(path: Path, beam_ids: tuple[str, ...]) -> tuple[list[tuple[float, str, int]], int]:
    """Fig. 7 machine, one Python step per row. Returns (crossings (t, beam, direction), aborted)."""
    known = set(beam_ids)
    state = {b: "IDLE" for b in beam_ids}
    # (state, pair, blocked) -> next state; forward path starts on a, backward on b
    nxt = {
        ("IDLE", "a", "1"): "A",
        ("IDLE", "b", "1"): "B'",
        ("A", "b", "1"): "AB",
        ("AB", "a", "0"): "B",
        ("AB", "b", "0"): "A",  # returning: the other pair clears first
        ("B'", "a", "1"): "AB'",
        ("AB'", "b", "0"): "A'",
        ("AB'", "a", "0"): "B'",  # returning
    }
    crossings: list[tuple[float, str, int]] = []
    aborted = 0
    with open(path, newline="") as fh:
        rows = csv.reader(fh)
        header = next(rows)
        it, ib, ip, ik = (header.index(c) for c in ("t", "beam", "pair", "blocked"))
        for row in rows:
            beam = row[ib]
            if beam not in known:
                continue
            s = state[beam]
            pair, blk = row[ip], row[ik]
            if s == "B" and pair == "b" and blk == "0":
                crossings.append((float(row[it]), beam, 1))
                state[beam] = "IDLE"
            elif s == "A'" and pair == "a" and blk == "0":
                crossings.append((float(row[it]), beam, -1))
                state[beam] = "IDLE"
            elif (s == "A" and pair == "a" and blk == "0") or (s == "B'" and pair == "b" and blk == "0"):
                aborted += 1
                state[beam] = "IDLE"
            else:
                state[beam] = nxt.get((s, pair, blk), "IDLE")
    return crossings, aborted


# --------------------------------------------------------------------------- timing


def timed(fn, repeats: int, budget: float = 10.0) -> tuple[float, object]:
    """(best wall time, last result) of up to ``repeats`` calls; stops once ``budget`` s are spent."""
    best, out, spent = float("inf"), None, 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        dt = time.perf_counter() - t0
        best, spent = min(best, dt), spent + dt
        if spent > budget:
            break
    return best, out


_PEAK_SCRIPT = """
import re, sys
import polars as pl
from onebit.readers.beams import decode_beam_log

def kib(key):
    with open("/proc/self/status") as fh:
        return int(re.search(rf"^{key}:\\s+(\\d+)", fh.read(), re.M).group(1))

path, what, beams = sys.argv[1], sys.argv[2], tuple(sys.argv[3].split(","))
pl.read_csv(path, n_rows=10)  # warm polars up outside the measurement
with open("/proc/self/clear_refs", "w") as fh:
    fh.write("5")  # reset the high-water mark VmHWM to the current RSS
before = kib("VmRSS")
out = decode_beam_log(path, beams) if what == "ours" else pl.read_csv(path)
print((kib("VmHWM") - before) / 1024.0)
"""


def peak_mb(path: Path, what: str, beam_ids: tuple[str, ...]) -> float | None:
    """Peak resident-memory growth (MB) of one call in a fresh interpreter; None if unsupported.

    Linux only: the high-water mark is reset through ``/proc/self/clear_refs`` after import and
    ``VmHWM - VmRSS(before)`` read after the call. A fresh process keeps freed pages of earlier
    work (allocator arenas) from hiding the growth.
    """
    try:
        out = subprocess.run(
            [sys.executable, "-c", _PEAK_SCRIPT, str(path), what, ",".join(beam_ids)],
            capture_output=True,
            text=True,
            check=True,
            timeout=600,
        )
        return float(out.stdout.strip())
    except (subprocess.SubprocessError, OSError, ValueError):
        return None


def _mb(v: float | str | None) -> str:
    return "n/a" if v is None else v if isinstance(v, str) else f"{v:.0f}"


def main() -> None:
    site = builtin_site("building")
    beam_ids = site.beam_ids
    print(f"beam-log reader vs pl.read_csv floor vs per-row Python peer, building site, beams {','.join(beam_ids)}")
    header = (
        f"{'N rows':>9} {'ours s':>8} {'read_csv s':>10} {'peer s':>8} {'ours/csv':>9} {'peer/ours':>9} "
        f"{'ours rows/s':>12} {'ours MB':>8} {'csv MB':>7} {'crossings':>9} {'aborted':>7}"
    )
    print(header)
    with tempfile.TemporaryDirectory() as tmp:
        for n in SIZES:
            frame, n_cross, n_abort = generate_beam_log(n, beam_ids)
            path = Path(tmp) / f"beams_{n}.csv"
            frame.write_csv(path)
            del frame
            repeats = 3 if n < 1_000_000 else 2
            t_ours, res = timed(lambda: decode_beam_log(path, beam_ids), repeats)
            t_csv, _ = timed(lambda: pl.read_csv(path), repeats)
            t_peer, (peer_cross, peer_abort) = timed(lambda: peer_decode(path, beam_ids), repeats)
            # memory costs one more call in a fresh process: skipped when a call takes > MEM_MAX_S
            mb_ours = peak_mb(path, "ours", beam_ids) if t_ours <= MEM_MAX_S else "skip"
            mb_csv = peak_mb(path, "csv", beam_ids)

            ours_cross = list(res.crossings.select("t", "beam", "direction").iter_rows())
            assert res.rejects.height == 0, res.rejects.head()
            assert res.unfinished.height == 0
            assert [(b, d) for _, b, d in ours_cross] == [(b, d) for _, b, d in peer_cross], "crossings differ"
            assert [t for t, _, _ in ours_cross] == [t for t, _, _ in peer_cross], "crossing times differ"
            assert len(ours_cross) == n_cross and res.aborted.height == peer_abort == n_abort

            print(
                f"{n:>9} {t_ours:>8.3f} {t_csv:>10.3f} {t_peer:>8.3f} {t_ours / t_csv:>9.1f} {t_peer / t_ours:>9.2f} "
                f"{n / t_ours:>12.3g} {_mb(mb_ours):>8} {_mb(mb_csv):>7} {n_cross:>9} {n_abort:>7}"
            )
    print(
        "ours/csv: time of the full reader over bare parsing (>1: slower than the floor); "
        "peer/ours: speed-up of ours over the per-row Python machine.\n"
        f"MB: peak resident-memory growth of one call in a fresh process (VmHWM reset via /proc/self/clear_refs); "
        f"page-granular, so ~0 for small files; 'skip' when one call of ours takes over {MEM_MAX_S:g} s.\n"
        "crossings and start-and-return counts of ours and the peer agree (asserted), crossing by crossing."
    )


if __name__ == "__main__":
    main()
