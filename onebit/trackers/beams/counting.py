"""Counting automaton M_C of Bobadilla et al., section V: verification and error correction.

Counting information space (Definition 2)
-----------------------------------------
With ``p`` regions and ``n`` indistinguishable agents, an information state is the count
vector ``eta = (n_1, ..., n_p)`` with ``sum_i n_i = n``::

    I_C = { eta in N^p : sum_i eta_i = n },   |I_C| = C(n + p - 1, p - 1)

(stars and bars; the paper prints ``C(p+n-1, n-1)``, which is the count for ``n`` and
``p`` swapped). For the building (p = 6) and n = 3, 4, 5, 6 this is 56, 126, 252, 462.

Counting automaton (Definition 3, eq. 1)
----------------------------------------
``M_C = (Sigma, I_C, eta_0, delta_C)``; a crossing ``y = beta^{+-1}`` is the directed edge
``s -> t`` of the region graph and::

    delta_C(eta, y) = eta - e_s + e_t     defined iff eta_s >= 1.

Verification (:func:`verify`) runs ``delta_C`` from ``eta_0`` without building the automaton:
only ``eta`` is kept (O(|R|) state) and every crossing is read once (O(|y|) time). The pass is
vectorised in chunks of ``chunk`` crossings: within a chunk the counts before crossing ``k``
are ``eta + C[k]`` with ``C`` the chunk's prefix sums of ``delta_k = e_t(k) - e_s(k)``, and
the string leaves ``L(M_C)`` at the first ``k`` with ``eta_s(k) + C[k]_s(k) < 1``.

Error correction (:func:`correct`)
----------------------------------
Only false negatives occur, so the corrected string is ``y`` with crossings inserted, and we
want the fewest insertions that put it in ``L(M_C)`` -- an edit distance to a regular
language with insertions only (Wagner 1974). As a shortest-path problem its nodes are
``(position i, count state eta)``; consuming ``y[i]`` costs 0 (when ``eta_{s(i)} >= 1``) and
inserting any crossing costs 1.

Canonical form (what makes it small). Postponing an inserted crossing past an observed one
never breaks feasibility unless the observed crossing leaves the region the inserted one
enters, and an inserted crossing still pending at the end can be deleted. So an optimal
correction exists in which insertions happen only right before an observed crossing ``y[k]``
whose source region ``s`` is empty (a *deficit*), and there they move exactly one agent from
an occupied region ``r`` to ``s`` along a shortest path of the region graph, at cost
``H[r, s]`` (hop distance). The search is therefore a dynamic programme over the reachable
count states only::

    D_0(eta) = 0 for eta in the start set (eta_0, or all of I_C when eta_0 is unknown)
    no deficit at k:  D(eta - e_s + e_t) <- D(eta)
    deficit at k:     D(eta - e_r + e_t) <- D(eta) + H[r, s]   for every r with eta_r >= 1

All live states are advanced together; runs of crossings where no live state has a deficit
are skipped in one vectorised step (as in :func:`verify`). After each deficit the states are
merged (same ``eta`` -> lowest cost) and pruned by dominance: ``eta_B`` is dropped when some
``eta_A`` has ``D(A) + d(A, B) <= D(B)`` with ``d(A, B) = |A - B|_1 / 2 * diam(G)`` an upper
bound on the insertions that turn ``A`` into ``B`` (each of the ``|A - B|_1 / 2`` displaced
agents walks at most ``diam(G)`` beams), because from ``A`` one can insert those moves and
then follow ``B``'s best continuation. Count states never reached from the start set are
never created.

The DP is exact: :func:`correct` returns the minimum number of insertions (tests compare it
with a breadth-first search over (position, count vector) with every insertion allowed).

Placement (:func:`place_insertions`). The canonical form puts every insertion as late as
possible. An inserted crossing ``u -> v`` can be moved earlier to any position from which,
up to its old position, region ``u`` still holds an agent for it and one for every observed
crossing that leaves ``u``: its *feasible window*. Counts say nothing about where in the
window the agent really crossed; when the insertion stands for a real drop ``u -> v`` the
true moment lies in it (the observed string has one agent too many in ``u`` from then on). ``placement="midpoint"`` (the default of
the ``correct`` stage) puts it at the middle *in time* of the window,
``tau = (t_first + t_last) / 2`` with ``t_first`` the time of the crossing that opens the
window and ``t_last`` that of the crossing that needed the insertion -- our choice where the
paper is silent: with no motion model, the middle minimises the worst-case distance to the
true moment. ``"earliest"`` moves each one (in order) to the start of its window (within
``window`` crossings), ``"latest"`` leaves it where the DP put it. All keep the string in
``L(M_C)`` and the number of insertions. Parallel beams (two beams joining the same two
regions, like b and c of the building) cannot be told apart by counts: the lowest beam id is
inserted. (A tie-break by the shortest walk between the neighbouring beams was measured on
the building and restored no more drops -- the simulator picks beams uniformly -- so it is
not used.)

The DP and the placement are sequential in the string (each step depends on the states the
previous one left); they are vectorised over the live count states and over runs of crossings.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass
from math import comb

import numpy as np

from onebit.core.config import MAX_GRID_CELLS, check_size
from onebit.core.lazy import lazy_module
from onebit.trackers.beams import kernels
from onebit.trackers.beams.assignment import region_deficits, region_events

_csgraph = lazy_module("scipy.sparse.csgraph")
_sparse = lazy_module("scipy.sparse")

PLACEMENTS = ("earliest", "latest", "midpoint")
_FAR = 10**6  # hop distance standing for "unreachable"

#: Crossings from which :func:`correct` runs the compiled DP by default.
COMPILED_MIN = 2_000


# --------------------------------------------------------------------------- I_C


def count_space_size(n_regions: int, n_agents: int) -> int:
    """``|I_C| = C(n + p - 1, p - 1)``: ways to put ``n`` agents in ``p`` regions."""
    return comb(n_agents + n_regions - 1, n_regions - 1)


def count_states(n_regions: int, n_agents: int) -> np.ndarray:
    """Every count vector of ``I_C`` as an ``(|I_C|, p)`` int array (lexicographic order).

    Built by extending the partial vectors one region at a time (numpy, no per-state loop).
    """
    states = np.zeros((1, 0), dtype=np.int64)
    left = np.array([n_agents], dtype=np.int64)
    for _r in range(n_regions - 1):
        reps = left + 1
        idx = np.repeat(np.arange(len(states)), reps)
        starts = np.cumsum(reps) - reps
        take = np.arange(len(idx)) - np.repeat(starts, reps)
        states = np.c_[states[idx], take]
        left = left[idx] - take
    return np.c_[states, left].astype(np.int64)


def crossing_deltas(source: np.ndarray, target: np.ndarray, n_regions: int) -> np.ndarray:
    """``(m, p)`` int32: row ``k`` is ``e_t(k) - e_s(k)``, the change of the count vector."""
    m = len(source)
    d = np.zeros((m, n_regions), dtype=np.int32)
    rows = np.arange(m)
    np.add.at(d, (rows, source), -1)
    np.add.at(d, (rows, target), 1)
    return d


def minimal_initial_counts(source: np.ndarray, target: np.ndarray, n_regions: int) -> np.ndarray:
    """Smallest ``eta_0`` (componentwise) from which the string is in ``L(M_C)``.

    ``eta_0[r] = max(0, max_k (exits_r - entries_r)(first k crossings))``; the string is in
    ``L(M_C)`` for some ``eta_0`` with ``sum eta_0 = n`` iff ``sum`` of this vector ``<= n``
    (extra agents can wait anywhere). Its sum is Algorithm 1's agent count (Prop. 3.1).
    Computed per region over the crossings' events, O(m) memory (no ``(m, p)`` table).
    """
    return region_deficits(source, target, n_regions)


def first_count_violation(source: np.ndarray, target: np.ndarray, n_regions: int, n_agents: int) -> int:
    """First crossing index ``k`` at which no ``eta_0`` with sum ``n_agents`` explains the prefix
    ``y[0..k]`` (-1 if none): the prefix needs ``need(k) = sum_r max(0, max_{j <= k} D_r(j))``
    agents (:func:`minimal_initial_counts` of the prefix).

    Vectorised over the per-region events (:func:`~onebit.trackers.beams.assignment.region_events`):
    each region's running maximum of ``max(0, D_r)`` is one offset ``maximum.accumulate``, its
    increases are credited to their crossing and ``need`` is their cumulative sum. O(m) memory.
    """
    m = len(source)
    if m == 0:
        return -1
    reg, j, running, starts, counts = region_events(source, target, n_regions)
    big = m + 1  # max(0, D_r) lies in [0, m]: offsetting region r by r * big keeps the scan per region
    off = reg * big
    cm = np.maximum.accumulate(np.maximum(running, 0) + off) - off
    prev = np.r_[0, cm[:-1]]
    prev[starts[counts > 0]] = 0  # each region's maximum starts at 0
    need = np.cumsum(np.bincount(j, weights=cm - prev, minlength=m))
    over = np.flatnonzero(need > n_agents)
    return int(over[0]) if over.size else -1


# --------------------------------------------------------------------------- verification


@dataclass(frozen=True)
class Verification:
    """Result of running M_C on a string.

    accepted : the string is in ``L(M_C)`` from ``eta_0``.
    first_violation : index of the first crossing whose source region is empty (-1 if none).
    final : count vector after the last crossing read (before the violation if rejected).
    """

    accepted: bool
    first_violation: int
    final: np.ndarray


def verify(source, target, initial, *, chunk: int = 65536) -> Verification:
    """Run ``delta_C`` from ``eta_0 = initial`` over the crossings ``source[k] -> target[k]``.

    O(|R| + chunk) memory and O(|y|) time: the string is read in chunks; within one the
    counts before crossing ``k`` are ``eta + C[k]`` (prefix sums of the deltas).
    """
    src = np.asarray(source, dtype=np.int64)
    tgt = np.asarray(target, dtype=np.int64)
    eta = np.asarray(initial, dtype=np.int64).copy()
    p = len(eta)
    if np.any(eta < 0):
        raise ValueError(f"initial counts must be >= 0, got {eta.tolist()}")
    for lo in range(0, len(src), chunk):
        s, t = src[lo : lo + chunk], tgt[lo : lo + chunk]
        c = np.cumsum(crossing_deltas(s, t, p), axis=0)
        before = eta[s] + np.r_[0, c[:-1][np.arange(len(s) - 1), s[1:]]] if len(s) > 1 else eta[s]
        bad = np.flatnonzero(before < 1)
        if bad.size:
            k = int(bad[0])
            eta = eta + (c[k - 1] if k > 0 else 0)
            return Verification(False, lo + k, eta)
        eta = eta + c[-1]
    return Verification(True, -1, eta)


# --------------------------------------------------------------------------- region graph helpers


@dataclass(frozen=True)
class RegionEdges:
    """The region graph as arrays: directed edges (one per beam and direction) and hops.

    edge_source, edge_target : (E,) region indices of every labelled edge.
    hops : (p, p) hop distance (edges are paired, so it is symmetric); -1 when unreachable.
    first_edge : (p, p) index of the lowest-numbered edge ``u -> v`` (-1 if none).
    predecessor : (p, p) scipy predecessor matrix of the shortest paths.
    """

    edge_source: np.ndarray
    edge_target: np.ndarray
    hops: np.ndarray
    first_edge: np.ndarray
    predecessor: np.ndarray
    edge_beam: tuple[str, ...] = ()
    edge_direction: tuple[int, ...] = ()

    @property
    def n_regions(self) -> int:
        return self.hops.shape[0]

    @property
    def diameter(self) -> int:
        return int(self.hops.max()) if self.hops.size else 0

    @classmethod
    def from_region_graph(cls, rg) -> RegionEdges:
        """Edges of a :class:`~onebit.core.region_graph.RegionGraph`: for every beam in
        sorted order its forward edge, then all backward edges (so ties between parallel
        beams, like b and c of the building, go to the first beam id)."""
        idx = rg.index
        beams = sorted(rg.beam_source)
        fs = [idx[rg.beam_source[b]] for b in beams]
        ft = [idx[rg.beam_target[b]] for b in beams]
        return cls.from_arrays(
            fs + ft,
            ft + fs,
            len(rg.names),
            beams=tuple(beams + beams),
            directions=tuple([1] * len(beams) + [-1] * len(beams)),
        )

    @classmethod
    def from_arrays(cls, edge_source, edge_target, n_regions: int, *, beams=(), directions=()) -> RegionEdges:
        es = np.asarray(edge_source, dtype=np.int64)
        et = np.asarray(edge_target, dtype=np.int64)
        adj = _sparse.csr_matrix((np.ones(len(es)), (es, et)), shape=(n_regions, n_regions))
        dist, pred = _csgraph.shortest_path(adj, method="D", unweighted=True, return_predecessors=True)
        hops = np.where(np.isfinite(dist), dist, -1).astype(np.int64)
        first = np.full((n_regions, n_regions), -1, dtype=np.int64)
        order = np.arange(len(es))[::-1]  # assign in reverse so the lowest index wins
        first[es[order], et[order]] = order
        return cls(es, et, hops, first, pred, tuple(beams), tuple(int(d) for d in directions))

    def path_edges(self, r: int, s: int) -> list[int]:
        """Edge indices of the shortest path ``r -> s`` (lowest-numbered parallel edge)."""
        nodes = [s]
        while nodes[-1] != r:
            nodes.append(int(self.predecessor[r, nodes[-1]]))
        nodes.reverse()
        return [int(self.first_edge[a, b]) for a, b in zip(nodes[:-1], nodes[1:])]


# --------------------------------------------------------------------------- correction


@dataclass(frozen=True)
class Correction:
    """Minimum-insertion correction of a crossing string.

    cost : number of inserted crossings (the minimum).
    initial : (p,) count vector ``eta_0`` used (given, or the DP's choice).
    source, target : (m + cost,) region indices of the corrected string.
    inserted : (m + cost,) bool, True for inserted crossings.
    observed_index : (m + cost,) index into the observed string, -1 for inserted crossings.
    edge : (m + cost,) edge index of inserted crossings (into ``RegionEdges``), -1 for observed.
    peak_states : largest number of live count states during the DP.
    events : number of deficit positions processed (DP steps that branched).
    time : (m + cost,) float times when observed ``times`` were given: the observed ones,
        and the placement's time for inserted crossings (NaN for ``"earliest"``/``"latest"``,
        whose times the caller interpolates); None without ``times``.
    """

    cost: int
    initial: np.ndarray
    source: np.ndarray
    target: np.ndarray
    inserted: np.ndarray
    observed_index: np.ndarray
    edge: np.ndarray
    peak_states: int
    events: int
    time: np.ndarray | None = None

    @property
    def insertion_positions(self) -> np.ndarray:
        """Index in the corrected string of every inserted crossing."""
        return np.flatnonzero(self.inserted)


def _merge_and_prune(E, cost, node, diam):
    """Keep the cheapest entry per count vector, then drop dominated states (see module doc)."""
    if len(E) > 1:
        key = np.ascontiguousarray(E).view(np.dtype((np.void, E.dtype.itemsize * E.shape[1]))).ravel()
        order = np.lexsort((node, cost, key))
        ks = key[order]
        first = np.r_[True, ks[1:] != ks[:-1]]
        keep = order[first]
        E, cost, node = E[keep], cost[keep], node[keep]
    if len(E) > 1 and cost.max() > cost.min():
        # d(A, B) = |A - B|_1 / 2 * diam; B dominated if cost_A + d(A, B) <= cost_B
        l1 = np.abs(E[:, None, :] - E[None, :, :]).sum(axis=2)
        bound = cost[:, None] + (l1 // 2) * diam
        dominated = (bound <= cost[None, :]) & (l1 > 0)
        alive = ~dominated.any(axis=0)
        E, cost, node = E[alive], cost[alive], node[alive]
    return E, cost, node


def _start_states(initial, n_agents: int | None, p: int) -> tuple[np.ndarray, int]:
    """``(start, n)``: the DP's start states -- the known ``eta_0``, or every count vector with
    sum ``n`` over ``p`` regions (bounded by :data:`MAX_GRID_CELLS`) -- and the agents' count."""
    if initial is not None:
        start = np.asarray(initial, dtype=np.int64).reshape(1, p)
        if np.any(start < 0):
            raise ValueError(f"initial counts must be >= 0, got {start.ravel().tolist()}")
        if n_agents is not None and int(start.sum()) != n_agents:
            raise ValueError(f"initial counts sum to {int(start.sum())}, not n = {n_agents}")
        n_agents = int(start.sum())
    elif n_agents is None:
        raise ValueError("give n_agents or initial")
    else:
        check_size(  # every count vector with sum n is a start state: C(n + p - 1, p - 1) rows of p
            float(math.comb(n_agents + p - 1, p - 1)) * p if p else 0.0,
            MAX_GRID_CELLS,
            what=f"count-state cells ({n_agents} agents over {p} regions, every start unknown)",
            field="[correct] n (or site.toml targets)",
            hint="fewer agents, or the known initial counts ([correct] initial / start_region)",
        )
        start = count_states(p, n_agents)
    return start, n_agents


