"""A labelled multi-Bernoulli particle filter over people under an array of binary sensors.

Model
-----
Sensor :math:`s` at :math:`p_s` with footprint radius :math:`R_s` reports a level
:math:`z_s \\in \\{0, 1\\}` every frame (a sensor held on is presence, not only its rising
edge). A person at :math:`x` triggers it with the soft footprint probability

.. math::

    d_s(x) = p_d \\, \\sigma\\!\\left(\\frac{R_s - \\lVert x - p_s \\rVert}{w}\\right),
    \\qquad \\sigma(u) = \\frac{1}{1 + e^{-u}}                                     \\tag{1}

(:math:`w \\to 0` is the hard disk of radius :math:`R_s`). People trigger independently and
the sensor fires on its own with the false-alarm rate :math:`p_f` (noisy-OR):

.. math::

    P(z_s = 0 \\mid x_1..x_n) = (1 - p_f) \\prod_i \\big(1 - d_s(x_i)\\big).        \\tag{2}

Filter
------
Track :math:`i` is a Bernoulli component: existence probability :math:`r_i` and :math:`N`
equally weighted particles :math:`x_i^{(n)} = (x, y, v_x, v_y)` after resampling.

*Prediction* (nearly-constant velocity, damped, frame period :math:`\\Delta`):

.. math::

    v' = a v + \\sigma_v \\sqrt{\\Delta}\\, \\varepsilon, \\quad x' = x + v' \\Delta, \\quad
    r' = p_s r                                                                     \\tag{3}

with positions clipped to the site's bounding box.

*Mean-field observation update.* The other tracks enter sensor :math:`s` through their
marginal miss probability :math:`q_{js} = 1 - r_j \\bar d_{js}`,
:math:`\\bar d_{js} = \\frac1N \\sum_n d_s(x_j^{(n)})`, so that

.. math::

    m_{is} = (1 - p_f) \\prod_{j \\ne i} q_{js}, \\qquad
    \\ell_i^{(n)} = \\sum_s \\log\\big[ z_s (1 - m_{is}(1 - d_s(x_i^{(n)})))
                                    + (1 - z_s)\\, m_{is}(1 - d_s(x_i^{(n)})) \\big]   \\tag{4}

is the log-likelihood of the frame with track :math:`i` present at particle :math:`n`, and
:math:`\\ell_i^{0} = \\sum_s \\log[z_s (1 - m_{is}) + (1 - z_s) m_{is}]` with track
:math:`i` absent. Real sensors miss a person for whole frames (a pyroelectric sensor goes
quiet over someone standing still; a reading arrives a frame late), so a present person is
*silent* -- triggers nothing -- with probability :math:`\\varepsilon` (``silent``):

.. math::

    \\ell_i^{(n)} \\leftarrow \\log\\big[(1 - \\varepsilon)\\, e^{\\ell_i^{(n)}}
                                  + \\varepsilon\\, e^{\\ell_i^{0}}\\big].                       \\tag{4'}

This bounds what one frame can do: the likelihood ratio below is at least
:math:`\\varepsilon`, so a reading that contradicts a track (every sensor over it off, a
far firing) lowers its existence by a bounded factor instead of zeroing it, and a firing
no particle explains leaves the particles' weights flat instead of degenerate. The
Bernoulli existence update is

.. math::

    L_i = \\frac1N \\sum_n e^{\\ell_i^{(n)} - \\ell_i^{0}}, \\qquad
    r_i \\leftarrow \\frac{r_i L_i}{r_i L_i + 1 - r_i},                            \\tag{5}

and particle :math:`n` is weighted by :math:`e^{\\ell_i^{(n)}}` and resampled
(systematic). The update is one Jacobi sweep: every track sees the others' predicted
:math:`q`. Sensors farther than :math:`R_s + 6w` from a particle contribute
:math:`d_s \\approx 0` and need no special case.

*Measurement-driven birth.* After the existing tracks' update, an on sensor is
unexplained when the updated tracks' particles -- whatever their existence -- trigger it with
probability below ``birth_explained``: :math:`1 - \\prod_j (1 - \\bar d_{js}) < \\beta` (a
tentative track by a firing gathers that firing's evidence over the frames; were its low
:math:`r_j` counted, a twin would be born beside it every frame and the two would split the
evidence and never be confirmed). Unexplained on sensors within ``birth_link`` of each
other form one group; each group gives a tentative track with existence ``birth_r`` and
particles drawn uniformly in the footprints of the group's sensors, zero-mean velocities;
the newborn are then updated on the same frame by Eqs. (4)-(5), the existing tracks
entering through their posterior :math:`q`. Existing tracks thus explain a frame first and
a person walking to the next sensor moves its track there instead of spawning a new one.

*Track management* (the cardinality). A track is confirmed the first time
:math:`r_i \\ge r_{\\mathrm{confirm}}` (and then reported back to its birth: the run is a
batch), deleted when :math:`r_i < r_{\\mathrm{delete}}`;
two tracks whose means come closer than ``merge_distance`` keep the one with the larger
:math:`r`. At most ``max_tracks`` tracks live at once (the lowest :math:`r` go first), so
the cost of a frame is :math:`O(\\text{max\\_tracks} \\cdot N \\cdot S)` whatever the number
of people. A confirmed track with :math:`r_i \\ge r_{\\mathrm{out}}` is reported at its
particle mean; at most ``max_out`` (the site's ``targets``) are reported per frame, the
largest :math:`r` first. Identities are the tracks' labels.

*Split* (two people under overlapping footprints; ``split_ratio > 0``). The mean-field update
cannot resolve two people half a metre apart: given a track's marginal, a second track's
best place is on top of it (it shares both people's firings), so two tracks of a close pair
drift together and merge. A split is a move of the field's kind (a twin proposed, kept if the
likelihood supports the larger cardinality) with a joint update of the pair:

1. *Proposal.* For every on sensor :math:`c` the tracks already explain
   (:math:`1 - \\prod_j q_{jc} \\ge \\beta`), a twin with particles uniform in :math:`c`'s
   footprint is scored by its Bernoulli likelihood ratio :math:`L_c` of Eq. (5), the tracks
   entering through their posterior :math:`q`; twins with :math:`L_c \\ge` ``split_ratio``
   (the frame is more probable with one more person there than without) are born, the
   largest :math:`L_c` first, none within ``birth_link`` of another, each coupled to the
   nearest uncoupled track.
2. *Joint update of a couple* :math:`(a, b)`: their particles are taken side by side, particle
   :math:`n` of both scored by the joint likelihood of Eq. (2) with both present

   .. math::

       \\ell_{ab}^{(n)} = \\sum_s \\log\\big[z_s (1 - o_s^{(n)}) + (1 - z_s)\\, o_s^{(n)}\\big],
       \\quad o_s^{(n)} = (1 - p_f) \\prod_{j \\ne a, b} q_{js}\\,
                          \\big(1 - d_s(x_a^{(n)})\\big)\\big(1 - d_s(x_b^{(n)})\\big)   \\tag{6}

   and both resampled with the same indices, so a pair of positions that explains the
   firings' spread together survives (particle :math:`n` of :math:`a` on the left is weighed
   with particle :math:`n` of :math:`b` on the right), not each track alone at the centre.
   Existences stay Eq. (5). A couple is not merged; it ends when either dies or their means
   are more than ``couple_distance`` apart.

The split runs in :func:`run_filter_reference` (``run_filter`` uses it whatever the length
when ``split_ratio > 0``; the compiled loop has no split).

The frames are processed in order (a filter is sequential); every step inside a frame is
vectorised over tracks, particles and sensors -- or, on logs of :data:`COMPILED_MIN_FRAMES`
frames or more, compiled (:mod:`onebit.trackers.binpf.kernels`: the sensors far from a track,
whose footprint is below ``2^-54``, are skipped).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from onebit.core.params import kernel_tuple
from onebit.trackers.binpf import kernels
from onebit.trackers.binpf.config import FilterParams

_TINY = 1e-12

#: :func:`run_filter` uses the compiled update from this many frames on.
COMPILED_MIN_FRAMES = 300


@dataclass
class FilterResult:
    """Per frame and track: ``frame``, ``label``, ``x``, ``y``, ``r``, ``reported`` (1-D arrays
    of one row per live track per frame), and per frame ``births``, ``deaths``, ``merges``,
    ``live``; the particles of every frame (``particles_xy`` (rows, 2), ``particles_frame``,
    ``particles_label``) for drawing."""

    frame: np.ndarray
    label: np.ndarray
    x: np.ndarray
    y: np.ndarray
    r: np.ndarray
    reported: np.ndarray
    births: np.ndarray
    deaths: np.ndarray
    merges: np.ndarray
    live: np.ndarray
    particles_xy: np.ndarray
    particles_frame: np.ndarray
    particles_label: np.ndarray


def kernel_params(p: FilterParams, log_particles: int) -> kernels.KernelParams:
    """The compiled loop's parameters: ``p``'s of the same names, and ``log_particles`` (>= 0)."""
    values = {n: getattr(p, n) for n in kernels.KernelParams._fields if n != "log_particles"}
    return kernel_tuple(kernels.KernelParams, **values, log_particles=max(int(log_particles), 0))


def footprint_probability(
    xy: np.ndarray, sensors: np.ndarray, radii: np.ndarray, *, pd: float, edge: float
) -> np.ndarray:
    """Eq. (1): ``d[..., s]`` for positions ``xy (..., 2)``, sensors ``(S, 2)``, radii ``(S,)``."""
    dist = np.sqrt(((xy[..., None, :] - sensors) ** 2).sum(-1))
    if edge <= 0:
        return np.where(dist <= radii, pd, 0.0)
    u = np.clip((radii - dist) / edge, -50.0, 50.0)
    return pd / (1.0 + np.exp(-u))


def frame_probability_off(
    positions: np.ndarray, sensors: np.ndarray, radii: np.ndarray, *, pd: float, pf: float, edge: float
) -> np.ndarray:
    """Eq. (2): ``P(z_s = 0 | positions (n, 2))`` for every sensor, ``(S,)``."""
    d = footprint_probability(positions, sensors, radii, pd=pd, edge=edge)
    return (1.0 - pf) * np.prod(1.0 - d, axis=0)


def predict(
    x: np.ndarray, r: np.ndarray, rng: np.random.Generator, p: FilterParams, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (3) on particles ``x (I, N, 4)`` and existences ``r (I,)``; returns new arrays."""
    v = p.damping * x[..., 2:] + p.accel_sigma * np.sqrt(p.period) * rng.standard_normal(x[..., 2:].shape)
    pos = x[..., :2] + v * p.period
    clipped = np.clip(pos, lo, hi)
    v = np.where(clipped != pos, 0.0, v)  # a particle that hits the wall stops
    return np.concatenate([clipped, v], axis=-1), r * p.survival


