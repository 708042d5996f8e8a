"""A labelled multi-Bernoulli particle filter over people under an array of binary sensors.

Model
-----
The sensor model is :mod:`onebit.trackers.binpf.footprint`: sensor :math:`s` reports a level
:math:`z_s \\in \\{0, 1\\}` every frame, a person at :math:`x` triggers it with its soft footprint
probability :math:`d_s(x)` (Eq. (1)), people trigger independently and the sensor fires on its
own with the false-alarm rate :math:`p_f`: :math:`P(z_s = 0 \\mid x_1..x_n)` is the noisy-OR of
Eq. (2).

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

*Split* and *count* (``split_ratio > 0``, ``count_ratio > 0``): the opt-in moves of
:mod:`onebit.trackers.binpf.moves` (Eqs. (6)-(8)) -- a twin proposed beside a track where the
firings' spread says two people stand close, and births where a cluster's local MAP count
exceeds its tracks. *Joint update* (``joint_distance > 0``, :mod:`onebit.trackers.binpf.joint`,
Eqs. (11)-(13)): close tracks weighed in pairs by the joint likelihood instead of Eq. (4); with
``joint_met`` only the pairs that met (Eq. (14): both confirmed and apart before they came close).

The split, the count and the joint update run in :func:`run_filter_reference` (``run_filter``
uses it, uncompiled, whatever the length when any of them is on; the compiled loop has none).

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
from onebit.trackers.binpf.footprint import TINY as _TINY
from onebit.trackers.binpf.footprint import birth_particles as birth_particles  # re-exported
from onebit.trackers.binpf.footprint import footprint_probability as footprint_probability  # re-exported
from onebit.trackers.binpf.footprint import frame_probability_off as frame_probability_off  # re-exported
from onebit.trackers.binpf.joint import close_pairs, joint_update, met_matrix, met_update
from onebit.trackers.binpf.moves import count_births as count_births  # re-exported
from onebit.trackers.binpf.moves import count_particles, couple, pair_loglik, split_proposals
from onebit.trackers.binpf.moves import local_map_people as local_map_people  # re-exported

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
    if not compiled or p.split_ratio > 0 or p.count_ratio > 0 or p.joint_distance > 0:  # reference loop only
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
    rows = (np.zeros((0, 2)), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0))
    counts = np.zeros((T, 4), dtype=np.int64)
    kp = kernel_params(p, log_particles)
    pxy, pfr, plab = [], [], []
    dbuf = np.empty((M, S, N))  # the footprints, near rows only (kernels.footprints_into)
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    for k0 in range(0, T, CHUNK_FRAMES):
        k1 = min(T, k0 + CHUNK_FRAMES)
        n_rows, next_label = int(state[2]), int(state[1])
        rows = _grown(rows, n_rows + M * (k1 - k0))  # at most M rows and M births a frame
        if ever.size < next_label + M * (k1 - k0):
            ever = np.concatenate([ever, np.zeros(max(M * (k1 - k0), ever.size), dtype=bool)])
        a, b, c = kernels.run_frames(
            on, k0, k1, state, x, hist, rowidx, r, labels, confirmed, ever, *rows,
            counts, sensors, radii, lo, hi, rng, kp, dbuf,
        )  # fmt: skip
        pxy.append(a)
        pfr.append(b)
        plab.append(c)
        if progress is not None:
            progress(k1, T)
    return _compiled_result(rows, int(state[2]), ever, counts, (pxy, pfr, plab), p)


def _compiled_result(rows: tuple, n_rows: int, ever, counts, logged: tuple, p: FilterParams) -> FilterResult:
    """The compiled run's :class:`FilterResult` from its buffers (``n_rows`` rows written)."""
    est, rows_frame, rows_label, rows_r = rows
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
        **_logged(*logged),
    )


def _grown(rows: tuple, need: int) -> tuple:
    """The compiled loop's row buffers ``(est (cap, 2), frame, label, r)``, grown (doubling) to at
    least ``need`` rows."""
    if rows[0].shape[0] >= need:
        return rows
    cap = max(need, 2 * rows[0].shape[0])
    return tuple(np.concatenate([a, np.zeros((cap - a.shape[0], *a.shape[1:]), dtype=a.dtype)]) for a in rows)