def _dropped_blocks(src, tgt, start, H, diam, max_chunk: int, compiled: bool | None):
    """``(blocks, q, peak, events)`` of the correction DP: the ``(position, region)`` of each
    block of insertions in string order, the best start state, the DP's peak width and events
    (compiled from :data:`COMPILED_MIN` crossings on, see :func:`correct`)."""
    if compiled if compiled is not None else len(src) >= COMPILED_MIN:
        best, parent, position, region, q, peak, events, bad = kernels.correction_dp(
            src,
            tgt,
            np.ascontiguousarray(start, dtype=np.int64),
            np.ascontiguousarray(H, dtype=np.int64),
            _FAR,
            int(diam),
        )
        if bad >= 0:
            raise ValueError(f"crossing {bad} cannot be explained: no agent can reach its source region")
        blocks = []
        node_q = int(best)
        while parent[node_q] >= 0:
            blocks.append((int(position[node_q]), int(region[node_q])))
            node_q = int(parent[node_q])
    else:
        blocks, q, peak, events = _correction_dp_reference(src, tgt, start, H, diam, max_chunk)
    blocks.reverse()
    return blocks, q, peak, events


def correct(
    source,
    target,
    edges: RegionEdges,
    *,
    n_agents: int | None = None,
    initial=None,
    placement: str = "midpoint",
    window: int = 4096,
    max_chunk: int = 8192,
    times=None,
    compiled: bool | None = None,
) -> Correction:
    """Fewest inserted crossings that put ``source -> target`` in ``L(M_C)``.

    Parameters
    ----------
    source, target : (m,) region indices of the observed crossings.
    edges : the region graph (:class:`RegionEdges`).
    n_agents : n; with ``initial=None`` every count vector with sum n is a free start state
        (the DP picks the one needing fewest insertions).
    initial : (p,) known ``eta_0`` (then ``n_agents`` defaults to its sum and must match).
    placement : ``"earliest"``, ``"latest"`` or ``"midpoint"`` (see :func:`place_insertions`).
    window : how many crossings back an insertion may be moved.
    times : (m,) sorted times of the observed crossings; ``"midpoint"`` then works in time and
        gives every inserted crossing one (``Correction.time``), otherwise it works on ranks.
    compiled : the DP as one compiled pass over the string
        (:func:`onebit.trackers.beams.kernels.correction_dp`); ``False`` runs the numpy
        reference (same result); ``None`` = compiled from :data:`COMPILED_MIN` crossings on
        (below it the reference is faster than starting numba in a fresh process).
    """
    if placement not in PLACEMENTS:
        raise ValueError(f"placement must be one of {PLACEMENTS}, got {placement!r}")
    src = np.asarray(source, dtype=np.int64)
    tgt = np.asarray(target, dtype=np.int64)
    p = edges.n_regions
    m = len(src)
    obs_times = None if times is None else np.asarray(times, dtype=np.float64)
    if obs_times is not None and (len(obs_times) != m or np.any(np.diff(obs_times) < 0)):
        raise ValueError(f"times must be {m} sorted values, one per observed crossing")
    start, n_agents = _start_states(initial, n_agents, p)
    if n_agents < 1 and m > 0:
        raise ValueError("a non-empty crossing string needs n >= 1 agents")
    H = np.where(edges.hops >= 0, edges.hops, _FAR)
    diam = max(edges.diameter, 1)

    blocks, q, peak, events = _dropped_blocks(src, tgt, start, H, diam, max_chunk, compiled)
    eta0 = start[q].astype(np.int64)

    ins_pos: list[int] = []
    ins_edge: list[int] = []
    for pos, r in blocks:  # one entry per block, a few per dropped crossing
        for e in edges.path_edges(r, int(src[pos])):
            ins_pos.append(pos)
            ins_edge.append(e)
    cor = _splice(src, tgt, np.asarray(ins_pos, dtype=np.int64), np.asarray(ins_edge, dtype=np.int64), edges)
    tau = np.full(len(cor[0]), np.nan)
    if placement != "latest" and len(ins_pos):
        el_times = None
        if times is not None:
            # inserted elements carry the time of the observed crossing they precede
            ob = cor[3]
            nxt = np.minimum.accumulate(np.where(ob >= 0, np.arange(len(ob)), len(ob))[::-1])[::-1]
            el_times = obs_times[ob[nxt]]
        *cor, tau = place_insertions(*cor, eta0, window=window, placement=placement, times=el_times)
    S, T, inserted, obs, edge = cor
    if times is not None:
        tau = np.where(inserted, tau, obs_times[np.maximum(obs, 0)]) if len(obs) else np.zeros(0)
    else:
        tau = None
    return Correction(int(inserted.sum()), eta0, S, T, inserted, obs, edge, int(peak), int(events), tau)


