"""CLUSTERTRACK (Singh et al., section 4.2, Algorithm 1; Appendix B; section 6 consensus).

A *particle* is a candidate trajectory ``P = (x[1], ..., x[t])``. At every instant t:

1. each of the K_{t-1} surviving particles is extended by m_t points drawn uniformly from
   F[t] (independently per particle), ``m_t = round(m_o * S_F(t))``: m_t K_{t-1} candidates
   (a tie at k + 1/2 goes to the even count in every unit, :func:`round_count`);
2. cost (section 4.2.1) = sum over n of the change in velocity::

       c[n] = || x[n+1] + x[n-1] - 2 x[n] ||,     cost(P) = sum_{n=2}^{t-1} c[n]

3. candidates are scanned in increasing cost; a candidate joins the cluster whose
   *cluster head* (first member) is nearest under
   ``D(P, CH) = (1/t) sum_l || P[l] - CH[l] ||`` when that minimum is below D_0 -- kept only if
   the cluster holds fewer than H -- and otherwise founds a new cluster (always kept); the
   scan stops when K are kept or L have been scanned.

At T the best (first) particle of every cluster is a track.

Vectorisation. The scan is sequential in the paper; here it loops once per *cluster head*,
never per particle: the distances of all scanned candidates to the newest head are computed
at once and folded into a running minimum; the next head is the first later candidate
whose running minimum is >= D_0 (the minimum only over heads founded before it, as in the
sequential scan). The trajectory part of D is kept as a matrix of summed distances between
surviving particles, updated per instant as ``PD_t = PD_{t-1}[parent, parent] + ||x_a - x_b||``,
so D costs O(1) per pair. Cluster ranks come from one stable sort; the H cap and the K / L
stops are cumulative sums. The compiled pass (:mod:`onebit.trackers.clustertrack.kernels`,
from :data:`PASS_COMPILED_MIN`) takes the same random draws and makes two compiled calls per
instant: the candidates' costs, then :func:`fused_scan` -- the scan, which sorts only the
first ``K`` of the order and visits the rest only where a candidate is live, the survivors'
summed distances and the cluster sizes (an instant costs in proportion to its ``m_t K``
candidates: the feasible space the on sensors leave and the targets, not the site).

Ties in cost (every cost is 0 for t <= 2) are broken in a random order, so the first
instants keep a random subset rather than the first particles generated.

Rules of thumb (section 4.2.2), used for every parameter not given::

    Q_hat = max_t lower_bound(t)      (times ``q_factor``)
    A_hat = sum_t S_F(t) / (T Q_hat)
    K     = H Q_hat,   L = H m_o mean_t S_F(t),   D_0 = A_hat^(1/n)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from onebit.core.config import MAX_GRID_CELLS, MAX_PARTICLES, check_size
from onebit.trackers.clustertrack import kernels
from onebit.trackers.clustertrack.space import FeasibleSpace

#: Relative distance to a half-integer below which :func:`round_count` takes a count to be
#: exactly that half-integer: far above the float noise of a product of lengths (1e-16
#: relative), far below one sample.
HALF_TOL = 1e-9


def round_count(v: float) -> int:
    """``round(v)`` (ties to even) of a count that exact arithmetic may put at ``k + 1/2``.

    The counts of CLUSTERTRACK, ``m_t = round(m_o S_F(t))`` and ``L = round(H m_o mean S_F)``,
    are unit-free products of a density in site units^-n and a measure in site units^n, and
    they sit exactly at a half-integer more often than not: on the 2-D raster
    ``S_F = N (R / 10)^2`` and ``m_o R^2 = 50`` make ``m_o S_F = N / 2``; in 1-D, lengths that
    are multiples of R / 2 times ``m_o R = 15`` do the same. The float product carries noise
    that depends on the site's units (``50 * (145 * 0.1**2) = 72.50000000000001`` on a site in
    metres, ``0.005 * (145 * 100.0) = 72.5`` in cm), and ``round`` let that noise decide: 73
    draws per particle in m, 72 in cm, and every later random draw of the run differed. So
    ``v`` is first snapped to the nearest half-integer when within a relative
    :data:`HALF_TOL` of it; the tie then goes to the even count, whatever the units.
    """
    half = round(2.0 * v) / 2.0
    if abs(v - half) <= HALF_TOL * max(1.0, abs(v)):
        v = half
    return int(round(v))


@dataclass(frozen=True)
class Params:
    """Resolved parameters of one CLUSTERTRACK run."""

    H: int
    m_o: float  # samples per unit length (1-D) or area (2-D)
    K: int
    L: int
    D0: float
    Q_hat: int
    A_hat: float


def rules_of_thumb(
    space: FeasibleSpace,
    *,
    H: int,
    m_o: float,
    q_hat: int = 0,
    q_factor: float = 1.0,
    K: int = 0,
    L: int = 0,
    D0: float = 0.0,
) -> Params:
    """Parameters from the data (section 4.2.2); a non-zero argument overrides its rule."""
    q = int(q_hat) if q_hat > 0 else max(1, int(np.ceil(q_factor * max(space.max_lower_bound, 1))))
    mean_sf = float(np.mean(space.sizes_all)) if space.sizes_all.size else 0.0
    a_hat = mean_sf / q
    k = int(K) if K > 0 else H * q
    check_size(  # the kept particles' summed distances are a (K, K) matrix
        float(k) * k,
        MAX_GRID_CELLS,
        what=f"particle pairs (K = {k:,} kept particles, squared)",
        field="[clustertrack] k (default h x q_hat)",
        hint="fewer kept particles",
    )
    l_ = int(L) if L > 0 else max(k, round_count(H * m_o * mean_sf))
    d0 = float(D0) if D0 > 0 else (a_hat ** (1.0 / space.dim) if a_hat > 0 else 1e-9)
    return Params(H, m_o, k, l_, d0, q, a_hat)


@dataclass
class RunResult:
    """One pass of Algorithm 1 over all instants.

    tracks : ``(N, T, dim)`` best particle of each final cluster, in the space's step order
        mapped back to original instants (index = original instant).
    costs : ``(N,)``. ``kept``, ``scanned``, ``clusters``, ``candidates``: ``(T,)`` per step.
    particles : per step, ``(K_t, dim)`` current positions, ``(K_t,)`` cluster ids and costs
        (for the recordings).
    """

    tracks: np.ndarray
    costs: np.ndarray
    kept: np.ndarray
    scanned: np.ndarray
    clusters: np.ndarray
    candidates: np.ndarray
    particles: list = field(default_factory=list)
    max_cluster: np.ndarray | None = None


def _norm(v: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis: ``np.sqrt(np.sum(v * v, axis=-1))`` with the squares
    added in the same order, without numpy's slow reduction over a length-1 or -2 axis."""
    s = v[..., 0] * v[..., 0]
    for q in range(1, v.shape[-1]):
        s = s + v[..., q] * v[..., q]
    return np.sqrt(s)


