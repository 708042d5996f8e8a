"""Who is who by habit: the decoded tracks of two people re-oriented between their meetings.

The decoder (:mod:`onebit.trackers.residents.decode`) follows people by motion alone. Where
two people meet, it cannot tell who left in which direction, and a wrong choice there swaps
their identities until the next meeting (docs/residents.md, "diagnosis"). Between two
meetings the two decoded fragments are two different people -- only *which* person each one
is can be wrong. People at home keep to their own tasks, so each person fires their own mix of
sensors (their *habits*), and the habits decide the orientation of every stretch between
meetings. Nothing here uses labels: the habits are learned from the events together with the
orientations.

Cuts. Events ``i = 0..n-1`` at nodes ``s_i`` with decoded persons ``y_i`` in ``{0, 1}``. Before
event ``i`` (``i >= 1``) person ``p`` is at the node of their last event before ``i``,
``u_p(i)``. A swap may have happened just before event ``i`` -- a *cut* ``i in C`` -- when both
people were seen and

::

    d(u_0(i), u_1(i)) <= meet                   (they are together: a meeting)           (H1)
    or |c(u_0(i) -> s_i) - c(u_1(i) -> s_i)| <= margin   (either could have fired i)

with ``c`` the motion cost of the decoder from a person's last node (eq. 3 of the model
module at the spread ``l0``, without the silence term; ``margin = 0``: off).
The cuts split the events into *intervals*; inside one the decoded fragments are kept, only
their names may be exchanged.

Orientation and habits. An orientation ``a_i`` in ``{0, 1}`` per event, constant inside an
interval (``a_i = a_{i-1}`` unless ``i in C``), gives event ``i`` to person ``z_i = y_i XOR
a_i``. Person ``p`` fires node ``s`` with probability ``theta_p(s)`` (a multinomial over the
nodes, Dirichlet prior with pseudo-count ``alpha`` per node). The orientations and habits
maximise

::

    L(a, theta) = sum_i ln theta_{z_i}(s_i) - lambda sum_{i in C} [a_i != a_{i-1}]
                  + alpha sum_p sum_s ln theta_p(s)                                       (H2)

(``lambda >= 0``: the cost of a swap at a meeting; 0: intervals are independent). Hard EM
(coordinate ascent on (H2), never decreasing it):

* *orientation step* -- given ``theta``, the best ``a`` exactly: a two-state Viterbi over the
  events, event ``i`` costing ``-ln theta_{y_i XOR a}(s_i)``, a change of state allowed only
  at cuts, at cost ``lambda`` (:func:`orient`; tested against all ``2^K`` orientations of the
  ``K`` intervals, :func:`orient_exhaustive`). With ``lambda = 0`` each interval takes the
  orientation whose events are likelier under the habits -- a swapped interval is flipped
  back whatever the decoder said;
* *habit step* -- given ``a``, the maximiser of (H2) in ``theta``::

      theta_p(s) = (n_p(s) + alpha) / (n_p + alpha S)                                     (H3)

  ``n_p(s)`` the events of person ``p`` at node ``s``, ``S`` the number of nodes.

It is a two-cluster problem over the intervals with a cannot-link inside each: the two
fragments of an interval are never the same person. (H2) has local maxima, so it starts from
the decoder's orientation (``a = 0``) and from ``restarts`` random ones (one coin per interval,
seeded), and keeps the best (H2). The two people's names are arbitrary (flipping every
interval leaves (H2) unchanged); the answer keeps the name of the decoder's first person on
its first event.
"""

from __future__ import annotations

from itertools import product

import numpy as np


def last_nodes(node: np.ndarray, track: np.ndarray, people: int = 2) -> np.ndarray:
    """``u[p, i]``: the node of person ``p``'s last event before event ``i`` (``-1``: none yet).
    ``(people, n)``.

    >>> last_nodes(np.array([5, 7, 6, 8]), np.array([0, 1, 0, 1])).tolist()
    [[-1, 5, 5, 6], [-1, -1, 7, 7]]
    """
    n = len(node)
    idx = np.arange(n)
    out = np.full((people, n), -1, dtype=np.int64)
    for p in range(people):
        last = np.maximum.accumulate(np.where(track == p, idx, -1))  # last own event at or before i
        before = np.r_[-1, last[:-1]]  # ... strictly before i
        out[p] = np.where(before >= 0, node[np.maximum(before, 0)], -1)
    return out


def meeting_cuts(
    node: np.ndarray, track: np.ndarray, dist: np.ndarray, *, meet: float, margin: float = 0.0, move_cost=None
) -> np.ndarray:
    """``cut[i]`` (``i >= 1``) of (H1): a swap may have happened just before event ``i``;
    ``cut[0]`` is False. ``move_cost(src, i) -> costs``: the decoder's ``c(src -> s_i)`` for an
    array of source nodes (needed when ``margin > 0``)."""
    n = len(node)
    cut = np.zeros(n, dtype=bool)
    if n < 2:
        return cut
    u = last_nodes(node, track)
    both = (u >= 0).all(axis=0)
    i = np.flatnonzero(both)
    cut[i] = dist[u[0, i], u[1, i]] <= meet
    if margin > 0 and move_cost is not None:
        for k in i[~cut[i]]:
            c = move_cost(u[:, k], int(k))
            cut[k] = abs(float(c[0]) - float(c[1])) <= margin
    cut[0] = False
    return cut


