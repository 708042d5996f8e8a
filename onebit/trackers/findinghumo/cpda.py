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
3. *Inference* at each event (:func:`pair_meeting`): the users of a meeting are together in
   slots ``s0 .. c`` (at one node, or with ``hops`` at adjacent nodes). Every path ``u`` has an
   incoming node ``in_u`` (before the meeting) and an outgoing node ``out_u`` (after it). The
   node state ``Y(j, u) = {in_u, out_sigma(u)}`` -- path ``u`` continues on the tail of path
   ``sigma(u)`` -- is chosen by maximising the joint probability of the pairing under the
   paper's conditional probability table ``P(Y(j,u) = {j2, j3} | j2) = a''(j2, j3)``::

       sigma* = argmax_sigma  prod_u a''(in_u, out_sigma(u))          (one meeting node)

   over all permutations ``sigma`` of the meeting's paths (``m!`` for ``m <= MAX_MEETING``).
   In general each pairing is scored by the a'' product along the whole joined paths
   (the terms away from the meeting are common to all pairings), which covers meetings on
   adjacent nodes and lets one meeting's decision see the others it shares nodes with. A
   permutation pairs every incoming path with exactly one outgoing one, so *flow
   conservation* holds by construction. Ties keep the HMM's pairing. Every decision is
   recorded with all alternatives' posteriors (:func:`decisions_table`).
4. *Switch*: where ``sigma*`` differs from the HMM output, the path tails are exchanged at the
   slot ``b`` inside the meeting where the joined paths stay continuous (one hop per slot) and
   score best: ``path_u[b:] <- path_sigma(u)[b:]``.

Events are handled in time order; a switch relabels the later slots, so the pass is repeated
until no switch happens (at most ``max_passes``); every switch raises the joint probability of
all paths, so this ends. The loop over events is inherently sequential (each switch changes the
paths the next event sees); a meeting has 2-3 users, so its pairings are few.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
import polars as pl

from onebit.models.graph_hmm.viterbi import log_safe

SWITCHES = pl.Schema({"slot": pl.Int64, "node": pl.String, "users": pl.String, "pairing": pl.String})


@dataclass(frozen=True)
class CpdaResult:
    paths: np.ndarray  # (K, D) corrected
    switches: list[tuple[int, int, tuple[int, ...], tuple[int, ...]]]  # (slot, node, users, sigma)
    passes: int
    decisions: list[dict] = field(default_factory=list)  # every event looked at (see :func:`decisions_table`)


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


def colocation_events(
    paths: np.ndarray, feature: np.ndarray, hops: np.ndarray | None = None
) -> list[tuple[int, tuple[int, ...]]]:
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
        lab = _component_labels(meet[:, :, c])
        for g in np.unique(lab):
            users = np.flatnonzero(lab == g)
            if users.size >= 2:
                events.append((c, tuple(users.tolist())))
    return events


def _neighbour_node(row: np.ndarray, node: int, start: int, stop: int, step: int) -> int:
    """First node different from ``node`` scanning ``row[start], row[start+step], ...`` up to
    (not including) ``stop``; -1 if none (or the user is absent)."""
    seg = row[start:stop:step] if step > 0 else row[start : stop if stop >= 0 else None : step]
    diff = np.flatnonzero(seg != node)
    if diff.size == 0:
        return -1
    return int(seg[diff[0]])


def _component_labels(adj: np.ndarray) -> np.ndarray:
    """Connected-component label of each of a handful of users (``adj`` (k, k) bool, read as
    undirected): the smallest index reachable, by boolean reachability products -- no sparse
    graph built for a matrix this small."""
    a = np.asarray(adj, dtype=bool)
    reach = a | a.T | np.eye(a.shape[0], dtype=bool)
    for _ in range(max(1, int(np.ceil(np.log2(max(a.shape[0], 2)))))):  # squaring: paths of length 2^i
        reach = (reach.astype(np.int64) @ reach.astype(np.int64)) > 0
    return reach.argmax(axis=1)


def _connected(adj: np.ndarray) -> bool:
    """Whether the users of a meeting (adjacency ``adj`` between their nodes, a handful) still
    form one group: the nodes reached from the first by repeated boolean products (at most
    ``m - 1`` steps), without building a sparse graph for a 2-5 node matrix."""
    a = np.asarray(adj, dtype=bool)
    a = a | a.T
    reach = a[0].copy()
    reach[0] = True
    for _ in range(a.shape[0] - 1):  # m - 1 <= 4 expansions
        nxt = reach | a[reach].any(axis=0)
        if (nxt == reach).all():
            break
        reach = nxt
    return bool(reach.all())