#: Candidates to scan from which :func:`scan_clusters` runs the compiled scan by default.
SCAN_COMPILED_MIN = 1_000

#: A pass of :func:`cluster_track` uses the compiled scan from ``steps x L`` = this on: below
#: it the numpy scan costs less than starting numba in a fresh process (~0.3-1 s, once).
PASS_COMPILED_MIN = 200_000


def scan_order(cost: np.ndarray, L: int, rng: np.random.Generator) -> np.ndarray:
    """The candidates to scan, in scan order: the ``L`` cheapest, by increasing cost, ties
    in a random order (one random permutation of all candidates, then a stable sort)."""
    sel = scan_selection(cost, L, rng)
    return sel[np.argsort(cost[sel], kind="stable")]


def scan_clusters(
    cost: np.ndarray,
    parent: np.ndarray,
    x: np.ndarray,
    pd: np.ndarray,
    steps: int,
    *,
    H: int,
    K: int,
    L: int,
    D0: float,
    rng: np.random.Generator,
    compiled: bool | None = None,
):
    """Steps 3-18 of Algorithm 1 over candidates ``(parent, x)`` with ``cost``.

    ``pd (K_prev, K_prev)``: summed distances between the parents over the earlier steps;
    ``steps`` = t (length of a candidate trajectory). Returns ``(kept, label, is_head,
    n_scanned)``: candidate indices kept (in scan order), their cluster ids (0.. in order of
    foundation), whether each is its cluster's head, and how many were scanned.

    The order (:func:`scan_order`) is numpy; the scan itself, sequential by nature, is the
    compiled :func:`onebit.trackers.clustertrack.kernels.scan_sorted`, which stops at the
    ``K``-th kept candidate (:func:`scan_clusters_reference` is its numpy reference). Only
    the start of the order is sorted (:func:`ordered_prefix`, the first ``SCAN_PREFIX x K``;
    all of it if the scan has not kept ``K`` by then): an Appendix B rerun keeps its ``K``
    among the first few dozen of thousands of candidates.
    ``compiled=None``: the kernel from :data:`SCAN_COMPILED_MIN` candidates to scan on
    (below, the numpy scan; same result).
    """
    if not (min(L, cost.size) >= SCAN_COMPILED_MIN if compiled is None else compiled):
        return scan_clusters_reference(cost, parent, x, pd, steps, H=H, K=K, L=L, D0=D0, rng=rng)
    sel = scan_selection(cost, L, rng)
    key = cost[sel]
    pdc = np.ascontiguousarray(pd, dtype=np.float64)
    x2 = x.reshape(x.shape[0], -1)
    first = min(sel.size, SCAN_PREFIX * max(int(K), 1))
    while True:  # the scan order's first `first` candidates; more only if the scan needs them
        order = sel[ordered_prefix(key, first)]
        par = np.ascontiguousarray(parent[order], dtype=np.int64)
        xs = np.ascontiguousarray(x2[order], dtype=np.float64)
        k, lab, head, scanned = kernels.scan_sorted(par, xs, pdc, float(steps), int(H), int(K), float(D0))
        if k.size >= K or first >= sel.size:
            return order[k], lab, head, int(scanned)
        first = sel.size


