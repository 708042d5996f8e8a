"""The residents decoder: the attribution of events to people that minimises eq. (1) of
:mod:`onebit.trackers.residents.model`.

State. Cost (1) depends on the past only through each person's *last* event (eq. 3 looks at
``s_j, t_j`` only), so after event ``i`` the state of a hypothesis is the set of the people's
last event indices -- ``K`` numbers, ``-1`` for a person not born yet, written in decreasing
order so that two hypotheses that differ only by the people's names are one state (the
relabelling symmetry). Event ``i`` is the newest, so it is always the first entry. Going from
event ``i-1`` to ``i`` a state ``(j_1, ..., j_K)`` moves to

* ``(i, j_1, ..., j_{k-1}, j_{k+1}, ..., j_K)`` at cost ``c(j_k, i)`` (person ``k`` fired ``i``), or
* ``(i, j_1, ..., j_{K-1})`` at cost ``b(i)`` when ``j_K = -1`` (a birth; ``-1`` entries are last).

Search. This is a Viterbi recursion over those states (a multiple-hypothesis tracker whose
hypotheses are merged exactly when they share a state): :func:`decode_events` keeps, after
each event, the ``beam`` cheapest states (all of them when ``beam`` is ``None``: the exact
minimum of (1); for two people the states number at most ``i + 1``), with a back-pointer to
the state they came from and the predecessor they chose, and reads the best attribution back
from the cheapest final state. :func:`decode_exhaustive` enumerates every attribution of a
short sequence (every set partition into at most ``K`` chains) and is the test oracle.

The recursion is inherently sequential over events; each step is vectorised over the states
and their ``K + 1`` moves with numpy (a few tens of microseconds per event).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np


@dataclass(frozen=True)
class Attribution:
    """The decoder's answer: ``pred[i]`` (previous event of the same person, ``-1`` = birth),
    ``track[i]`` (0, 1, ... in order of birth), the cost ``J`` of (1) and the number of people."""

    pred: np.ndarray
    track: np.ndarray
    cost: float
    people: int
    #: states kept after each event (the beam's occupancy)
    states: np.ndarray


def tracks_from_pred(pred: np.ndarray) -> np.ndarray:
    """Track number of every event from its predecessor: births numbered in time order.

    >>> tracks_from_pred(np.array([-1, -1, 0, 2, 1])).tolist()
    [0, 1, 0, 0, 1]
    """
    track = np.empty(len(pred), dtype=np.int64)
    n = 0
    for i, j in enumerate(pred):
        if j < 0:
            track[i] = n
            n += 1
        else:
            track[i] = track[j]
    return track


def preds_from_tracks(track: np.ndarray) -> np.ndarray:
    """Predecessor of every event (the previous event of its track, ``-1``: the track's first).

    >>> preds_from_tracks(np.array([0, 1, 0, 0, 1])).tolist()
    [-1, -1, 0, 2, 1]
    """
    pred = np.full(len(track), -1, dtype=np.int64)
    order = np.lexsort((np.arange(len(track)), track))
    same = track[order][1:] == track[order][:-1]
    pred[order[1:][same]] = order[:-1][same]
    return pred


def attribution_cost(pred: np.ndarray, move, birth: np.ndarray, *, stay: float | None = None) -> float:
    """Cost (1) of an attribution: ``move(j, i)`` for every link, ``birth[i]`` for every birth,
    plus the who-fires term (5) of each event when ``stay`` is given -- written event by event
    from its definition (the decoder's test oracle)."""
    total = 0.0
    track = tracks_from_pred(pred)
    for i, j in enumerate(pred):
        total += birth[i] if j < 0 else move(int(j), i)
        if stay is not None and i > 0:
            n = int(track[:i].max()) + 1  # people present before event i
            if j < 0:
                total += -np.log((1.0 - stay) / n)
            elif track[i] == track[i - 1]:
                total += -np.log(stay) if n >= 2 else 0.0
            else:
                total += -np.log((1.0 - stay) / (n - 1))
    return float(total)


def decode_events(
    move_row, birth: np.ndarray, *, people: int, beam: int | None = 64, stay: float | None = None, progress=None
) -> Attribution:
    """Minimise (1) over attributions of ``len(birth)`` events to at most ``people`` people.

    ``move_row(J, i) -> costs`` gives ``c(J[...], i)`` for an integer array ``J`` of earlier
    event indices (all ``>= 0``); ``birth[i]`` is ``b(i)``. ``beam``: states kept per event
    (``None`` = all, exact; ``1``: each event is committed to its cheapest continuation, an
    online assignment). ``stay``: the who-fires term of eq. (5) (:func:`who_fires`; ``None``
    = off). ``progress(done, total)`` is called every 1000 events.
    """
    n = len(birth)
    if n == 0:
        return Attribution(np.zeros(0, np.int64), np.zeros(0, np.int64), 0.0, 0, np.zeros(0, np.int64))
    if people < 1:
        raise ValueError(f"people = {people}: at least one person is needed to explain {n} events")
    K = int(people)
    states = np.full((1, K), -1, dtype=np.int64)
    cost = np.zeros(1)
    parents: list[np.ndarray] = []
    preds: list[np.ndarray] = []
    occupancy = np.empty(n, dtype=np.int64)
    drop = [np.delete(np.arange(K), k) for k in range(K)]  # columns kept when person k fires
    for i in range(n):
        B = states.shape[0]
        valid = states >= 0
        step = np.full((B, K + 1), np.inf)
        if valid.any():
            step[:, :K][valid] = move_row(states[valid], i)
        free = ~valid[:, K - 1]
        step[free, K] = birth[i]
        if stay is not None and i > 0:
            step += who_fires(states, i, stay)
        others = np.stack([states[:, d] for d in drop] + [states[:, : K - 1]], axis=1)  # (B, K + 1, K - 1)
        total = cost[:, None] + step  # (B, K + 1)
        pred_of = np.concatenate([states, np.full((B, 1), -1, dtype=np.int64)], axis=1)  # (B, K + 1)
        ok = np.isfinite(total)
        b_idx, m_idx = np.nonzero(ok)
        c = total[b_idx, m_idx]
        keys = others[b_idx, m_idx]  # (M, K - 1)
        # one state per key (the cheapest way into it), ties to the first candidate
        wide = keys.shape[1] > 0
        order = np.lexsort((np.arange(len(c)), c, *keys.T[::-1])) if wide else np.lexsort((np.arange(len(c)), c))
        if wide:
            ks = keys[order]
            first = np.ones(len(order), dtype=bool)
            first[1:] = np.any(ks[1:] != ks[:-1], axis=1)
            order = order[first]
        else:
            order = order[:1]
        if beam is not None and len(order) > beam:
            keep = np.argsort(c[order], kind="stable")[:beam]
            order = order[np.sort(keep)]
        b_new, m_new = b_idx[order], m_idx[order]
        states = np.concatenate([np.full((len(order), 1), i, dtype=np.int64), keys[order]], axis=1)
        cost = c[order]
        parents.append(b_new)
        preds.append(pred_of[b_new, m_new])
        occupancy[i] = len(cost)
        if progress is not None and (i + 1) % 1000 == 0:
            progress(i + 1, n)
    best = int(np.argmin(cost))
    pred = np.empty(n, dtype=np.int64)
    s = best
    for i in range(n - 1, -1, -1):
        pred[i] = preds[i][s]
        s = int(parents[i][s])
    track = tracks_from_pred(pred)
    return Attribution(pred, track, float(cost[best]), int((pred < 0).sum()), occupancy)


def who_fires(states: np.ndarray, i: int, stay: float) -> np.ndarray:
    """Eq. (5) of the model for every state (rows of last event indices) and move (columns: the
    person of that column fires event ``i``; the last column: a new person): ``-ln stay`` for
    the person who fired event ``i - 1`` when others are present, ``-ln((1 - stay) / (n - 1))``
    for another of the ``n`` present, ``-ln((1 - stay) / n)`` for a newcomer. ``(B, K + 1)``."""
    B, K = states.shape
    n = (states >= 0).sum(axis=1, keepdims=True).astype(float)  # people present (>= 1 after the first event)
    prev = states == i - 1
    with np.errstate(divide="ignore"):
        other = -np.log((1.0 - stay) / np.maximum(n - 1.0, 1.0))
        same = np.where(n >= 2, -np.log(stay), 0.0)
        out = np.where(prev, same, other)
        newcomer = -np.log((1.0 - stay) / n)
    return np.concatenate([out, newcomer], axis=1)


def decode_exhaustive(move, birth: np.ndarray, *, people: int, stay: float | None = None) -> Attribution:
    """Every attribution of the events to at most ``people`` people (labels in order of first
    appearance), the cheapest by (1); ``move(j, i)`` is ``c(j, i)``. Exponential: a test oracle
    for a dozen events at most."""
    n = len(birth)
    best_cost, best_pred = np.inf, None
    for labels in product(range(people), repeat=n):
        # canonical: each label's first use comes in order 0, 1, 2, ...
        seen = -1
        ok = True
        for lab in labels:
            if lab > seen + 1:
                ok = False
                break
            seen = max(seen, lab)
        if not ok:
            continue
        last = {}
        pred = np.empty(n, dtype=np.int64)
        for i, lab in enumerate(labels):
            pred[i] = last.get(lab, -1)
            last[lab] = i
        c = attribution_cost(pred, move, birth, stay=stay)
        if c < best_cost - 1e-12:
            best_cost, best_pred = c, pred
    track = tracks_from_pred(best_pred)
    return Attribution(best_pred, track, float(best_cost), int((best_pred < 0).sum()), np.zeros(n, np.int64))
