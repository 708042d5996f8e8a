"""Compiled (numba) kernel of CLUSTERTRACK's scan (Algorithm 1, steps 3-18).

The scan is inherently sequential: whether a candidate founds a cluster depends on the heads
founded before it, and the scan stops once ``K`` particles are kept. The vectorised numpy
scan (:func:`onebit.trackers.clustertrack.algorithm.scan_clusters_reference`) compares every
head with *every* later candidate, even those after the ``K``-th kept one; this kernel walks
the candidates in cost order and stops there, so a step costs ``O(scanned x heads)`` with no
temporaries. It keeps the numpy scan as its plain reference and test oracle
(``tests/trackers/clustertrack/test_kernels.py``: equal kept particles, labels, heads and
scan counts on random inputs): the same distance
``D = (pd[parent_a, parent_b] + ||x_a - x_b||) / t`` in the same order of operations, the
nearest head with the lowest index on ties, a new head when that distance is ``>= D_0``.
"""

from __future__ import annotations

import math

import numpy as np

from onebit.core.compiled import kernel


@kernel
def scan_sorted(par, xs, pd, steps, H, K, D0):
    """Scan candidates already in scan order (``par (m,)`` parents, ``xs (m, dim)`` positions).

    Returns ``(kept, label, is_head, scanned)``: positions in scan order of the kept
    candidates, their cluster ids (in order of foundation), whether each is its cluster's
    head, and how many candidates were scanned (``m`` unless ``K`` were kept first).
    """
    m = par.shape[0]
    dim = xs.shape[1]
    cap = min(K, m)
    heads = np.empty(cap, dtype=np.int64)
    counts = np.empty(cap, dtype=np.int64)
    kept = np.empty(cap, dtype=np.int64)
    label = np.empty(cap, dtype=np.int64)
    is_head = np.empty(cap, dtype=np.bool_)
    nh = 0
    nk = 0
    scanned = m
    for r in range(m):
        best = np.inf
        bh = -1
        pr = par[r]
        for h in range(nh):
            hp = heads[h]
            s = 0.0
            for q in range(dim):
                dv = xs[r, q] - xs[hp, q]
                s += dv * dv
            d = (pd[pr, par[hp]] + math.sqrt(s)) / steps
            if d < best:
                best = d
                bh = h
        if nh == 0 or best >= D0:  # no head within D0: found a cluster (always kept)
            heads[nh] = r
            counts[nh] = 1
            kept[nk], label[nk], is_head[nk] = r, nh, True
            nh += 1
            nk += 1
        elif counts[bh] < H:
            counts[bh] += 1
            kept[nk], label[nk], is_head[nk] = r, bh, False
            nk += 1
        if nk >= K:
            scanned = r + 1
            break
    return kept[:nk], label[:nk], is_head[:nk], scanned


@kernel
def candidate_costs(x, last1, last2, cost, m_t, curvature):
    """Cost of every candidate (section 4.2.1): candidate ``a m_t + j`` extends particle ``a``
    by ``x[a m_t + j]``; its cost is ``cost[a] + ||x + x[n-1] - 2 x[n]||`` (``curvature``) or
    ``cost[a]`` (the first two instants). The plain reference is
    :func:`onebit.trackers.clustertrack.algorithm.candidate_costs_reference` (same operations in
    the same order: equal costs)."""
    n, dim = x.shape[0], x.shape[1]
    out = np.empty(n)
    for r in range(n):
        a = r // m_t
        if curvature:
            s = 0.0
            for q in range(dim):
                v = (x[r, q] + last2[a, q]) - 2.0 * last1[a, q]
                s = v * v if q == 0 else s + v * v
            out[r] = cost[a] + math.sqrt(s)
        else:
            out[r] = cost[a] + 0.0
    return out


@kernel
def summed_distances(pd, par, xk):
    """``pd[par][:, par] + ||xk_a - xk_b||`` for the kept particles (their summed distances up to
    this instant); reference
    :func:`onebit.trackers.clustertrack.algorithm.summed_distances_reference`."""
    k, dim = xk.shape[0], xk.shape[1]
    out = np.empty((k, k))
    for a in range(k):
        for b in range(k):
            s = 0.0
            for q in range(dim):
                v = xk[a, q] - xk[b, q]
                s = v * v if q == 0 else s + v * v
            out[a, b] = pd[par[a], par[b]] + math.sqrt(s)
    return out