#: :func:`scan_clusters` orders the first ``SCAN_PREFIX x K`` candidates (then all of them if the
#: scan has not kept ``K`` by then): a rerun keeps its ``K`` from the first few dozen of
#: thousands of candidates, which then need no full sort.
SCAN_PREFIX = 4

#: The pass's fused scan (:func:`onebit.trackers.clustertrack.kernels.scan_step`) sorts the first
#: ``STEP_PREFIX x K`` candidates and takes the rest's live ones from a heap: 1 measured ~10 %
#: faster than 4 on the simulated line (a first run collapses into one full cluster), the same
#: on the grid.
STEP_PREFIX = 1


def fused_scan(
    cost: np.ndarray,
    sel: np.ndarray,
    x: np.ndarray,
    m_t: int,
    pd: np.ndarray,
    steps: int,
    *,
    H: int,
    K: int,
    D0: float,
    prefix: int,
):
    """The compiled pass's scan of one instant (:func:`onebit.trackers.clustertrack.kernels.scan_step`)
    over the selection ``sel`` (:func:`scan_selection`) of candidates extending particle
    ``i // m_t`` by ``x[i]``: ``(kept, label, is_head, scanned, pd_new, max_cluster)``, what
    :func:`scan_clusters_reference` and :func:`summed_distances_reference` give. The kernel
    sorts the first ``prefix x K`` of the order; their bound, the ``prefix x K``-th smallest
    cost, comes from numpy's partition (3x a compiled quickselect on the grid's 13 000)."""
    key = cost[sel]
    first = min(sel.size, prefix * max(int(K), 1))
    v = float(np.partition(key, first - 1)[first - 1]) if 0 < first < sel.size else 0.0
    return kernels.scan_step(key, sel, x, m_t, pd, float(steps), int(H), int(K), float(D0), first, v)


def scan_selection(cost: np.ndarray, L: int, rng: np.random.Generator) -> np.ndarray:
    """The candidates :func:`scan_order` scans, before it sorts them (same random numbers):
    one random permutation of all candidates, cut to the ``L`` cheapest."""
    n = cost.size
    perm = rng.permutation(n)
    lim = min(L, n)
    if lim < n:
        return perm[np.argpartition(cost[perm], lim - 1)[:lim]]
    return perm


