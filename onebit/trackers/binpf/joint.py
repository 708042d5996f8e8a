"""The joint update of close tracks (``joint_distance > 0``): two tracks whose footprints overlap
weighed together under Eq. (2), instead of each against the other's marginal (Eq. (4)).

Equation numbers continue those of :mod:`onebit.trackers.binpf.footprint` (1-2),
:mod:`onebit.trackers.binpf.filter` (3-5), :mod:`onebit.trackers.binpf.moves` (6-8) and
:mod:`onebit.trackers.binpf.evidence` (9-10); Eq. (14) restricts the pairs (``joint_met``).

Why
---
In the mean-field update (Eq. (4)) track :math:`a` sees track :math:`b` only through its
per-sensor miss probabilities :math:`q_{bs}`. When :math:`b`'s particles are spread over two
firing sensors, each sensor is half explained by :math:`b`, and :math:`a`'s best place is
between them, where :math:`b` is: two tracks of two close people are pulled together and
merged, and a newborn beside a track is explained away. The joint likelihood of a *pair of
positions* keeps what the marginal forgets: :math:`b` at one sensor and :math:`a` at the other
explain both firings, both at the same spot explain each only in part.

Pairs
-----
Tracks whose predicted particle means are closer than ``joint_distance`` are paired, each
track in at most one pair, two confirmed tracks before the others (a tentative newborn does not
take a confirmed track's partner) and the closest first (a third close track enters a pair through its
marginal, as in Eq. (4)); a couple of the split (:mod:`~onebit.trackers.binpf.moves`) keeps its
own update. Particle :math:`n` of :math:`a` is taken with particle :math:`n` of :math:`b`
(a joint particle). With the other tracks marginalised, :math:`m_s = (1 - p_f) \\prod_{j \\ne
a,b} q_{js}`, and :math:`A_s^{(n)} = 1 - d_s(x_a^{(n)})`, :math:`B_s^{(n)} = 1 - d_s(x_b^{(n)})`:

.. math::

    \\ell(o) = \\sum_s \\log\\big[z_s (1 - o_s) + (1 - z_s)\\, o_s\\big], \\quad
    \\ell_{11}^{(n)} = \\ell(m A^{(n)} B^{(n)}),\\;
    \\ell_{10}^{(n)} = \\ell(m A^{(n)}),\\;
    \\ell_{01}^{(n)} = \\ell(m B^{(n)}),\\;
    \\ell_{00} = \\ell(m)                                                             \\tag{11}

the frame's log-likelihood with both present, only :math:`a`, only :math:`b`, neither. Each
present person is silent with probability :math:`\\varepsilon` (Eq. (4')), so relative to
:math:`\\ell_{00}` (:math:`\\Lambda = e^{\\ell - \\ell_{00}}`):

.. math::

    \\lambda_{11}^{(n)} = (1 - \\varepsilon)^2 \\Lambda_{11}^{(n)}
        + \\varepsilon (1 - \\varepsilon) (\\Lambda_{10}^{(n)} + \\Lambda_{01}^{(n)}) + \\varepsilon^2,
    \\quad \\lambda_{10}^{(n)} = (1 - \\varepsilon) \\Lambda_{10}^{(n)} + \\varepsilon,
    \\quad \\lambda_{01}^{(n)} = (1 - \\varepsilon) \\Lambda_{01}^{(n)} + \\varepsilon.

The existences are the joint posterior's marginals (Eq. (5) when :math:`r_b = 0`), with
:math:`\\bar\\lambda = \\frac1N \\sum_n \\lambda^{(n)}`:

.. math::

    P_{11} = r_a r_b \\bar\\lambda_{11},\\; P_{10} = r_a (1 - r_b) \\bar\\lambda_{10},\\;
    P_{01} = (1 - r_a) r_b \\bar\\lambda_{01},\\; P_{00} = (1 - r_a)(1 - r_b),
    \\quad r_a \\leftarrow \\frac{P_{11} + P_{10}}{\\sum P},\\;
    r_b \\leftarrow \\frac{P_{11} + P_{01}}{\\sum P}.                                    \\tag{12}

Each track's particle :math:`n` is weighted by the likelihood given that track present,
:math:`w_a^{(n)} = r_b \\lambda_{11}^{(n)} + (1 - r_b) \\lambda_{10}^{(n)}` and
:math:`w_b^{(n)} = r_a \\lambda_{11}^{(n)} + (1 - r_a) \\lambda_{01}^{(n)}`, and both are
resampled (systematic) with the *same* uniform draw, so that where the two weights agree (both
tracks sure) the pairs survive whole.

*Labels.* The two tracks of a pair are exchangeable: the joint posterior of two people at
:math:`p_1, p_2` holds the pairs :math:`(p_1, p_2)` and :math:`(p_2, p_1)`, and each track's
marginal, the mixture of both, has its mean between them -- the coalescence of the two
tracks. Where the frame says two people are likelier than one,

.. math::

    \\beta_{ab} = \\frac{\\bar\\lambda_{11}}{\\max(\\bar\\lambda_{10}, \\bar\\lambda_{01})} \\ge \\kappa_j     \\tag{13}

(``joint_ratio``; :math:`\\kappa_j > 1`: with silence two people on one spot are already
likelier than one, :math:`\\beta \\approx 1 + \\varepsilon`), the labels are ordered: joint particle :math:`n` is swapped (whole states and smoothing
histories) when :math:`(x_a^{(n)} - x_b^{(n)}) \\cdot u < 0`, :math:`u` the principal axis
of the resampled differences :math:`x_a^{(n)} - x_b^{(n)}` (the line the two people stand on)
signed so that :math:`u \\cdot (\\mu_a - \\mu_b) \\ge 0`, :math:`\\mu` the tracks' predicted
means: :math:`a` keeps the member on its side; and
the pair is not merged (``merge_distance``). A pair kept apart stays apart, ordered, in the
next frames while :math:`\\beta_{ab} \\ge 1 / \\kappa_j` (one frame whose few firings one person
explains as well does not undo it) and while the two stay paired. Otherwise nothing is ordered
and the two may merge as before (a second track on one person: :math:`\\beta \\approx 1`).

Pairs that met (``joint_met``)
------------------------------
On the real array one walker often fires two sensors 1-1.6 m apart, which Eq. (2) explains
better by two people than by one (:math:`\\beta_{ab} > 2` in most frames); a newborn beside the
walker's track then gains existence from Eq. (12) and is kept apart by Eq. (13): a second track
on one person. Two people who *meet* come from two places. With ``joint_met`` the joint update
is given only to the pairs that met: tracks :math:`a, b` both confirmed and at least
:math:`D` = ``joint_distance`` apart at some frame before the first frame they were closer,

.. math::

    \\mathrm{met}(a, b) \\iff \\exists k' < k_0(a, b):\\; c_a(k') \\wedge c_b(k') \\wedge
        \\lVert \\mu_a(k') - \\mu_b(k') \\rVert \\ge D,
    \\quad k_0(a, b) = \\min\\{k : \\lVert \\mu_a(k) - \\mu_b(k) \\rVert < D\\}          \\tag{14}

(:math:`c` confirmed at the frame before, :math:`\\mu` the predicted means); every other close
pair -- a newborn beside a track above all -- keeps the mean-field update (Eq. (4)), as
without ``joint_distance``. A pair once close before it met never meets.
"""

