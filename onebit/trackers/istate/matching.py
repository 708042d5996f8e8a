"""Perfect matchings of small bipartite graphs (the targets' regions against each other): the
dominance test of the clean-up and the communication update (:mod:`onebit.trackers.istate.core`).
"""

from __future__ import annotations

import itertools
from functools import lru_cache

import numpy as np

from onebit.core.lazy import lazy_module

nx = lazy_module("networkx")


#: Largest ``n`` for which matchings are found by enumerating the ``n!`` permutations in numpy.
PERM_TABLE_MAX_N = 5


@lru_cache(maxsize=16)
def permutations(n: int) -> np.ndarray:
    """``(n!, n)`` table of all permutations of ``range(n)`` (the symmetric group S_n)."""
    return np.array(list(itertools.permutations(range(n))), dtype=np.int64).reshape(-1, n)


def has_perfect_matching(adj: np.ndarray) -> np.ndarray:
    """Whether each ``n x n`` bipartite graph ``adj[..., k, l]`` has a perfect matching.

    For ``n <= PERM_TABLE_MAX_N`` all ``n!`` permutations are tested at once in numpy
    (``any_tau all_k adj[k, tau(k)]``); above it each graph goes to networkx's
    Hopcroft-Karp maximum matching (a loop over graphs, documented as such).
    """
    adj = np.asarray(adj, dtype=bool)
    n = adj.shape[-1]
    lead = adj.shape[:-2]
    if n == 0:
        return np.ones(lead, dtype=bool)
    flat = adj.reshape(-1, n, n)
    if n <= PERM_TABLE_MAX_N:
        perms = permutations(n)
        rows = np.arange(n)
        ok = flat[:, rows[None, :], perms].all(axis=-1).any(axis=-1)
        return ok.reshape(lead)
    out = np.empty(len(flat), dtype=bool)
    for i, a in enumerate(flat):
        out[i] = _nx_perfect(a)
    return out.reshape(lead)


def _nx_perfect(a: np.ndarray) -> bool:
    n = a.shape[0]
    g = nx.Graph()
    g.add_nodes_from(range(2 * n))
    k, l = np.nonzero(a)
    g.add_edges_from(zip(k.tolist(), (l + n).tolist()))
    m = nx.bipartite.hopcroft_karp_matching(g, top_nodes=range(n))
    return len(m) == 2 * n


def enumerate_perfect_matchings(adj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All perfect matchings of a batch of bipartite graphs ``adj (G, n, n)``.

    Returns ``(graph, match)``: ``match[j]`` (``(n,)``) is a perfect matching of graph
    ``graph[j]``, row ``k`` matched to column ``match[j, k]``. The enumeration extends every
    partial matching row by row over all graphs at once (a breadth-first backtracking in
    numpy), so its cost grows with the number of partial matchings, not with ``n!`` -- the
    output-sensitive enumeration the paper cites [3], [19]. Partial matchings that leave
    a later row without a free neighbour are pruned at once.
    """
    adj = np.asarray(adj, dtype=bool)
    G, n, _ = adj.shape
    graph = np.arange(G)
    match = np.zeros((G, 0), dtype=np.int64)
    used = np.zeros((G, n), dtype=bool)
    for k in range(n):
        cand = adj[graph, k, :] & ~used  # (P, n)
        p, col = np.nonzero(cand)
        graph, match, used = graph[p], np.c_[match[p], col], used[p].copy()
        used[np.arange(len(p)), col] = True
        if k + 1 < n and len(graph):
            # prune: every later row needs at least one free neighbour
            alive = (adj[graph, k + 1 :, :] & ~used[:, None, :]).any(axis=-1).all(axis=-1)
            graph, match, used = graph[alive], match[alive], used[alive]
    return graph, match
