"""A literal, per-particle transcription of Algorithm 1's scan (steps 3-18).

This is the *reference* the vectorised :func:`onebit.trackers.clustertrack.algorithm.scan_clusters`
is tested against and benchmarked against: one Python iteration per scanned candidate, the
distance to every cluster head recomputed from the full trajectories
``D = (1/t) sum_l ||P[l] - CH[l]||``. It is deliberately not used by the tracker.
"""

from __future__ import annotations

import numpy as np


def scan_clusters_direct(order: np.ndarray, traj: np.ndarray, *, H: int, K: int, L: int, D0: float):
    """Scan candidates in the given ``order`` (already sorted by cost).

    ``traj (n, t, d)``: full candidate trajectories. Returns ``(kept, label, n_scanned)``
    with ``kept`` candidate indices in scan order and their cluster ids.
    """
    heads: list[int] = []
    count: list[int] = []
    kept: list[int] = []
    label: list[int] = []
    scanned = 0
    for i in order[:L]:  # one candidate per iteration, as in the pseudo-code
        if len(kept) >= K:
            break
        scanned += 1
        if heads:
            d = [float(np.mean(np.sqrt(np.sum((traj[i] - traj[h]) ** 2, axis=-1)))) for h in heads]
            j = int(np.argmin(d))
            if d[j] < D0:
                if count[j] < H:
                    count[j] += 1
                    kept.append(int(i))
                    label.append(j)
                continue
        heads.append(int(i))
        count.append(1)
        kept.append(int(i))
        label.append(len(heads) - 1)
    return np.asarray(kept, dtype=np.int64), np.asarray(label, dtype=np.int64), scanned
