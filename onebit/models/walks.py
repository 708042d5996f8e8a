"""The evidence of the home's count model that reads the order of the firings: the far pairs and
the sensors out of place (eq. F1), the log's clock (W0) and one walker's path (W1-W2). The
equations are in :mod:`onebit.models.occupancy`'s docstring."""

from __future__ import annotations

import numpy as np

#: (W2): the predecessors of a firing a walker's path may come from.
WALK_LOOKBACK = 64


def far_pairs(ts: np.ndarray, ks: np.ndarray, far: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The far pairs of time-sorted ON edges (times ``ts``, sensor indices ``ks``): every pair
    ``i < j`` with ``ts[j] - ts[i] <= window_s`` and ``far[ks[i], ks[j]]``, as index arrays
    ``(i, j)`` in order of the gap ``j - i`` (one vectorised pass per gap)."""
    firsts, seconds = [], []
    step = 1
    while step < ts.size:
        close = ts[step:] - ts[:-step] <= window_s
        if not close.any():
            break
        i = np.flatnonzero(close)
        hit = far[ks[i], ks[i + step]]
        firsts.append(i[hit])
        seconds.append(i[hit] + step)
        step += 1
    if not firsts:
        z = np.zeros(0, dtype=np.int64)
        return z, z
    return np.concatenate(firsts).astype(np.int64), np.concatenate(seconds).astype(np.int64)


def lifted_sensors(
    ks: np.ndarray, first: np.ndarray, second: np.ndarray, S: int, *, lift: float, least: int
) -> np.ndarray:
    """(F1): the sensors whose share of the far pairs' ends is out of proportion to their share
    of the firings -- misplaced on the plan, or seeing farther than their place -- as a boolean
    mask over the ``S`` sensors.

    With ``n_s`` the ON edges of sensor ``s`` (``N`` in all) and ``p_s`` the far pairs with an
    end at ``s`` (``P`` pairs, ``2P`` ends)::

        lambda_s = (p_s / 2P) / (n_s / N),     odd_s = lambda_s >= lift  and  p_s >= least       (F1)

    A second person's far pairs fall on the sensors people use, in proportion to their use
    (``lambda_s`` near 1); one sensor that pairs far with everything around it is a sensor out of
    place, and one person beside it makes them all."""
    _, p, lam = far_lift_of(ks, first, second, S)
    return (lam >= lift) & (p >= least)


def far_lift_of(
    ks: np.ndarray, first: np.ndarray, second: np.ndarray, S: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per sensor (F1): ``n_s`` its ON edges, ``p_s`` the far pairs with an end at it, and
    ``lambda_s = (p_s / 2P) / (n_s / N)`` (0 for a sensor with no ON edge or without far pairs)."""
    n = np.bincount(ks, minlength=S)
    p = np.bincount(ks[first], minlength=S) + np.bincount(ks[second], minlength=S)
    lam = np.zeros(S)
    if first.size:
        fired = n > 0
        lam[fired] = (p[fired] / (2.0 * first.size)) / (n[fired] / n.sum())
    return n, p, lam


def clock_tick(t: np.ndarray, *, clock_s: float, tick_phase: float) -> float:
    """The slack of the log's clock (:mod:`onebit.models.occupancy`, eq. W0): ``clock_s / 2`` when the times
    ``t`` share one phase modulo ``clock_s`` (mean resultant length at least ``tick_phase``),
    else 0 (also for ``clock_s = 0`` and for fewer than two times)."""
    t = np.asarray(t, dtype=float)
    if clock_s <= 0 or t.size < 2:
        return 0.0
    R = float(np.abs(np.exp(2j * np.pi * (t - t[0]) / clock_s).mean()))
    return 0.5 * float(clock_s) if R >= tick_phase else 0.0


def one_walker(
    t: np.ndarray, k: np.ndarray, hops: np.ndarray, *, walk_s: float, walk_slack: float, tick: float = 0.0
) -> np.ndarray:
    """Which firings (times ``t``, sorted; sensor indices ``k`` into ``hops``) lie on the longest
    path one walker can make of them (:mod:`onebit.models.occupancy`, eq. W1-W2; ``tick`` the log's clock
    slack, W0): a boolean mask."""
    n = t.size
    best = np.zeros(n, dtype=np.int64)
    prev = np.full(n, -1, dtype=np.int64)
    for j in range(n):
        lo = max(0, j - WALK_LOOKBACK)
        ok = hops[k[lo:j], k[j]] <= walk_slack + (t[j] - t[lo:j] + tick) / walk_s
        best[j] = 1
        if ok.any():
            c = np.flatnonzero(ok)
            i = lo + int(c[np.argmax(best[lo:j][c])])
            best[j] = best[i] + 1
            prev[j] = i
    on = np.zeros(n, dtype=bool)
    j = int(np.argmax(best)) if n else -1
    while j >= 0:
        on[j] = True
        j = int(prev[j])
    return on
