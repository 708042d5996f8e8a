"""The opt-in moves of binpf's filter: the split and the count. Both run in the filter's plain
loop (:func:`onebit.trackers.binpf.filter.run_filter_reference`; the compiled loop has neither).
Equation numbers continue those of :mod:`onebit.trackers.binpf.footprint` (Eqs. (1)-(2)) and
:mod:`onebit.trackers.binpf.filter` (Eqs. (3)-(5)).

*Split* (two people under overlapping footprints; ``split_ratio > 0``). The mean-field update
(:mod:`onebit.trackers.binpf.filter`) cannot resolve two people half a metre apart: given a
track's marginal, a second track's best place is on top of it (it shares both people's
firings), so two tracks of a close pair drift together and merge. A split is a move of the field's kind (a twin proposed, kept if the
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

*Count* (a cardinality the likelihood supports; ``count_ratio > 0``). The on sensors within
``birth_link`` of each other form clusters; cluster :math:`C` is judged on the sensors
:math:`S_C` within :math:`2(R + 3w)` of its on sensors (on and off). With people at
:math:`Y = (y_1..y_n)` Eq. (2) gives

.. math::

    \\ell_C(Y) = \\sum_{s \\in S_C} \\log\\big[z_s (1 - o_s(Y)) + (1 - z_s)\\, o_s(Y)\\big],
    \\qquad o_s(Y) = (1 - p_f) \\prod_{k} \\big(1 - d_s(y_k)\\big),                 \\tag{7}

and the count is the local MAP under a prior that charges each person a factor
:math:`\\kappa` (``count_ratio``), :math:`P(n) \\propto \\kappa^{-n}`:

.. math::

    \\hat n_C = \\max\\{n : \\ell_C(\\hat Y_n) - \\ell_C(\\hat Y_{n-1}) \\ge \\log \\kappa\\}   \\tag{8}

(the search adds people one at a time and stops at the first that falls short).
:math:`\\hat Y_n` is searched on a 0.2 m grid over the cluster's footprints: the better of
:math:`\\hat Y_{n-1}` plus the best new point and :math:`\\hat Y_{n-1}` with one person replaced
by the best pair of points within :math:`R` of it (two people 0.5 m apart are better
explained by a pair than by one in the middle plus one anywhere), then two passes moving
each person to its best point given the others. The tracks whose particle mean lies within
:math:`R + 3w` of the cluster's on sensors take the places nearest them (closest pair first);
a place left over is a person no track explains. It is born -- particles
:math:`\\mathcal N(y, \\max(w, 0.1)^2)`, existence ``birth_r``, updated on the frame like
any newborn -- when the frame before also left an untracked place within :math:`R` of it
(``count_persist`` = 2 frames; a single frame's firings are too noisy a count). The regular
births of the frame count as tracks here.
"""

from __future__ import annotations

import numpy as np

from onebit.trackers.binpf.config import FilterParams
from onebit.trackers.binpf.footprint import TINY as _TINY
from onebit.trackers.binpf.footprint import birth_particles, footprint_probability, frame_probability_off


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


def _cluster_loglik(y: np.ndarray, z: np.ndarray, sensors: np.ndarray, radii: np.ndarray, p: FilterParams) -> float:
    """Eq. (2)'s log-likelihood of the levels ``z`` of ``sensors`` with people at ``y (n, 2)``."""
    off = frame_probability_off(y, sensors, radii, pd=p.pd, pf=p.pf, edge=p.edge)
    return float(np.log(np.maximum(np.where(z, 1.0 - off, off), _TINY)).sum())


def local_map_people(z, sensors, radii, p: FilterParams, step: float = 0.2, passes: int = 2):
    """The local MAP configurations of Eq. (7) for one cluster's sensors: ``[Y_0, Y_1, ...]``,
    ``Y_n (n, 2)`` the best ``n`` people found on a grid of ``step``, while a person adds at
    least ``log count_ratio`` to the log-likelihood, and their log-likelihoods
    :math:`\\ell(Y_n)`; see "Count"."""
    if not z.any():
        return [np.zeros((0, 2))], [_cluster_loglik(np.zeros((0, 2)), z, sensors, radii, p)]
    lo = sensors[z].min(axis=0) - radii[z].max()
    hi = sensors[z].max(axis=0) + radii[z].max()
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0] + step / 2, step), np.arange(lo[1], hi[1] + step / 2, step))
    grid = np.c_[gx.ravel(), gy.ravel()]
    dg = footprint_probability(grid, sensors, radii, pd=p.pd, edge=p.edge)  # (G, S)
    reach = radii[z].max()

    def loglik(off):  # Eq. (2) summed over the sensors (last axis)
        return np.log(np.maximum(np.where(z, 1.0 - off, off), _TINY)).sum(axis=-1)

    def best(others: list[int]) -> tuple[int, float]:  # one person's best grid point, the others fixed
        ll = loglik((1.0 - p.pf) * np.prod(1.0 - dg[others], axis=0)[None, :] * (1.0 - dg))
        g = int(np.argmax(ll))
        return g, float(ll[g])

    def split(chosen: list[int]) -> tuple[list[int], float]:  # person a replaced by the best pair near it
        top: tuple[list[int], float] = ([], -np.inf)
        for a in range(len(chosen)):
            rest = chosen[:a] + chosen[a + 1 :]
            near = np.flatnonzero(np.hypot(*(grid - grid[chosen[a]]).T) <= reach)
            base = (1.0 - p.pf) * np.prod(1.0 - dg[rest], axis=0) * (1.0 - dg[near])  # (P, S)
            ll = loglik(base[:, None, :] * (1.0 - dg[near])[None, :, :])  # (P, P)
            u, v = np.unravel_index(int(np.argmax(ll)), ll.shape)
            if ll[u, v] > top[1]:
                top = ([*rest, int(near[u]), int(near[v])], float(ll[u, v]))
        return top

    chosen: list[int] = []
    ll = float(loglik((1.0 - p.pf) * np.ones(len(z))))
    out, lls = [np.zeros((0, 2))], [ll]
    while len(chosen) <= int(z.sum()):
        g, ll_new = best(chosen)
        trial = [*chosen, g]
        if chosen:  # or one person split into two where the firings' spread says so
            two, ll_two = split(chosen)
            if ll_two > ll_new:
                trial, ll_new = two, ll_two
        for _ in range(passes if len(trial) > 1 else 0):  # each person to its best place given the others
            for a in range(len(trial)):
                trial[a], ll_new = best(trial[:a] + trial[a + 1 :])
        if ll_new - ll < np.log(p.count_ratio):
            break
        chosen, ll = trial, ll_new
        out.append(grid[chosen])
        lls.append(ll)
    return out, lls


