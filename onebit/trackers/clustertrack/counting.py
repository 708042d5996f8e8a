"""Target counting from one snapshot (Singh et al., section 3).

* :func:`greedy_min_targets` -- Theorem 4: sort the contributions g_i by right end point,
  take the first, delete every interval overlapping it, repeat. The picked intervals are a
  maximum set of pairwise disjoint g_i (= positively independent sensors, Theorem 3) and a
  target at the right end of each is a minimum set of targets consistent with F, so
  ``|T| = |S|``. O(n log n): one sort, then one jump per picked target (below).
* :func:`positively_independent` -- the pairwise relation of section 3.2.1.
* :func:`snapshot_bounds_1d` / :func:`snapshot_bounds_2d` -- per instant: the lower bound on
  the target count, and per component of F the lower bound on the targets inside it
  (Appendix B needs both).

Non-ideal sensing (R_i < R_o) can split a g_i into several intervals. The greedy then runs on
the convex hulls of the g_i: disjoint hulls are disjoint sets, so the count is still a valid
lower bound (exact, and equal to the minimum hitting set, in the ideal case where every
g_i is one interval). For the per-component bounds only sensors whose g_i lies in one
component count, since only those force a target into that component.

In 2-D both quantities are NP-hard (Appendix A); the bound used is the paper's: the number
of connected components of F, counting a component only when some on-sensor's whole g_i
lies inside it (only then must it hold a target).
"""

from __future__ import annotations

import numpy as np

from onebit.trackers.clustertrack.feasible import Feasible1D


def greedy_min_targets(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Theorem 4's greedy on closed intervals ``[lo_k, hi_k]``.

    Returns ``(picked, positions)``: indices of a maximum set of pairwise disjoint intervals
    (in the order picked) and the minimal target positions (their right end points).

    The greedy's next pick after a target at ``p`` is the interval with the smallest right
    end among those starting after ``p``: with the intervals sorted by ``lo`` and a suffix
    arg-minimum of ``hi``, it is one ``searchsorted``. The loop runs once per *picked* target
    (inherently sequential: each pick depends on the previous one), never over sensors.
    """
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    n = lo.size
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    o = np.argsort(lo, kind="stable")
    lo_s, hi_s = lo[o], hi[o]
    rev = hi_s[::-1]
    acc = np.minimum.accumulate(rev)
    at = np.maximum.accumulate(np.where(rev == acc, np.arange(n), 0))
    suffix_arg = (n - 1 - at)[::-1]  # suffix_arg[k]: index (sorted by lo) of min hi over k..n-1
    picked = []
    k = 0
    while k < n:
        j = suffix_arg[k]
        picked.append(o[j])
        k = int(np.searchsorted(lo_s, hi_s[j], side="right"))
    picked_a = np.asarray(picked, dtype=np.int64)
    return picked_a, hi[picked_a]


def positively_independent(f: Feasible1D, x: np.ndarray, r_outer: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Section 3.2.1: on-sensors ``i, j`` are positively independent when their sensing
    ranges are disjoint or their contributions lie in different components of F.

    Returns ``(sensors, matrix)``: the on-sensors with a non-empty g_i (indices into the
    sensor array) and the symmetric ``(m, m)`` boolean relation (diagonal False).
    """
    hull, s = f.hulls()
    if s.size == 0:
        return s, np.zeros((0, 0), dtype=bool)
    a = np.c_[x[s] - r_outer[s], x[s] + r_outer[s]]
    disjoint = (a[:, None, 1] < a[None, :, 0]) | (a[None, :, 1] < a[:, None, 0])
    comp = f.component_of((hull[:, 0] + hull[:, 1]) / 2.0)
    single = _single_component(f, s)
    other = single[:, None] & single[None, :] & (comp[:, None] != comp[None, :])
    rel = disjoint | other
    np.fill_diagonal(rel, False)
    return s, rel


def _single_component(f: Feasible1D, sensors: np.ndarray) -> np.ndarray:
    """For each sensor in ``sensors``: do all pieces of its g_i lie in one component?"""
    if f.pieces.size == 0:
        return np.zeros(sensors.size, dtype=bool)
    s, inv = np.unique(f.piece_sensor, return_inverse=True)
    cmin = np.full(s.size, np.iinfo(np.int64).max)
    cmax = np.full(s.size, -1)
    np.minimum.at(cmin, inv, f.piece_component)
    np.maximum.at(cmax, inv, f.piece_component)
    k = np.clip(np.searchsorted(s, sensors), 0, s.size - 1)
    return (s[k] == sensors) & (cmin == cmax)[k]


def snapshot_bounds_1d(f: Feasible1D) -> tuple[int, np.ndarray, np.ndarray]:
    """``(lower_bound, component_bounds, minimal_targets)`` of one 1-D snapshot.

    ``lower_bound``: Theorem 4's greedy on the hulls of the g_i. ``component_bounds[c]``:
    the greedy restricted to sensors whose g_i lies in component ``c``, counted per component.
    ``minimal_targets``: positions of a minimal set of targets (right end points).
    """
    hull, s = f.hulls()
    picked, pos = greedy_min_targets(hull[:, 0], hull[:, 1])
    nc = len(f.components)
    bounds = np.zeros(nc, dtype=np.int64)
    if s.size:
        single = _single_component(f, s)
        sub = np.flatnonzero(single)
        if sub.size:
            p2, pos2 = greedy_min_targets(hull[sub, 0], hull[sub, 1])
            c = f.component_of(pos2)
            bounds = np.bincount(c[c >= 0], minlength=nc).astype(np.int64)
    return int(picked.size), bounds, pos


def snapshot_bounds_2d(
    labels: np.ndarray, n_comp: int, on_idx: np.ndarray, outer: np.ndarray
) -> tuple[int, np.ndarray]:
    """``(lower_bound, component_bounds)`` of one 2-D raster snapshot.

    ``labels (cells,)``: component labels of F (0 outside, 1..n_comp); ``outer (n, cells)``:
    on-range masks; ``on_idx``: the on-sensors. A component is forced (bound 1) when the
    whole rasterised g_i of some on-sensor lies in it. Vectorised over sensors and cells.
    """
    bounds = np.zeros(n_comp, dtype=np.int64)
    if n_comp == 0 or on_idx.size == 0:
        return 0, bounds
    m = outer[on_idx] & (labels[None, :] > 0)
    big = np.iinfo(np.int64).max
    lmin = np.where(m, labels[None, :], big).min(axis=1)
    lmax = np.where(m, labels[None, :], -1).max(axis=1)
    forced = np.unique(lmin[(lmax >= 0) & (lmin == lmax)]) - 1
    bounds[forced] = 1
    return int(bounds.sum()), bounds
