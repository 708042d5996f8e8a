"""Global association of path fragments by a minimum-cost flow (``findinghumo-flow``).

Beyond the paper: FindingHuMo's CPDA pairs the paths at each co-location over ``C`` windows;
here the decoded paths are cut into *fragments* at every co-location (meeting) and the
fragments are chained into identities over the whole run at once.

Fragments and meetings. ``P`` (U, D) are the decoded node paths (``-1`` absent). Two tracks
are *in contact* in slot ``s`` when both are present, at most one hop apart and neither is at
an entry/exit node. A *meeting* ``M`` is a maximal run of slots ``s0..s1`` in which the same
group of tracks is one connected component of the contact graph. Each meeting gets one cut
slot ``b_M`` in ``s0+1 .. s1+1`` (the latest one at which the most pairs ``(u, v)`` of its
tracks can be joined without a jump, ``hops(P[u, b-1], P[v, b]) <= 1``). Every track is cut
at the cut slots of its meetings; a fragment ``f = (u, a_f, e_f)`` is track ``u`` over slots
``a_f .. e_f - 1``.

Flow network (:func:`min_cost_cover`): per fragment ``f`` an arc ``f_in -> f_out`` of capacity 1
and cost ``-BIG`` (every fragment is covered); ``source -> f_in`` with the birth cost
``beta_f``; ``f_out -> sink`` with the death cost ``delta_f``; a join arc ``f_out -> g_in`` with
cost ``c(f, g)`` for every allowed join; ``source -> sink`` for unused units. The supply is
the number of fragments (an upper bound on the identities). A minimum-cost flow (integral:
``networkx.min_cost_flow``, network simplex, costs scaled to integers) is a set of disjoint
chains covering every fragment that minimises::

    sum_chains [ beta_first + sum_{(f, g) consecutive} c(f, g) + delta_last ]

which is the negative log-likelihood of the identities under the cost model below, and the
number of chains -- the user count -- follows from the entry/exit signatures: births are free
only at the start of the run or at an entry node (``beta = 0``, else ``BIRTH``), deaths only at
the end of the run or at an exit node.

Joins and costs (:func:`join_cost`). At the cut slot ``b`` of a meeting every fragment ending
at ``b`` may continue on every fragment starting at ``b`` of the same meeting whose first
node is within one hop of its last node. With ``x`` = the distinct nodes of ``f`` (``x_k``
dwelt ``n_k`` slots) and ``y`` those of ``g``::

    c(f, g) = - sum_i log a''(z_i, z_{i+2})      z = distinct(x[-2:] ++ y[:2]) (EATG 2-hop, eq. 2)
              + (log pace_f - log pace_g)^2 / (2 sigma^2)                       (when both paces are known)
              + lambda [track_f != track_g]                                      (the HMM's pairing among equals)
              [ - log Geom(n_x_last + n_y_first ; mu_turn if x_{-2} = y_2 else mu_pass) ]  (``turn_dwell``)

``lambda`` is ``switch_cost``. With ``turn_dwell``, a visit joined across the cut (same node)
is scored by its dwell: ``mu_pass`` / ``mu_turn`` are the mean dwell (slots) of the visits in the decoded paths away
from meetings that pass through a node / turn back at it (a user turning at a route end
pauses; one passing through does not); ``Geom(n; mu) = (1 - 1/mu)^(n-1) / mu``. A fragment's
pace (dwell times) is the median dwell of its visits strictly inside it: each user's own walking
speed, which persists across a meeting. A track
that ends (not at an exit, not at the end) may continue on a track that starts up to
``max_gap`` slots later within reach (``hops <= gap + 1``) at cost
``-log (A'^(gap+1))[last_f, first_g]`` (the EATG 1-hop chain bridging the gap, eq. 1) plus the
pace term -- an association across the run that the per-meeting CPDA cannot make.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from onebit.core.lazy import lazy_module

_nx = lazy_module("networkx")
_csgraph = lazy_module("scipy.sparse.csgraph")
_sparse = lazy_module("scipy.sparse")

#: reward for covering a fragment (larger than any chain cost)
BIG = 1e6
#: cost of a birth / death away from the run's ends and the doors
BIRTH = 30.0
#: costs are scaled by this and rounded for the integral network simplex
SCALE = 1000.0


@dataclass(frozen=True)
class Fragment:
    track: int
    start: int  # first slot
    end: int  # one past the last slot


@dataclass(frozen=True)
class Meeting:
    tracks: tuple[int, ...]
    s0: int
    s1: int
    cut: int  # cut slot b: fragments end at b and start at b


def contact(paths: np.ndarray, hops: np.ndarray, feature: np.ndarray) -> np.ndarray:
    """(U, U, D) bool: tracks ``u != v`` present, at most one hop apart, neither at a feature node."""
    u = paths.shape[0]
    q = np.maximum(paths, 0)
    ok = (paths >= 0) & ~feature[q]
    near = hops[q[:, None, :], q[None, :, :]] <= 1
    return near & ok[:, None, :] & ok[None, :, :] & ~np.eye(u, dtype=bool)[:, :, None]


def meetings(paths: np.ndarray, hops: np.ndarray, feature: np.ndarray) -> list[Meeting]:
    """The meetings of ``paths`` (module docstring), in time order. Vectorised: one connected-
    components call over the (slot, track) contact graph of the whole run."""
    n_u, d = paths.shape
    if n_u < 2 or d == 0:
        return []
    c = contact(paths, hops, feature)
    a, b, s = np.nonzero(c)
    vid = lambda uu, ss: ss * n_u + uu  # noqa: E731
    g = _sparse.coo_matrix((np.ones(a.size), (vid(a, s), vid(b, s))), shape=(n_u * d, n_u * d))
    _, lab = _csgraph.connected_components(g, directed=False)
    lab = lab.reshape(d, n_u)  # (slot, track)
    inside = c.any(axis=1).T  # (slot, track): in contact with someone
    groups: list[tuple[int, tuple[int, ...]]] = []
    for ss in range(d):  # group membership per slot (a few tracks): a small loop over slots
        tr = np.flatnonzero(inside[ss])
        for lb in np.unique(lab[ss, tr]):
            groups.append((ss, tuple(tr[lab[ss, tr] == lb].tolist())))
    runs: dict[tuple[int, ...], list[list[int]]] = {}
    for ss, grp in groups:
        r = runs.setdefault(grp, [])
        if r and r[-1][1] == ss - 1:
            r[-1][1] = ss
        else:
            r.append([ss, ss])
    out = []
    for grp, spans in runs.items():
        for s0, s1 in spans:
            cut = _cut_slot(paths, np.asarray(grp), s0, s1, hops)
            if cut is not None:
                out.append(Meeting(grp, s0, s1, cut))
    return sorted(out, key=lambda m: (m.cut, m.tracks))


def _cut_slot(paths: np.ndarray, grp: np.ndarray, s0: int, s1: int, hops: np.ndarray) -> int | None:
    d = paths.shape[1]
    best, best_n = None, -1
    for b in range(s0 + 1, min(s1 + 1, d - 1) + 1):
        prev, nxt = paths[grp, b - 1], paths[grp, b]
        if (prev < 0).any() or (nxt < 0).any():
            continue
        n_ok = int((hops[prev[:, None], nxt[None, :]] <= 1).sum())
        if n_ok >= best_n:
            best, best_n = b, n_ok
    return best


def fragments(paths: np.ndarray, meets: list[Meeting]) -> list[Fragment]:
    """Each track cut at the cut slots of its meetings; absent slots at a piece's ends trimmed."""
    cuts: dict[int, set[int]] = {}
    for m in meets:
        for u in m.tracks:
            cuts.setdefault(u, set()).add(m.cut)
    out = []
    for u in range(paths.shape[0]):
        present = np.flatnonzero(paths[u] >= 0)
        if present.size == 0:
            continue
        bounds = [int(present[0]), *sorted(cuts.get(u, ())), int(present[-1]) + 1]
        for a, e in zip(bounds[:-1], bounds[1:]):
            seg = np.flatnonzero(paths[u, a:e] >= 0)
            if seg.size:
                out.append(Fragment(u, a + int(seg[0]), a + int(seg[-1]) + 1))
    return out


