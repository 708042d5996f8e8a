"""O'Kane I-state filter: step cost against n, M and sensing regions; communication update
against the direct O(M^2 n!) formula; batched shapely against a per-region loop.

1. **Filter step** (:func:`info_state_update`: motion update, observation update with
   clean-up and cap per detection) in a 10 x 8 room with two obstacles and 12 square sensing
   regions, after a warm-up of random stages so the I-state has grown to its cap; timed
   against n = 1..5 targets (M = 10), M = 1..50 (n = 3) and 1..8 detections per step.
2. **Communication update**: :func:`communicate` (perfect matchings of the
   non-empty-intersection graph) against :func:`communicate_bruteforce` (every element pair
   and every permutation) on random I-states of E = 10 elements, n = 1..5; both results are
   checked equal; printed: the ratio and the number of intersections each computes.
3. **Batching**: :func:`observation_update` (one vectorised shapely call over all E n
   regions) against the same update written as a Python loop over elements and regions.

Run with ``python -m benchmarks.bench_istate``.
"""

from __future__ import annotations

import time

import numpy as np
import shapely
from shapely.geometry import Point, box

from onebit._testing.oracles import communicate_bruteforce
from onebit.trackers.istate.core import (
    IState,
    clean_up,
    communicate,
    info_state_update,
    observation_update,
    same_elements,
)

ROOM = box(0, 0, 10, 8)
FREE = shapely.difference(ROOM, shapely.union_all([box(3, 2, 4, 6), box(6.5, 0, 7, 3)]))
REGIONS = [box(x - 1.6, y - 1.6, x + 1.6, y + 1.6) for x in (1.25, 3.75, 6.25, 8.75) for y in (1.35, 4.0, 6.65)]


def _timeit(fn, *, repeat: int = 3) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def grown_istate(n: int, M: int, *, seed: int = 0, stages: int = 25, shape: str = "rect") -> IState:
    """An I-state after ``stages`` stages of n targets on a random walk in FREE, every
    region holding a target detecting (capped at M)."""
    rng = np.random.default_rng(seed)
    eta = IState.initial(FREE, n)
    pos = np.column_stack([rng.uniform(0.2, 2.8, n), rng.uniform(0.2, 7.8, n)])
    for _ in range(stages):
        prop = pos + rng.uniform(-1, 1, (n, 2)) * 0.4 / np.sqrt(2)
        ok = shapely.contains_xy(FREE, prop[:, 0], prop[:, 1])
        pos = np.where(ok[:, None], prop, pos)
        hit = [r for r in REGIONS if shapely.contains_xy(r, pos[:, 0], pos[:, 1]).any()]
        eta = info_state_update(eta, hit, step=0.4, free_space=FREE, shape=shape, max_elements=M)
    return eta, pos


def detections_at(pos: np.ndarray, k: int) -> list:
    """Up to ``k`` regions holding a target at ``pos`` (consistent with the I-state)."""
    hit = [r for r in REGIONS if shapely.contains_xy(r, pos[:, 0], pos[:, 1]).any()]
    return (hit * k)[:k]


def bench_filter() -> None:
    print("filter step (rect regions): motion update + observation updates + clean-up + cap,")
    print("from a random I-state of E = M elements (n = 3 unless varied); last row: a grown exact-polygon I-state")
    print(f"{'n':>3} {'M':>4} {'det':>4} {'E':>4} {'ms/step':>9}   (E = elements before the step)")
    prev = None
    rng = np.random.default_rng(1)
    det2 = [box(2, 1, 6, 5), box(5, 3, 9, 7)]
    for n in (1, 2, 3, 4, 5):
        eta = random_istate(rng, 10, n)
        t = _timeit(lambda: info_state_update(eta, det2, step=0.4, free_space=FREE, shape="rect", max_elements=10))
        growth = f"  x{t / prev:.1f} vs n-1" if prev else ""
        prev = t
        print(f"{n:>3} {10:>4} {2:>4} {eta.size:>4} {t * 1e3:>9.2f}{growth}")
    for M in (1, 5, 10, 25, 50):
        eta = random_istate(rng, M, 3)
        t = _timeit(lambda: info_state_update(eta, det2, step=0.4, free_space=FREE, shape="rect", max_elements=M))
        print(f"{3:>3} {M:>4} {2:>4} {eta.size:>4} {t * 1e3:>9.2f}")
    eta = random_istate(rng, 10, 3)
    for d in (1, 2, 4, 8):
        det = [box(x, y, x + 4, y + 4) for x, y in rng.uniform([0, 0], [6, 4], (d, 2))]
        t = _timeit(lambda: info_state_update(eta, det, step=0.4, free_space=FREE, shape="rect", max_elements=10))
        print(f"{3:>3} {10:>4} {d:>4} {eta.size:>4} {t * 1e3:>9.2f}")
    eta, pos = grown_istate(3, 10, shape="exact")
    det2 = detections_at(pos, 2)
    t = _timeit(lambda: info_state_update(eta, det2, step=0.4, free_space=FREE, shape="exact", max_elements=10))
    print(f"exact polygons, n = 3, M = 10, E = {eta.size}: {t * 1e3:.2f} ms/step")