def _splice(src, tgt, ins_pos, ins_edge, edges: RegionEdges):
    """Corrected arrays with inserted edges placed right before observed crossing ``ins_pos``."""
    m = len(src)
    total = m + len(ins_pos)
    # sort key: observed k at 2k+1, insertions before k at 2k (stable keeps path order)
    key = np.r_[2 * np.arange(m) + 1, 2 * ins_pos]
    order = np.argsort(key, kind="stable")
    S = np.r_[src, edges.edge_source[ins_edge]][order] if total else np.zeros(0, np.int64)
    T = np.r_[tgt, edges.edge_target[ins_edge]][order] if total else np.zeros(0, np.int64)
    inserted = np.r_[np.zeros(m, bool), np.ones(len(ins_pos), bool)][order]
    obs = np.r_[np.arange(m), np.full(len(ins_pos), -1)][order]
    edge = np.r_[np.full(m, -1), ins_edge][order]
    return S.astype(np.int64), T.astype(np.int64), inserted, obs.astype(np.int64), edge.astype(np.int64)


def place_insertions(
    S, T, inserted, obs, edge, initial, *, window: int = 4096, placement: str = "midpoint", times=None
):
    """Move every inserted crossing ``u -> v`` to a place of its feasible window.

    Processed in string order. For the insertion at index ``q`` the count of ``u`` before
    index ``y < q`` is ``c_u[y]``; moving it to ``x`` lowers ``c_u`` by one on ``[x, q)``, which
    is allowed iff ``c_u[y] >= 1 + [S[y] = u]`` for every ``y`` in ``[x, q)``. The feasible
    window is ``[x_lo, q]`` with ``x_lo`` one past the last ``y`` violating that (searched
    within ``window`` crossings); every position in it keeps the string in ``L(M_C)``.

    ``times`` (one per element, sorted; inserted elements carry the time of the crossing they
    precede) gives every element a time; without it the element's rank is used. The place:

    * ``"earliest"``: ``x = x_lo``;  ``"latest"``: ``x = q`` (where the DP put it);
    * ``"midpoint"``: ``tau = (t[x_lo - 1] + t[q + 1]) / 2``, the middle in time of the
      window (``t[-1]`` = ``min(0, t[0])``, the start of the recording; rank -1 without times).

    For ``"midpoint"`` the crossing goes at the first ``x`` of the window with ``t[x] > tau``
    and gets time ``tau`` (clipped to its neighbours), so times stay sorted.
    Sequential over insertions, vectorised over the window.

    Returns ``S, T, inserted, obs, edge, tau`` with ``tau`` NaN for ``"earliest"``/``"latest"``.
    """
    if placement not in PLACEMENTS:
        raise ValueError(f"placement must be one of {PLACEMENTS}, got {placement!r}")
    S, T, inserted, obs, edge = S.copy(), T.copy(), inserted.copy(), obs.copy(), edge.copy()
    n_el = len(S)
    tt = np.arange(n_el, dtype=np.float64) if times is None else np.asarray(times, dtype=np.float64).copy()
    tau_out = np.full(n_el, np.nan)
    t0 = (tt[0] - 1.0 if n_el else 0.0) if times is None else min(0.0, float(tt[0]) if n_el else 0.0)
    init = np.asarray(initial, dtype=np.int64)
    p = len(init)
    # P[y] = net count change of every region from the elements before index y
    P = np.zeros((n_el + 1, p), dtype=np.int32)
    if n_el:
        P[1:] = np.cumsum(crossing_deltas(S, T, p), axis=0)
    for q in np.flatnonzero(inserted).tolist():
        u, v = int(S[q]), int(T[q])
        lo = max(0, q - window)
        c = init[u] + P[lo:q, u]  # agents in u before each y in [lo, q)
        need = 1 + (S[lo:q] == u)
        bad = np.flatnonzero(c < need)
        x_lo = lo + (int(bad[-1]) + 1 if bad.size else 0)
        tau = np.nan
        if placement == "earliest":
            x = x_lo
        elif placement == "latest":
            x = q
        else:
            t_before = tt[x_lo - 1] if x_lo > 0 else t0
            tau = 0.5 * (t_before + tt[q + 1])  # middle of the feasible window in time
            tau = float(np.clip(tau, t_before, tt[q + 1]))
            x = x_lo + int(np.searchsorted(tt[x_lo:q], tau, side="right"))
        tt[q] = tau if np.isfinite(tau) else tt[q]
        tau_out[q] = tau
        if x < q:
            for arr in (S, T, inserted, obs, edge, tt, tau_out):
                arr[x : q + 1] = np.r_[arr[q], arr[x:q]]
            P[x + 1 : q + 1] = P[x:q]  # the elements of [x, q) moved one place right
            P[x + 1 : q + 1, u] -= 1
            P[x + 1 : q + 1, v] += 1
    if times is None:
        tau_out[:] = np.nan
    return S, T, inserted, obs, edge, tau_out


