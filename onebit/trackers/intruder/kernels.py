"""The SIR particle filter's iteration as one compiled (numba) kernel: propagate, weigh,
estimate and resample fused, with no ``(N, K)`` or ``(n, N)`` temporaries.

The loop over iterations is inherently sequential (each needs the previous posterior) and so
is the rejection sampling of the intruder model (a particle is redrawn until it lands), so
they are compiled loops (``numba.njit(cache=True)``, :mod:`onebit.core.compiled`). Everything follows the named numpy
steps that stay the plain reference implementation and the test oracle
(``tests/trackers/intruder/test_kernels.py``; same seed -> same particles, estimates and
resampling, ESS and spread to 1e-9):

=====================================  ==================================================
fused here                             reference
=====================================  ==================================================
propagate (box rooms)                  :func:`onebit.models.motion.propagate`
log-likelihood                         :func:`onebit.models.pir.log_weights`
normalise, ESS, spread                 :func:`onebit.trackers.intruder.filter.normalise`, ...
estimate                               :func:`onebit.trackers.intruder.filter.estimate_cell`
systematic / multinomial resampling    :func:`onebit.trackers.intruder.filter.systematic_resample`, ...
=====================================  ==================================================

Same random numbers. The kernel draws from the run's ``numpy.random.Generator`` (numba
shares its bit generator and implements the same algorithms) in the reference's order:
per rejection round all the speed noises of the particles still to place, then all their
orientation noises; one uniform for systematic resampling (``N`` for multinomial).

Likelihood without temporaries. Section VII-B.2 of the paper (see
:mod:`onebit.trackers.intruder.filter`)::

    log P(S_i = 0 | x) = xi_i log(1 - p0_i) + sum_{k touched, q_ik > 0} log(L_ik / (1 - p0_i))

Only cells of a sensor's region ``R_i`` under the particle's box change the sensor's
factor, so the deployment is stored per cell (a CSR list of the sensors whose ``q_ik > 0``).
Particles whose boxes start in the same cell touch the same block of cells, so they are
grouped by that cell (a counting sort, within windows of 16384 consecutive particles whose
coordinates stay in cache at any N) and each cell's entries are applied to a batch of up
to 256 of them at once (a loop over particles the compiler vectorises; a particle whose box
misses the cell takes the factor 1 exactly). Each particle thus meets its ``K`` touched
cells once, in the same order as alone, accumulating per sensor
``D_i = prod_k (L_ik / (1 - p0_i)) - 1`` (``D <- D + d + D d``, exact for small factors, so
``-expm1(log1p(D) + ...)`` keeps the precision of the reference's sum of logs). A sensor
whose region the box misses contributes the constant of an empty neighbourhood, summed
once per iteration. The factors of the silent sensors are multiplied and take one ``log``
per particle; a fired sensor takes ``log(-expm1(.))``. Blind sensors are left out (they add
the same constant to every particle), as in the reference.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from onebit.core.compiled import kernel

PROB_FLOOR = 1e-12
LOG_FLOOR = math.log(PROB_FLOOR)
TWO_PI = 2 * math.pi


class MotionParams(NamedTuple):
    """The intruder model (:class:`onebit.models.motion.Motion`, same fields) for :func:`_run_box`."""

    period: float
    v_max: float
    speed_sigma: float
    turn_scale: float
    max_retries: int


class Model(NamedTuple):
    """The deployment on the grid, as the likelihood and the estimate read it."""

    grid: np.ndarray  #: (5,) x0, y0, cell, nx, ny
    cell_ptr: np.ndarray  #: CSR of the sensors per cell (:func:`cell_lists`)
    cell_sensor: np.ndarray
    cell_q: np.ndarray
    p0: np.ndarray  #: (n,) false-alarm probability per sensor
    xi: np.ndarray  #: (n,) cells of each region R_i
    a: np.ndarray  #: (n,) 1 - p0, as the reference computes it
    half_w: float  #: the intruder's half width
    half_d: float  #: the intruder's half depth
    mask: np.ndarray  #: (ny, nx) cells inside the room


class Resampling(NamedTuple):
    """When and how the filter resamples, and which particles it logs."""

    systematic: bool  #: systematic (else multinomial) resampling
    always: bool  #: every iteration (else when the ESS is below ``ess_threshold N``)
    ess_threshold: float
    pick: np.ndarray  #: (L,) indices of the particles logged per iteration


class Outputs(NamedTuple):
    """What every iteration ``k`` writes (row ``k`` of each)."""

    est: np.ndarray  #: (T, 2) estimate
    ess: np.ndarray  #: (T,) effective sample size
    resampled: np.ndarray  #: (T,) bool
    logged_xy: np.ndarray  #: (T, L, 2)
    logged_w: np.ndarray  #: (T, L)
    spread: np.ndarray  #: (T,)


# --------------------------------------------------------------------------- propagate


@kernel
def _propagate_box(
    x, y, theta, v, rng, period, v_max, speed_sigma, turn_scale, max_retries, box, idx, pack, noise, work, cand
):
    """:func:`onebit.models.motion.propagate` in a box room, in place; returns (redraws, clamped).

    Each rejection round runs in three passes with few unpredictable branches: the proposals'
    speeds and orientations (the ones with an admissible speed listed), the positions of
    those (``cos``/``sin`` only for them) and the room test, then in particle order the
    accepted ones written over their particle and the rejected ones packed (old position,
    orientation, speed and the orientation noise scale ``min(pi, turn_scale / v)``) for the
    next round, which reads them in order. The first round reads the particles where they
    are (a particle's old state is needed by no other). A proposal's orientation is reduced
    to ``[0, 2 pi)``; a particle never placed keeps its position and orientation (reduced, as
    the reference does for every particle) with speed 0.

    ``idx``, ``cand`` ``(N,)`` int64, ``pack (5, N)``, ``noise (2, N)`` and ``work (6, N)``
    are workspace (kept by the caller across iterations); a round's noises are drawn one by
    one into ``noise``, the same numbers as ``rng.normal(0, sigma, m)``."""
    n = x.shape[0]
    ox, oy, oth, ov, sg = pack[0], pack[1], pack[2], pack[3], pack[4]
    dv, dth = noise[0], noise[1]
    tv, tt, pxa, pya, tha, acc = work[0], work[1], work[2], work[3], work[4], work[5]
    bx0, by0, bx1, by1 = box[0], box[1], box[2], box[3]
    m = n
    redraws = 0
    for rnd in range(max_retries):
        if m == 0:
            break
        for a in range(m):  # all the speed noises of the round, then all the orientation noises
            dv[a] = rng.normal(0.0, speed_sigma)
        for a in range(m):
            dth[a] = rng.normal(0.0, 1.0)
        first = rnd == 0
        k = 0
        for a in range(m):  # proposals; the ones with an admissible speed listed in `cand`
            if first:  # the particle itself, not yet packed
                v0, th0 = v[a], theta[a]
                sg[a] = min(math.pi, turn_scale / max(v0, 1e-9))
            else:
                v0, th0 = ov[a], oth[a]
            vv = v0 + dv[a]
            tv[a] = vv
            tt[a] = th0 + dth[a] * sg[a]
            acc[a] = 0.0
            cand[k] = a
            k += int(vv >= 0.0 and vv <= v_max)
        for j in range(k):  # positions of those, and the room test
            a = cand[j]
            step = tv[a] * period
            th = tt[a]
            px = (x[a] if first else ox[a]) + step * math.cos(th)
            py = (y[a] if first else oy[a]) + step * math.sin(th)
            pxa[a], pya[a], tha[a] = px, py, np.mod(th, TWO_PI)
            acc[a] = 1.0 if (px >= bx0 and px <= bx1 and py >= by0 and py <= by1) else 0.0
        keep = 0
        for a in range(m):  # in particle order: pack every proposal's particle, keep the rejected
            ok = acc[a] != 0.0
            if first:
                p, px0, py0, th0, v0 = a, x[a], y[a], theta[a], v[a]
            else:
                p, px0, py0, th0, v0 = idx[a], ox[a], oy[a], oth[a], ov[a]
            idx[keep], ox[keep], oy[keep], oth[keep], ov[keep], sg[keep] = p, px0, py0, th0, v0, sg[a]
            x[p] = pxa[a] if ok else px0
            y[p] = pya[a] if ok else py0
            theta[p] = tha[a] if ok else th0
            v[p] = tv[a] if ok else v0
            keep += int(not ok)
        redraws += keep  # rejected proposals of this round
        m = keep
    # the rest stay at their old (valid) position with speed 0
    for a in range(m):
        p = idx[a] if max_retries > 0 else a  # no round: none was packed
        theta[p] = np.mod(theta[p], TWO_PI)
        v[p] = 0.0
    return redraws, m


# --------------------------------------------------------------------------- weights


@kernel
def _sensor_factors(fired, blind, p0, xi):
    """Per sensor, relative to no touched cell (``F = 1``, ``D = 0``): fired, the factor
    ``clip(alpha + beta D) * gamma``; silent, ``max(F, lo)`` (``slow``: the floor binds with no
    touched cell, summed in logs). Returns ``(alpha, beta, lo, gamma, c, slow, base)``, ``c_i =
    xi_i log(1 - p0_i)`` and ``base`` the live sensors' log-probabilities with no touched cell."""
    n = p0.shape[0]
    alpha = np.empty(n)
    beta = np.empty(n)
    lo = np.empty(n)
    gamma = np.empty(n)
    ci = np.empty(n)
    slow = np.zeros(n, dtype=np.bool_)
    base = 0.0
    for i in range(n):
        ci[i] = xi[i] * math.log1p(-min(p0[i], 1.0 - PROB_FLOOR))
        if fired[i]:
            hc = -math.expm1(ci[i])
            p_empty = min(max(hc, PROB_FLOOR), 1.0)
            alpha[i], beta[i], lo[i], gamma[i] = hc, -(1.0 - hc), PROB_FLOOR, 1.0 / p_empty
            const = math.log(p_empty)
        else:
            alpha[i], beta[i], lo[i], gamma[i] = 1.0, 1.0, math.exp(LOG_FLOOR - ci[i]), 1.0
            slow[i] = ci[i] < LOG_FLOOR  # the floor binds with no touched cell: summed in logs
            const = max(ci[i], LOG_FLOOR)
        if not blind[i]:
            base += const
    return alpha, beta, lo, gamma, ci, slow, base


@kernel
def _live_cell_entries(blind, cell_ptr, cell_sensor, cell_q, p0, a):
    """The live sensors' entries per cell (:func:`cell_lists` without the blind sensors):
    ``(ptr, sensor, 1 - p0, max(q, p0) - p0, 1 / a)``."""
    n_cells = cell_ptr.shape[0] - 1
    lptr = np.zeros(n_cells + 1, dtype=np.int64)
    nnz = 0
    for e in range(cell_sensor.shape[0]):
        if not blind[cell_sensor[e]]:
            nnz += 1
    lsen = np.empty(nnz, dtype=np.int64)
    lomp = np.empty(nnz)
    lqq = np.empty(nnz)
    linv = np.empty(nnz)
    m = 0
    for cell in range(n_cells):
        for e in range(cell_ptr[cell], cell_ptr[cell + 1]):
            i = cell_sensor[e]
            if blind[i]:
                continue
            lsen[m] = i
            lomp[m] = 1.0 - p0[i]
            lqq[m] = max(cell_q[e], p0[i]) - p0[i]
            linv[m] = 1.0 / a[i]
            m += 1
        lptr[cell + 1] = m
    return lptr, lsen, lomp, lqq, linv


@kernel
def _log_likelihood(x, y, fired, blind, grid, cell_ptr, cell_sensor, cell_q, p0, xi, a, half_w, half_d, out):
    """``out[p] = log P(E | x_p)`` over the live sensors (:func:`onebit.models.pir.log_weights`).

    Per live sensor ``i`` with ``c_i = xi_i log(1 - p0_i)``, the product ``F_i`` of its
    touched cells' ratios and ``D_i = F_i - 1`` (module docstring): silent,
    ``log P = max(c_i + log F_i, log floor)``; fired,
    ``log P = log clip(-expm1(c_i + log F_i)) = log clip(h_i - (1 - h_i) D_i)`` with
    ``h_i = -expm1(c_i)`` (both terms >= 0: no cancellation; ``D_i`` from its own recursion
    when ``F_i > 1/2``, where ``F_i - 1`` would cancel). Each sensor's probability is taken
    relative to its value with no touched cell (ratio exactly 1) and the ratios are
    multiplied, so a particle costs one ``log``.
    """
    n = p0.shape[0]
    N = x.shape[0]
    x0, y0, c, nx, ny = grid[0], grid[1], grid[2], int(grid[3]), int(grid[4])
    live = np.empty(n, dtype=np.int64)
    n_live = 0
    for i in range(n):
        if not blind[i]:
            live[n_live] = i
            n_live += 1
    if n_live == 0:
        for p in range(N):
            out[p] = 0.0
        return
    alpha, beta, lo, gamma, ci, slow, base = _sensor_factors(fired, blind, p0, xi)
    lptr, lsen, lomp, lqq, linv = _live_cell_entries(blind, cell_ptr, cell_sensor, cell_q, p0, a)
    kx = int(math.ceil(2 * half_w / c)) + 1
    ky = int(math.ceil(2 * half_d / c)) + 1
    # particles by the first cell (ix0, iy0) of their box: those sharing it touch the same
    # kx x ky block of cells, so each cell's entries are applied to a batch of them at once
    # (a loop over particles the compiler vectorises); origins with no cell of the block in
    # the grid touch nothing
    gx, gy = nx + kx - 1, ny + ky - 1
    WINDOW = 16384  # particles sorted together: their coordinates stay in cache at any N
    org = np.empty(WINDOW, dtype=np.int64)
    order = np.empty(WINDOW, dtype=np.int64)
    count = np.zeros(gx * gy + 2, dtype=np.int64)
    CH = 256
    Vs = np.empty((kx * ky, CH))
    F = np.ones((n, CH))
    D = np.zeros((n, CH))
    ox = np.empty(kx)
    oy = np.empty(ky)
    touched = np.zeros(n, dtype=np.bool_)
    geom = (gx, gy, kx, ky, x0, y0, c, nx, ny, half_w, half_d)
    cells = (lptr, lsen, lomp, lqq, linv)
    scratch = (Vs, F, D, ox, oy, touched)
    sensors = (n_live, live, base, fired, slow, alpha, beta, gamma, lo, ci)
    for w0 in range(0, N, WINDOW):
        _likelihood_window(x, y, w0, min(N, w0 + WINDOW), org, order, count, geom, cells, scratch, sensors, out)


@kernel
def _likelihood_window(x, y, w0, w1, org, order, count, geom, cells, scratch, sensors, out):
    """:func:`_log_likelihood` for particles ``w0:w1``: grouped by the first cell of their box
    (a counting sort), then each cell's entries applied to a batch of them at once. ``geom``,
    ``cells``, ``scratch`` and ``sensors`` bundle the arrays and numbers it shares with
    :func:`_log_likelihood` (the block's and grid's shape, the live cell entries, the batch's
    work arrays, the sensors' factors)."""
    gx, gy, kx, ky, x0, y0, c, nx, ny, half_w, half_d = geom
    lptr, lsen, lomp, lqq, linv = cells
    Vs, F, D, ox, oy, touched = scratch
    n_live, live, base, fired, slow, alpha, beta, gamma, lo, ci = sensors
    n = F.shape[0]
    CH = F.shape[1]
    acc_b = np.empty(CH)
    prod_b = np.empty(CH)
    _group_by_origin(x, y, w0, w1, org, order, count, gx, gy, kx, ky, x0, y0, c, half_w, half_d)
    # origin o's particles: order[count[o]:count[o + 1]] (o = gx gy: no cell of the block in the grid)
    for o in range(gx * gy + 1):
        lo_o, hi_o = count[o], count[o + 1]
        for b0 in range(lo_o, hi_o, CH):
            m = min(CH, hi_o - b0)
            if o < gx * gy:
                ix0, iy0 = o % gx - (kx - 1), o // gx - (ky - 1)
                _block_fractions(x, y, order, b0, m, ix0, iy0, kx, ky, x0, y0, c, nx, ny, half_w, half_d, ox, oy, Vs)
                for by in range(ky):
                    iy = iy0 + by
                    if iy < 0 or iy >= ny:
                        continue
                    for bx in range(kx):
                        ix = ix0 + bx
                        if ix < 0 or ix >= nx:
                            continue
                        cell = iy * nx + ix
                        Vb = Vs[by * kx + bx]
                        for e in range(lptr[cell], lptr[cell + 1]):
                            i = lsen[e]
                            touched[i] = True
                            Fi, Di = F[i], D[i]
                            le, lq, li = lomp[e], lqq[e], linv[e]
                            for j in range(m):  # a particle whose box misses the cell (V = 0): factor 1
                                V = Vb[j]
                                r = max(le - V * lq, PROB_FLOOR) * li if V != 0.0 else 1.0
                                d = r - 1.0
                                Di[j] = Di[j] + d + Di[j] * d  # (1 + D)(1 + d) - 1: precise near a product of 1
                                Fi[j] *= r  # the product itself: precise when it is small
            if n_live <= 16:  # sensor by sensor over the batch (the rescaling below never triggers)
                _combine_batch(F, D, m, n_live, live, base, fired, slow, alpha, beta, gamma, lo, ci, acc_b, prod_b)
                for j in range(m):
                    out[order[b0 + j]] = acc_b[j] + math.log(prod_b[j])
            else:  # particle by particle, rescaled when the product leaves [1e-200, 1e200]
                _combine_each(F, D, m, n_live, live, base, fired, slow, alpha, beta, gamma, lo, ci, order, b0, out)
            for i in range(n):  # reset what this batch touched
                if touched[i]:
                    touched[i] = False
                    for j in range(m):
                        F[i, j] = 1.0
                        D[i, j] = 0.0


@kernel
def _group_by_origin(x, y, w0, w1, org, order, count, gx, gy, kx, ky, x0, y0, c, half_w, half_d):
    """Particles ``w0:w1`` grouped by the first cell of their box (a counting sort): origin
    ``o``'s particles are ``order[count[o]:count[o + 1]]`` (``o = gx gy``: no cell of the block
    in the grid)."""
    for o in range(gx * gy + 2):
        count[o] = 0
    for p in range(w0, w1):
        jx = int(math.floor((x[p] - half_w - x0) / c)) + kx - 1
        jy = int(math.floor((y[p] - half_d - y0) / c)) + ky - 1
        o = jy * gx + jx if 0 <= jx < gx and 0 <= jy < gy else gx * gy
        org[p - w0] = o
        count[o + 2] += 1
    for o in range(gx * gy + 1):
        count[o + 2] += count[o + 1]
    for p in range(w0, w1):
        o = org[p - w0] + 1
        order[count[o]] = p
        count[o] += 1


@kernel
def _block_fractions(x, y, order, b0, m, ix0, iy0, kx, ky, x0, y0, c, nx, ny, half_w, half_d, ox, oy, Vs):
    """``Vs[by kx + bx, j]``: the fraction of cell ``(ix0 + bx, iy0 + by)`` that the box of
    particle ``order[b0 + j]`` covers (0 outside the grid), for the ``m`` particles of a batch."""
    for j in range(m):
        p = order[b0 + j]
        xp, yp = x[p], y[p]
        for b in range(kx):
            ix = ix0 + b
            left = x0 + ix * c
            ov = min(xp + half_w, left + c) - max(xp - half_w, left)
            ox[b] = min(max(ov, 0.0), c) / c if 0 <= ix < nx else 0.0
        for b in range(ky):
            iy = iy0 + b
            bottom = y0 + iy * c
            ov = min(yp + half_d, bottom + c) - max(yp - half_d, bottom)
            oy[b] = min(max(ov, 0.0), c) / c if 0 <= iy < ny else 0.0
        for by in range(ky):
            for bx in range(kx):
                Vs[by * kx + bx, j] = oy[by] * ox[bx]


@kernel
def _combine_each(F, D, m, n_live, live, base, fired, slow, alpha, beta, gamma, lo, ci, order, b0, out):
    """The per-particle combination of :func:`_log_likelihood` for a batch of ``m`` particles
    one at a time (many live sensors): the product rescaled into logs whenever it leaves
    ``[1e-200, 1e200]``; ``out[order[b0 + j]]`` gets particle ``j``'s log-likelihood."""
    for j in range(m):
        p = order[b0 + j]
        acc = base
        prod = 1.0
        for t in range(n_live):
            i = live[t]
            Fi = F[i, j]
            Di = D[i, j] if Fi > 0.5 else Fi - 1.0
            if fired[i]:
                prod *= min(max(alpha[i] + beta[i] * Di, PROB_FLOOR), 1.0) * gamma[i]
            elif slow[i]:
                acc += max(ci[i] + math.log(Fi), LOG_FLOOR) - LOG_FLOOR
            else:
                prod *= max(Fi, lo[i])
            if prod < 1e-200 or prod > 1e200:
                acc += math.log(prod)
                prod = 1.0
        out[p] = acc + math.log(prod)


@kernel
def _combine_batch(F, D, m, n_live, live, base, fired, slow, alpha, beta, gamma, lo, ci, acc, prod):
    """The per-particle combination of :func:`_log_likelihood` for a batch of ``m`` particles,
    sensor by sensor (loops over the batch the compiler vectorises): ``acc[j] + log(prod[j])``
    is particle ``j``'s log-likelihood, with the same operations in the same order as one
    particle at a time. Each factor lies in ``[1e-12, 1e12]`` (a fired sensor's probability
    ratio is at most ``1 / p_empty <= 1e12``, a silent one's at most 1), so with at most 16 live
    sensors the product stays within ``[1e-192, 1e192]``: the rescaling of the one-particle
    loop (at 1e-200 / 1e200) never happens, and is left out."""
    for j in range(m):
        acc[j] = base
        prod[j] = 1.0
    for t in range(n_live):
        i = live[t]
        Fr, Dr = F[i], D[i]
        if fired[i]:
            al, be, ga = alpha[i], beta[i], gamma[i]
            for j in range(m):
                Fi = Fr[j]
                Di = Dr[j] if Fi > 0.5 else Fi - 1.0
                prod[j] *= min(max(al + be * Di, PROB_FLOOR), 1.0) * ga
        elif slow[i]:
            cc = ci[i]
            for j in range(m):
                acc[j] += max(cc + math.log(Fr[j]), LOG_FLOOR) - LOG_FLOOR
        else:
            lw = lo[i]
            for j in range(m):
                prod[j] *= max(Fr[j], lw)


# --------------------------------------------------------------------------- estimate, resample


@kernel
def _estimate(x, y, w, grid, half_w, half_d, mask, d, cells):
    """:func:`onebit.trackers.intruder.filter.estimate_cell` (difference array in the same
    order of additions as its four ``np.add.at``); ``d`` is ``(ny + 1, nx + 1)`` scratch,
    ``cells`` ``(4, N)`` int64 scratch."""
    x0, y0, c, nx, ny = grid[0], grid[1], grid[2], int(grid[3]), int(grid[4])
    N = x.shape[0]
    ilo, ihi, jlo, jhi = cells[0], cells[1], cells[2], cells[3]
    for p in range(N):
        ilo[p] = int(min(max(math.ceil((x[p] - half_w - x0) / c - 0.5 - 1e-12), 0.0), float(nx)))
        ihi[p] = int(min(max(math.floor((x[p] + half_w - x0) / c - 0.5 + 1e-12), -1.0), float(nx - 1)))
        jlo[p] = int(min(max(math.ceil((y[p] - half_d - y0) / c - 0.5 - 1e-12), 0.0), float(ny)))
        jhi[p] = int(min(max(math.floor((y[p] + half_d - y0) / c - 0.5 + 1e-12), -1.0), float(ny - 1)))
    d[:, :] = 0.0
    for p in range(N):
        if ilo[p] <= ihi[p] and jlo[p] <= jhi[p]:
            d[jlo[p], ilo[p]] += w[p]
    for p in range(N):
        if ilo[p] <= ihi[p] and jlo[p] <= jhi[p]:
            d[jlo[p], ihi[p] + 1] += -w[p]
    for p in range(N):
        if ilo[p] <= ihi[p] and jlo[p] <= jhi[p]:
            d[jhi[p] + 1, ilo[p]] += -w[p]
    for p in range(N):
        if ilo[p] <= ihi[p] and jlo[p] <= jhi[p]:
            d[jhi[p] + 1, ihi[p] + 1] += w[p]
    for j in range(1, ny + 1):
        for i in range(nx + 1):
            d[j, i] = d[j - 1, i] + d[j, i]
    for j in range(ny + 1):
        for i in range(1, nx + 1):
            d[j, i] = d[j, i - 1] + d[j, i]
    bj, bi = 0, 0
    best = -np.inf
    first = True
    for j in range(ny):
        for i in range(nx):
            val = d[j, i] if mask[j, i] else -np.inf
            if first or val > best:
                best, bj, bi, first = val, j, i, False
    return x0 + (bi + 0.5) * c, y0 + (bj + 0.5) * c


@kernel
def _resample(w, rng, systematic, idx, cs):
    """Systematic (one uniform) or multinomial (``N`` uniforms) resampling indices into ``idx``
    (``cs``: ``(N,)`` scratch for the cumulative weights)."""
    n = w.shape[0]
    s = 0.0
    for i in range(n):
        s += w[i]
        cs[i] = s
    if systematic:
        r = rng.random()
        j = 0
        for i in range(n):
            u = (r + i) / n
            while j < n and cs[j] < u:
                j += 1
            idx[i] = min(j, n - 1)
    else:
        us = rng.random(n)
        for i in range(n):
            idx[i] = min(np.searchsorted(cs, us[i]), n - 1)


@kernel
def _update(k, x, y, theta, v, w, uniform, rng, fired, blind, model, rs, out, lw, scratch, idx, cells, buf):
    """Weigh, estimate, log and resample after the propagation of iteration ``k``; returns
    whether the weights are uniform afterwards. ``model`` (:class:`Model`), ``rs``
    (:class:`Resampling`), the outputs ``out`` (:class:`Outputs`, row ``k`` written); ``lw``,
    ``idx``, ``buf`` ``(N,)``, ``cells`` ``(4, N)`` and ``scratch`` are workspace."""
    N = x.shape[0]
    grid, cell_ptr, cell_sensor, cell_q, p0, xi, a = (
        model.grid, model.cell_ptr, model.cell_sensor, model.cell_q, model.p0, model.xi, model.a
    )  # fmt: skip
    half_w, half_d, mask = model.half_w, model.half_d, model.mask
    systematic, always, ess_threshold, pick = rs.systematic, rs.always, rs.ess_threshold, rs.pick
    est, ess, resampled, logged_xy, logged_w, spread = (
        out.est, out.ess, out.resampled, out.logged_xy, out.logged_w, out.spread
    )  # fmt: skip
    _log_likelihood(x, y, fired, blind, grid, cell_ptr, cell_sensor, cell_q, p0, xi, a, half_w, half_d, lw)
    mx = -np.inf
    log_uniform = math.log(1.0 / N)
    for p in range(N):
        lw[p] += log_uniform if uniform else math.log(max(w[p], 1e-300))
        if lw[p] > mx:
            mx = lw[p]
    tot = 0.0
    for p in range(N):
        w[p] = math.exp(lw[p] - mx)
        tot += w[p]
    s2 = 0.0
    mxw, myw = 0.0, 0.0
    for p in range(N):
        w[p] = w[p] / tot
        s2 += w[p] * w[p]
        mxw += w[p] * x[p]
        myw += w[p] * y[p]
    ess[k] = 1.0 / s2
    ex, ey = _estimate(x, y, w, grid, half_w, half_d, mask, scratch, cells)
    est[k, 0], est[k, 1] = ex, ey
    sp = 0.0
    for p in range(N):
        sp += w[p] * ((x[p] - mxw) ** 2 + (y[p] - myw) ** 2)
    spread[k] = math.sqrt(sp)
    for j in range(pick.shape[0]):
        logged_xy[k, j, 0], logged_xy[k, j, 1] = x[pick[j]], y[pick[j]]
        logged_w[k, j] = w[pick[j]]
    if always or ess[k] < ess_threshold * N:
        _resample(w, rng, systematic, idx, buf)
        for arr in (x, y, theta, v):
            for p in range(N):
                buf[p] = arr[idx[p]]
            arr[:] = buf
        for p in range(N):
            w[p] = 1.0 / N
        resampled[k] = True
        return True
    return False


@kernel
def _run_box(x, y, theta, v, w, rng, fired, blind, motion, box, model, rs, out, redraws, clamped):
    """Every iteration in a box room: propagate with ``motion`` (:class:`MotionParams`) in the
    room ``box`` then :func:`_update` (see the module docstring), with one workspace for the
    whole run (no allocation per iteration); ``redraws`` and ``clamped`` per iteration beside
    ``out``."""
    N = x.shape[0]
    lw = np.empty(N)
    scratch = np.empty((int(model.grid[4]) + 1, int(model.grid[3]) + 1))
    idx = np.empty(N, dtype=np.int64)
    buf = np.empty(N)
    cells = np.empty((4, N), dtype=np.int64)
    pack = np.empty((5, N))
    noise = np.empty((2, N))
    work = np.empty((6, N))
    cand = np.empty(N, dtype=np.int64)
    uniform = False
    for k in range(fired.shape[0]):  # sequential: each iteration needs the previous posterior
        r, c = _propagate_box(
            x,
            y,
            theta,
            v,
            rng,
            motion.period,
            motion.v_max,
            motion.speed_sigma,
            motion.turn_scale,
            motion.max_retries,
            box,
            idx,
            pack,
            noise,
            work,
            cand,
        )
        redraws[k], clamped[k] = r, c
        uniform = _update(
            k, x, y, theta, v, w, uniform, rng, fired[k], blind[k], model, rs, out, lw, scratch, idx, cells, buf
        )


@kernel
def _update_one(k, x, y, theta, v, w, uniform, rng, fired, blind, model, rs, out):
    """:func:`_update` for one iteration of a room that is not a box (propagated outside)."""
    N = x.shape[0]
    return _update(
        k, x, y, theta, v, w, uniform, rng, fired, blind, model, rs, out,
        np.empty(N),
        np.empty((int(model.grid[4]) + 1, int(model.grid[3]) + 1)),
        np.empty(N, dtype=np.int64),
        np.empty((4, N), dtype=np.int64),
        np.empty(N),
    )  # fmt: skip


# --------------------------------------------------------------------------- the deployment per cell


def cell_lists(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The deployed grids ``q (n, ny, nx)`` per cell: CSR ``(ptr (ny nx + 1,), sensor, q)``
    listing, for every cell (row-major), the sensors with ``q_ik > 0`` in sensor order."""
    n = q.shape[0]
    flat = q.reshape(n, int(np.prod(q.shape[1:])))
    cell, sensor = np.nonzero(flat.T)  # row-major over (cell, sensor): sensors in order per cell
    ptr = np.zeros(flat.shape[1] + 1, dtype=np.int64)
    np.add.at(ptr, cell + 1, 1)
    return np.cumsum(ptr), sensor.astype(np.int64), flat[sensor, cell].astype(np.float64)