def junction_score(seq, log_a2: np.ndarray) -> float:
    """Sum of ``log a''(s_i, s_{i+2})`` over the distinct-node sequence of ``seq`` (unknowns,
    ``-1``, dropped): the log probability of a path under the paper's CPT
    ``P(Y(j,u) = {j2, j3} | j2) = a''(j2, j3)`` at every node it passes."""
    s = np.asarray(seq, dtype=np.int64)
    s = s[s >= 0]
    if s.size < 3:
        return 0.0
    s = s[np.concatenate([[True], s[1:] != s[:-1]])]
    return float(log_a2[s[:-2], s[2:]].sum()) if s.size >= 3 else 0.0


def meeting_start(paths: np.ndarray, users: np.ndarray, c: int, hops: np.ndarray | None) -> int:
    """First slot ``s0`` of the run of slots ending at ``c`` in which the users of one event
    stay together (all present; at one node, or with ``hops`` one connected group within 1 hop)."""
    s0 = c
    while s0 > 0:
        at = paths[users, s0 - 1]
        if (at < 0).any():
            break
        if hops is None and (at != at[0]).any():
            break
        if hops is not None and not _connected(hops[np.ix_(at, at)] <= 1):
            break
        s0 -= 1
    return s0


#: the most users of one meeting whose pairings are enumerated (m! pairings); larger meetings are kept
MAX_MEETING = 5


def _ends(row: np.ndarray, b: int) -> tuple[int, int, int, int]:
    """``(h2, h1, t1, t2)``: the last two distinct known nodes of ``row[:b]`` (``h1`` the last)
    and the first two of ``row[b:]`` (``t1`` the first); ``-1`` where there are fewer."""
    out = []
    for seq in (row[:b][::-1], row[b:]):  # walk out from the junction
        got: list[int] = []
        for x in seq:
            if x >= 0 and (not got or x != got[-1]):
                got.append(int(x))
                if len(got) == 2:
                    break
        out.append(got + [-1] * (2 - len(got)))
    (h1, h2), (t1, t2) = out
    return h2, h1, t1, t2


def _cross(h2: int, h1: int, t1: int, t2: int, log_a2: np.ndarray) -> float:
    """The :func:`junction_score` terms of ``head ++ tail`` that span the junction (the
    distinct-node triples with nodes on both sides): with ``h1 == t1`` the sequences merge
    there and only ``a''(h2, t2)`` spans it; else ``a''(h2, t1) + a''(h1, t2)``."""
    if h1 < 0 or t1 < 0:
        return 0.0
    if h1 == t1:
        return float(log_a2[h2, t2]) if h2 >= 0 and t2 >= 0 else 0.0
    return (float(log_a2[h2, t1]) if h2 >= 0 else 0.0) + (float(log_a2[h1, t2]) if t2 >= 0 else 0.0)


def pair_meeting(
    paths: np.ndarray, users: np.ndarray, s0: int, c: int, log_a2: np.ndarray, hops: np.ndarray | None
) -> tuple[list[tuple[int, ...]], np.ndarray, np.ndarray]:
    """Every pairing of one meeting with its log joint probability and its switching slot.

    The meeting: users ``users`` together in slots ``s0..c``. Pairing ``sigma`` continues user
    ``u`` on the tail of user ``sigma(u)``, switched at a slot ``b`` in ``s0+1 .. c+1``
    (``path_u[b:] <- path_sigma(u)[b:]``). Its log joint probability is that of the joined
    paths under the paper's CPT ``P(Y(j,u) = {j2, j3} | j2) = a''(j2, j3)`` at every node they
    pass (:func:`junction_score` of each whole joined path)::

        log P(sigma, b) = sum_u junction_score(path_u[:b] ++ path_sigma(u)[b:])

    Only the terms around the switch differ between pairings -- at a one-node meeting that is
    the paper's ``a''(in_u, out_sigma(u))`` -- but scoring the whole paths makes one meeting's
    decision account for the others it shares nodes with. Computed without rescoring whole
    paths: the heads ``path_u[:b]`` and tails ``path_u[b:]`` are the same multiset for every
    pairing, so with ``X(sigma, b) = sum_u cross(head_u, tail_sigma(u))`` the terms spanning the
    junction (:func:`_cross`)::

        log P(sigma, b) - log P(identity) = X(sigma, b) - X(identity, b)

    returned relative to the identity (``logp[0] = 0``; posteriors and decisions use only
    differences), so a meeting costs nothing in the run's length. Exact:
    :func:`onebit._testing.oracles.pair_meeting_reference` scores every joined path whole and is the test oracle. A switching slot at which a joined
    path would jump (consecutive nodes more than one hop apart, with ``hops``) is not allowed;
    a pairing with no allowed slot gets ``-inf``. Per pairing the best slot is kept (the
    latest among equals). Returns (pairings, the identity first; log P; switching slot).
    """
    m = users.size
    perms, logp, slot, rows = _pairings(paths, users, c)
    logp[0] = 0.0  # log P relative to the HMM's pairing: the whole paths' common terms cancel
    slots = list(range(c + 1, s0, -1))
    ends = {b: [_ends(rows[u], b) for u in range(m)] for b in slots}  # (h2, h1, t1, t2) per user
    base = {b: logp[0] - sum(_cross(e[0], e[1], e[2], e[3], log_a2) for e in ends[b]) for b in slots}
    # Where the HMM's own pairing is impossible under a'' at slot b (base = +inf), an
    # impossible alternative scores inf - inf = nan and is never taken (nan > x is False), a
    # possible one +inf, which the caller reads as "no finite best" and keeps the HMM's pairing.
    with np.errstate(invalid="ignore"):
        _score_pairings(perms, logp, slot, slots, ends, base, rows, hops, log_a2, m)
    return perms, logp, slot