def _correction_dp_reference(src, tgt, start, H, diam, max_chunk: int = 8192):
    """The dynamic programme of :func:`correct` vectorised in numpy over the live count states
    and over runs of crossings without deficits: the reference of the compiled
    :func:`onebit.trackers.beams.kernels.correction_dp` and its test oracle. Returns
    ``(blocks, start index, peak states, events)`` with ``blocks`` the (position, source
    region) of each insertion block, last first."""
    p = start.shape[1]
    m = len(src)
    E = start.astype(np.int32)
    cost = np.zeros(len(E), dtype=np.int64)
    node = np.arange(len(E), dtype=np.int64)  # start nodes 0..K0-1 (no parent)
    par: list[np.ndarray] = [np.full(len(E), -1, dtype=np.int64)]
    npos: list[np.ndarray] = [np.full(len(E), -1, dtype=np.int64)]
    nreg: list[np.ndarray] = [np.full(len(E), -1, dtype=np.int64)]
    n_nodes = len(E)
    E, cost, node = _merge_and_prune(E, cost, node, diam)
    peak, events = len(E), 0
    i, L = 0, 64
    while i < m:
        hi = min(m, i + L)
        s, t = src[i:hi], tgt[i:hi]
        c = np.cumsum(crossing_deltas(s, t, p), axis=0)
        cpre_s = np.r_[0, c[:-1][np.arange(len(s) - 1), s[1:]]] if len(s) > 1 else np.zeros(1, np.int32)
        before = E[:, s] + cpre_s[None, :]  # (K, l) agents in the source region before crossing k
        bad_any = (before < 1).any(axis=0)
        if not bad_any.any():
            E = E + c[-1]
            i, L = hi, min(2 * L, max_chunk)
            continue
        k = int(np.argmax(bad_any))
        if k:
            E = E + c[k - 1]
        pos, sk, tk = i + k, int(s[k]), int(t[k])
        deficit = E[:, sk] < 1
        okE = E[~deficit].copy()
        okE[:, sk] -= 1
        okE[:, tk] += 1
        dE = E[deficit]
        rows, rs = np.nonzero(dE >= 1)
        reach = H[rs, sk] < _FAR
        rows, rs = rows[reach], rs[reach]
        newE = dE[rows].copy()
        newE[np.arange(len(rows)), rs] -= 1
        newE[:, tk] += 1
        newcost = cost[deficit][rows] + H[rs, sk]
        newnode = np.arange(n_nodes, n_nodes + len(rows), dtype=np.int64)
        par.append(node[deficit][rows])
        npos.append(np.full(len(rows), pos, dtype=np.int64))
        nreg.append(rs.astype(np.int64))
        n_nodes += len(rows)
        E = np.concatenate([okE, newE])
        cost = np.concatenate([cost[~deficit], newcost])
        node = np.concatenate([node[~deficit], newnode])
        if len(E) == 0:
            raise ValueError(f"crossing {pos} cannot be explained: no agent can reach its source region")
        E, cost, node = _merge_and_prune(E, cost, node, diam)
        peak, events = max(peak, len(E)), events + 1
        i, L = pos + 1, 64

    best = int(np.lexsort((node, cost))[0])
    parent = np.concatenate(par)
    position = np.concatenate(npos)
    region = np.concatenate(nreg)
    blocks: list[tuple[int, int]] = []  # (position, source region r) of each insertion block
    q = int(node[best])
    while parent[q] >= 0:
        blocks.append((int(position[q]), int(region[q])))
        q = int(parent[q])
    return blocks, q, peak, events


