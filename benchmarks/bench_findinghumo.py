"""FindingHuMo decoders: first-order Viterbi vs hmmlearn's C++ Viterbi, decoder time per slot
against graph size and user count, and the memory of the second-order decoder.

``python -m benchmarks.bench_findinghumo``. Times are best of a few repeats; the equality of
our path and hmmlearn's is checked on every model.
"""

from __future__ import annotations

import time
import tracemalloc

import networkx as nx
import numpy as np


def _best(fn, repeat=3):
    best = np.inf
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def viterbi_vs_hmmlearn(n_slots: int = 1000) -> None:
    from hmmlearn import _hmmc

    from onebit.models.graph_hmm import kernels
    from onebit.models.graph_hmm.viterbi import viterbi_first_order, viterbi_first_order_batch

    print(
        f"first-order Viterbi, {n_slots} slots: ours (compiled kernel; numpy reference beside) vs hmmlearn _hmmc.viterbi (C++)"
    )
    print(
        f"{'states':>7} {'ours ms':>9} {'hmmlearn ms':>12} {'ratio':>7} {'numpy ref ms':>13} {'batch of 10 numpy/each ms':>26}"
    )
    rng = np.random.default_rng(0)
    for s in (5, 20, 50, 100, 200, 400):
        pi = np.log(rng.dirichlet(np.ones(s)))
        a = np.log(rng.dirichlet(np.ones(s), size=s))
        b = np.log(rng.random((n_slots, s)) + 1e-3)
        kernels.viterbi_first_order(pi, a, b[:2])  # compiled (or loaded from the cache) outside the timing
        t_ours, (p_ours, lp) = _best(lambda: kernels.viterbi_first_order(pi, a, b))
        t_np, (p_np, _) = _best(lambda: viterbi_first_order(pi, a, b))
        pi_p, a_p = np.exp(pi), np.exp(a)  # _hmmc.viterbi takes probabilities and log frame probabilities
        t_ref, (lp_ref, p_ref) = _best(lambda: _hmmc.viterbi(pi_p, a_p, b))
        assert (
            np.array_equal(p_ours, p_ref) and np.array_equal(p_np, p_ref) and abs(lp - lp_ref) < 1e-6 * abs(lp_ref)
        ), "paths differ"
        bb = np.broadcast_to(b, (10, n_slots, s)).copy()
        t_batch, _ = _best(lambda: viterbi_first_order_batch(np.broadcast_to(pi, (10, s)), a, bb), repeat=1)
        print(
            f"{s:>7} {t_ours * 1e3:>9.2f} {t_ref * 1e3:>12.2f} {t_ours / t_ref:>7.2f} {t_np * 1e3:>13.2f} {t_batch * 1e3 / 10:>26.2f}"
        )


def _grid_site(n_nodes: int):
    """A corridor grid of about ``n_nodes`` nodes (rows of 10), as (nodes, edges, signatures)."""
    cols = 10
    rows = max(2, n_nodes // cols)
    g = nx.grid_2d_graph(rows, cols)
    nodes = tuple(f"{r}_{c}" for r, c in g.nodes)
    edges = tuple((f"{a[0]}_{a[1]}", f"{b[0]}_{b[1]}") for a, b in g.edges)
    return nodes, edges


def _walk_activity(hops: np.ndarray, users: int, n_slots: int, rng) -> np.ndarray:
    n = hops.shape[0]
    pos = rng.integers(0, n, size=users)
    act = np.zeros((n_slots, n), bool)
    for t in range(n_slots):  # synthetic data generation, sequential by nature
        move = rng.random(users) < 0.35
        for u in np.flatnonzero(move):
            nb = np.flatnonzero(hops[pos[u]] == 1)
            pos[u] = rng.choice(nb)
        act[t, pos] = True
    return act


def decoder_scaling(n_slots: int = 40) -> None:
    from onebit.models.graph_hmm.adaptive import DecoderParams, decode_run
    from onebit.models.graph_hmm.eatg import hop_matrix, layout_eatg

    print(f"\ndecoder time per slot (ms), {n_slots} slots, grid corridors, 2 sweeps, 1 restart (the default 6 restarts")
    print("cost up to 6x); real time is 1000 ms per slot")
    print(f"{'nodes':>6} {'users':>6} {'adaptive+2nd':>13} {'full 1st':>9} {'full 2nd':>9}")
    rng = np.random.default_rng(1)
    for n_nodes, users in ((20, 1), (20, 3), (20, 10), (100, 3), (100, 10), (200, 3), (200, 10), (500, 3)):
        nodes, edges = _grid_site(n_nodes)
        hops = hop_matrix(nodes, edges)
        eatg = layout_eatg(nodes, hops)
        act = _walk_activity(hops, users, n_slots, rng)
        row = []
        for mode in ("adaptive", "full1", "full2"):
            if mode == "full2" and len(nodes) > 100:
                row.append("   (skip)")
                continue
            t, _ = _best(lambda: decode_run(act, eatg, params=DecoderParams(mode=mode, sweeps=2, restarts=1)), repeat=1)
            row.append(f"{t / n_slots * 1e3:9.2f}")
        print(f"{len(nodes):>6} {users:>6} {row[0]:>13} {row[1]:>9} {row[2]:>9}")


def second_order_memory() -> None:
    from onebit.models.graph_hmm.viterbi import viterbi_motion_second_order

    print("\nsecond-order (distinct-node context) Viterbi memory (window of 7 slots; peak traced by tracemalloc)")
    print(f"{'states':>7} {'peak MiB':>9} {'model S^3 MiB':>14}")
    rng = np.random.default_rng(2)
    for s in (10, 20, 40, 80, 120):
        a2 = np.log(rng.dirichlet(np.ones(s), size=(s, s)))
        a1 = np.log(rng.dirichlet(np.ones(s), size=s))
        b = np.log(rng.random((7, s)))
        tracemalloc.start()
        viterbi_motion_second_order(np.zeros(s), np.diag(a1), a2, b)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"{s:>7} {peak / 2**20:>9.2f} {a2.nbytes / 2**20:>14.2f}")


def main() -> None:
    viterbi_vs_hmmlearn()
    decoder_scaling()
    second_order_memory()


if __name__ == "__main__":
    main()