def orient(cost: np.ndarray, cut: np.ndarray, *, switch: float = 0.0) -> tuple[np.ndarray, float]:
    """The orientation ``a`` (per event, in ``{0, 1}``) minimising ``sum_i cost[i, a_i] +
    switch * #{i in C: a_i != a_{i-1}}`` with ``a_i = a_{i-1}`` off the cuts (the orientation
    step of (H2)); ``cost`` ``(n, 2)``: ``-ln theta`` of event ``i`` kept (0) or swapped (1).
    Returns ``(a, minimum)``; ties keep the decoder's orientation (0). A two-state Viterbi.

    >>> a, c = orient(np.array([[1.0, 0.0], [0.0, 5.0], [3.0, 0.0]]), np.array([False, False, True]))
    >>> a.tolist(), float(c)
    ([0, 0, 1], 1.0)
    """
    n = len(cost)
    if n == 0:
        return np.zeros(0, dtype=np.int64), 0.0
    # forward: acc[i, a] = cheapest cost of events 0..i with a_i = a; back[i, a] = a_{i-1}
    acc = np.empty((n, 2))
    back = np.zeros((n, 2), dtype=np.int64)
    acc[0] = cost[0]
    for i in range(1, n):
        stay = acc[i - 1]
        if cut[i]:
            other = acc[i - 1, ::-1] + switch
            take = other < stay  # ties: stay
            acc[i] = np.where(take, other, stay) + cost[i]
            back[i] = np.where(take, 1 - np.arange(2), np.arange(2))
        else:
            acc[i] = stay + cost[i]
            back[i] = np.arange(2)
    a = np.empty(n, dtype=np.int64)
    a[-1] = 0 if acc[-1, 0] <= acc[-1, 1] else 1
    for i in range(n - 1, 0, -1):
        a[i - 1] = back[i, a[i]]
    return a, float(acc[-1, a[-1]])


def orient_exhaustive(cost: np.ndarray, cut: np.ndarray, *, switch: float = 0.0) -> tuple[np.ndarray, float]:
    """:func:`orient` by trying all ``2^K`` orientations of the ``K`` intervals (test oracle)."""
    n = len(cost)
    if n == 0:
        return np.zeros(0, dtype=np.int64), 0.0
    interval = np.cumsum(cut) - int(cut[0])
    k = int(interval[-1]) + 1
    best, best_a = np.inf, None
    for o in product((0, 1), repeat=k):
        a = np.asarray(o, dtype=np.int64)[interval]
        total = float(cost[np.arange(n), a].sum()) + switch * float(np.count_nonzero(a[1:] != a[:-1]))
        if total < best - 1e-12:
            best, best_a = total, a
    return best_a, best


def habit_costs(node: np.ndarray, label: np.ndarray, n_nodes: int, *, alpha: float) -> np.ndarray:
    """``-ln theta_p(s)`` of (H3) for both people, from the events ``node`` given to ``label``
    (0/1). ``(2, n_nodes)``.

    >>> np.exp(-habit_costs(np.array([0, 0, 1]), np.array([0, 0, 1]), 3, alpha=1.0)).round(3).tolist()
    [[0.6, 0.2, 0.2], [0.25, 0.5, 0.25]]
    """
    counts = np.zeros((2, n_nodes))
    np.add.at(counts, (label, node), 1.0)
    theta = (counts + alpha) / (counts.sum(axis=1, keepdims=True) + alpha * n_nodes)
    return -np.log(theta)


def objective(
    node: np.ndarray, label: np.ndarray, a: np.ndarray, n_nodes: int, *, alpha: float, switch: float, cut: np.ndarray
) -> float:
    """(H2) at the habits (H3) of the labels ``label XOR a`` (larger is better)."""
    z = label ^ a
    neg = habit_costs(node, z, n_nodes, alpha=alpha)
    flips = np.count_nonzero((a[1:] != a[:-1]) & cut[1:]) if len(a) > 1 else 0
    return float(-neg[z, node].sum() - switch * flips - alpha * neg.sum())


def reorient(
    node: np.ndarray,
    track: np.ndarray,
    cut: np.ndarray,
    n_nodes: int,
    *,
    alpha: float = 1.0,
    switch: float = 0.0,
    restarts: int = 8,
    iterations: int = 50,
    seed: int = 0,
) -> np.ndarray:
    """The persons (0/1) of every event after hard EM on (H2) (module docstring): from the
    decoder's orientation and ``restarts`` random ones, the best (H2). ``track`` must hold
    two people (0 and 1)."""
    n = len(node)
    if n == 0 or not cut.any():
        return track.copy()
    label = track.astype(np.int64)
    interval = np.cumsum(cut)
    k = int(interval[-1]) + 1
    rng = np.random.default_rng(seed)
    starts = [np.zeros(n, dtype=np.int64)] + [rng.integers(0, 2, size=k)[interval] for _ in range(restarts)]
    best, best_a = -np.inf, starts[0]
    for a in starts:
        for _ in range(iterations):
            neg = habit_costs(node, label ^ a, n_nodes, alpha=alpha)
            cost = np.column_stack([neg[label, node], neg[1 - label, node]])
            new, _ = orient(cost, cut, switch=switch)
            if np.array_equal(new, a):
                break
            a = new
        val = objective(node, label, a, n_nodes, alpha=alpha, switch=switch, cut=cut)
        if val > best + 1e-9:
            best, best_a = val, a
    z = label ^ best_a
    return z if z[0] == label[0] else 1 - z