def _logged(pxy: list, pfr: list, plab: list) -> dict[str, np.ndarray]:
    """:class:`FilterResult`'s logged particles from the per-frame (or per-chunk) lists."""
    return {
        "particles_xy": np.concatenate(pxy) if pxy else np.zeros((0, 2)),
        "particles_frame": np.concatenate(pfr) if pfr else np.zeros(0, np.int64),
        "particles_label": np.concatenate(plab) if plab else np.zeros(0, np.int64),
    }


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
    T = on.shape[0]
    if compiled is None:
        compiled = T >= COMPILED_MIN_FRAMES
    rng = np.random.default_rng(seed)
    sensors = np.ascontiguousarray(sensors, dtype=np.float64)
    radii = np.ascontiguousarray(radii, dtype=np.float64)
    m = _Steps(sensors, radii, lo, hi, p, rng, compiled)
    st = _State.empty(T, p)
    for k in range(T):
        z = on[k]
        q = _update_tracks(st, m, z)
        newx, born = _births(st, m, z, q)
        if born:
            _add_newborn(st, m, z, newx, born, k)
        _confirm_delete_merge(st, p, k)
        _end_couples(st, p)
        st.live[k] = len(st.r)
        _write_rows(st, k)
        if log_particles > 0 and len(st.r):
            _log_particles(st, k, min(log_particles, p.particles))
        if progress is not None:
            progress(k + 1, T)
    return _result(st, p)


@dataclass
class _State:
    """The reference loop's state between frames: the live tracks (one row each) and what the run
    has written so far."""

    x: np.ndarray  # (I, N, 4) particles
    hist: np.ndarray  # (I, N, L + 1, 2) positions at frames k-L..k (last = now)
    rowidx: np.ndarray  # (I, L + 1) row of (track, frame k-L+j), -1 = none
    r: np.ndarray  # (I,) existences
    labels: np.ndarray  # (I,)
    confirmed: np.ndarray  # (I,) bool
    partner: dict[int, int]  # label -> label of its coupled twin ("Split")
    places: np.ndarray  # the count's untracked places of the frame before ("Count")
    apart: set  # label pairs the joint update keeps apart, from merging (joint.py, Eq. (13))
    far: set  # label pairs that met: both confirmed and apart before they came close (Eq. (14))
    near: set  # label pairs close before they met (Eq. (14))
    next_label: int
    ever_confirmed: set[int]
    n_rows: int  # rows written
    est: np.ndarray  # (cap, 2) the rows' smoothed positions
    rows: dict[str, list]  # frame, label, r of every row, a list of arrays per frame
    births: np.ndarray  # (T,) per frame
    deaths: np.ndarray
    merges: np.ndarray
    live: np.ndarray
    particles: tuple[list, list, list]  # logged particles: xy, frame, label

    @classmethod
    def empty(cls, T: int, p: FilterParams) -> _State:
        N, L = p.particles, p.smooth_lag
        return cls(
            x=np.zeros((0, N, 4)),
            hist=np.zeros((0, N, L + 1, 2)),
            rowidx=np.zeros((0, L + 1), dtype=np.int64),
            r=np.zeros(0),
            labels=np.zeros(0, dtype=np.int64),
            confirmed=np.zeros(0, dtype=bool),
            partner={},
            places=np.zeros((0, 2)),
            apart=set(),
            far=set(),
            near=set(),
            next_label=0,
            ever_confirmed=set(),
            n_rows=0,
            est=np.zeros((1024, 2)),
            rows={k: [] for k in ("frame", "label", "r")},
            births=np.zeros(T, np.int64),
            deaths=np.zeros(T, np.int64),
            merges=np.zeros(T, np.int64),
            live=np.zeros(T, np.int64),
            particles=([], [], []),
        )

    def keep(self, keep: np.ndarray) -> None:
        """Only the tracks where ``keep``."""
        self.x, self.hist, self.rowidx = self.x[keep], self.hist[keep], self.rowidx[keep]
        self.r, self.labels, self.confirmed = self.r[keep], self.labels[keep], self.confirmed[keep]