def ordered_prefix(key: np.ndarray, k: int) -> np.ndarray:
    """The first ``k`` of ``np.argsort(key, kind="stable")`` in O(len(key) + k log k): every
    position with a key below the ``k``-th smallest value, then the first positions holding
    that value, sorted by key then position."""
    n = key.size
    if k >= n:
        return np.argsort(key, kind="stable")
    if k <= 0:
        return np.zeros(0, dtype=np.int64)
    v = np.partition(key, k - 1)[k - 1]
    below = np.flatnonzero(key < v)
    at = np.flatnonzero(key == v)[: k - below.size]
    idx = np.sort(np.concatenate([below, at]))  # by position (the two are disjoint)
    return idx[np.argsort(key[idx], kind="stable")]


def scan_clusters_reference(
    cost: np.ndarray,
    parent: np.ndarray,
    x: np.ndarray,
    pd: np.ndarray,
    steps: int,
    *,
    H: int,
    K: int,
    L: int,
    D0: float,
    rng: np.random.Generator,
):
    """Steps 3-18 of Algorithm 1, vectorised in numpy (once per cluster head over every later
    candidate): the plain reference of :func:`scan_clusters` and its test oracle.

    ``pd (K_prev, K_prev)``: summed distances between the parents over the earlier steps;
    ``steps`` = t (length of a candidate trajectory). Returns ``(kept, label, is_head,
    n_scanned)``: candidate indices kept (in scan order), their cluster ids (0.. in order of
    foundation), whether each is its cluster's head, and how many were scanned.
    """
    order = scan_order(cost, L, rng)
    par, xs = parent[order], x[order]
    m = order.size
    dmin = np.full(m, np.inf)
    amin = np.full(m, -1, dtype=np.int64)
    heads: list[int] = []
    pos = 0
    while True:  # once per cluster head, vectorised over the later candidates
        h = len(heads)
        heads.append(pos)
        amin[pos] = h
        dmin[pos] = 0.0
        if len(heads) >= K or pos + 1 >= m:
            break
        rest = slice(pos + 1, m)
        d = (pd[par[rest], par[pos]] + _norm(xs[rest] - xs[pos])) / steps
        better = d < dmin[rest]
        dmin[rest] = np.where(better, d, dmin[rest])
        amin[rest] = np.where(better, h, amin[rest])
        nxt = np.flatnonzero(dmin[rest] >= D0)
        if nxt.size == 0:
            break
        pos = pos + 1 + int(nxt[0])
    # candidates after the last head founded that were never compared belong to no cluster yet:
    # they lie beyond the K-th head, so they can never be kept (the scan stops at K kept)
    scanned_upto = m
    valid = amin >= 0
    label = np.where(valid, amin, len(heads))
    idx = np.arange(m)
    o = np.lexsort((idx, label))
    lab_sorted = label[o]
    start = np.r_[True, lab_sorted[1:] != lab_sorted[:-1]]
    first = np.maximum.accumulate(np.where(start, np.arange(m), 0))
    rank = np.empty(m, dtype=np.int64)
    rank[o] = np.arange(m) - first
    keep = valid & (rank < H)
    ck = np.cumsum(keep)
    keep &= ck <= K
    if ck[-1] >= K:
        scanned_upto = int(np.searchsorted(ck, K) + 1)
    is_head = np.zeros(m, dtype=bool)
    is_head[np.asarray(heads)] = True
    kidx = np.flatnonzero(keep)
    return order[kidx], label[kidx], is_head[kidx], scanned_upto


def _traced_back(heads: np.ndarray, pos_hist: list, par_hist: list, order: np.ndarray, dim: int) -> np.ndarray:
    """``(H, T, dim)`` tracks of the last step's ``heads``, traced back step by step through
    each step's survivors (``pos_hist``) and parents (``par_hist``), by original instant."""
    T = len(pos_hist)
    tracks = np.empty((heads.size, T, dim))
    idx = heads
    for s in range(T - 1, -1, -1):
        tracks[:, order[s], :] = pos_hist[s][idx]
        idx = par_hist[s][idx]
    return tracks