def others_miss(q: np.ndarray, pf: float) -> np.ndarray:
    """``m (I, S)`` of Eq. (4): ``(1 - p_f) prod_{j != i} q_js`` from ``q (I, S)``, by prefix and
    suffix products (no division, exact when some ``q_js`` is 0)."""
    n = q.shape[0]
    ones = np.ones((1, q.shape[1]))
    pre = np.cumprod(np.vstack([ones, q[:-1]]), axis=0) if n else q
    suf = np.cumprod(np.vstack([ones, q[::-1][:-1]]), axis=0)[::-1] if n else q
    return (1.0 - pf) * pre * suf


def observation_update(
    x: np.ndarray, r: np.ndarray, z: np.ndarray, sensors: np.ndarray, radii: np.ndarray, p: FilterParams
) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. (4)-(5): log-weights ``(I, N)`` of the particles and updated existences ``(I,)``."""
    d = footprint_probability(x[..., :2], sensors, radii, pd=p.pd, edge=p.edge)  # (I, N, S)
    q = 1.0 - r[:, None] * d.mean(axis=1)  # (I, S)
    m = others_miss(q, p.pf)  # (I, S)
    off_present = m[:, None, :] * (1.0 - d)  # (I, N, S)
    zb = z[None, None, :]
    like = np.where(zb, 1.0 - off_present, off_present)
    ell = np.log(np.maximum(like, _TINY)).sum(-1)  # (I, N)
    ell0 = np.log(np.maximum(np.where(z[None, :], 1.0 - m, m), _TINY)).sum(-1)  # (I,)
    if p.silent > 0:  # Eq. (4'): a present person is silent this frame with probability eps
        ell = np.logaddexp(np.log1p(-p.silent) + ell, np.log(p.silent) + ell0[:, None])
    rel = ell - ell0[:, None]
    top = rel.max(axis=1)
    L_log = top + np.log(np.exp(rel - top[:, None]).mean(axis=1))  # log L_i
    # r L / (r L + 1 - r) in log space
    with np.errstate(divide="ignore"):
        a = np.log(np.maximum(r, _TINY)) + L_log
        b = np.log(np.maximum(1.0 - r, _TINY))
    r_new = 1.0 / (1.0 + np.exp(np.clip(b - a, -700, 700)))
    return ell, r_new


def systematic_resample(logw: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices ``(I, N)`` drawn by systematic resampling of every row of ``logw (I, N)``."""
    I, N = logw.shape
    w = np.exp(logw - logw.max(axis=1, keepdims=True))
    c = np.cumsum(w, axis=1)
    c /= c[:, -1:]
    u = (rng.random((I, 1)) + np.arange(N)[None, :]) / N
    idx = np.empty((I, N), dtype=np.int64)
    for i in range(I):  # one searchsorted per track (rows are few; vectorised inside)
        idx[i] = np.minimum(np.searchsorted(c[i], u[i], side="right"), N - 1)
    return idx