@dataclass
class _Steps:
    """What every frame's steps share: the sensors, the site's box, the parameters, the generator
    and whether the update and the resampling are the compiled kernels."""

    sensors: np.ndarray
    radii: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    p: FilterParams
    rng: np.random.Generator
    compiled: bool

    def update(self, xs, rs, z):
        """Eqs. (4)-(5): ``(ell, r_new, d)`` (``d`` the footprints when compiled, else ``None``)."""
        p = self.p
        if self.compiled:
            return kernels.observation_update(
                np.ascontiguousarray(xs), rs, z, self.sensors, self.radii, p.pd, p.pf, p.edge, p.silent
            )
        return (*observation_update(xs, rs, z, self.sensors, self.radii, p), None)

    def resampled(self, ell, xs, hs):
        """Particles and histories resampled by the log-weights ``ell``, and the indices."""
        if self.compiled:  # the same draw per track, the walk and the copies compiled
            idx = kernels.systematic_resample(np.ascontiguousarray(ell), self.rng.random((len(ell), 1)))
            return (*kernels.gather_particles(np.ascontiguousarray(xs), np.ascontiguousarray(hs), idx), idx)
        idx = systematic_resample(ell, self.rng)
        return np.take_along_axis(xs, idx[..., None], axis=1), np.take_along_axis(hs, idx[..., None, None], axis=1), idx


def _update_tracks(st: _State, m: _Steps, z: np.ndarray) -> np.ndarray:
    """Predict (Eq. (3)) and update (Eqs. (4)-(5), a couple jointly by Eq. (6)) the existing tracks,
    which get the first chance to explain the frame; returns their posterior miss
    probabilities ``q (I, S)`` (from the particles, whatever their existence: see the birth)."""
    p = m.p
    st.x, st.r = predict(st.x, st.r, m.rng, p, m.lo, m.hi)
    st.hist = np.concatenate([st.hist[:, :, 1:], st.x[:, :, None, :2]], axis=2)
    st.rowidx = np.concatenate([st.rowidx[:, 1:], np.full((len(st.r), 1), -1)], axis=1)
    if not len(st.r):
        return np.zeros((0, len(z)))
    xp, hp, rp = st.x, st.hist, st.r  # predicted (the joint update's input)
    ell, st.r, d = m.update(st.x, st.r, z)
    labels = st.labels
    pairs = [
        (int(np.flatnonzero(labels == a)[0]), int(np.flatnonzero(labels == b)[0]))
        for a, b in st.partner.items()
        if a < b and a in labels and b in labels
    ]
    if pairs:
        ell = ell.copy()
        for ia, ib in pairs:
            ell[ia] = ell[ib] = pair_loglik(st.x, st.r, z, ia, ib, m.sensors, m.radii, p)
        idx = systematic_resample(ell, m.rng)
        for ia, ib in pairs:
            idx[ib] = idx[ia]
        st.x = np.take_along_axis(st.x, idx[..., None], axis=1)
        st.hist = np.take_along_axis(st.hist, idx[..., None, None], axis=1)
    else:
        st.x, st.hist, idx = m.resampled(ell, st.x, st.hist)
    joined = _joint_pairs(st, m, z, xp, hp, rp) if p.joint_distance > 0 else 0
    if m.compiled and not joined:  # the resampled particles' footprints are the update's, copied
        return 1.0 - kernels.resampled_mean(d, idx)
    return 1.0 - footprint_probability(st.x[..., :2], m.sensors, m.radii, pd=p.pd, edge=p.edge).mean(axis=1)