def cluster_track(space: FeasibleSpace, p: Params, rng: np.random.Generator, *, record: bool = False) -> RunResult:
    """One pass of Algorithm 1 over the space's steps (sequential in time by nature).

    Memory and time linear in the number of steps: a particle carries only what the next
    step needs -- its last two positions (for the cost increment), its cost and its summed
    distances to the others (``pd``) -- and each step stores its survivors' positions and
    parents, from which the final tracks are traced back once. (Copying every surviving
    trajectory at every step, ``O(K t)`` per step, made a pass ``O(K T^2)``.)
    """
    T, dim = space.T, space.dim
    last1 = np.zeros((1, dim))  # position at step - 1 of each of the K_{t-1} particles
    last2 = np.zeros((1, dim))  # position at step - 2
    cost = np.zeros(1)
    pd = np.zeros((1, 1))
    kept_n = np.zeros(T, dtype=np.int64)
    scanned_n = np.zeros(T, dtype=np.int64)
    clusters_n = np.zeros(T, dtype=np.int64)
    cand_n = np.zeros(T, dtype=np.int64)
    max_cluster = np.zeros(T, dtype=np.int64)
    particles = []
    pos_hist: list[np.ndarray] = []  # per step: survivors' positions (K_t, dim)
    par_hist: list[np.ndarray] = []  # per step: survivors' parents (indices into the step before)
    label = np.zeros(1, dtype=np.int64)
    is_head = np.ones(1, dtype=bool)
    compiled = T * p.L >= PASS_COMPILED_MIN
    for step in range(T):
        kprev = cost.size
        m_t = max(1, round_count(p.m_o * space.size(step)))
        check_size(
            float(kprev) * m_t,
            MAX_PARTICLES,
            what=f"candidate particles ({kprev:,} kept x {m_t:,} each)",
            field="[clustertrack] m_o_r / m_o_r2",
            hint="fewer particles per unit of feasible space",
        )
        x = space.sample(step, kprev * m_t, rng, compiled=compiled).reshape(-1, dim)
        if x.shape[0] == 0:  # F empty (nobody anywhere, or inconsistent readings): keep the particles where they are
            x = last1 if step > 0 else np.zeros((1, dim))
            m_t = 1
        if compiled:  # two compiled calls per instant; the random draws stay numpy's (same stream)
            x = np.ascontiguousarray(x, dtype=np.float64)
            c = kernels.candidate_costs(x, last1, last2, cost, m_t, step >= 2)
            sel = scan_selection(c, p.L, rng)
            kept, label, is_head, scanned, pd, biggest = fused_scan(
                c, sel, x, m_t, pd, step + 1, H=p.H, K=p.K, D0=p.D0, prefix=STEP_PREFIX
            )
            par = kept // m_t
            xk = x[kept]
            clusters_n[step] = np.count_nonzero(is_head)
            max_cluster[step] = biggest
        else:
            parent = np.repeat(np.arange(kprev), m_t)
            c = candidate_costs_reference(x, last1, last2, cost, m_t, step >= 2)
            kept, label, is_head, scanned = scan_clusters(
                c, parent, x, pd, step + 1, H=p.H, K=p.K, L=p.L, D0=p.D0, rng=rng, compiled=False
            )
            par = parent[kept]
            xk = x[kept]
            pd = summed_distances_reference(pd, par, xk)
            clusters_n[step] = np.unique(label).size
            max_cluster[step] = np.bincount(label).max()
        last2, last1 = last1[par], xk
        pos_hist.append(xk)
        par_hist.append(par)
        cost = c[kept]
        kept_n[step], scanned_n[step], cand_n[step] = kept.size, scanned, c.size
        if record:
            particles.append((xk.copy(), label.copy(), cost.copy()))
    heads = np.flatnonzero(is_head)
    tracks = _traced_back(heads, pos_hist, par_hist, space.order, dim)
    if record:
        # particles were recorded in step order; store them by original instant
        by_t = [None] * T
        for s, item in enumerate(particles):
            by_t[int(space.order[s])] = item
        particles = by_t
    return RunResult(tracks, cost[heads], kept_n, scanned_n, clusters_n, cand_n, particles, max_cluster)


