"""Counting-automaton error correction (section V): time and memory against string length and
agent count, side by side with a plain breadth-first search.

Input (seeded, not timed): on the building's region graph (6 regions, 7 beams), ``n`` agents
take random walks, one random agent moving at a time, for ``m / 0.95`` crossings; 5 % of the
crossings are then dropped. ``eta_0`` is unknown (every count vector with sum n is a start);
placement is the default ``"midpoint"`` (on ranks: no times are given).

Timed:

* **ours**: :func:`onebit.trackers.beams.counting.correct` -- DP over the reachable count
  states only, runs without deficits skipped in one vectorised step, dominance pruning;
* **peer**: 0-1 breadth-first search over (position, full count vector) where consuming the
  next crossing costs 0 and inserting any crossing costs 1, no pruning (only on the small end:
  it grows with ``m * |I_C| * |edges|``).

Both must find the same number of insertions (asserted). Printed: seconds, peak traced memory
(``tracemalloc``, a second untimed run, up to m = 10^4), peak live count states, peer/ours time ratio, and the growth of ours' time
from the previous size (10 = linear in m).

Run with ``python -m benchmarks.bench_counting``.
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np

from onebit.core.region_graph import build_region_graph
from onebit.datasets.builtin import builtin_site
from onebit.trackers.beams.counting import RegionEdges, correct, count_space_size, count_states, min_insertions_bfs

SIZES = (1_000, 10_000, 100_000)
AGENTS = (2, 3, 4, 5, 6)
DROP = 0.05
#: (m, n) pairs on which the peer runs (it is quadratic-ish and pure Python).
PEER = {(1_000, 2), (1_000, 3), (1_000, 4), (10_000, 2)}
#: memory is traced (a second run) up to this m; tracemalloc slows the 10^5 runs ~10x.
MEMORY_UP_TO = 10_000


def dropped_walks(edges: RegionEdges, m: int, n: int, *, seed: int = 0):
    """(src, tgt, number dropped): random walks of n agents with DROP of the crossings removed."""
    rng = np.random.default_rng(seed)
    p = edges.n_regions
    out = [np.flatnonzero(edges.edge_source == r) for r in range(p)]
    total = int(m / (1 - DROP))
    pos = rng.integers(0, p, n)
    who = rng.integers(0, n, total).tolist()
    pick = rng.random(total).tolist()
    ids = np.empty(total, dtype=np.int64)
    for j in range(total):  # input generation, not timed
        o = out[pos[who[j]]]
        e = o[int(pick[j] * len(o))]
        ids[j] = e
        pos[who[j]] = edges.edge_target[e]
    keep = rng.random(total) >= DROP
    return edges.edge_source[ids][keep], edges.edge_target[ids][keep], int((~keep).sum())


def peer_bfs(src, tgt, edges: RegionEdges, n: int) -> int:
    """Plain 0-1 BFS over (position, count vector) from every eta_0 with sum n."""
    return min_insertions_bfs(src, tgt, edges, count_states(edges.n_regions, n))


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _peak_mb(fn) -> float:
    """Peak traced allocation of a second, untimed call (tracemalloc slows numpy-heavy code)."""
    tracemalloc.start()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / 1e6


def main() -> None:
    edges = RegionEdges.from_region_graph(build_region_graph(builtin_site("building")))
    src, tgt, _ = dropped_walks(edges, 100, 2)
    correct(src, tgt, edges, n_agents=2, compiled=True)  # numba's start and the cached DP, outside the timing
    print(
        f"building: {edges.n_regions} regions, {len(edges.edge_source)} labelled edges, drop {DROP:.0%}, eta_0 unknown"
    )
    print(
        f"{'m':>7} {'n':>2} {'|I_C|':>5} {'dropped':>7} {'inserted':>8} {'ours s':>8} {'ours MB':>8} {'peak K':>6} "
        f"{'growth':>6} {'peer s':>8} {'peer MB':>8} {'peer/ours':>9}"
    )
    prev: dict[int, float] = {}
    for n in AGENTS:
        for m in SIZES:
            src, tgt, nd = dropped_walks(edges, m, n, seed=m + n)
            res, t_ours = _timed(lambda: correct(src, tgt, edges, n_agents=n))
            mb_ours = _peak_mb(lambda: correct(src, tgt, edges, n_agents=n)) if m <= MEMORY_UP_TO else float("nan")
            growth = f"{t_ours / prev[n]:.1f}" if n in prev else "-"
            prev[n] = t_ours
            peer = ("-", "-", "-")
            if (m, n) in PEER:
                cost, t_peer = _timed(lambda: peer_bfs(src, tgt, edges, n))
                mb_peer = _peak_mb(lambda: peer_bfs(src, tgt, edges, n)) if m <= 1_000 else float("nan")
                assert cost == res.cost, f"peer found {cost} insertions, ours {res.cost} (m={m}, n={n})"
                peer = (f"{t_peer:.3f}", f"{mb_peer:.1f}", f"{t_peer / t_ours:.0f}x")
            print(
                f"{len(src):>7} {n:>2} {count_space_size(edges.n_regions, n):>5} {nd:>7} {res.cost:>8} "
                f"{t_ours:>8.3f} {mb_ours:>8.1f} {res.peak_states:>6} {growth:>6} {peer[0]:>8} {peer[1]:>8} {peer[2]:>9}",
                flush=True,
            )


if __name__ == "__main__":
    main()
