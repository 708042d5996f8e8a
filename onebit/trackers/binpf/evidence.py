"""Which of the filter's rows to report: the sensors' evidence for each track over a short window.

The filter reports a confirmed track while its existence :math:`r_i \\ge r_{out}`
(:func:`onebit.trackers.binpf.filter.report_rows`). The existence is a running average of the
evidence: it rises slowly after a birth (a person is missed for the frames their track needs
to be confirmed) and falls slowly after the person left (one quiet frame costs at most the
factor ``silent``, so a track outlives its person by several frames), and a second track on
one person keeps the existence it had. With ``[binpf] evidence_ratio`` :math:`\\kappa > 0` the
batch stage reports instead, among the rows of every track the filter reported at some frame
(any existence), those the frames around them support.

Support of a row
----------------
At frame :math:`k` the candidate rows (positions :math:`x_1..x_n`, the filter's smoothed means)
are ranked by existence, largest first, and each is scored given those ranked before it, with
the likelihood of Eq. (2) (:mod:`onebit.trackers.binpf.footprint`):

.. math::

    \\ell_k(X) = \\sum_s \\big[ z_{ks} \\log(1 - P(z_s = 0 \\mid X))
                          + (1 - z_{ks}) \\log P(z_s = 0 \\mid X) \\big],

    \\delta_{ik} = \\log\\big[(1 - \\varepsilon)\\, e^{\\ell_k(X_{<i} \\cup \\{x_i\\}) - \\ell_k(X_{<i})}
                            + \\varepsilon\\big]                                       \\tag{9}

(:math:`X_{<i}` the rows ranked before :math:`i`, :math:`\\varepsilon` = ``silent`` as in
Eq. (4')). The :math:`\\delta_{ik}` of a frame sum to the silent-tempered log-likelihood ratio
of all its rows against none (the chain rule), so a row that only repeats what the rows
before it explain (a second track on one person) scores about 0 or less, a row whose
footprints are all off (a person who left) scores down to :math:`\\log \\varepsilon`, and a
row over a firing no other row explains scores up to :math:`\\log((1 - \\varepsilon) d / p_f)`.

Reported rows
-------------
Row :math:`(i, k)` is reported when its track's support over the window of
:math:`h` = ``evidence_window`` frames either side reaches :math:`\\log \\kappa`:

.. math::

    \\Delta_{ik} = \\sum_{|j - k| \\le h,\\ (i, j) \\text{ a row}} \\delta_{ij} \\ge \\log \\kappa,
                                                                                     \\tag{10}

then at most ``max_out`` per frame, the largest existence first. A track thus starts being
reported where the firings that made it begin, not frames later when its existence crossed
:math:`r_{out}`, and stops :math:`h` frames after the last frames that support it. The
sensors are sluggish and a person may be silent for a frame or two, hence the window. Cost:
:math:`O(\\text{rows} \\times \\text{sensors})`, in blocks of whole frames.
"""

from __future__ import annotations

import numpy as np

from onebit.trackers.binpf.footprint import TINY, footprint_probability

#: Most ``rows x sensors`` footprints held at once (blocks of whole frames).
BLOCK_CELLS = 1 << 22