def candidate_costs_reference(
    x: np.ndarray, last1: np.ndarray, last2: np.ndarray, cost: np.ndarray, m_t: int, curvature: bool
) -> np.ndarray:
    """Cost of every candidate, ``(K m_t,)``: candidate ``a m_t + j`` extends particle ``a``
    (last positions ``last1[a]``, ``last2[a]``, cost ``cost[a]``) by ``x[a m_t + j]``; it adds
    the change in velocity ``||x + x[n-1] - 2 x[n]||`` when ``curvature`` (from the third
    instant on). Plain reference of :func:`onebit.trackers.clustertrack.kernels.candidate_costs`."""
    kprev, dim = cost.size, x.shape[-1]
    if not curvature:
        return np.repeat(cost, m_t) + np.zeros(x.shape[0])
    inc = _norm(x.reshape(kprev, m_t, dim) + last2[:, None, :] - (2.0 * last1)[:, None, :]).reshape(-1)
    return np.repeat(cost, m_t) + inc


def summed_distances_reference(pd: np.ndarray, par: np.ndarray, xk: np.ndarray) -> np.ndarray:
    """Summed distances between the kept particles ``(k, k)``: their parents' (``pd``) plus this
    instant's ``||xk_a - xk_b||``. Plain reference of
    :func:`onebit.trackers.clustertrack.kernels.summed_distances`."""
    return pd[np.ix_(par, par)] + _norm(xk[:, None, :] - xk[None, :, :])