def meeting_joins(
    paths: np.ndarray, frags: list[Fragment], meets: list[Meeting], hops: np.ndarray
) -> list[tuple[int, int, int, int]]:
    """Every allowed join at a meeting's cut slot: ``(f, g, cut, last node of f)`` for ``f``
    ending and ``g`` starting at the cut, ``g``'s first node within one hop of ``f``'s last."""
    by_end = {(f.track, f.end): i for i, f in enumerate(frags)}
    by_start = {(f.track, f.start): i for i, f in enumerate(frags)}
    out = []
    for m in meets:
        ins = [by_end[(u, m.cut)] for u in m.tracks if (u, m.cut) in by_end]
        outs = [by_start[(u, m.cut)] for u in m.tracks if (u, m.cut) in by_start]
        for f in ins:
            last = int(paths[frags[f].track, m.cut - 1])
            out.extend((f, g, m.cut, last) for g in outs if hops[last, paths[frags[g].track, m.cut]] <= 1)
    return out


def assemble(paths: np.ndarray, frags: list[Fragment], succ: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The identities' paths (K, D) from the chains of ``succ``, and each fragment's identity."""
    ident = np.full(len(frags), -1, dtype=np.int64)
    found = chains(succ)
    out = np.full((len(found), paths.shape[1]), -1, dtype=np.int64)
    for k, ch in enumerate(found):
        for f in ch:
            fr = frags[f]
            ident[f] = k
            out[k, fr.start : fr.end] = paths[fr.track, fr.start : fr.end]
    return out, ident


def visits(row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct nodes of a path piece (absent slots dropped) and their dwell in slots."""
    r = row[row >= 0]
    if r.size == 0:
        return r, r
    start = np.concatenate([[True], r[1:] != r[:-1]])
    idx = np.flatnonzero(start)
    return r[idx], np.diff(np.append(idx, r.size))


def dwell_means(paths: np.ndarray, meets: list[Meeting]) -> tuple[float, float]:
    """``(mu_pass, mu_turn)``: mean dwell of the visits that pass through / turn back at a node,
    over the decoded visits that are not inside a meeting (defaults 2 and 4 slots)."""
    busy = np.zeros(paths.shape, bool)
    for m in meets:
        busy[list(m.tracks), m.s0 : m.s1 + 1] = True
    passing, turning = [], []
    for u in range(paths.shape[0]):  # per track (a handful), per piece between meetings
        row = np.where(busy[u], -2, paths[u])
        for piece in np.split(row, np.flatnonzero(row == -2)):
            pn, pd = visits(piece[piece >= 0])
            for k in range(1, pn.size - 1):
                (turning if pn[k - 1] == pn[k + 1] else passing).append(pd[k])
    mu_pass = float(np.mean(passing)) if passing else 2.0
    mu_turn = float(np.mean(turning)) if turning else 4.0
    return max(mu_pass, 1.0), max(mu_turn, 1.0)


def pace(nodes: np.ndarray, dwell: np.ndarray) -> float | None:
    """Median dwell of a fragment's inner visits (slots per node), ``None`` when it has none."""
    return float(np.median(dwell[1:-1])) if nodes.size >= 3 else None


def log_geom(n: int, mu: float) -> float:
    p = 1.0 / mu
    return (n - 1) * math.log1p(-p) + math.log(p) if p < 1.0 else (0.0 if n == 1 else -50.0)


def join_cost(
    x: tuple[np.ndarray, np.ndarray],
    y: tuple[np.ndarray, np.ndarray],
    log_a2: np.ndarray,
    mu: tuple[float, float] | None,
    sigma: float,
    pace_f: float | None,
    pace_g: float | None,
) -> float:
    """``c(f, g)`` of the module docstring from the visits ``x`` of ``f`` and ``y`` of ``g``
    (``mu = None``: without the turn/pass dwell term)."""
    xn, xd = x
    yn, yd = y
    z = np.concatenate([xn[-2:], yn[:2]])
    z = z[np.concatenate([[True], z[1:] != z[:-1]])] if z.size else z
    # every triple of z straddles the junction (x[-2:] and y[:2] hold none of their own)
    cost = -float(log_a2[z[:-2], z[2:]].sum()) if z.size >= 3 else 0.0
    same = bool(xn.size and yn.size and xn[-1] == yn[0])
    if mu is not None and same and xn.size >= 2 and yn.size >= 2:
        n = int(xd[-1] + yd[0])
        cost -= log_geom(n, mu[1] if xn[-2] == yn[1] else mu[0])
    if pace_f is not None and pace_g is not None:
        cost += (math.log(pace_f) - math.log(pace_g)) ** 2 / (2 * sigma**2)
    return cost


def min_cost_cover(
    n: int, birth: np.ndarray, death: np.ndarray, joins: dict[tuple[int, int], float]
) -> tuple[np.ndarray, float]:
    """Chains covering fragments ``0..n-1`` at minimum total cost (module docstring).

    ``birth[f]`` / ``death[f]``: cost of a chain starting / ending at ``f``; ``joins[(f, g)]``:
    cost of ``g`` following ``f`` (``f`` must end before ``g`` starts: the graph is acyclic).
    Returns ``succ`` (n,) -- the fragment following each one, ``-1`` at a chain's end -- and
    the total cost (without the coverage rewards).
    """
    g = _nx.DiGraph()
    g.add_node("s", demand=-n)
    g.add_node("t", demand=n)
    g.add_edge("s", "t", capacity=n, weight=0)
    w = lambda c: int(round(c * SCALE))  # noqa: E731
    for f in range(n):
        g.add_edge(("i", f), ("o", f), capacity=1, weight=w(-BIG))
        g.add_edge("s", ("i", f), capacity=1, weight=w(birth[f]))
        g.add_edge(("o", f), "t", capacity=1, weight=w(death[f]))
    for (f, h), c in joins.items():
        g.add_edge(("o", f), ("i", h), capacity=1, weight=w(c))
    flow = _nx.min_cost_flow(g)
    succ = np.full(n, -1, dtype=np.int64)
    total = 0.0
    for f in range(n):
        for nxt, v in flow[("o", f)].items():
            if v and nxt != "t":
                succ[f] = nxt[1]
                total += joins[(f, nxt[1])]
            elif v:
                total += death[f]
        if flow["s"][("i", f)]:
            total += birth[f]
    return succ, total


def chains(succ: np.ndarray) -> list[list[int]]:
    """The chains of a successor array, each from its first fragment, ordered by first fragment."""
    has_pred = np.zeros(succ.size, bool)
    has_pred[succ[succ >= 0]] = True
    out = []
    for f in np.flatnonzero(~has_pred).tolist():
        ch = [f]
        while succ[ch[-1]] >= 0:
            ch.append(int(succ[ch[-1]]))
        out.append(ch)
    return out