def count_births(z, means, sensors, radii, p: FilterParams, before=None) -> tuple[np.ndarray, np.ndarray]:
    """The people the local MAP count of each cluster of on sensors finds beyond the tracks
    near it (Eq. (7)): ``(born (B, 2), places (P, 2))`` -- ``places`` every such untracked
    place of this frame, ``born`` those of them within a footprint radius of an untracked
    place of the frame before (``before``) when ``count_persist >= 2`` (one frame before is
    looked at, whatever the value), every place when ``count_persist <= 1``; see "Count"."""
    on = np.flatnonzero(z)
    if on.size == 0:
        return np.zeros((0, 2)), np.zeros((0, 2))
    pts = sensors[on]
    adj = np.sqrt(((pts[:, None] - pts[None]) ** 2).sum(-1)) <= p.birth_link
    lab = np.arange(on.size)
    while True:  # clusters of on sensors: connected components, as birth_groups
        new = np.where(adj, lab[None, :], on.size).min(axis=1)
        if np.array_equal(new, lab):
            break
        lab = new
    reach = radii.max() + 3.0 * max(p.edge, 0.0)
    places = []
    for g in np.unique(lab):
        c = on[lab == g]
        near = np.flatnonzero(np.sqrt(((sensors[:, None] - sensors[c][None]) ** 2).sum(-1)).min(axis=1) <= 2 * reach)
        Y = local_map_people(z[near], sensors[near], radii[near], p)[0][-1]
        dt = np.sqrt(((means[:, None] - sensors[c][None]) ** 2).sum(-1)).min(axis=1) if len(means) else np.zeros(0)
        mine = means[dt <= reach]  # the tracks under this cluster
        if len(Y) <= len(mine):
            continue
        cost = np.sqrt(((Y[:, None] - mine[None]) ** 2).sum(-1))  # (places, tracks)
        free = np.ones(len(Y), bool)
        for _ in range(len(mine)):  # the tracks take the places nearest them, closest pair first
            a, b = np.unravel_index(np.argmin(cost), cost.shape)
            free[a] = False
            cost[a, :] = cost[:, b] = np.inf
        places.extend(Y[free])
    places = np.array(places).reshape(-1, 2)
    if p.count_persist <= 1:
        return places, places
    before = np.zeros((0, 2)) if before is None else before
    seen = np.sqrt(((places[:, None] - before[None]) ** 2).sum(-1)).min(axis=1) <= radii.max() if len(before) else []
    return places[np.asarray(seen, bool)] if len(before) else np.zeros((0, 2)), places


def count_particles(y: np.ndarray, rng: np.random.Generator, p: FilterParams, lo, hi) -> np.ndarray:
    """``(N, 4)`` particles of a person the count places at ``y``: positions
    :math:`\\mathcal N(y, \\sigma_c^2)`, :math:`\\sigma_c` = ``max(edge, 0.1)``, clipped to the
    site; velocities :math:`\\mathcal N(0, \\sigma_b^2)`."""
    N = p.particles
    xy = np.clip(y + max(p.edge, 0.1) * rng.standard_normal((N, 2)), lo, hi)
    return np.c_[xy, p.birth_speed * rng.standard_normal((N, 2))]


def couple(partner: dict, labels, mean_old, mean_new, first_label: int, reach: float) -> None:
    """Couple newborn ``first_label + t`` (mean ``mean_new[t]``) to the nearest uncoupled old track
    within ``reach`` (``partner``: label -> label, both ways); see "Split" and "Count"."""
    for t, m in enumerate(mean_new):
        dd = np.hypot(*(mean_old - m).T)
        for j in np.argsort(dd):
            if dd[j] > reach:
                break
            if int(labels[j]) not in partner:
                a, b = int(labels[j]), first_label + t
                partner[a], partner[b] = b, a
                break


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