def birth_groups(z: np.ndarray, q: np.ndarray, sensors: np.ndarray, p: FilterParams) -> list[np.ndarray]:
    """Groups of unexplained on sensors (indices), see "Measurement-driven birth"."""
    explained = 1.0 - np.prod(q, axis=0) if q.size else np.zeros(len(z))
    cand = np.nonzero(z & (explained < p.birth_explained))[0]
    if cand.size == 0:
        return []
    pts = sensors[cand]
    adj = np.sqrt(((pts[:, None] - pts[None]) ** 2).sum(-1)) <= p.birth_link
    # connected components, numbered by their lowest member (as scipy's csgraph numbers them):
    # every sensor takes the lowest label among its neighbours until nothing changes (the few
    # on sensors of a frame: no sparse matrix to build)
    lab = np.arange(cand.size)
    while True:
        new = np.where(adj, lab[None, :], cand.size).min(axis=1)
        if np.array_equal(new, lab):
            break
        lab = new
    return [cand[lab == g] for g in np.unique(lab)]


def birth_particles(
    group: np.ndarray, sensors: np.ndarray, radii: np.ndarray, rng: np.random.Generator, p: FilterParams
) -> np.ndarray:
    """``(N, 4)`` particles uniform in the footprints of ``group``'s sensors, velocities
    :math:`\\mathcal N(0, \\sigma_b^2)`."""
    N = p.particles
    which = group[rng.integers(0, len(group), N)]
    rad = radii[which] * np.sqrt(rng.random(N))
    ang = rng.random(N) * 2 * np.pi
    xy = sensors[which] + np.c_[rad * np.cos(ang), rad * np.sin(ang)]
    v = p.birth_speed * rng.standard_normal((N, 2))
    return np.c_[xy, v]


