"""Compiled (numba) kernels of the binpf observation update (Eqs. (1), (2), (4), (4'), (5)).

The numpy update (:func:`onebit.trackers.binpf.filter.observation_update`) builds a dozen
``(tracks, particles, sensors)`` temporaries per frame and evaluates the footprint of every
sensor at every particle. These kernels compute each footprint once, in one pass, and only
where it can matter: sensor ``s`` is *near* track ``i`` when some particle of ``i`` may lie
within ``R_s + CUT_EDGES w`` of it (``R_s`` with a hard disk, ``w = 0``), judged from the
box that holds the track's particles. Beyond that, :math:`d_s(x) < p_d e^{-38} <
2^{-54}`, so ``1 - d`` and ``1 - r d`` round to exactly 1 in double precision: a far
sensor gives ``q_is = 1`` and adds to the track's particle log-likelihoods
:math:`\\ell_i^{(n)}` the same constant it adds to :math:`\\ell_i^0`, which cancels in the
existence update (Eq. (5) uses :math:`\\ell_i^{(n)} - \\ell_i^0`) and in the resampling
weights (defined up to a per-track constant). So a frame costs
``O(tracks x particles x sensors near them)``, not the whole array.

They equal the numpy functions to rounding (the sums run in another order and numba's
``exp``/``log`` may differ from numpy's in the last bit; ``tests/trackers/binpf/test_filter.py``
holds them to ``1e-9``); a whole run keeps its tracks unless a resampling draw falls within
that rounding of a particle's cumulative weight.
"""

from __future__ import annotations

import math

import numpy as np

from onebit.core.compiled import kernel

#: A sensor farther than ``R_s + CUT_EDGES x w`` from every particle of a track has
#: :math:`d_s \le p_d e^{-38} < 2^{-54}` for it: ``1 - d`` is exactly 1 in double precision.
CUT_EDGES = 38.0

_TINY = 1e-12


@kernel
def near_sensors(x, sensors, radii, edge):
    """``(I, S)`` bool: sensor ``s`` may be within ``R_s + CUT_EDGES w`` of a particle of
    track ``i`` (distance from the sensor to the box of the track's particles)."""
    I, N, S = x.shape[0], x.shape[1], sensors.shape[0]
    near = np.zeros((I, S), dtype=np.bool_)
    cut = CUT_EDGES * edge if edge > 0 else 0.0
    for i in range(I):
        x0 = np.inf
        x1 = -np.inf
        y0 = np.inf
        y1 = -np.inf
        for n in range(N):
            x0 = min(x0, x[i, n, 0])
            x1 = max(x1, x[i, n, 0])
            y0 = min(y0, x[i, n, 1])
            y1 = max(y1, x[i, n, 1])
        for s in range(S):
            dx = max(x0 - sensors[s, 0], 0.0, sensors[s, 0] - x1)
            dy = max(y0 - sensors[s, 1], 0.0, sensors[s, 1] - y1)
            near[i, s] = math.sqrt(dx * dx + dy * dy) <= radii[s] + cut
    return near


@kernel
def footprints(x, sensors, radii, pd, edge, near):
    """Eq. (1) ``d (I, N, S)`` where ``near[i, s]``, 0 elsewhere (below ``2^-54`` there)."""
    I, N, S = x.shape[0], x.shape[1], sensors.shape[0]
    d = np.zeros((I, N, S))
    for i in range(I):
        for s in range(S):
            if not near[i, s]:
                continue
            for n in range(N):
                dx = x[i, n, 0] - sensors[s, 0]
                dy = x[i, n, 1] - sensors[s, 1]
                dist = math.sqrt(dx * dx + dy * dy)
                if edge <= 0:
                    d[i, n, s] = pd if dist <= radii[s] else 0.0
                else:
                    u = min(max((radii[s] - dist) / edge, -50.0), 50.0)
                    d[i, n, s] = pd / (1.0 + math.exp(-u))
    return d


