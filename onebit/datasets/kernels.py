"""Compiled (numba) sequential loops of the simulators.

:func:`pir_refractory` walks a PIR's on-periods in time order: whether a period is kept (and
from when) depends on the last period kept on the same sensor -- inherently sequential per
sensor -- so it is a compiled loop (``numba.njit(cache=True)``, :mod:`onebit.core.compiled`).
Its plain reference and test oracle is
:func:`onebit._testing.oracles.pir_refractory_reference` (``tests/datasets/test_kernels.py``).
"""

from __future__ import annotations

import math

import numpy as np

from onebit.core.compiled import kernel


@kernel
def pir_refractory(col, start, end, times, refr, dt):
    """Apply a PIR's refractory time to its on-periods (sample-index runs).

    ``col[k]`` is the sensor of period ``k``, which covers samples ``start[k] <= j < end[k]``
    (periods sorted by start; ``times`` the sample times, spacing ``dt``). After a kept period
    ending at sample ``e`` the sensor is blind until ``b_i = times[min(e, K-1)] + refr[i]``,
    i.e. until sample ``r_i = ceil((b_i - times[0]) / dt)``. A period with ``end <= r_i`` is
    dropped; otherwise it is kept from ``max(start, r_i)`` and sets the next blind time.
    Returns ``(keep (n,) bool, keep_start (n,) int64)``.
    """
    n = col.shape[0]
    K = times.shape[0]
    keep = np.ones(n, dtype=np.bool_)
    keep_s = start.copy()
    blind = np.full(refr.shape[0], -np.inf)
    for k in range(n):
        i = col[k]
        ready = 0
        if np.isfinite(blind[i]):
            ready = int(math.ceil((blind[i] - times[0]) / dt - 1e-9))
        if end[k] <= ready:
            keep[k] = False
            continue
        keep_s[k] = max(start[k], ready)
        blind[i] = times[min(end[k], K - 1)] + refr[i]
    return keep, keep_s