from __future__ import annotations

import numpy as np

from onebit.trackers.binpf.config import FilterParams
from onebit.trackers.binpf.footprint import TINY as _TINY
from onebit.trackers.binpf.footprint import footprint_probability


def close_pairs(
    means: np.ndarray,
    reach: float,
    skip: np.ndarray | None = None,
    first: np.ndarray | None = None,
    allow: np.ndarray | None = None,
) -> list[tuple[int, int]]:
    """Pairs ``(a, b)``, ``a < b``, of tracks whose means ``(I, 2)`` are closer than ``reach``,
    each track in at most one pair: the pairs of two tracks where ``first`` (the confirmed ones)
    before the others, each group the closest first; tracks where ``skip`` take no part; with
    ``allow (I, I)`` (symmetric) only the pairs it allows (Eq. (14): the pairs that met)."""
    n = len(means)
    if n < 2 or reach <= 0:
        return []
    dm = np.sqrt(((means[:, None] - means[None]) ** 2).sum(-1))
    iu, ju = np.triu_indices(n, 1)
    close = dm[iu, ju] < reach
    if allow is not None:
        close &= np.asarray(allow, bool)[iu, ju]
    iu, ju, dd = iu[close], ju[close], dm[iu, ju][close]
    used = np.zeros(n, bool) if skip is None else np.asarray(skip, bool).copy()
    out = []
    rank = np.zeros(len(dd)) if first is None else ~(np.asarray(first, bool)[iu] & np.asarray(first, bool)[ju])
    for k in np.lexsort((dd, rank)):
        a, b = int(iu[k]), int(ju[k])
        if not used[a] and not used[b]:
            used[a] = used[b] = True
            out.append((a, b))
    return out