@kernel
def observation_update(x, r, z, sensors, radii, pd, pf, edge, silent):
    """Eqs. (4), (4'), (5): log-weights ``(I, N)`` (up to a per-track constant), updated
    existences ``(I,)`` and the footprints ``d (I, N, S)`` (0 away from the track); the
    compiled :func:`onebit.trackers.binpf.filter.observation_update` (its reference), summing
    over the sensors near each track only."""
    I, N, S = x.shape[0], x.shape[1], sensors.shape[0]
    near = near_sensors(x, sensors, radii, edge)
    d = footprints(x, sensors, radii, pd, edge, near)
    q = np.ones((I, S))
    for i in range(I):
        for s in range(S):
            if near[i, s]:
                acc = 0.0
                for n in range(N):
                    acc += d[i, n, s]
                q[i, s] = 1.0 - r[i] * (acc / N)
    # m_is = (1 - p_f) prod_{j != i} q_js by prefix and suffix products
    m = np.empty((I, S))
    for s in range(S):
        pre = 1.0
        for i in range(I):
            m[i, s] = pre
            pre *= q[i, s]
        suf = 1.0
        for i in range(I - 1, -1, -1):
            m[i, s] = (1.0 - pf) * m[i, s] * suf
            suf *= q[i, s]
    ell = np.zeros((I, N))
    r_new = np.empty(I)
    log_keep = math.log1p(-silent) if silent > 0 else 0.0
    log_sil = math.log(silent) if silent > 0 else 0.0
    for i in range(I):
        ell0 = 0.0
        for s in range(S):
            if not near[i, s]:
                continue
            mi = m[i, s]
            ell0 += math.log(max(1.0 - mi if z[s] else mi, _TINY))
            for n in range(N):
                off = mi * (1.0 - d[i, n, s])
                ell[i, n] += math.log(max(1.0 - off if z[s] else off, _TINY))
        if silent > 0:
            b = log_sil + ell0
            for n in range(N):
                a = log_keep + ell[i, n]
                hi = max(a, b)
                ell[i, n] = hi + math.log1p(math.exp(-abs(a - b)))
        top = -np.inf
        for n in range(N):
            top = max(top, ell[i, n] - ell0)
        acc = 0.0
        for n in range(N):
            acc += math.exp(ell[i, n] - ell0 - top)
        L_log = top + math.log(acc / N)
        a = math.log(max(r[i], _TINY)) + L_log
        b = math.log(max(1.0 - r[i], _TINY))
        r_new[i] = 1.0 / (1.0 + math.exp(min(max(b - a, -700.0), 700.0)))
    return ell, r_new, d


@kernel
def resampled_mean(d, idx):
    """:math:`\\bar d_{is}` of the resampled particles ``idx (I, N)`` from their footprints before
    resampling ``d (I, N, S)`` (a resampled particle is a copy: its footprint is the
    original's), without evaluating a footprint again."""
    I, N, S = d.shape[0], d.shape[1], d.shape[2]
    out = np.zeros((I, S))
    for i in range(I):
        for n in range(N):
            k = idx[i, n]
            for s in range(S):
                out[i, s] += d[i, k, s]
        for s in range(S):
            out[i, s] /= N
    return out


@kernel
def systematic_resample(logw, u0):
    """Indices ``(I, N)`` of systematic resampling of every row of ``logw (I, N)`` with the
    uniform draws ``u0 (I, 1)``: the compiled
    :func:`onebit.trackers.binpf.filter.systematic_resample` (its reference; the same
    operations but numba's ``exp``, so equal unless a draw falls within rounding of a
    particle's cumulative weight)."""
    I, N = logw.shape[0], logw.shape[1]
    idx = np.empty((I, N), dtype=np.int64)
    c = np.empty(N)
    for i in range(I):
        top = -np.inf
        for n in range(N):
            top = max(top, logw[i, n])
        acc = 0.0
        for n in range(N):
            acc += math.exp(logw[i, n] - top)
            c[n] = acc
        for n in range(N):
            c[n] /= acc
        k = 0
        for n in range(N):  # u increases with n: one merge walk (searchsorted side="right")
            u = (u0[i, 0] + n) / N
            while k < N and c[k] <= u:
                k += 1
            idx[i, n] = min(k, N - 1)
    return idx


@kernel
def gather_particles(x, hist, idx):
    """``x[i, idx[i, n]]`` and ``hist[i, idx[i, n]]`` for every track and particle (the
    resampled copies; ``np.take_along_axis`` of both in one pass)."""
    I, N = idx.shape[0], idx.shape[1]
    xo = np.empty((I, N, x.shape[2]))
    ho = np.empty((I, N, hist.shape[2], hist.shape[3]))
    for i in range(I):
        for n in range(N):
            k = idx[i, n]
            xo[i, n] = x[i, k]
            ho[i, n] = hist[i, k]
    return xo, ho
