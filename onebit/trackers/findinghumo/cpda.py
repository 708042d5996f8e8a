"""CPDA, the Crossover Path Disambiguation Algorithm (paper section III-C).

Input: the decoded node paths of the ``K`` users over the last ``C`` HMM windows, as a
(K, D) array of node indices (``-1`` where a user is not present).

1. *Interaction graph* ``G_I``: the nodes the paths visit and the directed edges between
   consecutive distinct nodes of each path (:func:`interaction_graph`).
2. *Feature / non-feature nodes*: a node where a path can only continue one way -- visited
   by one path at a time, or an entry/exit node -- is a feature node. A *non-feature* node is
   one where two or more paths are present in the same slot (a crossover): which incoming
   path continues on which outgoing segment is ambiguous there. Each such meeting is an event
   ``(c, j)``: the last slot ``c`` of a run of slots in which the same set of users is at ``j``.
3. *Inference* at each event: every path ``u`` there has an incoming node ``in_u`` (the last
   node before ``j`` within the CPDA horizon ``W = C d_max`` slots) and an outgoing segment
   starting at ``out_u`` (the first node after ``j`` within ``W``). The node state
   ``Y(j, u) = {in_u, out_sigma(u)}`` is chosen by maximising the joint probability of the
   pairing, with the paper's conditional probability table ``P(Y(j,u) = {j2, j3} | j2) = a''(j2, j3)``::

       sigma* = argmax_sigma  prod_u a''(in_u, out_sigma(u))

   over permutations ``sigma`` of the paths at ``j``. A permutation pairs every incoming path
   with exactly one outgoing segment, so *flow conservation* (as many paths leave ``j`` as
   enter it) holds by construction. The maximisation is a linear assignment on
   ``-log a''`` (``scipy.optimize.linear_sum_assignment``); ties keep the HMM's pairing
   (a ``1e-9`` bonus on the identity). An unknown ``in`` or ``out`` (path starts, ends or does
   not move within ``W``) contributes a factor 1.
4. *Switch*: where ``sigma*`` differs from the HMM output, the path tails after ``c`` are
   exchanged: ``path_u[c+1:] <- path_sigma(u)[c+1:]``.

Events are handled in time order; a switch relabels the later slots, so the pass is repeated
until no switch happens (at most ``max_passes``). The loop over events is inherently
sequential (each switch changes the paths the next event sees).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.trackers.findinghumo.viterbi import log_safe
from onebit.core.lazy import lazy_module

_optimize = lazy_module("scipy.optimize")
_csgraph = lazy_module("scipy.sparse.csgraph")
_sparse = lazy_module("scipy.sparse")

SWITCHES = pl.Schema({"slot": pl.Int64, "node": pl.String, "users": pl.String, "pairing": pl.String})


@dataclass(frozen=True)
class CpdaResult:
    paths: np.ndarray  # (K, D) corrected
    switches: list[tuple[int, int, tuple[int, ...], tuple[int, ...]]]  # (slot, node, users, sigma)
    passes: int


def interaction_graph(paths: np.ndarray, nodes: tuple[str, ...]):
    """Directed ``networkx.MultiDiGraph`` of the decoded paths: one edge per path step between
    distinct consecutive nodes, with attributes ``user`` and ``slot`` (slot of arrival)."""
    import networkx as nx

    g = nx.MultiDiGraph()
    k, d = paths.shape
    prev = paths[:, :-1]
    nxt = paths[:, 1:]
    u, t = np.nonzero((prev != nxt) & (prev >= 0) & (nxt >= 0))
    g.add_nodes_from(nodes[i] for i in np.unique(paths[paths >= 0]))
    for uu, tt in zip(u.tolist(), t.tolist()):
        g.add_edge(nodes[prev[uu, tt]], nodes[nxt[uu, tt]], user=uu, slot=tt + 1)
    return g


def colocation_events(paths: np.ndarray, feature: np.ndarray, hops: np.ndarray | None = None) -> list[tuple[int, tuple[int, ...]]]:
    """Meeting events ``(c, users)``: slot ``c`` is the last of a run in which the same group of
    >= 2 users meets -- at one node (the paper's non-feature node), or, with ``hops``, also at
    adjacent nodes (two users crossing on an edge between slots, which a slot-level decoder
    turns into two paths that bounce back without ever sharing a node).

    ``feature``: (N,) bool, nodes never treated as crossovers (entry/exit nodes).
    Vectorised over users and slots: ``meet[u, v, t]``.
    """
    k, d = paths.shape
    if k < 2 or d == 0:
        return []
    p = paths
    present = p >= 0
    both = present[:, None, :] & present[None, :, :]
    if hops is None:
        meet = (p[:, None, :] == p[None, :, :]) & both
    else:
        q = np.maximum(p, 0)
        meet = (hops[q[:, None, :], q[None, :, :]] <= 1) & both
    meet &= ~np.eye(k, dtype=bool)[:, :, None]
    meet &= ~feature[np.maximum(p, 0)][:, None, :] & ~feature[np.maximum(p, 0)][None, :, :]
    nxt = np.concatenate([meet[:, :, 1:], np.zeros((k, k, 1), bool)], axis=2)
    ends = (meet & ~nxt).any(axis=(0, 1)) | (meet != nxt).any(axis=(0, 1)) & meet.any(axis=(0, 1))
    events = []
    for c in np.flatnonzero(ends).tolist():  # per event slot: groups = connected components
        _, lab = _csgraph.connected_components(_sparse.csr_matrix(meet[:, :, c]), directed=False)
        for g in np.unique(lab):
            users = np.flatnonzero(lab == g)
            if users.size >= 2:
                events.append((c, tuple(users.tolist())))
    return events


def _neighbour_node(row: np.ndarray, node: int, start: int, stop: int, step: int) -> int:
    """First node different from ``node`` scanning ``row[start], row[start+step], ...`` up to
    (not including) ``stop``; -1 if none (or the user is absent)."""
    seg = row[start:stop:step] if step > 0 else row[start:stop if stop >= 0 else None:step]
    diff = np.flatnonzero(seg != node)
    if diff.size == 0:
        return -1
    return int(seg[diff[0]])


def _connected(adj: np.ndarray) -> bool:
    """Whether the users of a meeting (adjacency ``adj`` between their nodes) still form one group."""
    return _csgraph.connected_components(_sparse.csr_matrix(adj), directed=False)[0] == 1


def junction_score(seq: list[int], log_a2: np.ndarray) -> float:
    """Sum of ``log a''(s_i, s_{i+2})`` over the distinct-node sequence ``seq`` (unknowns dropped)."""
    s = [x for x in seq if x >= 0]
    s = [x for i, x in enumerate(s) if i == 0 or x != s[i - 1]]
    return float(sum(log_a2[s[i], s[i + 2]] for i in range(len(s) - 2)))


def cpda(
    paths: np.ndarray,
    a2: np.ndarray,
    *,
    horizon: int,
    feature: np.ndarray | None = None,
    hops: np.ndarray | None = None,
    max_passes: int = 5,
) -> CpdaResult:
    """Disambiguate crossovers in ``paths`` (K, D) with the 2-hop weights ``a2`` = A'' (N, N).

    With ``hops`` (the 1-hop graph's hop matrix) users meeting at adjacent nodes are also
    considered; pairing ``u -> v`` there joins ``u``'s path up to its node ``m_u`` with ``v``'s
    tail from ``m_v``, scored by :func:`junction_score` of ``[in_u, m_u, m_v, out_v]`` (for
    ``m_u = m_v`` this is the paper's ``a''(in_u, out_v)``); a pairing whose joined path
    would jump (``m_u`` more than one hop from ``m_v`` or from ``v``'s next node) is not allowed.
    """
    paths = np.array(paths, dtype=np.int64, copy=True)
    n = a2.shape[0]
    feature = np.zeros(n, bool) if feature is None else np.asarray(feature, bool)
    log_a2 = log_safe(a2)
    switches = []
    passes = 0
    for passes in range(1, max_passes + 1):
        changed = False
        for c, group in colocation_events(paths, feature, hops):
            users = np.asarray(group)
            at = paths[users, c]
            if (at < 0).any():
                continue
            # events are listed before the pass; an earlier switch may have moved these users apart
            if (hops is None and (at != at[0]).any()) or (hops is not None and not _connected(hops[np.ix_(at, at)] <= 1)):
                continue
            d = paths.shape[1]
            lo, hi = max(0, c - horizon), min(d, c + 1 + horizon)
            ins = [_neighbour_node(paths[u], m, c, lo - 1, -1) for u, m in zip(users, at)]
            outs = [_neighbour_node(paths[u], m, c + 1, hi, 1) for u, m in zip(users, at)]
            m = users.size
            nxt = paths[users, c + 1] if c + 1 < d else np.full(m, -1)
            cost = np.zeros((m, m))
            for a in range(m):  # m is the size of one meeting (2-3 users): tiny
                for b in range(m):
                    if hops is not None and (hops[at[a], at[b]] > 1 or (nxt[b] >= 0 and hops[at[a], nxt[b]] > 1)):
                        cost[a, b] = 1e12  # not allowed: the joined path would jump
                    else:
                        cost[a, b] = min(-junction_score([ins[a], at[a], at[b], outs[b]], log_a2), 1e6)
            cost = cost - 1e-9 * np.eye(m)
            r, col = _optimize.linear_sum_assignment(cost)
            sigma = col[np.argsort(r)]
            if np.array_equal(sigma, np.arange(m)):
                continue
            tails = paths[users[sigma], c + 1 :].copy()
            paths[users, c + 1 :] = tails
            switches.append((int(c), int(at[0]), tuple(users.tolist()), tuple(users[sigma].tolist())))
            changed = True
        if not changed:
            break
    return CpdaResult(paths, switches, passes)


def switches_table(result: CpdaResult, nodes: tuple[str, ...], slot0: int = 0) -> pl.DataFrame:
    rows = [
        (slot0 + c, nodes[j], " ".join(map(str, u)), " ".join(map(str, s)))
        for c, j, u, s in result.switches
    ]
    return pl.DataFrame(rows, schema=SWITCHES, orient="row")