def row_support(
    frame: np.ndarray,
    r: np.ndarray,
    xy: np.ndarray,
    on: np.ndarray,
    sensors: np.ndarray,
    radii: np.ndarray,
    *,
    pd: float,
    pf: float,
    edge: float,
    silent: float,
) -> np.ndarray:
    """Eq. (9): :math:`\\delta` of every row ``(frame, r, xy (n, 2))``, the frame's rows ranked
    by ``r`` (largest first, ties in row order); ``on (frames, sensors)`` the levels."""
    n = frame.size
    out = np.zeros(n)
    if n == 0:
        return out
    order = np.lexsort((np.arange(n), -r, frame))
    f = frame[order]
    step = max(1, BLOCK_CELLS // max(1, sensors.shape[0]))
    a = 0
    while a < n:
        b = min(n, a + step)
        if b < n:  # end the block on a frame boundary (a frame's rows are one chain)
            b = int(np.searchsorted(f, f[b - 1], side="right"))
        idx = order[a:b]
        fb = f[a:b]
        d = footprint_probability(xy[idx], sensors, radii, pd=pd, edge=edge)
        lmiss = np.log(np.maximum(1.0 - d, TINY))  # log(1 - d_s(x_i))
        cum = np.cumsum(lmiss, axis=0)
        first = np.searchsorted(fb, fb, side="left")  # first row of each row's frame in the block
        before = cum - lmiss - (cum[first] - lmiss[first]) + np.log1p(-pf)  # log P(z_s = 0 | X_<i)
        after = before + lmiss
        z = on[fb].astype(bool)

        def loglik(logoff: np.ndarray, z: np.ndarray = z) -> np.ndarray:
            return np.where(z, np.log(np.maximum(-np.expm1(logoff), TINY)), logoff).sum(axis=1)

        ratio = loglik(after) - loglik(before)
        if silent > 0:
            out[idx] = np.logaddexp(np.log1p(-silent) + ratio, np.log(silent))
        else:
            out[idx] = ratio
        a = b
    return out


def window_support(frame: np.ndarray, label: np.ndarray, delta: np.ndarray, h: int) -> np.ndarray:
    """Eq. (10): per row, the sum of ``delta`` over the rows of the same ``label`` at most
    ``h`` frames from it (one frame per label and row)."""
    n = frame.size
    if n == 0:
        return np.zeros(0)
    labs, inv = np.unique(label, return_inverse=True)
    span = int(frame.max()) - int(frame.min()) + 2 * h + 2
    key = inv.astype(np.int64) * span + (frame - frame.min()).astype(np.int64)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    cs = np.concatenate([[0.0], np.cumsum(delta[order])])
    lo = np.searchsorted(ks, ks - h, side="left")  # the same label: keys of other labels are > span apart
    hi = np.searchsorted(ks, ks + h, side="right")
    out = np.empty(n)
    out[order] = cs[hi] - cs[lo]
    return out


def window_support_reference(frame: np.ndarray, label: np.ndarray, delta: np.ndarray, h: int) -> np.ndarray:
    """:func:`window_support` by a loop over the rows (the test oracle)."""
    out = np.zeros(frame.size)
    for i in range(frame.size):
        same = (label == label[i]) & (np.abs(frame - frame[i]) <= h)
        out[i] = delta[same].sum()
    return out


def evidence_rows(
    frame: np.ndarray,
    label: np.ndarray,
    r: np.ndarray,
    xy: np.ndarray,
    on: np.ndarray,
    sensors: np.ndarray,
    radii: np.ndarray,
    *,
    candidates: np.ndarray,
    ratio: float,
    window: int,
    pd: float,
    pf: float,
    edge: float,
    silent: float,
    max_out: int = 0,
) -> np.ndarray:
    """Which rows are reported (boolean, per row): among ``candidates`` (boolean per row), those
    with :math:`\\Delta_{ik} \\ge \\log` ``ratio`` (Eqs. (9)-(10), the support computed among the
    candidates only), then at most ``max_out`` per frame (> 0), the largest ``r`` first."""
    if ratio <= 0:
        raise ValueError(f"evidence ratio must be > 0, got {ratio}")
    rep = np.zeros(frame.size, bool)
    idx = np.flatnonzero(candidates)
    if idx.size == 0:
        return rep
    delta = row_support(frame[idx], r[idx], xy[idx], on, sensors, radii, pd=pd, pf=pf, edge=edge, silent=silent)
    rep[idx] = window_support(frame[idx], label[idx], delta, window) >= np.log(ratio)
    if max_out > 0 and rep.any():
        k = np.flatnonzero(rep)
        order = k[np.lexsort((-r[k], frame[k]))]
        f = frame[order]
        rank = np.arange(order.size) - np.searchsorted(f, f, side="left")
        rep[order[rank >= max_out]] = False
    return rep