def split_proposals(z, q, x, r, sensors, radii, rng, p, update, room):
    """Twin particles ``(B, N, 4)`` for the on sensors the tracks explain whose twin's
    likelihood ratio (Eq. (5), the tracks entering through their posterior) is at least
    ``split_ratio``; see "Split"."""
    explained = 1.0 - np.prod(q, axis=0)
    cand = np.flatnonzero(z & (explained >= p.birth_explained))
    if cand.size == 0:
        return np.zeros((0, p.particles, 4))
    tx = np.stack([birth_particles(np.array([s]), sensors, radii, rng, p) for s in cand])
    L = np.empty(cand.size)
    for c in range(cand.size):
        _, rr, _ = update(np.concatenate([x, tx[c : c + 1]]), np.concatenate([r, [p.birth_r]]))
        rb = min(max(rr[-1], 1e-300), 1 - 1e-16)
        L[c] = rb * (1 - p.birth_r) / (p.birth_r * (1 - rb))
    order = np.argsort(-L, kind="stable")
    chosen: list[int] = []
    for c in order:
        if L[c] < p.split_ratio or len(chosen) >= room:
            break
        if all(np.hypot(*(sensors[cand[c]] - sensors[cand[o]])) > p.birth_link for o in chosen):
            chosen.append(int(c))
    return tx[chosen]


