"""Joining the filter's reported tracklets across short gaps (one min-cost assignment).

A Bernoulli track dies when its person is silent for a few frames (between sensors, standing
still) and a new one is born when they fire again: two tracklets, one person. Tracklet
:math:`A` (last reported at frame :math:`e_A`, position :math:`q_A`) may continue as tracklet
:math:`B` (first reported at :math:`s_B`, position :math:`p_B`) when

.. math::

    1 \\le s_B - e_A \\le g_{\\max} + 1, \\qquad
    \\lVert p_B - q_A \\rVert \\le v_{\\max} \\Delta (s_B - e_A) + \\rho,

(``max_gap`` frames missing at most, a walking speed ``max_speed`` and a slack
:math:`\\rho` of one footprint), at cost

.. math::

    c_{AB} = \\lVert p_B - q_A \\rVert + \\lambda \\, (s_B - e_A - 1),

with :math:`\\lambda = v_{\\max} \\Delta / 2` per missing frame. Every end is joined to at
most one start and every start to at most one end by one minimum-cost assignment
(infeasible pairs left out); chains of joined
tracklets take the label of their first tracklet. The missing frames of a join are filled by
linear interpolation between :math:`q_A` and :math:`p_B` -- a frame is filled only while
fewer than ``max_out`` tracks are reported there, so the bound still holds.

Cost linear in the log. Only ends and starts at most ``max_gap + 1`` frames apart can join,
so the feasible pairs are found by one sorted search per end (:func:`join_pairs`, not the
``(ends, starts)`` matrix of :func:`join_costs`, which grew as the square of the log: 2.4 GB
and 10 s on 47 500 frames of the simulated line), and the assignment is a sparse one
(:func:`best_joins_sparse`: ``scipy.sparse.csgraph.min_weight_full_bipartite_matching`` on
the pairs plus one "unmatched" edge per end and per start). It gives the dense assignment's
joins (:func:`best_joins`, its reference and test oracle: the largest matching, then the
cheapest), the same pairs whenever that cheapest matching is unique.
"""

from __future__ import annotations

import numpy as np

from onebit.core.lazy import lazy_module

_optimize = lazy_module("scipy.optimize")  # loaded when a run links, not when the CLI starts
_sparse = lazy_module("scipy.sparse")
_csgraph = lazy_module("scipy.sparse.csgraph")


def tracklet_ends(frame: np.ndarray, label: np.ndarray, x: np.ndarray, y: np.ndarray):
    """Per tracklet (distinct label): ``(labels, start frame, start xy, end frame, end xy)``."""
    labs = np.unique(label)
    if labs.size == 0:
        z = np.zeros(0, np.int64)
        return labs, z, np.zeros((0, 2)), z, np.zeros((0, 2))
    order = np.lexsort((frame, label))
    lab_sorted = label[order]
    first = order[np.searchsorted(lab_sorted, labs, side="left")]
    last = order[np.searchsorted(lab_sorted, labs, side="right") - 1]
    return labs, frame[first], np.c_[x[first], y[first]], frame[last], np.c_[x[last], y[last]]


def join_costs(
    s_frame, s_xy, e_frame, e_xy, *, period: float, max_gap: int, max_speed: float, slack: float
) -> np.ndarray:
    """``(ends, starts)`` cost :math:`c_{AB}` of joining end A to start B, ``inf`` where infeasible."""
    step = s_frame[None, :] - e_frame[:, None]  # s_B - e_A
    dist = np.sqrt(((s_xy[None, :, :] - e_xy[:, None, :]) ** 2).sum(-1))
    ok = (step >= 1) & (step <= max_gap + 1) & (dist <= max_speed * period * step + slack)
    cost = dist + 0.5 * max_speed * period * (step - 1)
    return np.where(ok, cost, np.inf)


