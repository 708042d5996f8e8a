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
``O(tracks x particles x sensors near them)``, not the whole array: the frame loop
(:func:`run_frames`) evaluates the near rows only, into a buffer kept between frames
(:func:`observation_update_local`, :func:`resampled_mean_near`), and nothing reads the others
-- on a 30 x 30 ceiling array with 10 people a frame costs about what it costs on 10 x 10
(``benchmarks/bench_binpf_scale.py``). What is left per frame over the whole array is
``O(tracks x sensors)`` without the particles (which sensors are near, the miss
probabilities), under a millisecond at 900 sensors and 40 tracks.

They equal the numpy functions to rounding (the sums run in another order and numba's
``exp``/``log`` may differ from numpy's in the last bit; ``tests/trackers/binpf/test_filter.py``
holds them to ``1e-9``); a whole run keeps its tracks unless a resampling draw falls within
that rounding of a particle's cumulative weight.
"""

from __future__ import annotations

import math
from typing import NamedTuple

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


#: :func:`exp_into`'s constants: ``log2(e)`` and ``ln 2`` in two parts (Cody and Waite), so that
#: ``y - k ln 2`` is exact to a few ulp for ``|k| < 2^20``.
_LOG2E = 1.4426950408889634
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10

#: :func:`observation_update` multiplies at most this many likelihood terms (each >= 1e-12)
#: before taking their log: the product stays above 1e-192, far from underflow.
LOG_EVERY = 16


@kernel
def _exp_poly(y):
    """``(p, k)`` with ``exp(y) = p 2^k``: a Taylor polynomial of degree 13 on
    ``r = y - k ln 2``, ``|r| <= ln 2 / 2`` (Cody and Waite's two-part ``ln 2``), in plain
    arithmetic that LLVM vectorises (:func:`exp_into`, :func:`footprints`)."""
    kf = math.floor(y * _LOG2E + 0.5)
    rr = (y - kf * _LN2_HI) - kf * _LN2_LO
    p = 1.0 / 6227020800.0
    p = p * rr + 1.0 / 479001600.0
    p = p * rr + 1.0 / 39916800.0
    p = p * rr + 1.0 / 3628800.0
    p = p * rr + 1.0 / 362880.0
    p = p * rr + 1.0 / 40320.0
    p = p * rr + 1.0 / 5040.0
    p = p * rr + 1.0 / 720.0
    p = p * rr + 1.0 / 120.0
    p = p * rr + 1.0 / 24.0
    p = p * rr + 1.0 / 6.0
    p = p * rr + 0.5
    p = p * rr + 1.0
    return p * rr + 1.0, (np.int64(kf) + 1023) << 52


@kernel
def exp_into(y, out, bits):
    """``out[j] = exp(y[j])`` for ``|y| <= 700``, within 2 ulp of ``math.exp``
    (:func:`_exp_poly`, ``2^k`` built in the int64 scratch ``bits`` and read as float64): a
    loop LLVM vectorises, ~2 ns an element against ~4 for the scalar library call."""
    n = y.size
    for j in range(n):
        out[j], bits[j] = _exp_poly(y[j])
    scale = bits[:n].view(np.float64)
    for j in range(n):
        out[j] *= scale[j]


@kernel
def footprints(x, sensors, radii, pd, edge, near):
    """Eq. (1) ``d (I, S, N)`` -- sensors before particles, so a row is one sensor over a
    track's particles -- where ``near[i, s]``, 0 elsewhere (below ``2^-54`` there). The
    logistic's ``exp`` is :func:`exp_into`'s, fused into the row's loop."""
    d = np.empty((x.shape[0], sensors.shape[0], x.shape[1]))
    footprints_into(x, sensors, radii, pd, edge, near, d, True)
    return d


@kernel
def footprints_into(x, sensors, radii, pd, edge, near, d, zero):
    """:func:`footprints` into ``d[:I]`` (a buffer kept between frames): the rows of the near
    sensors only, the others set to 0 when ``zero`` and left as they are otherwise (then no
    kernel reads them: :func:`track_miss`, :func:`weigh` and :func:`resampled_mean_near`
    visit near rows only). A frame's cost then follows the sensors near the tracks, not the
    array: no ``(I, S, N)`` array is filled or allocated."""
    I, N, S = x.shape[0], x.shape[1], sensors.shape[0]
    bits = np.empty(N, dtype=np.int64)
    px = np.empty(N)
    py = np.empty(N)
    for i in range(I):
        for n in range(N):  # the track's positions, contiguous
            px[n] = x[i, n, 0]
            py[n] = x[i, n, 1]
        for s in range(S):
            if not near[i, s]:
                if zero:
                    d[i, s, :] = 0.0
                continue
            sx, sy, rs = sensors[s, 0], sensors[s, 1], radii[s]
            row = d[i, s]
            if edge <= 0:
                for n in range(N):
                    dx = px[n] - sx
                    dy = py[n] - sy
                    row[n] = pd if math.sqrt(dx * dx + dy * dy) <= rs else 0.0
                continue
            for n in range(N):
                dx = px[n] - sx
                dy = py[n] - sy
                u = min(max((rs - math.sqrt(dx * dx + dy * dy)) / edge, -50.0), 50.0)
                row[n], bits[n] = _exp_poly(-u)
            scale = bits.view(np.float64)
            for n in range(N):
                row[n] = pd / (1.0 + row[n] * scale[n])


@kernel
def observation_update(x, r, z, sensors, radii, pd, pf, edge, silent):
    """Eqs. (4), (4'), (5): log-weights ``(I, N)`` (up to a per-track constant), updated
    existences ``(I,)`` and the footprints ``d (I, S, N)`` (:func:`footprints`: 0 away from the
    track); the compiled :func:`onebit.trackers.binpf.filter.observation_update` (its
    reference, equal to rounding), summing over the sensors near each track only
    (:func:`track_miss`, :func:`others_miss`, :func:`weigh`)."""
    near = near_sensors(x, sensors, radii, edge)
    d = footprints(x, sensors, radii, pd, edge, near)
    q = track_miss(d, r, near)
    ell, r_new = weigh(d, near, others_miss(q, pf), r, z, silent)
    return ell, r_new, d


@kernel
def observation_update_local(x, r, z, sensors, radii, pd, pf, edge, silent, dbuf):
    """:func:`observation_update` with the footprints in the buffer ``dbuf (>= I, S, N)``, near
    rows only (:func:`footprints_into`): the same log-weights and existences, bit for bit
    (every sum visits the same terms in the same order), and ``near (I, S)`` for
    :func:`resampled_mean_near`. Returns ``(ell, r_new, d, near)``, ``d`` a view of ``dbuf``."""
    I = x.shape[0]
    near = near_sensors(x, sensors, radii, edge)
    d = dbuf[:I]
    footprints_into(x, sensors, radii, pd, edge, near, d, False)
    q = track_miss(d, r, near)
    ell, r_new = weigh(d, near, others_miss(q, pf), r, z, silent)
    return ell, r_new, d, near


@kernel
def newborn_update(xb, rb, q_old, z, sensors, radii, pd, pf, edge, silent):
    """:func:`observation_update` of ``[old tracks, newborn xb]`` for the newborn only: their
    log-weights and existences, the old tracks entering through their ``q_old (I, S)`` alone.

    The old tracks have just been updated and resampled: their particles are copies of
    particles whose footprints are known, so ``q_old = 1 - r_i dbar_is`` with ``dbar`` the
    :func:`resampled_mean` is what :func:`track_miss` gives on the copies -- the same sums
    in the same order -- except on a sensor the copies' smaller box no longer reaches,
    where ``r dbar < 2^-54`` and ``1 - r dbar`` rounds to exactly the 1 it gives. So this
    equals the newborn's rows of :func:`observation_update` on the concatenation, bit for
    bit, without evaluating the old tracks' footprints again."""
    near = near_sensors(xb, sensors, radii, edge)
    d = footprints(xb, sensors, radii, pd, edge, near)
    I, B = q_old.shape[0], xb.shape[0]
    q = np.empty((I + B, q_old.shape[1]))
    q[:I] = q_old
    q[I:] = track_miss(d, rb, near)
    m = others_miss(q, pf)
    return weigh(d, near, m[I:], rb, z, silent)


@kernel
def track_miss(d, r, near):
    """``q (I, S)``: ``1 - r_i dbar_is`` (the mean footprint over the particles, ``d (I, S, N)``)
    where ``near[i, s]``, 1 elsewhere."""
    I, S, N = d.shape[0], d.shape[1], d.shape[2]
    q = np.ones((I, S))
    for i in range(I):
        # per near sensor, the sum over particles in order (the rows of the other sensors are
        # not read: :func:`footprints_into` may leave them unset)
        for s in range(S):
            if near[i, s]:
                acc = 0.0
                for n in range(N):
                    acc += d[i, s, n]
                q[i, s] = 1.0 - r[i] * (acc / N)
    return q


@kernel
def others_miss(q, pf):
    """``m (I, S)``: ``m_is = (1 - p_f) prod_{j != i} q_js`` by prefix and suffix products (the
    compiled :func:`onebit.trackers.binpf.filter.others_miss`)."""
    I, S = q.shape[0], q.shape[1]
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
    return m


@kernel
def weigh(d, near, m, r, z, silent):
    """Eqs. (4), (4'), (5) for tracks with footprints ``d (I, S, N)`` and the others' miss
    probabilities ``m (I, S)``: ``(ell (I, N), r_new (I,))``. A particle's log-likelihood is
    the log of the product of its terms, one log per :data:`LOG_EVERY` near sensors; every
    loop over particles is plain arithmetic that LLVM vectorises."""
    I, S, N = d.shape[0], d.shape[1], d.shape[2]
    ell = np.zeros((I, N))
    r_new = np.empty(I)
    prod = np.empty(N)
    log_keep = math.log1p(-silent) if silent > 0 else 0.0
    log_sil = math.log(silent) if silent > 0 else 0.0
    for i in range(I):
        ell0 = 0.0
        for s in range(S):
            if near[i, s]:
                mi = m[i, s]
                ell0 += math.log(max(1.0 - mi if z[s] else mi, _TINY))
        terms = 0
        for n in range(N):
            prod[n] = 1.0
        for s in range(S):
            if not near[i, s]:
                continue
            mi = m[i, s]
            if z[s]:  # on: 1 - m (1 - d)
                for n in range(N):
                    prod[n] *= max(1.0 - mi * (1.0 - d[i, s, n]), _TINY)
            else:  # off: m (1 - d)
                for n in range(N):
                    prod[n] *= max(mi * (1.0 - d[i, s, n]), _TINY)
            terms += 1
            if terms == LOG_EVERY:
                for n in range(N):
                    ell[i, n] += math.log(prod[n])
                    prod[n] = 1.0
                terms = 0
        for n in range(N):
            ell[i, n] += math.log(prod[n])
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
    return ell, r_new


@kernel
def resampled_mean(d, idx):
    """:math:`\\bar d_{is}` of the resampled particles ``idx (I, N)`` from their footprints before
    resampling ``d (I, S, N)`` (a resampled particle is a copy: its footprint is the
    original's), without evaluating a footprint again."""
    I, S, N = d.shape[0], d.shape[1], d.shape[2]
    out = np.zeros((I, S))
    for i in range(I):
        for n in range(N):  # the same order per sensor as one sum each, S sums side by side
            k = idx[i, n]
            for s in range(S):
                out[i, s] += d[i, s, k]
        for s in range(S):
            out[i, s] /= N
    return out


@kernel
def resampled_mean_near(d, idx, near):
    """:func:`resampled_mean` reading the near rows only (0 elsewhere): the same values where
    ``near`` (the same sums in the same order), without reading a row :func:`footprints_into`
    left unset."""
    I, S, N = d.shape[0], d.shape[1], d.shape[2]
    out = np.zeros((I, S))
    for i in range(I):
        for s in range(S):
            if near[i, s]:
                acc = 0.0
                for n in range(N):
                    acc += d[i, s, idx[i, n]]
                out[i, s] = acc / N
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


@kernel
def gather_shift(x, hist, idx, xo, ho):
    """The resampled copies of tracks ``0 .. I - 1`` (``I, N = idx.shape``) into ``xo`` and
    ``ho``, their histories moved on by a frame: ``xo[i, n] = x[i, k]``, ``ho[i, n, :L] =
    hist[i, k, 1:]``, ``ho[i, n, L] = x[i, k, :2]`` (``k = idx[i, n]``) -- the shift of
    :func:`onebit.trackers.binpf.filter.run_filter_reference` before its update, then its
    gather (:func:`gather_particles`), in one pass of copies."""
    I, N, L1 = idx.shape[0], idx.shape[1], hist.shape[2]
    for i in range(I):
        for n in range(N):
            k = idx[i, n]
            for c in range(x.shape[2]):
                xo[i, n, c] = x[i, k, c]
            for j in range(L1 - 1):
                ho[i, n, j, 0] = hist[i, k, j + 1, 0]
                ho[i, n, j, 1] = hist[i, k, j + 1, 1]
            ho[i, n, L1 - 1, 0] = x[i, k, 0]
            ho[i, n, L1 - 1, 1] = x[i, k, 1]


@kernel
def birth_groups_of(z, q, n_tracks, sensors, birth_explained, birth_link):
    """:func:`onebit.trackers.binpf.filter.birth_groups` compiled: ``(members, starts)`` -- the
    groups' sensors one after the other (each group by increasing sensor, groups by their
    lowest member, scipy's order) and where each group starts (``len(starts) - 1`` groups).
    ``q (I, S)`` of the first ``n_tracks`` tracks."""
    S = z.size
    cand = np.empty(S, dtype=np.int64)
    nc = 0
    for s in range(S):
        if not z[s]:
            continue
        prod = 1.0
        for i in range(n_tracks):
            prod *= q[i, s]
        explained = 1.0 - prod if n_tracks > 0 else 0.0
        if explained < birth_explained:
            cand[nc] = s
            nc += 1
    lab = np.arange(nc)
    new = np.empty(nc, dtype=np.int64)
    changed = True
    while changed:  # every sensor takes the lowest label among its neighbours (itself included)
        changed = False
        for a in range(nc):
            best = nc
            for b in range(nc):
                dx = sensors[cand[a], 0] - sensors[cand[b], 0]
                dy = sensors[cand[a], 1] - sensors[cand[b], 1]
                if math.sqrt(dx * dx + dy * dy) <= birth_link and lab[b] < best:
                    best = lab[b]
            new[a] = best
        for a in range(nc):
            if new[a] != lab[a]:
                changed = True
            lab[a] = new[a]
    members = np.empty(nc, dtype=np.int64)
    starts = np.empty(nc + 1, dtype=np.int64)
    ng = 0
    nm = 0
    for g in range(nc):  # labels are members' own indices: group g exists when some lab == g
        first = True
        for a in range(nc):
            if lab[a] == g:
                if first:
                    starts[ng] = nm
                    ng += 1
                    first = False
                members[nm] = cand[a]
                nm += 1
    starts[ng] = nm
    return members, starts[: ng + 1]


@kernel
def _grow(a, n):
    """``a`` with room for at least ``n`` rows along its first axis (doubling)."""
    if a.shape[0] >= n:
        return a
    cap = max(n, 2 * a.shape[0])
    out = np.empty((cap,) + a.shape[1:], dtype=a.dtype)
    out[: a.shape[0]] = a
    return out


class KernelParams(NamedTuple):
    """:func:`run_frames`' parameters: the :class:`~onebit.trackers.binpf.config.FilterParams`
    of the same names (declared there), as float64 / int64
    (:func:`onebit.trackers.binpf.filter.kernel_params`)."""

    pd: float
    pf: float
    edge: float
    period: float
    damping: float
    accel_sigma: float
    survival: float
    silent: float
    birth_r: float
    birth_explained: float
    birth_link: float
    birth_speed: float
    r_confirm: float
    r_delete: float
    merge_distance: float
    particles: int
    smooth_lag: int
    max_tracks: int
    log_particles: int  #: particles per track and frame logged


@kernel
def run_frames(  # noqa: PLR0913, PLR0915 -- one compiled frame loop: the filter's whole state is its arguments
    on,
    k0,
    k1,
    state,
    x_state,
    hist_state,
    rowidx,
    r,
    labels,
    confirmed,
    ever,
    est,
    rows_frame,
    rows_label,
    rows_r,
    counts,
    sensors,
    radii,
    lo,
    hi,
    rng,
    kp,
    dbuf,
):
    """Frames ``k0 .. k1 - 1`` of :func:`onebit.trackers.binpf.filter.run_filter_reference`, in
    one compiled loop with the same draws from the same ``numpy.random.Generator`` ``rng``
    (numba draws NumPy's stream), in the same order, and the same kernels for the update and
    the resampling.

    State (updated in place): ``state = [tracks, next_label, n_rows]``; per track slot
    ``x_state (M, N, 4)``, ``hist_state (M, N, L+1, 2)``, ``rowidx (M, L+1)``, ``r``, ``labels``,
    ``confirmed`` (first ``tracks`` live); ``ever[label]`` confirmed once (sized for every
    label the frames can make); the output rows ``est (rows, 2)``, ``rows_frame``,
    ``rows_label``, ``rows_r`` (sized for ``n_rows + M (k1 - k0)``); ``counts (T, 4)``:
    births, deaths, merges, live. ``kp``: the parameters (:class:`KernelParams`);
    ``dbuf (max_tracks, S, N)``: the footprints' buffer (:func:`observation_update_local`),
    kept by the caller, so that a frame neither allocates nor fills a ``(tracks, sensors,
    particles)`` array: its cost follows the sensors within reach of the tracks.
    Returns the logged particles of these frames: ``(xy (P, 2), frame (P,), label (P,))``.
    """
    pd, pf, edge, period = kp.pd, kp.pf, kp.edge, kp.period
    damping, accel_sigma, survival, silent = kp.damping, kp.accel_sigma, kp.survival, kp.silent
    birth_r, birth_explained, birth_link, birth_speed = kp.birth_r, kp.birth_explained, kp.birth_link, kp.birth_speed
    r_confirm, r_delete, merge_distance = kp.r_confirm, kp.r_delete, kp.merge_distance
    N, L, max_tracks, log_p = kp.particles, kp.smooth_lag, kp.max_tracks, kp.log_particles
    S = sensors.shape[0]
    I = state[0]
    next_label = state[1]
    n_rows = state[2]
    sig = accel_sigma * np.sqrt(period)
    # the particles and their histories, and a second pair the resampling gathers into (the
    # two are swapped, not copied back; the state arrays hold the result at the end)
    x, hist = x_state, hist_state
    x_alt, hist_alt = np.empty_like(x_state), np.empty_like(hist_state)
    flips = 0
    lp = min(log_p, N)
    pxy = np.empty((max(lp * max_tracks * min(k1 - k0, 64), 1), 2))
    pfr = np.empty(pxy.shape[0], dtype=np.int64)
    plab = np.empty(pxy.shape[0], dtype=np.int64)
    npl = 0
    keep = np.empty(max_tracks, dtype=np.bool_)
    mean = np.empty((max_tracks, 2))
    hsum = np.empty((L + 1, 2))
    for k in range(k0, k1):
        z = on[k]
        # Eq. (3): prediction, draws (tracks, particles, 2) in C order
        eps = rng.standard_normal(I * N * 2)
        for i in range(I):
            for n in range(N):
                for c in range(2):
                    v = damping * x[i, n, 2 + c] + sig * eps[(i * N + n) * 2 + c]
                    pos = x[i, n, c] + v * period
                    cl = min(max(pos, lo[c]), hi[c])
                    x[i, n, c] = cl
                    x[i, n, 2 + c] = 0.0 if cl != pos else v
            r[i] = r[i] * survival
            # (the histories move on by a frame in the resampling's gather: gather_shift)
            for j in range(L):
                rowidx[i, j] = rowidx[i, j + 1]
            rowidx[i, L] = -1
        dbar = np.zeros((I, S))  # the resampled particles' mean footprints
        if I > 0:  # existing tracks first: they get the first chance to explain the frame
            ell, rn, d, near = observation_update_local(x[:I], r[:I], z, sensors, radii, pd, pf, edge, silent, dbuf)
            u0 = rng.random(I).reshape(I, 1)
            idx = systematic_resample(ell, u0)
            gather_shift(x, hist, idx, x_alt, hist_alt)
            x, x_alt = x_alt, x
            hist, hist_alt = hist_alt, hist
            flips += 1
            r[:I] = rn
            dbar = resampled_mean_near(d, idx, near)
        q = 1.0 - dbar
        members, starts = birth_groups_of(z, q, I, sensors, birth_explained, birth_link)
        ng = starts.size - 1
        room = max_tracks - I
        if ng > 0 and room > 0:
            size = np.empty(ng, dtype=np.int64)
            for g in range(ng):
                size[g] = starts[g + 1] - starts[g]
            order = np.argsort(-size, kind="mergesort")[:room]  # largest first, stable
            nb = order.size
            for b in range(nb):
                g = order[b]
                ms = members[starts[g] : starts[g + 1]]
                which = ms[rng.integers(0, ms.size, N)]
                u = rng.random(N)
                turn = rng.random(N)
                vel = rng.standard_normal(N * 2)
                t = I + b
                for n in range(N):
                    rad = radii[which[n]] * np.sqrt(u[n])
                    ang = turn[n] * 2 * np.pi
                    x[t, n, 0] = sensors[which[n], 0] + rad * np.cos(ang)
                    x[t, n, 1] = sensors[which[n], 1] + rad * np.sin(ang)
                    x[t, n, 2] = birth_speed * vel[2 * n]
                    x[t, n, 3] = birth_speed * vel[2 * n + 1]
                    for j in range(L + 1):
                        hist[t, n, j, 0] = x[t, n, 0]
                        hist[t, n, j, 1] = x[t, n, 1]
                r[t] = birth_r
                for j in range(L + 1):
                    rowidx[t, j] = -1
                labels[t] = next_label + b
                confirmed[t] = False
            # the newborn are updated on this frame with the others' posterior miss probabilities
            # (the old tracks through their q alone: newborn_update, equal to observation_update's rows)
            q_old = np.empty((I, S))
            for i in range(I):
                for s in range(S):
                    q_old[i, s] = 1.0 - r[i] * dbar[i, s]
            ell, rb = newborn_update(x[I : I + nb], r[I : I + nb], q_old, z, sensors, radii, pd, pf, edge, silent)
            u0 = rng.random(nb).reshape(nb, 1)
            idx = systematic_resample(ell, u0)
            xo, ho = gather_particles(x[I : I + nb], hist[I : I + nb], idx)
            x[I : I + nb] = xo
            hist[I : I + nb] = ho
            r[I : I + nb] = rb
            next_label += nb
            counts[k, 0] = nb
            I += nb
        for i in range(I):
            confirmed[i] = confirmed[i] or r[i] >= r_confirm
            keep[i] = r[i] >= r_delete
        # merge: of two tracks closer than merge_distance keep the larger r
        n_merge = 0
        if I > 1 and merge_distance > 0:
            for i in range(I):
                for c in range(2):
                    acc = 0.0
                    for n in range(N):
                        acc += x[i, n, c]
                    mean[i, c] = acc / N
            order = np.argsort(-r[:I], kind="mergesort")
            for ap in range(I):
                a = order[ap]
                if not keep[a]:
                    continue
                for bp in range(ap + 1, I):
                    b = order[bp]
                    dx = mean[a, 0] - mean[b, 0]
                    dy = mean[a, 1] - mean[b, 1]
                    if keep[b] and np.sqrt(dx * dx + dy * dy) < merge_distance:
                        keep[b] = False
                        confirmed[a] = confirmed[a] or confirmed[b]
                        n_merge += 1
        n_drop = 0
        j = 0
        for i in range(I):  # compact the kept tracks to the front, in order
            if not keep[i]:
                n_drop += 1
                continue
            if j != i:
                x[j] = x[i]
                hist[j] = hist[i]
                rowidx[j] = rowidx[i]
                r[j] = r[i]
                labels[j] = labels[i]
                confirmed[j] = confirmed[i]
            j += 1
        I = j
        counts[k, 1] = n_drop - n_merge
        counts[k, 2] = n_merge
        counts[k, 3] = I
        for i in range(I):
            if confirmed[i]:
                ever[labels[i]] = True
            rowidx[i, L] = n_rows + i
            rows_frame[n_rows + i] = k
            rows_label[n_rows + i] = labels[i]
            rows_r[n_rows + i] = r[i]
        n_rows += I
        for i in range(I):  # every smoothed estimate still in the window
            hsum[:] = 0.0  # per (lag, axis): the sum over particles in order, side by side
            for n in range(N):
                for jj in range(L + 1):
                    hsum[jj, 0] += hist[i, n, jj, 0]
                    hsum[jj, 1] += hist[i, n, jj, 1]
            for jj in range(L + 1):
                row = rowidx[i, jj]
                if row >= 0:
                    est[row, 0] = hsum[jj, 0] / N
                    est[row, 1] = hsum[jj, 1] / N
        if lp > 0 and I > 0:
            need = npl + I * lp
            pxy = _grow(pxy, need)
            pfr = _grow(pfr, need)
            plab = _grow(plab, need)
            for i in range(I):
                for n in range(lp):
                    pxy[npl, 0] = x[i, n, 0]
                    pxy[npl, 1] = x[i, n, 1]
                    pfr[npl] = k
                    plab[npl] = labels[i]
                    npl += 1
    if flips % 2 == 1:  # the result is in the second pair
        x_state[:] = x
        hist_state[:] = hist
    state[0] = I
    state[1] = next_label
    state[2] = n_rows
    return pxy[:npl], pfr[:npl], plab[:npl]