def random_istate(rng, E: int, n: int) -> IState:
    rows = []
    for _ in range(E):
        c = rng.uniform([0, 0], [10, 8], (n, 2))
        r = rng.uniform(0.8, 2.5, n)
        rows.append([box(x - s, y - s, x + s, y + s) for (x, y), s in zip(c, r)])
    return clean_up(IState.from_elements(rows), shape="rect")


def bench_communication() -> None:
    print("\ncommunication update: perfect matchings vs the direct O(Ea Eb n!) formula (E = 10 each)")
    print("(shape rect: ours intersects boxes in numpy; shape exact: both sides use shapely, so the")
    print(" ratio is the matching enumeration's alone)")
    print(f"{'shape':>6} {'n':>3} {'Ea':>3} {'Eb':>3} {'out':>5} {'matching ms':>12} {'direct ms':>10} {'ratio':>7}")
    for shape in ("rect", "exact"):
        rng = np.random.default_rng(2)
        for n in (1, 2, 3, 4, 5):
            a, b = random_istate(rng, 10, n), random_istate(rng, 10, n)
            fast = communicate(a, b, shape=shape)
            slow = communicate_bruteforce(a, b, shape=shape)
            assert same_elements(fast, slow), f"n = {n}: matching result differs from the direct formula"
            tf = _timeit(lambda: communicate(a, b, shape=shape))
            ts = _timeit(lambda: communicate_bruteforce(a, b, shape=shape), repeat=1 if n == 5 else 3)
            print(
                f"{shape:>6} {n:>3} {a.size:>3} {b.size:>3} {fast.size:>5} {tf * 1e3:>12.2f} {ts * 1e3:>10.2f} {ts / tf:>6.1f}x"
            )


def observation_loop(eta: IState, sensing) -> IState:
    """The peer: Algorithm 1 lines 10-14 as a Python loop, one shapely call per region."""
    rows = []
    for row in eta.regions:
        for j in range(eta.n):
            r = sensing.intersection(row[j])
            if not r.is_empty:
                new = list(row)
                new[j] = r
                rows.append(new)
    return IState.from_elements(rows, n=eta.n)


def bench_batching() -> None:
    print("\nobservation update: batched shapely vs a per-region Python loop (exact polygons)")
    print(f"{'E':>4} {'n':>3} {'batched ms':>11} {'loop ms':>9} {'ratio':>7}")
    rng = np.random.default_rng(3)
    S = Point(5, 4).buffer(2.5)
    for E, n in ((10, 3), (50, 5), (200, 5)):
        rows = [[Point(*rng.uniform([0, 0], [10, 8])).buffer(rng.uniform(1, 3)) for _ in range(n)] for _ in range(E)]
        eta = IState.from_elements(rows)
        a = observation_update(eta, S)
        b = observation_loop(eta, S)
        assert a.size == b.size
        tb = _timeit(lambda: observation_update(eta, S))
        tl = _timeit(lambda: observation_loop(eta, S))
        print(f"{E:>4} {n:>3} {tb * 1e3:>11.2f} {tl * 1e3:>9.2f} {tl / tb:>6.1f}x")


def main() -> None:
    bench_filter()
    bench_communication()
    bench_batching()


if __name__ == "__main__":
    main()