def join_pairs(
    s_frame, s_xy, e_frame, e_xy, *, period: float, max_gap: int, max_speed: float, slack: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The feasible pairs of :func:`join_costs` and their costs, ``(ends, starts, cost)``, in
    time and memory linear in the tracklets: per end, the starts 1 .. ``max_gap + 1`` frames
    later, from one sort of the starts (the same gate and cost, the same operations)."""
    order = np.argsort(s_frame, kind="stable")
    sf = s_frame[order]
    lo = np.searchsorted(sf, e_frame + 1, side="left")
    hi = np.searchsorted(sf, e_frame + max_gap + 1, side="right")
    n = hi - lo
    ends = np.repeat(np.arange(e_frame.size), n)
    starts = order[np.repeat(lo - np.cumsum(n) + n, n) + np.arange(int(n.sum()))]
    step = s_frame[starts] - e_frame[ends]
    dist = np.sqrt(((s_xy[starts] - e_xy[ends]) ** 2).sum(-1))
    ok = (step >= 1) & (step <= max_gap + 1) & (dist <= max_speed * period * step + slack)
    cost = dist + 0.5 * max_speed * period * (step - 1)
    return ends[ok], starts[ok], cost[ok]


def best_joins_sparse(
    ends: np.ndarray, starts: np.ndarray, cost: np.ndarray, n_ends: int, n_starts: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`best_joins` on the feasible pairs ``(ends, starts, cost)`` alone.

    A full matching, on rows = ends + one dummy per start and columns = starts + one dummy
    per end, of: every pair (cost ``c + 1``), end A to its dummy and start B's dummy to B
    (cost ``big + 1``, ``big`` above any matching's total), and start B's dummy to end A's
    dummy for every pair (A, B) (cost 1; every edge is offset by 1, as the solver takes a
    zero for no edge, and a full matching has ``n_ends + n_starts`` edges whatever it is).
    A matching M of pairs is the full matching that sends the unmatched ends and starts to
    their dummies and the dummy of each matched start B to the dummy of its end: its cost is
    ``sum c + big (n_ends + n_starts - 2 |M|) + const``, so the cheapest full matching is the
    largest M, then the cheapest."""
    if cost.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    big = float(cost.sum()) + 1.0
    ne, ns, m = n_ends, n_starts, cost.size
    rows = np.concatenate([ends, np.arange(ne), ne + np.arange(ns), ne + starts])
    cols = np.concatenate([starts, ns + np.arange(ne), np.arange(ns), ns + ends])
    w = np.concatenate([cost + 1.0, np.full(ne + ns, big + 1.0), np.ones(m)])
    graph = _sparse.csr_array((w, (rows, cols)), shape=(ne + ns, ns + ne))
    r, c = _csgraph.min_weight_full_bipartite_matching(graph)
    real = (r < ne) & (c < ns)
    return r[real].astype(np.int64), c[real].astype(np.int64)


def best_joins(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The joins ``(ends, starts)``: among the matchings of finite-cost pairs, the largest, and
    of those the cheapest (infeasible pairs priced above any feasible matching's total)."""
    finite = np.isfinite(cost)
    if not finite.any():
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    big = cost[finite].sum() + 1.0
    r, c = _optimize.linear_sum_assignment(np.where(finite, cost, big))
    keep = finite[r, c]
    return r[keep], c[keep]


def link_tracklets(
    frame: np.ndarray,
    label: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    *,
    period: float,
    max_gap: int,
    max_speed: float,
    slack: float,
    max_out: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Join tracklets of the reported rows ``(frame, label, x, y)`` (see the module docstring).

    Returns ``(frame, label, x, y, joins)``: the rows relabelled, plus the interpolated rows
    of the gaps, sorted by frame then label; ``joins`` is the number of joins made."""
    labs, s_f, s_xy, e_f, e_xy = tracklet_ends(frame, label, x, y)
    n = labs.size
    if n < 2 or max_gap < 0:
        return frame, label, x, y, 0
    pe, ps, pc = join_pairs(s_f, s_xy, e_f, e_xy, period=period, max_gap=max_gap, max_speed=max_speed, slack=slack)
    r, c = best_joins_sparse(pe, ps, pc, n, n)
    if r.size == 0:
        return frame, label, x, y, 0
    nxt = np.full(n, -1, dtype=np.int64)
    nxt[r] = c
    has_prev = np.zeros(n, bool)
    has_prev[c] = True
    new_of = np.arange(n)
    for head in np.flatnonzero(~has_prev):  # follow each chain from its first tracklet (chains are few)
        k = head
        while nxt[k] >= 0:
            new_of[nxt[k]] = new_of[head]
            k = nxt[k]
    idx = np.searchsorted(labs, label)
    new_label = labs[new_of[idx]]
    # fill the gaps, cheapest joins first, only where fewer than max_out are reported
    counts = (
        np.bincount(frame, minlength=int(frame.max()) + 2).astype(np.int64) if frame.size else np.zeros(1, np.int64)
    )
    add_f, add_l, add_x, add_y = [], [], [], []
    pair_cost = dict(zip(zip(pe.tolist(), ps.tolist()), pc.tolist()))
    for a, b in sorted(zip(r.tolist(), c.tolist()), key=lambda ab: pair_cost[ab]):
        gap = np.arange(e_f[a] + 1, s_f[b])
        if gap.size == 0:
            continue
        if max_out > 0:
            gap = gap[counts[gap] < max_out]
        w = ((gap - e_f[a]) / (s_f[b] - e_f[a]))[:, None]
        xy = (1 - w) * e_xy[a] + w * s_xy[b]
        counts[gap] += 1
        add_f.append(gap)
        add_l.append(np.full(gap.size, labs[new_of[a]]))
        add_x.append(xy[:, 0])
        add_y.append(xy[:, 1])
    f = np.concatenate([frame, *add_f]).astype(np.int64)
    lab = np.concatenate([new_label, *add_l]).astype(label.dtype)
    xx = np.concatenate([x, *add_x])
    yy = np.concatenate([y, *add_y])
    o = np.lexsort((lab, f))
    return f[o], lab[o], xx[o], yy[o], int(r.size)