def _loglik(off: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Eq. (11)'s :math:`\\ell(o)` summed over the last axis (sensors)."""
    return np.log(np.maximum(np.where(z, 1.0 - off, off), _TINY)).sum(-1)


def pair_likelihoods(da: np.ndarray, db: np.ndarray, m: np.ndarray, z: np.ndarray, silent: float):
    """Eq. (11) with silence: ``(lam11 (N,), lam10 (N,), lam01 (N,))``, relative to the frame's
    likelihood with neither present, from the footprints ``da, db (N, S)`` of the joint particles,
    the others' miss ``m (S,)`` and the levels ``z (S,)``."""
    A, B = 1.0 - da, 1.0 - db
    l00 = _loglik(m, z)
    r11 = _loglik(m * A * B, z) - l00
    r10 = _loglik(m * A, z) - l00
    r01 = _loglik(m * B, z) - l00
    e = silent
    # in log space: lam11 = (1-e)^2 e^r11 + e(1-e)(e^r10 + e^r01) + e^2
    terms = [2 * np.log1p(-e) + r11]
    if e > 0:
        le = np.log(e)
        terms += [le + np.log1p(-e) + r10, le + np.log1p(-e) + r01, np.full_like(r11, 2 * le)]
    top = np.max(terms, axis=0)
    lam11 = np.exp(top) * sum(np.exp(t - top) for t in terms)
    lam10 = (1.0 - e) * np.exp(r10) + e
    lam01 = (1.0 - e) * np.exp(r01) + e
    return lam11, lam10, lam01


def pair_existence(ra: float, rb: float, lam11, lam10, lam01) -> tuple[float, float]:
    """Eq. (12): the pair's existences from the mean likelihoods."""
    P11 = ra * rb * np.mean(lam11)
    P10 = ra * (1.0 - rb) * np.mean(lam10)
    P01 = (1.0 - ra) * rb * np.mean(lam01)
    P00 = (1.0 - ra) * (1.0 - rb)
    tot = P11 + P10 + P01 + P00
    return float((P11 + P10) / tot), float((P11 + P01) / tot)


def resample_common(wa: np.ndarray, wb: np.ndarray, u: float) -> tuple[np.ndarray, np.ndarray]:
    """Systematic resampling of the weights ``wa, wb (N,)`` (not log) with the same offset
    ``u`` in [0, 1): indices ``(N,)`` each."""
    N = len(wa)
    pos = (u + np.arange(N)) / N
    out = []
    for w in (wa, wb):
        c = np.cumsum(w)
        c = c / c[-1]
        out.append(np.minimum(np.searchsorted(c, pos, side="right"), N - 1))
    return out[0], out[1]


def order_swaps(diff: np.ndarray, side: np.ndarray) -> np.ndarray:
    """Which joint particles to swap (Eq. (13)'s ordering): ``diff (N, 2)`` the members'
    differences :math:`x_a - x_b`, ``side (2,)`` :math:`\\mu_a - \\mu_b`. The axis is the
    principal one of the differences (the line the pair lies along), signed to agree with
    ``side``; particles whose difference points the other way are swapped."""
    _, vecs = np.linalg.eigh(diff.T @ diff)
    axis = vecs[:, -1]
    if axis @ side < 0:
        axis = -axis
    return diff @ axis < 0


def joint_update(
    x: np.ndarray,
    r_prior: np.ndarray,
    z: np.ndarray,
    sensors: np.ndarray,
    radii: np.ndarray,
    p: FilterParams,
    pairs: list[tuple[int, int]],
    uniforms: np.ndarray,
    apart_before: np.ndarray | None = None,
):
    """Eqs. (11)-(13) for ``pairs`` of tracks of predicted particles ``x (I, N, 4)`` with
    predicted existences ``r_prior (I,)``: ``(r (P, 2), idx (P, 2, N), swap (P, N) bool, two
    (P,) bool)`` -- the pairs' new existences, each member's resampling indices, which joint
    particles to swap after resampling, and whether :math:`\\beta_{ab} \\ge` ``joint_ratio`` (ordered, not to be
    merged). ``uniforms (P,)``: the systematic draw of each pair; ``apart_before (P,)``: the
    pairs kept apart the frame before (they stay apart while :math:`\\beta_{ab} \\ge 1 / \\kappa_j`)."""
    d = footprint_probability(x[..., :2], sensors, radii, pd=p.pd, edge=p.edge)  # (I, N, S)
    q = 1.0 - r_prior[:, None] * d.mean(axis=1)  # (I, S)
    means = x[..., :2].mean(axis=1)
    P, N = len(pairs), x.shape[1]
    r_out = np.zeros((P, 2))
    idx = np.zeros((P, 2, N), dtype=np.int64)
    swap = np.zeros((P, N), bool)
    two = np.zeros(P, bool)
    for k, (a, b) in enumerate(pairs):
        others = np.ones(len(r_prior), bool)
        others[[a, b]] = False
        m = (1.0 - p.pf) * np.prod(q[others], axis=0)
        ra, rb = float(r_prior[a]), float(r_prior[b])
        lam11, lam10, lam01 = pair_likelihoods(d[a], d[b], m, z, p.silent)
        r_out[k] = pair_existence(ra, rb, lam11, lam10, lam01)
        wa = rb * lam11 + (1.0 - rb) * lam10
        wb = ra * lam11 + (1.0 - ra) * lam01
        ia, ib = resample_common(wa, wb, float(uniforms[k]))
        idx[k, 0], idx[k, 1] = ia, ib
        beta = lam11.mean() / max(lam10.mean(), lam01.mean())
        was = apart_before is not None and bool(apart_before[k])
        two[k] = beta >= p.joint_ratio or (was and beta * p.joint_ratio >= 1.0)
        if two[k]:
            swap[k] = order_swaps(x[a, ia, :2] - x[b, ib, :2], means[a] - means[b])
    return r_out, idx, swap, two


def met_update(
    labels: np.ndarray, means: np.ndarray, confirmed: np.ndarray, reach: float, far: set, near: set
) -> tuple[set, set]:
    """Eq. (14)'s bookkeeping for the live tracks ``labels (I,)`` with means ``(I, 2)`` and
    ``confirmed (I,)``: ``far`` holds the label pairs (frozensets) seen both confirmed and at
    least ``reach`` apart before they were ever closer (they met), ``near`` those seen closer first.
    Returns both updated and kept to the live labels."""
    live = {int(v) for v in labels}
    far = {key for key in far if key <= live}
    near = {key for key in near if key <= live}
    n = len(labels)
    if n < 2:
        return far, near
    dm = np.sqrt(((means[:, None] - means[None]) ** 2).sum(-1))
    for a in range(n):
        for b in range(a + 1, n):
            key = frozenset((int(labels[a]), int(labels[b])))
            if key in far or key in near:
                continue
            if dm[a, b] < reach:
                near.add(key)
            elif confirmed[a] and confirmed[b]:
                far.add(key)
    return far, near


def met_matrix(labels: np.ndarray, far: set) -> np.ndarray:
    """``(I, I)`` bool: the tracks ``labels`` whose pair is in ``far`` (Eq. (14))."""
    n = len(labels)
    out = np.zeros((n, n), bool)
    for a in range(n):
        for b in range(a + 1, n):
            out[a, b] = out[b, a] = frozenset((int(labels[a]), int(labels[b]))) in far
    return out
