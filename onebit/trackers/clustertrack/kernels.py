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