def pair_loglik(x, r, z, ia, ib, sensors, radii, p):
    """Joint log-likelihood ``(N,)`` of a coupled pair's particles taken side by side: track
    ``ia``'s particle ``n`` and track ``ib``'s particle ``n`` present together, the other tracks
    entering through their marginal miss probabilities; see "Split"."""
    d = footprint_probability(x[..., :2], sensors, radii, pd=p.pd, edge=p.edge)  # (I, N, S)
    q = 1.0 - r[:, None] * d.mean(axis=1)
    others = np.ones(len(r), bool)
    others[[ia, ib]] = False
    m = (1.0 - p.pf) * np.prod(q[others], axis=0)  # (S,)
    off = m[None, :] * (1.0 - d[ia]) * (1.0 - d[ib])  # (N, S)
    like = np.where(z[None, :], 1.0 - off, off)
    return np.log(np.maximum(like, _TINY)).sum(-1)


def report_rows(
    frame: np.ndarray, label: np.ndarray, r: np.ndarray, confirmed_labels: np.ndarray, p: FilterParams
) -> np.ndarray:
    """Which rows are reported: the track was confirmed at some frame (the run is a batch, so
    a confirmed track is reported back to its birth), :math:`r \\ge r_{out}` at the row's
    frame, and at most ``max_out`` per frame, the largest :math:`r` first."""
    rep = np.isin(label, confirmed_labels) & (r >= p.r_out)
    if p.max_out > 0 and rep.any():
        idx = np.nonzero(rep)[0]
        order = idx[np.lexsort((-r[idx], frame[idx]))]  # by frame, then r descending
        f = frame[order]
        first = np.searchsorted(f, f, side="left")
        rank = np.arange(len(order)) - first
        rep[order[rank >= p.max_out]] = False
    return rep


#: :func:`run_filter`'s compiled loop runs this many frames per call (between calls: progress).
CHUNK_FRAMES = 20_000