def _joint_pairs(st: _State, m: _Steps, z: np.ndarray, xp: np.ndarray, hp: np.ndarray, rp: np.ndarray) -> int:
    """The joint update (:mod:`onebit.trackers.binpf.joint`, Eqs. (11)-(13)) of the close pairs of
    predicted tracks ``xp, hp, rp`` (a split couple excluded): their existences, particles and
    histories replace the mean-field ones in ``st``; a pair that two people explain best is
    kept from merging (``st.apart``, carried to the next frame: Eq. (13)); with ``joint_met`` only
    the pairs that met (Eq. (14), ``st.far``). Returns the number of pairs."""
    p = m.p
    before, st.apart = st.apart, set()
    in_couple = np.array([int(lab) in st.partner for lab in st.labels], bool)
    means = xp[..., :2].mean(axis=1)
    allow = None
    if p.joint_met:
        st.far, st.near = met_update(st.labels, means, st.confirmed, p.joint_distance, st.far, st.near)
        allow = met_matrix(st.labels, st.far)
    pairs = close_pairs(means, p.joint_distance, skip=in_couple, first=st.confirmed, allow=allow)
    if not pairs:
        return 0
    was = np.array([frozenset((int(st.labels[a]), int(st.labels[b]))) in before for a, b in pairs], bool)
    r2, idx, swap, two = joint_update(xp, rp, z, m.sensors, m.radii, p, pairs, m.rng.random(len(pairs)), was)
    x, h, r = st.x.copy(), st.hist.copy(), st.r.copy()
    for k, (a, b) in enumerate(pairs):
        xa, xb = xp[a, idx[k, 0]], xp[b, idx[k, 1]]
        ha, hb = hp[a, idx[k, 0]], hp[b, idx[k, 1]]
        s = swap[k]
        x[a], x[b] = np.where(s[:, None], xb, xa), np.where(s[:, None], xa, xb)
        h[a], h[b] = np.where(s[:, None, None], hb, ha), np.where(s[:, None, None], ha, hb)
        r[a], r[b] = r2[k]
        if two[k]:
            st.apart.add(frozenset((int(st.labels[a]), int(st.labels[b]))))
    st.x, st.hist, st.r = x, h, r
    return len(pairs)


def _births(st: _State, m: _Steps, z: np.ndarray, q: np.ndarray) -> tuple[np.ndarray | None, int]:
    """The frame's newborn particles ``(B, N, 4)`` (``None`` when none) and ``B``: a track per
    group of on sensors the updated tracks leave unexplained (whatever their existence: a
    tentative track near a firing gathers its evidence, no twin is born), then the split's
    twins, each coupled to the nearest uncoupled track, or the count's births."""
    p = m.p
    groups = birth_groups(z, q, m.sensors, p)
    room = p.max_tracks - len(st.r)
    newx = None
    if groups and room > 0:
        groups = sorted(groups, key=len, reverse=True)[:room]
        newx = np.stack([birth_particles(g, m.sensors, m.radii, m.rng, p) for g in groups])
    twins = np.zeros((0, p.particles, 4))
    if p.split_ratio > 0 and len(st.r) and room - len(groups) > 0:
        update = lambda xs, rs: m.update(xs, rs, z)  # noqa: E731
        twins = split_proposals(z, q, st.x, st.r, m.sensors, m.radii, m.rng, p, update, room - len(groups))
    elif p.count_ratio > 0 and room - len(groups) > 0:
        means = st.x[..., :2].mean(axis=1)
        if newx is not None:
            means = np.concatenate([means, newx[..., :2].mean(axis=1)])
        ys, st.places = count_births(z, means, m.sensors, m.radii, p, st.places)
        ys = ys[: room - len(groups)]
        twins = np.stack([count_particles(y, m.rng, p, m.lo, m.hi) for y in ys]) if len(ys) else twins
    if len(twins) and p.split_ratio > 0:  # each twin is coupled to the nearest uncoupled track
        mean_old, mean_new = st.x[..., :2].mean(axis=1), twins[..., :2].mean(axis=1)
        couple(st.partner, st.labels, mean_old, mean_new, st.next_label + len(groups), np.inf)
    if len(twins):
        newx = twins if newx is None else np.concatenate([newx, twins])
    return newx, 0 if newx is None else len(groups) + len(twins)


def _add_newborn(st: _State, m: _Steps, z: np.ndarray, newx: np.ndarray, born: int, k: int) -> None:
    """The newborn, updated on this frame with the others' posterior miss probabilities (Eqs.
    (4)-(5)) and resampled, join the tracks with existence ``birth_r`` and new labels."""
    p = m.p
    newr = np.full(born, p.birth_r)
    ell, rall, _ = m.update(np.concatenate([st.x, newx]), np.concatenate([st.r, newr]), z)
    nb = slice(len(st.r), None)
    newh = np.repeat(newx[:, :, None, :2], p.smooth_lag + 1, axis=2)
    newx, newh, _ = m.resampled(ell[nb], newx, newh)
    st.x, st.hist, st.r = (
        np.concatenate([st.x, newx]),
        np.concatenate([st.hist, newh]),
        np.concatenate([st.r, rall[nb]]),
    )
    st.rowidx = np.concatenate([st.rowidx, np.full((born, p.smooth_lag + 1), -1)])
    st.labels = np.concatenate([st.labels, np.arange(st.next_label, st.next_label + born)])
    st.confirmed = np.concatenate([st.confirmed, np.zeros(born, bool)])
    st.next_label += born
    st.births[k] = born