def _score_pairings(perms, logp, slot, slots, ends, base, rows, hops, log_a2, m) -> None:
    """Fill ``logp``/``slot`` of every non-identity pairing with its best slot (:func:`pair_meeting`)."""
    for k, p in enumerate(perms[1:], start=1):  # m <= MAX_MEETING users, a few slots: tiny
        for b in slots:
            if _jumps(rows, p, b, hops):
                continue
            e = ends[b]
            score = base[b] + sum(_cross(e[u][0], e[u][1], e[p[u]][2], e[p[u]][3], log_a2) for u in range(m))
            if score > logp[k] + 1e-9:
                logp[k], slot[k] = score, b


def _pairings(paths: np.ndarray, users: np.ndarray, c: int):
    """Every pairing of a meeting's users (the identity first), their log P to fill (``-inf``),
    their switching slots (``c + 1``) and the users' paths (views: a meeting costs its own
    slots, not the run's)."""
    perms = list(itertools.permutations(range(users.size)))
    return perms, np.full(len(perms), -np.inf), np.full(len(perms), c + 1, dtype=np.int64), [paths[u] for u in users]


def _jumps(rows: np.ndarray, p, b: int, hops: np.ndarray | None) -> bool:
    """Whether switching to pairing ``p`` at slot ``b`` makes a joined path jump (consecutive
    known nodes more than one hop apart)."""
    if hops is None or b >= len(rows[0]):
        return False
    return any(
        rows[u][b - 1] >= 0 and rows[p[u]][b] >= 0 and hops[rows[u][b - 1], rows[p[u]][b]] > 1 for u in range(len(p))
    )


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
    considered. Each meeting's pairing is chosen by :func:`pair_meeting` (the joint probability
    of the joined paths under a''); the HMM's pairing is kept unless another is strictly more
    probable, so every switch raises the joint probability of all paths and the passes end
    (at a fixed point when ``max_passes`` allows). ``horizon`` (``C d_max`` slots) bounds how
    far back and on the incoming / outgoing nodes recorded with a decision are looked for.
    """
    paths = np.array(paths, dtype=np.int64, copy=True)
    n = a2.shape[0]
    feature = np.zeros(n, bool) if feature is None else np.asarray(feature, bool)
    log_a2 = log_safe(a2)
    switches = []
    decisions: list[dict] = []
    passes = 0
    for passes in range(1, max_passes + 1):
        changed = False
        for c, group in colocation_events(paths, feature, hops):
            users = np.asarray(group)
            at = paths[users, c]
            if (at < 0).any() or users.size > MAX_MEETING:
                continue
            # events are listed before the pass; an earlier switch may have moved these users apart
            if (hops is None and (at != at[0]).any()) or (
                hops is not None and not _connected(hops[np.ix_(at, at)] <= 1)
            ):
                continue
            d = paths.shape[1]
            s0 = meeting_start(paths, users, c, hops)
            lo, hi = max(0, s0 - horizon), min(d, c + 1 + horizon)
            ins = [_neighbour_node(paths[u], paths[u, s0], s0, lo - 1, -1) for u in users]
            outs = [_neighbour_node(paths[u], m, c + 1, hi, 1) for u, m in zip(users, at)]
            perms, logp, slot = pair_meeting(paths, users, s0, c, log_a2, hops)
            ident = 0  # permutations() lists the identity first
            # among the most probable pairings (equal within 1e-9: rounding does not pick), the one
            # that re-pairs the fewest users -- the HMM's pairing kept where it can be -- then the first
            if np.isfinite(logp.max()):
                top = np.flatnonzero(logp >= logp.max() - 1e-9)
                moved = [sum(int(i != j) for i, j in enumerate(perms[k])) for k in top]
                best = int(top[int(np.argmin(moved))])
            else:
                best = ident
            if not np.isfinite(logp[best]) or logp[best] <= logp[ident] + 1e-9:
                best = ident
            sigma = np.asarray(perms[best])
            decisions.append(_decision(passes, c, at, users, ins, outs, perms, logp, best))
            if best == ident:
                continue
            b = int(slot[best])
            paths[users, b:] = paths[users[sigma], b:].copy()
            switches.append((int(b - 1), int(at[0]), tuple(users.tolist()), tuple(users[sigma].tolist())))
            changed = True
        if not changed:
            break
    return CpdaResult(paths, switches, passes, decisions)


def pairing_probabilities(logp: np.ndarray) -> np.ndarray:
    """Posterior of each pairing of a meeting, ``P(sigma) ∝ exp(log P(sigma))`` (forbidden
    pairings, ``-inf``, get 0; uniform when every pairing is forbidden)."""
    logp = np.asarray(logp, float)
    top = logp.max() if logp.size else -np.inf
    if not np.isfinite(top):
        return np.full(logp.size, 1.0 / max(logp.size, 1))
    w = np.exp(logp - top)
    return w / w.sum()


def _decision(pass_no, c, at, users, ins, outs, perms, logp, best) -> dict:
    return {
        "pass": int(pass_no),
        "slot": int(c),
        "nodes": tuple(int(x) for x in at),
        "users": tuple(int(u) for u in users),
        "ins": tuple(int(x) for x in ins),
        "outs": tuple(int(x) for x in outs),
        "sigma": tuple(int(x) for x in perms[best]),
        "perms": perms,
        "prob": pairing_probabilities(logp),
    }


DECISIONS = pl.Schema(
    {
        "pass": pl.Int64,
        "slot": pl.Int64,
        "node": pl.String,
        "users": pl.String,
        "ins": pl.String,
        "outs": pl.String,
        "pairing": pl.String,
        "switched": pl.Boolean,
        "p_chosen": pl.Float64,
        "p_keep": pl.Float64,
        "alternatives": pl.String,
    }
)


def decisions_table(result: CpdaResult, nodes: tuple[str, ...]) -> pl.DataFrame:
    """One row per co-location event CPDA decided: the users there, their incoming and
    outgoing nodes (``-`` unknown), the pairing chosen (user ``users[i]`` continues on the
    tail of ``pairing[i]``), whether it switched, its posterior, the posterior of keeping the
    HMM's pairing, and every alternative as ``"pairing:probability"``."""
    name = lambda j: nodes[j] if j >= 0 else "-"  # noqa: E731
    rows = []
    for d in result.decisions:
        users = d["users"]
        alts = "; ".join(f"{' '.join(str(users[i]) for i in p)}:{pr:.3f}" for p, pr in zip(d["perms"], d["prob"]))
        ident = tuple(range(len(users)))
        p_of = dict(zip(d["perms"], d["prob"].tolist()))
        rows.append(
            (
                d["pass"],
                d["slot"],
                " ".join(name(j) for j in d["nodes"]),
                " ".join(map(str, users)),
                " ".join(name(j) for j in d["ins"]),
                " ".join(name(j) for j in d["outs"]),
                " ".join(str(users[i]) for i in d["sigma"]),
                d["sigma"] != ident,
                float(p_of.get(d["sigma"], 1.0)),
                float(p_of.get(ident, 1.0)),
                alts,
            )
        )
    return pl.DataFrame(rows, schema=DECISIONS, orient="row")


def switches_table(result: CpdaResult, nodes: tuple[str, ...], slot0: int = 0) -> pl.DataFrame:
    rows = [(slot0 + c, nodes[j], " ".join(map(str, u)), " ".join(map(str, s))) for c, j, u, s in result.switches]
    return pl.DataFrame(rows, schema=SWITCHES, orient="row")