def min_insertions_bfs(src, tgt, edges: RegionEdges, starts) -> int:
    """Reference (unpruned) minimum number of insertions: a plain 0-1 breadth-first search.

    Nodes are ``(i, eta)`` = (position in the observed string, full count vector); consuming
    ``y[i]`` from ``eta`` costs 0, inserting any crossing of the region graph costs 1; the
    search starts from every count vector in ``starts`` and stops at the first node with
    ``i = |y|``. Exponential state space and one Python step per node: it is the test
    oracle and the benchmark peer of :func:`correct`, not something to run on long strings.
    """
    src = [int(v) for v in src]
    tgt = [int(v) for v in tgt]
    es = [int(v) for v in edges.edge_source]
    et = [int(v) for v in edges.edge_target]
    m = len(src)
    dist: dict = {}
    dq: collections.deque = collections.deque()
    for s in starts:
        node = (0, tuple(int(x) for x in s))
        dist[node] = 0
        dq.append(node)
    while dq:
        node = dq.popleft()
        i, eta = node
        d = dist[node]
        if i == m:
            return d
        if eta[src[i]] >= 1:
            e = list(eta)
            e[src[i]] -= 1
            e[tgt[i]] += 1
            nxt = (i + 1, tuple(e))
            if dist.get(nxt, 1 << 60) > d:
                dist[nxt] = d
                dq.appendleft(nxt)
        for a, b in zip(es, et):
            if eta[a] >= 1:
                e = list(eta)
                e[a] -= 1
                e[b] += 1
                nxt = (i, tuple(e))
                if dist.get(nxt, 1 << 60) > d + 1:
                    dist[nxt] = d + 1
                    dq.append(nxt)
    raise ValueError("no sequence of insertions makes the string valid from these initial counts")