def _confirm_delete_merge(st: _State, p: FilterParams, k: int) -> None:
    """Track management: confirm at ``r_confirm``, delete below ``r_delete``, and of two tracks
    closer than ``merge_distance`` (not a couple, not a joint pair two people explain) keep the
    larger ``r``."""
    st.confirmed |= st.r >= p.r_confirm
    keep = st.r >= p.r_delete
    r, labels = st.r, st.labels
    mean = st.x[..., :2].mean(axis=1)
    if len(r) > 1 and p.merge_distance > 0:
        dm = np.sqrt(((mean[:, None] - mean[None]) ** 2).sum(-1))
        order = np.argsort(-r, kind="stable")
        for a_pos, a in enumerate(order):  # tracks are few (<= max_tracks)
            if not keep[a]:
                continue
            for b in order[a_pos + 1 :]:
                if (
                    keep[b]
                    and dm[a, b] < p.merge_distance
                    and st.partner.get(int(labels[a])) != int(labels[b])
                    and frozenset((int(labels[a]), int(labels[b]))) not in st.apart
                ):
                    keep[b] = False
                    st.confirmed[a] |= st.confirmed[b]
                    st.merges[k] += 1
    st.deaths[k] = int((~keep).sum()) - st.merges[k]
    st.keep(keep)
    st.ever_confirmed.update(st.labels[st.confirmed].tolist())


def _end_couples(st: _State, p: FilterParams) -> None:
    """A couple ends when one dies or the two are farther apart than ``couple_distance``."""
    if not st.partner:
        return
    mean = st.x[..., :2].mean(axis=1)
    pos = {int(lab): i for i, lab in enumerate(st.labels)}
    for a, b in list(st.partner.items()):
        if a not in pos or b not in pos or np.hypot(*(mean[pos[a]] - mean[pos[b]])) > p.couple_distance:
            st.partner.pop(a, None)


def _write_rows(st: _State, k: int) -> None:
    """This frame's rows, then every smoothed estimate still in the window."""
    n = len(st.r)
    st.rowidx[:, -1] = st.n_rows + np.arange(n)
    st.n_rows += n
    if st.n_rows > len(st.est):
        cap = max(2 * len(st.est), st.n_rows)
        st.est = np.concatenate([st.est, np.zeros((cap - len(st.est), 2))])
    m = st.rowidx >= 0
    st.est[st.rowidx[m]] = st.hist.mean(axis=1)[m]
    st.rows["frame"].append(np.full(n, k))
    st.rows["label"].append(st.labels.copy())
    st.rows["r"].append(st.r.copy())


def _log_particles(st: _State, k: int, n: int) -> None:
    """The first ``n`` particles of every track at frame ``k``, for drawing."""
    sub = st.x[:, :n, :2]
    pxy, pfr, plab = st.particles
    pxy.append(sub.reshape(-1, 2))
    pfr.append(np.full(sub.shape[0] * sub.shape[1], k))
    plab.append(np.repeat(st.labels, sub.shape[1]))


def _result(st: _State, p: FilterParams) -> FilterResult:
    """The run's :class:`FilterResult` from the loop's final state."""
    cat = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in st.rows.items()}
    frame, label = cat["frame"].astype(np.int64), cat["label"].astype(np.int64)
    reported = report_rows(frame, label, cat["r"], np.array(sorted(st.ever_confirmed), dtype=np.int64), p)
    pxy, pfr, plab = st.particles
    return FilterResult(
        frame=frame,
        label=label,
        x=st.est[: st.n_rows, 0].copy(),
        y=st.est[: st.n_rows, 1].copy(),
        r=cat["r"],
        reported=reported,
        births=st.births,
        deaths=st.deaths,
        merges=st.merges,
        live=st.live,
        **_logged(pxy, pfr, plab),
    )
