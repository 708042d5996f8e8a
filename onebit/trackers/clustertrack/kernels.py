"""Compiled (numba) kernels of CLUSTERTRACK's pass (Algorithm 1): the scan (steps 3-18), the
candidates' costs, the survivors' summed distances and the mapping of the random draws onto F.

The scan is inherently sequential: whether a candidate founds a cluster depends on the heads
founded before it, and the scan stops once ``K`` particles are kept. The vectorised numpy
scan (:func:`onebit.trackers.clustertrack.algorithm.scan_clusters_reference`) compares every
head with *every* later candidate, even those after the ``K``-th kept one. :func:`scan_sorted`
walks candidates already sorted and stops there (``scan_clusters``' compiled path);
:func:`scan_step`, the pass's one call per instant, sorts only the start of the order and
visits the rest only where a candidate is *live* (would found a head or join a cluster that
is not full), so an instant costs ``O(L x heads)`` plus the live candidates, not a sort of
``L``. Both keep the numpy scan as their plain reference and test oracle
(``tests/trackers/clustertrack/test_kernels.py``: equal kept particles, labels, heads, scan
counts and summed distances on random inputs): the same distance
``D = (pd[parent_a, parent_b] + ||x_a - x_b||) / t`` in the same order of operations, the
nearest head with the lowest index on ties, a new head when that distance is ``>= D_0``. The
random draws themselves stay numpy's (:mod:`onebit.trackers.clustertrack.algorithm`), so a
compiled pass gives the numpy pass's result.
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


@kernel
def kth_smallest(key, k):
    """The ``k``-th smallest value of ``key`` (0-based): ``np.partition(key, k)[k]``, by
    quickselect on a copy (numba's ``np.partition`` cost ten times numpy's here)."""
    a = key.copy()
    lo, hi = 0, a.size - 1
    while lo < hi:
        mid = (lo + hi) // 2  # median of three as the pivot
        x, y, z = a[lo], a[mid], a[hi]
        piv = max(min(x, y), min(max(x, y), z))
        i, j = lo, hi
        while i <= j:
            while a[i] < piv:
                i += 1
            while a[j] > piv:
                j -= 1
            if i <= j:
                a[i], a[j] = a[j], a[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            return a[k]
    return a[k]


@kernel
def ordered_prefix(key, k):
    """The first ``k`` of ``np.argsort(key, kind="stable")``: every position with a key below
    the ``k``-th smallest value, then the first positions holding that value, by key then
    position (a stable sort gives one answer, so this equals
    :func:`onebit.trackers.clustertrack.algorithm.ordered_prefix`, its reference)."""
    n = key.size
    if k >= n:
        return np.argsort(key, kind="mergesort")
    if k <= 0:
        return np.zeros(0, dtype=np.int64)
    return ordered_prefix_at(key, k, kth_smallest(key, k - 1))


@kernel
def ordered_prefix_at(key, k, v):
    """:func:`ordered_prefix` given ``v``, the ``k``-th smallest key (``0 < k < len(key)``)."""
    n = key.size
    nb = 0
    for i in range(n):
        if key[i] < v:
            nb += 1
    idx = np.empty(k, dtype=np.int64)  # by position: the keys below v and the first k - nb at v
    na = 0
    at = 0
    for i in range(n):
        if key[i] < v:
            idx[na] = i
            na += 1
        elif key[i] == v and at < k - nb:
            idx[na] = i
            na += 1
            at += 1
    kv = np.empty(na)
    for i in range(na):
        kv[i] = key[idx[i]]
    return idx[np.argsort(kv, kind="mergesort")]


@kernel
def _head_distance(i, j, par, sel, x, pd, steps):
    """``D`` between candidates ``sel[i]`` and ``sel[j]`` as :func:`scan_sorted` computes it."""
    a, b = sel[i], sel[j]
    s = 0.0
    for q in range(x.shape[1]):
        dv = x[a, q] - x[b, q]
        s += dv * dv
    return (pd[par[i], par[j]] + math.sqrt(s)) / steps


@kernel
def _before(key, i, j):
    """Whether position ``i`` comes before ``j`` in the stable order of ``key``."""
    return key[i] < key[j] or (key[i] == key[j] and i < j)


@kernel
def _sift_down(heap, v, size, key, ri):
    """Restore the min-heap ``heap[:size]`` (of indices into ``ri``, by scan order) below ``v``."""
    while True:
        c = 2 * v + 1
        if c >= size:
            return
        if c + 1 < size and _before(key, ri[heap[c + 1]], ri[heap[c]]):
            c += 1
        if _before(key, ri[heap[c]], ri[heap[v]]):
            heap[c], heap[v] = heap[v], heap[c]
            v = c
        else:
            return


@kernel
def _sift_up(heap, v, key, ri):
    """Restore the min-heap after a push at ``v``."""
    while v > 0:
        up = (v - 1) // 2
        if _before(key, ri[heap[v]], ri[heap[up]]):
            heap[up], heap[v] = heap[v], heap[up]
            v = up
        else:
            return


@kernel
def _scan_prefix(o, par, sel, x, pd, steps, H, K, D0, heads, counts, kept, label, is_head):
    """The sorted prefix ``o`` of the scan order, scanned in turn (:func:`scan_sorted`'s loop):
    each candidate founds a head (nearest head ``>= D_0``), joins its nearest cluster if it
    holds fewer than ``H``, or is dropped. Fills ``heads``/``counts``/``kept``/``label``/
    ``is_head``; returns ``(heads, kept, scanned, stop)`` counts, ``stop`` the candidate at
    which the ``K``-th was kept (-1: not reached, ``scanned`` then ``sel.size``)."""
    nh = 0
    nk = 0
    scanned = sel.size
    stop = -1
    for r in range(o.size):
        i = o[r]
        best = np.inf
        bh = -1
        for h in range(nh):
            d = _head_distance(i, heads[h], par, sel, x, pd, steps)
            if d < best:
                best = d
                bh = h
        if nh == 0 or best >= D0:
            heads[nh] = i
            counts[nh] = 1
            kept[nk], label[nk], is_head[nk] = i, nh, True
            nh += 1
            nk += 1
        elif counts[bh] < H:
            counts[bh] += 1
            kept[nk], label[nk], is_head[nk] = i, bh, False
            nk += 1
        if nk >= K:
            scanned = r + 1
            stop = i
            break
    return nh, nk, scanned, stop


@kernel
def _nearest_heads(ri, heads, nh, par, sel, x, pd, steps):
    """``(best, head)``: each candidate ``ri[u]``'s distance to its nearest head so far and
    that head (``inf``, -1 without heads)."""
    m = ri.size
    best_r = np.full(m, np.inf)
    bh_r = np.full(m, -1, dtype=np.int64)
    for h in range(nh):
        for u in range(m):
            d = _head_distance(ri[u], heads[h], par, sel, x, pd, steps)
            if d < best_r[u]:
                best_r[u] = d
                bh_r[u] = h
    return best_r, bh_r


@kernel
def _after_new_head(
    i, h, key, ri, par, sel, x, pd, steps, H, D0, best_r, bh_r, heap, in_heap, near, counts, size, free, live
):
    """Head ``h`` founded by candidate ``i``: every candidate after ``i`` in the scan order
    whose nearest head it becomes is updated -- its old state taken out of the live counts,
    pushed on the heap if it became live, its new state counted. Returns ``(size, free, live)``."""
    for w in range(ri.size):
        if not _before(key, i, ri[w]):
            continue
        d = _head_distance(ri[w], i, par, sel, x, pd, steps)
        if d >= best_r[w]:
            continue
        if in_heap[w]:  # take its old state out of the counts
            if best_r[w] >= D0:
                free -= 1
                live -= 1
            else:
                near[bh_r[w]] -= 1
                if counts[bh_r[w]] < H:
                    live -= 1
        best_r[w] = d
        bh_r[w] = h
        if best_r[w] >= D0 or counts[h] < H:
            if not in_heap[w]:
                in_heap[w] = True
                heap[size] = w
                size += 1
                _sift_up(heap, size - 1, key, ri)
        if in_heap[w]:
            if best_r[w] >= D0:
                free += 1
                live += 1
            else:
                near[h] += 1
                if counts[h] < H:
                    live += 1
    return size, free, live


@kernel
def _scan_rest(o, key, par, sel, x, pd, steps, H, K, D0, heads, counts, kept, label, is_head, nh, nk):
    """The candidates after the sorted prefix ``o``, scanned through a heap of the live ones
    (:func:`scan_step`'s docstring). Continues the fills of :func:`_scan_prefix` from ``nh``
    heads and ``nk`` kept; returns ``(heads, kept, stop)`` as it does."""
    n = sel.size
    stop = -1
    rest = np.ones(n, dtype=np.bool_)
    for r in range(o.size):
        rest[o[r]] = False
    ri = np.flatnonzero(rest)
    m = ri.size
    best_r, bh_r = _nearest_heads(ri, heads, nh, par, sel, x, pd, steps)
    # the live candidates (that would found a head or join a cluster not yet full) in a
    # heap by scan order; `live` counts those in the heap, through `free` (would found)
    # and `near[h]` (nearest head h, within D0); the scan ends when none is left
    heap = np.empty(m, dtype=np.int64)  # indices into ri
    in_heap = np.zeros(m, dtype=np.bool_)
    near = np.zeros(heads.size, dtype=np.int64)
    free = 0
    live = 0
    size = 0
    for u in range(m):
        if best_r[u] >= D0 or counts[bh_r[u]] < H:
            heap[size] = u
            size += 1
            in_heap[u] = True
            if best_r[u] >= D0:
                free += 1
                live += 1
            else:
                near[bh_r[u]] += 1
                live += 1
    for v in range(size // 2 - 1, -1, -1):
        _sift_down(heap, v, size, key, ri)
    while live > 0:
        u = heap[0]  # the next live-or-not candidate in scan order
        size -= 1
        heap[0] = heap[size]
        _sift_down(heap, 0, size, key, ri)
        in_heap[u] = False
        if best_r[u] >= D0:
            free -= 1
            live -= 1
        else:
            near[bh_r[u]] -= 1
            if counts[bh_r[u]] < H:
                live -= 1
        i = ri[u]
        if best_r[u] >= D0:  # founds a cluster; later candidates compare with it too
            h = nh
            heads[nh] = i
            counts[nh] = 1
            kept[nk], label[nk], is_head[nk] = i, nh, True
            nh += 1
            nk += 1
            if nk >= K:
                stop = i
                break
            size, free, live = _after_new_head(
                i,
                h,
                key,
                ri,
                par,
                sel,
                x,
                pd,
                steps,
                H,
                D0,
                best_r,
                bh_r,
                heap,
                in_heap,
                near,
                counts,
                size,
                free,
                live,
            )
        elif counts[bh_r[u]] < H:  # joins its nearest cluster
            h = bh_r[u]
            counts[h] += 1
            kept[nk], label[nk], is_head[nk] = i, h, False
            nk += 1
            if counts[h] == H:  # full: its near candidates are no longer live
                live -= near[h]
            if nk >= K:
                stop = i
                break
    return nh, nk, stop


@kernel
def scan_step(key, sel, x, m_t, pd, steps, H, K, D0, first, v):
    """Steps 3-18 of Algorithm 1 and the survivors' summed distances, in one call per instant.

    ``sel`` the candidates to scan before they are ordered
    (:func:`onebit.trackers.clustertrack.algorithm.scan_selection`; candidate ``i`` extends
    particle ``i // m_t`` by ``x[i]``), ``key = cost[sel]``; the scan order is the stable
    order of ``key``. ``first``: how many to sort first, ``v``: the ``first``-th smallest key
    when ``first < len(sel)`` (numpy's partition finds it faster than a kernel; see
    :func:`onebit.trackers.clustertrack.algorithm.fused_scan`). Returns ``(kept, label, is_head, scanned, pd_new,
    max_cluster)``: kept candidate indices in scan order, their cluster ids, heads,
    candidates scanned, the kept particles' summed distances (:func:`summed_distances`) and
    the largest cluster's size -- what the numpy pass computes
    (:func:`onebit.trackers.clustertrack.algorithm.scan_clusters_reference`, then
    ``summed_distances_reference``), with the same distances in the same order of operations.

    Cost follows what the scan keeps, not what it passes over. The first ``first``
    candidates of the order are sorted (:func:`ordered_prefix`) and scanned in turn. If ``K``
    are not kept by then, the rest are not sorted: each gets its nearest head so far at once,
    and only the *live* ones -- that would found a head (nearest head ``>= D_0``) or join a
    cluster holding fewer than ``H`` -- go into a heap by scan order. Every other candidate
    would join a full cluster and be dropped, so where it lies in the order changes nothing
    -- unless a later head becomes its nearest: a new head updates the candidates after it
    and pushes those it makes live. The scan pops the heap (skipping what has gone dead as
    clusters filled) until no live candidate is left or ``K`` are kept. A scan that
    collapses into full clusters (the usual first run) thus costs ``O(L x heads)`` per
    instant plus the live candidates' heap, instead of a sort of ``L``."""
    n = sel.size
    par = np.empty(n, dtype=np.int64)
    for i in range(n):
        par[i] = sel[i] // m_t
    cap = min(K, n)
    heads = np.empty(cap, dtype=np.int64)  # positions in sel
    counts = np.empty(cap, dtype=np.int64)
    kept = np.empty(cap, dtype=np.int64)  # positions in sel, in scan order
    label = np.empty(cap, dtype=np.int64)
    is_head = np.empty(cap, dtype=np.bool_)
    o = np.argsort(key, kind="mergesort") if first >= n else ordered_prefix_at(key, first, v)
    nh, nk, scanned, stop = _scan_prefix(o, par, sel, x, pd, steps, H, K, D0, heads, counts, kept, label, is_head)
    if stop < 0 and o.size < n:
        nh, nk, stop = _scan_rest(o, key, par, sel, x, pd, steps, H, K, D0, heads, counts, kept, label, is_head, nh, nk)
        if stop >= 0:  # its rank in the order
            scanned = 0
            for i in range(n):
                if not _before(key, stop, i):
                    scanned += 1
    out = np.empty(nk, dtype=np.int64)
    pk = np.empty(nk, dtype=np.int64)
    for a in range(nk):
        out[a] = sel[kept[a]]
        pk[a] = out[a] // m_t
    pd_new = summed_distances(pd, pk, np.ascontiguousarray(x[out]))
    biggest = 0
    for h in range(nh):
        biggest = max(biggest, counts[h])
    return out, label[:nk].copy(), is_head[:nk].copy(), scanned, pd_new, biggest


@kernel
def map_intervals(u, iv, total):
    """Points ``iv[k, 0] + u' - (cum[k] - length[k])``, ``u' = u total``, ``k`` the interval
    holding ``u'`` in the cumulative lengths: the mapping of
    :func:`onebit.trackers.clustertrack.feasible.sample_intervals` (its reference; the same
    operations, so equal points), found by counting over the few intervals of F instead of
    one binary search per draw."""
    c = iv.shape[0]
    length = np.empty(c)
    cum = np.empty(c)
    acc = 0.0
    for k in range(c):
        length[k] = iv[k, 1] - iv[k, 0]
        acc = length[k] if k == 0 else acc + length[k]
        cum[k] = acc
    out = np.empty(u.size)
    for r in range(u.size):
        v = u[r] * total
        k = 0
        if c <= 16:  # searchsorted(cum, v, side="right"): cum is sorted, so count the ends <= v
            for j in range(c):  # (no early exit: no branch to mispredict)
                k += cum[j] <= v
        else:
            k = np.searchsorted(cum, v, side="right")
        k = min(k, c - 1)
        out[r] = iv[k, 0] + v - (cum[k] - length[k])
    return out


@kernel
def jitter_cells(xy, k, u, cell):
    """``xy[k] + (u - 0.5) cell``: cell centres ``xy (m, 2)`` drawn by ``k (n,)``, each moved
    uniformly inside its cell by ``u (n, 2)`` -- the arithmetic of
    :func:`onebit.trackers.clustertrack.feasible.sample_cell_centres` (its reference; the same
    operations, so equal points) in one pass instead of four temporaries."""
    n = k.size
    out = np.empty((n, 2))
    for r in range(n):
        for q in range(2):
            out[r, q] = xy[k[r], q] + (u[r, q] - 0.5) * cell
    return out