def run_filter(
    on: np.ndarray,
    sensors: np.ndarray,
    radii: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    p: FilterParams,
    *,
    seed: int = 0,
    log_particles: int = 0,
    progress=None,
    compiled: bool | None = None,
) -> FilterResult:
    """Run the filter over frames ``on (T, S)`` (bool levels); see the module docstring.

    ``compiled`` (``None`` = from :data:`COMPILED_MIN_FRAMES` frames on): every frame in one
    compiled loop (:func:`onebit.trackers.binpf.kernels.run_frames`, :data:`CHUNK_FRAMES`
    frames a call) -- the same steps as :func:`run_filter_reference` with ``compiled=True``,
    its plain reference and test oracle, drawing the same numbers from the same generator in
    the same order (numba draws NumPy's stream): the same tracks, to rounding (numba's
    ``sin``/``cos``/``exp`` may differ from numpy's in the last bit). Measured on the
    simulated 19-sensor line: ~0.1 ms a frame against ~2 ms for the per-frame Python loop.
    ``compiled=False``: :func:`run_filter_reference` with the numpy update.
    """
    T, S = on.shape
    if compiled is None:
        compiled = T >= COMPILED_MIN_FRAMES
    if not compiled or p.split_ratio > 0:  # the split is in the reference loop only
        return run_filter_reference(
            on, sensors, radii, lo, hi, p, seed=seed, log_particles=log_particles, progress=progress, compiled=False
        )
    rng = np.random.default_rng(seed)
    on = np.ascontiguousarray(on, dtype=np.bool_)
    sensors = np.ascontiguousarray(sensors, dtype=np.float64).reshape(-1, 2)
    radii = np.ascontiguousarray(radii, dtype=np.float64)
    N, L, M = p.particles, p.smooth_lag, p.max_tracks
    state = np.zeros(3, dtype=np.int64)  # live tracks, next label, rows written
    x = np.zeros((M, N, 4))
    hist = np.zeros((M, N, L + 1, 2))
    rowidx = np.full((M, L + 1), -1, dtype=np.int64)
    r = np.zeros(M)
    labels = np.zeros(M, dtype=np.int64)
    confirmed = np.zeros(M, dtype=bool)
    ever = np.zeros(0, dtype=bool)
    est = np.zeros((0, 2))
    rows_frame = np.zeros(0, dtype=np.int64)
    rows_label = np.zeros(0, dtype=np.int64)
    rows_r = np.zeros(0)
    counts = np.zeros((T, 4), dtype=np.int64)
    kp = kernel_params(p, log_particles)
    pxy, pfr, plab = [], [], []
    dbuf = np.empty((M, S, N))  # the footprints, near rows only (kernels.footprints_into)
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    for k0 in range(0, T, CHUNK_FRAMES):
        k1 = min(T, k0 + CHUNK_FRAMES)
        n_rows, next_label = int(state[2]), int(state[1])
        need = n_rows + M * (k1 - k0)  # at most M rows and M births a frame
        if est.shape[0] < need:
            cap = max(need, 2 * est.shape[0])
            est = np.concatenate([est, np.zeros((cap - est.shape[0], 2))])
            rows_frame = np.concatenate([rows_frame, np.zeros(cap - rows_frame.size, dtype=np.int64)])
            rows_label = np.concatenate([rows_label, np.zeros(cap - rows_label.size, dtype=np.int64)])
            rows_r = np.concatenate([rows_r, np.zeros(cap - rows_r.size)])
        if ever.size < next_label + M * (k1 - k0):
            ever = np.concatenate([ever, np.zeros(max(M * (k1 - k0), ever.size), dtype=bool)])
        a, b, c = kernels.run_frames(
            on, k0, k1, state, x, hist, rowidx, r, labels, confirmed, ever, est,
            rows_frame, rows_label, rows_r, counts, sensors, radii, lo, hi, rng, kp, dbuf,
        )  # fmt: skip
        pxy.append(a)
        pfr.append(b)
        plab.append(c)
        if progress is not None:
            progress(k1, T)
    n_rows = int(state[2])
    frame, label, rr = rows_frame[:n_rows].copy(), rows_label[:n_rows].copy(), rows_r[:n_rows].copy()
    reported = report_rows(frame, label, rr, np.flatnonzero(ever).astype(np.int64), p)
    return FilterResult(
        frame=frame,
        label=label,
        x=est[:n_rows, 0].copy(),
        y=est[:n_rows, 1].copy(),
        r=rr,
        reported=reported,
        births=counts[:, 0].copy(),
        deaths=counts[:, 1].copy(),
        merges=counts[:, 2].copy(),
        live=counts[:, 3].copy(),
        particles_xy=np.concatenate(pxy) if pxy else np.zeros((0, 2)),
        particles_frame=np.concatenate(pfr) if pfr else np.zeros(0, np.int64),
        particles_label=np.concatenate(plab) if plab else np.zeros(0, np.int64),
    )