def trajectory_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``D`` between every trajectory of ``a (p, T, d)`` and ``b (q, T, d)``: ``(p, q)``."""
    return np.mean(_norm(a[:, None] - b[None, :]), axis=-1)


def usage(space: FeasibleSpace, tracks: np.ndarray) -> list[np.ndarray]:
    """Per original instant: number of tracks in each component of F (every instant at once:
    :meth:`FeasibleSpace.components_of`, one ``bincount`` over instant x component)."""
    T = space.sizes_all.size
    nc = np.array([b.size for b in space.comp_bounds_all], dtype=np.int64)
    off = np.cumsum(nc) - nc
    counts = np.zeros(int(nc.sum()), dtype=np.int64)
    if tracks.shape[0] and counts.size:
        c = space.components_of(tracks)
        inside = (c >= 0) & (c < nc[None, :])
        counts = np.bincount((off[None, :] + c)[inside], minlength=counts.size).astype(np.int64)
    return [counts[off[t] : off[t] + nc[t]] for t in range(T)]


def underused(space: FeasibleSpace, tracks: np.ndarray) -> tuple[int, int, int] | None:
    """First ``(t_o, c_o, deficit)`` in the scan order 1, T, 2, T-1, ... (Appendix B)."""
    T = space.sizes_all.size
    use = usage(space, tracks)
    scan = np.empty(T, dtype=np.int64)
    scan[0::2] = np.arange((T + 1) // 2)
    scan[1::2] = np.arange(T - 1, (T + 1) // 2 - 1, -1)[: T // 2]
    for t in scan:  # over instants
        gap = space.comp_bounds_all[t] - use[t]
        bad = np.flatnonzero(gap > 0)
        if bad.size:
            return int(t), int(bad[0]), int(gap[bad[0]])
    return None


@dataclass
class TrackResult:
    """CLUSTERTRACK with Appendix B reruns."""

    tracks: np.ndarray  # (N, T, dim)
    costs: np.ndarray  # (N,)
    origin: np.ndarray  # (N,) 0 = first run, k = k-th rerun
    params: Params
    first: RunResult
    reruns: int
    satisfied: bool


def clustertrack(
    space: FeasibleSpace,
    p: Params,
    rng: np.random.Generator,
    *,
    max_reruns: int = 10,
    rerun: bool = True,
    record: bool = False,
    hard_limit: int = 40,
    high_cost: float = 10.0,
    max_tracks: int = 0,
) -> TrackResult:
    """Algorithm 1, then Appendix B: rerun through under-used components.

    While some instant t_o has a component c_o holding fewer tracks than its lower bound,
    rerun with F[t_o] restricted to c_o, reversing time when t_o > T/2. The paper's Q_hat for
    a rerun -- "the number of new trajectories we are looking to generate" -- is the deficit
    ``q = bound(t_o, c_o) - tracks through c_o``, so the rerun's budget is ``K = H q`` and it
    retains at most the q cheapest new tracks that cluster (D < D_0) with no existing track.
    After ``max_reruns`` reruns the clustering check is dropped (the q cheapest new tracks
    are retained). ``hard_limit`` bounds the total number of reruns.

    Monopolised reruns. With ``K = H q`` (one cluster when q = 1) the first cluster that is
    cheap at t = 3 takes the whole budget before the target through c_o is scored. With many
    targets that cluster is usually a zero-cost jump between components set up by the
    uninformative t <= 2 ties (Q^2 component pairs against Q true ones), and the rerun
    returns a high-cost trajectory that clusters with nothing, so it is retained, satisfies
    (t_o, c_o) and leaves the target unfound: with 10 targets, 21 reruns and 17 spurious
    tracks. So when every retained new track costs more than ``high_cost`` times the
    cheapest existing track (the paper's "significantly high cost", section 6: 10x), the
    rerun is repeated once with the budget of section 4.2.2's rule for the rerun's own space,
    ``K = H Q_hat`` (that space is F at every instant but t_o, so its particles must carry
    every target there), and its q cheapest new tracks replace the first attempt's when it
    yields any. ``high_cost = 0`` keeps the paper-literal single attempt.

    Bound. ``max_tracks`` > 0 (the stage passes min(``targets``, Q_hat), the count the
    algorithm itself estimates) caps the result: no rerun starts once that many tracks exist,
    a rerun adds at most the missing number, and a first pass with more clusters keeps its
    ``max_tracks`` cheapest. A track spans every instant, so this is also the most tracks
    at once. Real readings (spurious firings) raise the per-component lower bounds far past
    the people present; without the cap every such component drew a rerun and a track
    (11-38 tracks for 3-6 people).
    """
    first = cluster_track(space, p, rng, record=record)
    tracks, costs = first.tracks, first.costs
    if max_tracks > 0 and costs.size > max_tracks:
        best = np.sort(np.argsort(costs, kind="stable")[:max_tracks])
        tracks, costs = tracks[best], costs[best]
    origin = np.zeros(costs.size, dtype=np.int64)
    n = 0
    T = space.sizes_all.size
    while rerun and n < hard_limit and (max_tracks <= 0 or costs.size < max_tracks):
        u = underused(space, tracks)
        if u is None:
            break
        t_o, c_o, q = u
        if max_tracks > 0:
            q = min(q, max_tracks - costs.size)
        n += 1
        sub = space.restricted(t_o, c_o)
        if t_o > T / 2:
            sub = sub.reversed()
        check = n <= max_reruns
        new, nc = _rerun(sub, p, p.H * q, q, tracks, check, rng)
        limit = high_cost * max(float(costs.min()), 1e-9) if costs.size else np.inf
        if high_cost > 0 and nc.size and nc.min() > limit and p.K > p.H * q:
            new2, nc2 = _rerun(sub, p, p.K, q, tracks, check, rng)
            if nc2.size:
                new, nc = new2, nc2
        tracks = np.concatenate([tracks, new])
        costs = np.concatenate([costs, nc])
        origin = np.concatenate([origin, np.full(nc.size, n)])
    return TrackResult(tracks, costs, origin, p, first, n, underused(space, tracks) is None)


def _rerun(
    sub: FeasibleSpace, p: Params, K: int, q: int, tracks: np.ndarray, check: bool, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """One Appendix B rerun with budget K: the q cheapest new tracks (that cluster with no
    track in ``tracks`` when ``check``), ``(tracks (<=q, T, d), costs)``."""
    res = cluster_track(sub, Params(p.H, p.m_o, K, p.L, p.D0, q, p.A_hat), rng)
    new, nc = res.tracks, res.costs
    if check and tracks.shape[0] and new.shape[0]:
        fresh = trajectory_distance(new, tracks).min(axis=1) >= p.D0
        new, nc = new[fresh], nc[fresh]
    best = np.argsort(nc, kind="stable")[:q]  # the q new trajectories the rerun looks for
    return new[best], nc[best]


def leader_clusters(trajs: np.ndarray, costs: np.ndarray, D0: float) -> np.ndarray:
    """Cluster trajectories the way Algorithm 1 does (scan by cost, nearest head within D_0,
    no cap): returns a cluster id per trajectory. Loops once per head."""
    n = costs.size
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    order = np.argsort(costs, kind="stable")
    d = trajectory_distance(trajs[order], trajs[order])
    dmin = np.full(n, np.inf)
    lab = np.full(n, -1, dtype=np.int64)
    pos, h = 0, 0
    while True:
        lab[pos] = h
        dmin[pos] = 0.0
        rest = np.arange(pos + 1, n)
        better = d[rest, pos] < dmin[rest]
        dmin[rest] = np.where(better, d[rest, pos], dmin[rest])
        lab[rest] = np.where(better, h, lab[rest])
        nxt = np.flatnonzero(dmin[rest] >= D0)
        if nxt.size == 0:
            break
        pos = pos + 1 + int(nxt[0])
        h += 1
    out = np.empty(n, dtype=np.int64)
    out[order] = lab
    return out


@dataclass
class Consensus:
    """Multi-run consensus (section 6, Fig. 12b)."""

    tracks: np.ndarray  # (M, T, dim) every kept track of every run
    costs: np.ndarray
    run: np.ndarray  # run index of each track
    cluster: np.ndarray  # consensus cluster of each track
    support: np.ndarray  # per cluster: fraction of runs with a track in it
    count: int  # clusters supported by at least ``min_support`` of the runs
    runs: int


def seed_runs(
    space: FeasibleSpace,
    p: Params,
    seeds: list[int],
    max_reruns: int = 10,
    high_cost: float = 10.0,
    max_tracks: int = 0,
) -> list[TrackResult]:
    """The runs :func:`consensus` makes for ``seeds``, one after another: ``clustertrack(space,
    p, default_rng(seed), max_reruns=..., high_cost=..., max_tracks=...)`` each. A module-level
    function, so that a worker process can make some of a stage's runs (they are independent:
    each has its own generator) and hand them to :func:`consensus` as ``known``."""
    return [
        clustertrack(
            space, p, np.random.default_rng(s), max_reruns=max_reruns, high_cost=high_cost, max_tracks=max_tracks
        )
        for s in seeds
    ]


def consensus(
    space: FeasibleSpace,
    p: Params,
    seeds: list[int],
    *,
    ratio: float = 10.0,
    min_support: float = 0.5,
    max_reruns: int = 10,
    high_cost: float = 10.0,
    known: dict[int, TrackResult] | None = None,
    max_tracks: int = 0,
) -> Consensus:
    """Run CLUSTERTRACK once per seed, drop tracks costing more than ``ratio`` times the
    cheapest, cluster the rest (Algorithm 1's criterion) and count the clusters that hold a
    track from at least ``min_support`` of the runs (the paper's "biased by the number of
    trajectories in each cluster").

    ``known``: runs already made with these arguments (``clustertrack(space, p,
    default_rng(seed), max_reruns=max_reruns, high_cost=high_cost)``, e.g. the stage's own
    run), by seed; they are used as they are instead of being run again (same result)."""
    known = known or {}
    all_t, all_c, all_r = [], [], []
    for k, s in enumerate(seeds):  # independent runs (one per seed)
        r = known[s] if s in known else seed_runs(space, p, [s], max_reruns, high_cost, max_tracks)[0]
        all_t.append(r.tracks)
        all_c.append(r.costs)
        all_r.append(np.full(r.costs.size, k))
    tr = np.concatenate(all_t) if all_t else np.zeros((0, space.sizes_all.size, space.dim))
    co = np.concatenate(all_c) if all_c else np.zeros(0)
    ru = np.concatenate(all_r) if all_r else np.zeros(0, dtype=np.int64)
    if co.size:
        keep = co <= ratio * max(float(co.min()), 1e-9)
        tr, co, ru = tr[keep], co[keep], ru[keep]
    lab = leader_clusters(tr, co, p.D0)
    nclu = int(lab.max()) + 1 if lab.size else 0
    hit = np.zeros((nclu, len(seeds)), dtype=bool)
    hit[lab, ru] = True
    support = hit.mean(axis=1) if nclu else np.zeros(0)
    return Consensus(tr, co, ru, lab, support, int(np.sum(support >= min_support)), len(seeds))