def run_filter_reference(
    on: np.ndarray,
    sensors: np.ndarray,
    radii: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    p: FilterParams,
    *,
    seed: int = 0,
    log_particles: int = 0,
    progress=None,
    compiled: bool | None = None,
) -> FilterResult:
    """The filter over frames ``on (T, S)`` (bool levels), one Python step per frame: the plain
    reference of :func:`run_filter`'s compiled loop; see the module docstring.

    Positions are fixed-lag smoothed by the particles' genealogy: every track keeps its
    particles' positions of the last ``smooth_lag`` frames, permuted by each resampling, so
    the estimate of frame :math:`k` is the mean over the particles that survived to
    :math:`k + \\text{lag}` of where their ancestors were at :math:`k` (a later reading that
    says where a person went corrects where they were).

    ``compiled``: the observation update, the birth test's footprints and the resampling by
    the kernels of :mod:`onebit.trackers.binpf.kernels` (a frame's cost follows the sensors
    near the tracks; the same random draws, equal to rounding); ``None`` = from
    :data:`COMPILED_MIN_FRAMES` frames on (below, numba's start-up in a fresh process costs
    more than it saves).
    """
    rng = np.random.default_rng(seed)
    T, S = on.shape
    if compiled is None:
        compiled = T >= COMPILED_MIN_FRAMES
    sensors = np.ascontiguousarray(sensors, dtype=np.float64)
    radii = np.ascontiguousarray(radii, dtype=np.float64)

    def update(xs, rs):
        if compiled:
            return kernels.observation_update(
                np.ascontiguousarray(xs), rs, z, sensors, radii, p.pd, p.pf, p.edge, p.silent
            )
        return (*observation_update(xs, rs, z, sensors, radii, p), None)

    N = p.particles
    L = p.smooth_lag
    x = np.zeros((0, N, 4))
    hist = np.zeros((0, N, L + 1, 2))  # positions at frames k-L..k (last = now)
    rowidx = np.zeros((0, L + 1), dtype=np.int64)  # row of (track, frame k-L+j), -1 = none
    r = np.zeros(0)
    labels = np.zeros(0, dtype=np.int64)
    partner: dict[int, int] = {}  # label -> label of its coupled twin ("Split")
    confirmed = np.zeros(0, dtype=bool)
    ever_confirmed: set[int] = set()
    next_label = 0
    n_rows = 0
    cap = 1024
    est = np.zeros((cap, 2))
    rows: dict[str, list] = {k: [] for k in ("frame", "label", "r")}
    births = np.zeros(T, np.int64)
    deaths = np.zeros(T, np.int64)
    merges = np.zeros(T, np.int64)
    live = np.zeros(T, np.int64)
    pxy, pfr, plab = [], [], []

    def resampled(ell, xs, hs):
        if compiled:  # the same draw per track, the walk and the copies compiled
            idx = kernels.systematic_resample(np.ascontiguousarray(ell), rng.random((len(ell), 1)))
            return (*kernels.gather_particles(np.ascontiguousarray(xs), np.ascontiguousarray(hs), idx), idx)
        idx = systematic_resample(ell, rng)
        return np.take_along_axis(xs, idx[..., None], axis=1), np.take_along_axis(hs, idx[..., None, None], axis=1), idx

    for k in range(T):
        z = on[k]
        x, r = predict(x, r, rng, p, lo, hi)
        hist = np.concatenate([hist[:, :, 1:], x[:, :, None, :2]], axis=2)
        rowidx = np.concatenate([rowidx[:, 1:], np.full((len(r), 1), -1)], axis=1)
        if len(r):  # existing tracks first: they get the first chance to explain the frame
            ell, r, d = update(x, r)
            pairs = [
                (int(np.flatnonzero(labels == a)[0]), int(np.flatnonzero(labels == b)[0]))
                for a, b in partner.items()
                if a < b and a in labels and b in labels
            ]
            if pairs:
                ell = ell.copy()
                for ia, ib in pairs:
                    ell[ia] = ell[ib] = pair_loglik(x, r, z, ia, ib, sensors, radii, p)
                idx = systematic_resample(ell, rng)
                for ia, ib in pairs:
                    idx[ib] = idx[ia]
                x = np.take_along_axis(x, idx[..., None], axis=1)
                hist = np.take_along_axis(hist, idx[..., None, None], axis=1)
            else:
                x, hist, idx = resampled(ell, x, hist)
        # birth from the on sensors the updated tracks' particles leave unexplained (whatever
        # their existence: a tentative track near a firing gathers its evidence, no twin is born)
        if not len(r):
            q = np.zeros((0, S))
        elif compiled:  # the resampled particles' footprints are the update's, copied
            q = 1.0 - kernels.resampled_mean(d, idx)
        else:
            q = 1.0 - footprint_probability(x[..., :2], sensors, radii, pd=p.pd, edge=p.edge).mean(axis=1)
        groups = birth_groups(z, q, sensors, p)
        room = p.max_tracks - len(r)
        newx = None
        if groups and room > 0:
            groups = sorted(groups, key=len, reverse=True)[:room]
            newx = np.stack([birth_particles(g, sensors, radii, rng, p) for g in groups])
        if p.split_ratio > 0 and len(r) and room - len(groups) > 0:
            twins = split_proposals(z, q, x, r, sensors, radii, rng, p, update, room - len(groups))
            mean_old = x[..., :2].mean(axis=1)
            for t_i, tw in enumerate(twins):  # each twin is coupled to the nearest uncoupled track
                dd = np.hypot(*(mean_old - tw[:, :2].mean(axis=0)).T)
                for j in np.argsort(dd):
                    if int(labels[j]) not in partner:
                        a, b = int(labels[j]), next_label + len(groups) + t_i
                        partner[a], partner[b] = b, a
                        break
            if len(twins):
                groups = [*groups, *([None] * len(twins))]
                newx = twins if newx is None else np.concatenate([newx, twins])
        if newx is not None:
            newr = np.full(len(groups), p.birth_r)
            # the newborn are updated on this frame with the others' posterior miss probabilities
            ell, rall, _ = update(np.concatenate([x, newx]), np.concatenate([r, newr]))
            nb = slice(len(r), None)
            newh = np.repeat(newx[:, :, None, :2], L + 1, axis=2)
            newx, newh, _ = resampled(ell[nb], newx, newh)
            x, hist, r = np.concatenate([x, newx]), np.concatenate([hist, newh]), np.concatenate([r, rall[nb]])
            rowidx = np.concatenate([rowidx, np.full((len(groups), L + 1), -1)])
            labels = np.concatenate([labels, np.arange(next_label, next_label + len(groups))])
            confirmed = np.concatenate([confirmed, np.zeros(len(groups), bool)])
            next_label += len(groups)
            births[k] = len(groups)
        confirmed |= r >= p.r_confirm
        keep = r >= p.r_delete
        # merge: of two tracks closer than merge_distance keep the larger r
        mean = x[..., :2].mean(axis=1)
        if len(r) > 1 and p.merge_distance > 0:
            dm = np.sqrt(((mean[:, None] - mean[None]) ** 2).sum(-1))
            order = np.argsort(-r, kind="stable")
            for a_pos, a in enumerate(order):  # tracks are few (<= max_tracks)
                if not keep[a]:
                    continue
                for b in order[a_pos + 1 :]:
                    if keep[b] and dm[a, b] < p.merge_distance and partner.get(int(labels[a])) != int(labels[b]):
                        keep[b] = False
                        confirmed[a] |= confirmed[b]
                        merges[k] += 1
        deaths[k] = int((~keep).sum()) - merges[k]
        x, hist, rowidx, r, labels, confirmed = (
            x[keep],
            hist[keep],
            rowidx[keep],
            r[keep],
            labels[keep],
            confirmed[keep],
        )
        ever_confirmed.update(labels[confirmed].tolist())
        if partner:  # a couple ends when one dies or the two are far apart
            mean = x[..., :2].mean(axis=1)
            pos = {int(lab): i for i, lab in enumerate(labels)}
            for a, b in list(partner.items()):
                if a not in pos or b not in pos or np.hypot(*(mean[pos[a]] - mean[pos[b]])) > p.couple_distance:
                    partner.pop(a, None)
        live[k] = len(r)
        # this frame's rows, then every smoothed estimate still in the window
        rowidx[:, -1] = n_rows + np.arange(len(r))
        n_rows += len(r)
        if n_rows > cap:
            cap = max(2 * cap, n_rows)
            est = np.concatenate([est, np.zeros((cap - len(est), 2))])
        m = rowidx >= 0
        est[rowidx[m]] = hist.mean(axis=1)[m]
        rows["frame"].append(np.full(len(r), k))
        rows["label"].append(labels.copy())
        rows["r"].append(r.copy())
        if log_particles > 0 and len(r):
            sub = x[:, : min(log_particles, N), :2]
            pxy.append(sub.reshape(-1, 2))
            pfr.append(np.full(sub.shape[0] * sub.shape[1], k))
            plab.append(np.repeat(labels, sub.shape[1]))
        if progress is not None:
            progress(k + 1, T)
    cat = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in rows.items()}
    frame, label = cat["frame"].astype(np.int64), cat["label"].astype(np.int64)
    reported = report_rows(frame, label, cat["r"], np.array(sorted(ever_confirmed), dtype=np.int64), p)
    return FilterResult(
        frame=frame,
        label=label,
        x=est[:n_rows, 0].copy(),
        y=est[:n_rows, 1].copy(),
        r=cat["r"],
        reported=reported,
        births=births,
        deaths=deaths,
        merges=merges,
        live=live,
        particles_xy=np.concatenate(pxy) if pxy else np.zeros((0, 2)),
        particles_frame=np.concatenate(pfr) if pfr else np.zeros(0, np.int64),
        particles_label=np.concatenate(plab) if plab else np.zeros(0, np.int64),
    )
