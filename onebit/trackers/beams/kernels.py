"""Compiled (numba) kernels of the beams tracker's sequential passes: Algorithm 1 (base and
with the section IV variations A-E) and the counting automaton's search helpers.

Algorithm 1 is inherently sequential -- the agent chosen for crossing ``j`` depends on every
queue operation before it -- so it is a compiled loop (``numba.njit(cache=True)``, :mod:`onebit.core.compiled`). The
region queues are doubly linked lists threaded through the agents (every agent is in
exactly one queue), so a pop from either end is O(1) and removing the agent line 5 picks
from the middle of ``Q_source`` (variations B, D, E) is O(1) after the O(|Q_source|) scan
for it. Each kernel keeps the plain Python implementation as its reference and test oracle
(``tests/trackers/beams/test_kernels.py``: equal agents, initial regions, teams,
unexplained crossings and reasons on random strings and constraints):

=============================  ===================================================================
kernel                         reference
=============================  ===================================================================
:func:`assign_base`            :func:`onebit.trackers.beams.assignment.assign_agents_reference`
:func:`assign_constrained`     :func:`onebit.trackers.beams.assignment.assign_constrained_reference`
=============================  ===================================================================

Reasons of unexplained crossings are returned as codes and counts (:data:`WHY`) and written
as text by the caller, in the reference's words.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from onebit.core.compiled import kernel

#: Why an agent of ``Q_source`` was not eligible, in the reference's words (the order of the
#: ``why`` columns returned by :func:`assign_constrained`).
WHY = ("track length", "in region < traversal time", "team bound of target")

#: Codes of unexplained crossings returned by :func:`assign_constrained`.
CAPACITY, NO_ELIGIBLE, LENGTH_ONE, ALL_KNOWN, NO_ROOM = 0, 1, 2, 3, 4


@kernel
def _push(r, a, head, tail, nxt, prv, size):
    """Append agent ``a`` at the tail of region ``r``'s queue."""
    nxt[a] = -1
    prv[a] = tail[r]
    if tail[r] >= 0:
        nxt[tail[r]] = a
    else:
        head[r] = a
    tail[r] = a
    size[r] += 1


@kernel
def _unlink(r, a, head, tail, nxt, prv, size):
    """Remove agent ``a`` from region ``r``'s queue."""
    if prv[a] >= 0:
        nxt[prv[a]] = nxt[a]
    else:
        head[r] = nxt[a]
    if nxt[a] >= 0:
        prv[nxt[a]] = prv[a]
    else:
        tail[r] = prv[a]
    size[r] -= 1


@kernel
def assign_base(src, tgt, n_regions, lifo):
    """Algorithm 1 without variations: ``(agents (m,), initial regions (n,))``."""
    m = src.shape[0]
    head = np.full(n_regions, -1, dtype=np.int64)
    tail = np.full(n_regions, -1, dtype=np.int64)
    size = np.zeros(n_regions, dtype=np.int64)
    nxt = np.empty(m, dtype=np.int64)
    prv = np.empty(m, dtype=np.int64)
    initial = np.empty(m, dtype=np.int64)
    out = np.empty(m, dtype=np.int64)
    n = 0
    for j in range(m):  # sequential: each choice depends on every queue operation before it
        s = src[j]
        if size[s] > 0:
            a = tail[s] if lifo else head[s]
            _unlink(s, a, head, tail, nxt, prv, size)
        else:
            a = n
            initial[n] = s
            n += 1
        out[j] = a
        _push(tgt[j], a, head, tail, nxt, prv, size)
    return out, initial[:n].copy()


@kernel
def _initial_agents(init, init_team, p, cap_agents, n_teams):
    """The queues of ``p`` regions holding the known initial agents (``init`` their regions,
    ``init_team`` their teams, -1 none) and room for ``cap_agents`` agents in all: ``(head,
    tail, size, nxt, prv, initial, visits, entered, team, team_count)``."""
    head = np.full(p, -1, dtype=np.int64)
    tail = np.full(p, -1, dtype=np.int64)
    size = np.zeros(p, dtype=np.int64)
    nxt = np.empty(cap_agents, dtype=np.int64)
    prv = np.empty(cap_agents, dtype=np.int64)
    initial = np.empty(cap_agents, dtype=np.int64)
    visits = np.empty(cap_agents, dtype=np.int64)
    entered = np.empty(cap_agents)
    team = np.empty(cap_agents, dtype=np.int64)
    team_count = np.zeros((p, max(n_teams, 1)), dtype=np.int64)
    for a in range(init.shape[0]):
        r = init[a]
        _push(r, a, head, tail, nxt, prv, size)
        initial[a] = r
        visits[a] = 1
        entered[a] = -np.inf
        team[a] = init_team[a]
        if init_team[a] >= 0 and n_teams > 0:
            team_count[r, init_team[a]] += 1
    return head, tail, size, nxt, prv, initial, visits, entered, team, team_count


class ScanRules(NamedTuple):
    """What makes an agent of ``Q_source`` eligible at line 5 (the variations), fixed for a
    string of crossings (:func:`assign_constrained`'s arguments of the same names)."""

    lifo: bool  #: scan from the queue's tail (LIFO), else from its head
    L: int  #: maximum track length (variation B), 0: none
    prefer_short: bool  #: the eligible agent with the fewest regions visited first (B)
    use_time: bool  #: minimum traversal times apply (E)
    times: np.ndarray  #: (m,) the crossings' times
    tau: np.ndarray  #: (p,) minimum traversal time per region
    has_team_cap: bool  #: team capacities apply (D)
    team_cap: np.ndarray  #: (p, teams) ``U_r``, -1: unbounded
    has_rank: bool  #: team ranks apply (D)
    rank: np.ndarray  #: (teams,) exit priority of each team, lower leaves first
    n_teams: int  #: number of teams (the key of an agent without one)


class AgentState(NamedTuple):
    """The agents as :func:`assign_constrained` changes them (in place), by agent index."""

    visits: np.ndarray  #: (agents,) crossings so far, the initial region counted
    entered: np.ndarray  #: (agents,) time the agent entered its region
    team: np.ndarray  #: (agents,) team, -1: none
    team_count: np.ndarray  #: (p, teams) agents of each team per region
    nxt: np.ndarray  #: (agents,) next agent in its region's queue, -1: none
    prv: np.ndarray  #: (agents,) previous agent in its region's queue, -1: none


@kernel
def _eligible_agent(a, j, s, t, rules, agents, cnt, order):
    """Line 5 of Algorithm 1 with the variations (``rules``, :class:`ScanRules`; ``agents``,
    :class:`AgentState`): the eligible agent of ``Q_source`` (``s``, scanned from agent ``a``
    in queue order) with the smallest key, or -1. ``cnt``/``order`` get the agents refused
    for each reason of :data:`WHY` and the order the reasons were met."""
    cnt[:] = 0
    order[:] = -1
    seen = 0
    best0, best1 = 0, 0
    found = False
    pick = -1
    while a >= 0:
        why_k = -1
        k = agents.team[a]
        if rules.L > 0 and agents.visits[a] >= rules.L:
            why_k = 0
        elif rules.use_time and rules.times[j] - agents.entered[a] < rules.tau[s]:
            why_k = 1
        elif (
            rules.has_team_cap
            and k >= 0
            and 0 <= rules.team_cap[t, k]
            and rules.team_cap[t, k] <= agents.team_count[t, k]
        ):
            why_k = 2
        if why_k >= 0:
            if cnt[why_k] == 0:
                order[why_k] = seen
                seen += 1
            cnt[why_k] += 1
        else:
            k0 = rules.rank[k] if (rules.has_rank and k >= 0) else rules.n_teams
            k1 = agents.visits[a] if rules.prefer_short else 0
            if not found or k0 < best0 or (k0 == best0 and k1 < best1):
                found = True
                best0, best1 = k0, k1
                pick = a
        a = agents.prv[a] if rules.lifo else agents.nxt[a]
    return pick


@kernel
def _unexplained(nu, j, q_size, L, can_create, cnt, order, un, code, why, why_order, q_len):
    """Row ``nu`` of the unexplained crossings: crossing ``j``, its code, the refusals and
    ``|Q_source| = q_size``."""
    un[nu] = j
    q_len[nu] = q_size
    if q_size > 0:
        code[nu] = NO_ELIGIBLE
        why[nu] = cnt
        why_order[nu] = order
    elif L == 1:
        code[nu] = LENGTH_ONE
    elif not can_create:
        code[nu] = ALL_KNOWN
    else:
        code[nu] = NO_ROOM


@kernel
def assign_constrained(
    src,
    tgt,
    n_regions,
    lifo,
    cap,
    tau,
    use_time,
    times,
    L,
    prefer_short,
    team_cap,
    has_team_cap,
    rank,
    has_rank,
    n_teams,
    init,
    init_team,
    known_initial,
    max_agents,
):
    """Algorithm 1 with the variations (see :mod:`onebit.trackers.beams.assignment`).

    Returns ``(agents (m,), initial (n,), team (n,), unexplained (k,), code (k,), why (k, 3),
    why_order (k, 3), q_len (k,))``: for each unexplained crossing its code, the number of
    agents of ``Q_source`` refused for each reason of :data:`WHY`, the order those reasons
    were first met in the scan (-1: not met) and ``|Q_source|``.
    """
    m = src.shape[0]
    n0 = init.shape[0]
    head, tail, size, nxt, prv, initial, visits, entered, team, team_count = _initial_agents(
        init, init_team, n_regions, n0 + m, n_teams
    )
    rules = ScanRules(lifo, L, prefer_short, use_time, times, tau, has_team_cap, team_cap, has_rank, rank, n_teams)
    agents = AgentState(visits, entered, team, team_count, nxt, prv)
    n = n0
    allow_new = not known_initial
    limit = n0 if known_initial else max_agents
    peak = size.copy()
    scan = L > 0 or prefer_short or use_time or has_team_cap or has_rank
    out = np.full(m, -1, dtype=np.int64)
    un = np.empty(m, dtype=np.int64)
    code = np.empty(m, dtype=np.int64)
    why = np.zeros((m, 3), dtype=np.int64)
    why_order = np.full((m, 3), -1, dtype=np.int64)
    q_len = np.zeros(m, dtype=np.int64)
    nu = 0
    cnt = np.zeros(3, dtype=np.int64)
    order = np.full(3, -1, dtype=np.int64)
    for j in range(m):  # sequential: each choice depends on every queue operation before it
        s, t = src[j], tgt[j]
        if cap[t] >= 0 and size[t] >= cap[t]:
            un[nu], code[nu] = j, CAPACITY
            nu += 1
            continue
        pick = -1
        if size[s] > 0 and not scan:
            pick = tail[s] if lifo else head[s]
        elif size[s] > 0:
            pick = _eligible_agent(tail[s] if lifo else head[s], j, s, t, rules, agents, cnt, order)
        if pick >= 0:
            _unlink(s, pick, head, tail, nxt, prv, size)
            agent = pick
        else:
            can_create = allow_new and (limit == 0 or n < limit) and L != 1
            room = cap[s] < 0 or peak[s] + 1 <= cap[s]
            if can_create and room:
                agent = n
                initial[n] = s
                visits[n] = 1
                entered[n] = -np.inf
                team[n] = -1
                n += 1
                peak[s] += 1
            else:
                _unexplained(nu, j, size[s], L, can_create, cnt, order, un, code, why, why_order, q_len)
                nu += 1
                continue
        k = team[agent]
        if k >= 0 and n_teams > 0:
            team_count[s, k] -= 1
            team_count[t, k] += 1
        out[j] = agent
        visits[agent] += 1
        entered[agent] = times[j]
        _push(t, agent, head, tail, nxt, prv, size)
        if size[t] > peak[t]:
            peak[t] = size[t]
    return (
        out,
        initial[:n].copy(),
        team[:n].copy(),
        un[:nu].copy(),
        code[:nu].copy(),
        why[:nu].copy(),
        why_order[:nu].copy(),
        q_len[:nu].copy(),
    )


# --------------------------------------------------------------------------- counting automaton


@kernel
def _merge_and_prune(E, cost, node, diam):
    """:func:`onebit.trackers.beams.counting._merge_and_prune`: the cheapest entry (then the
    lowest node) per count vector, states in the order of their count vectors' bytes (what
    numpy's sort of the ``void`` view gives: little-endian int32, compared byte by byte),
    then the dominated states dropped."""
    K, p = E.shape
    if K > 1:
        order = np.argsort(node, kind="mergesort")
        order = order[np.argsort(cost[order], kind="mergesort")]
        for q in range(p - 1, -1, -1):  # lexsort: the first component is the primary key
            col = np.empty(K, dtype=np.uint32)
            for r in range(K):
                v = np.uint32(E[order[r], q])
                col[r] = ((v & 0xFF) << 24) | (((v >> 8) & 0xFF) << 16) | (((v >> 16) & 0xFF) << 8) | (v >> 24)
            order = order[np.argsort(col, kind="mergesort")]
        keep = np.empty(K, dtype=np.int64)
        nk = 0
        for r in range(K):
            a = order[r]
            same = nk > 0
            if same:
                b = keep[nk - 1]
                for q in range(p):
                    if E[a, q] != E[b, q]:
                        same = False
                        break
            if not same:
                keep[nk] = a
                nk += 1
        keep = keep[:nk]
        E, cost, node = E[keep], cost[keep], node[keep]
    K = E.shape[0]
    if K > 1 and cost.max() > cost.min():
        alive = np.ones(K, dtype=np.bool_)
        for b in range(K):
            for a in range(K):
                l1 = 0
                for q in range(p):
                    l1 += abs(E[a, q] - E[b, q])
                if l1 > 0 and cost[a] + (l1 // 2) * diam <= cost[b]:
                    alive[b] = False
                    break
        E, cost, node = E[alive], cost[alive], node[alive]
    return E, cost, node


@kernel
def correction_dp(src, tgt, start, H, far, diam):
    """The dynamic programme of :func:`onebit.trackers.beams.counting.correct` over the live
    count states (see that module's docstring), crossing by crossing.

    Returns ``(best, parent, position, region, start_index, peak, events, error_pos)``: the
    node of the cheapest final state (lowest node on ties), every node's parent, insertion
    position and source region (``-1`` for start nodes), the start state the best path comes
    from, the peak number of live states, the number of deficit events, and ``error_pos``
    ``>= 0`` when crossing ``error_pos`` could not be explained (no state left).
    """
    m = src.shape[0]
    K0, p = start.shape
    E = start.astype(np.int32)
    cost = np.zeros(K0, dtype=np.int64)
    node = np.arange(K0, dtype=np.int64)
    cap = max(16, 4 * K0)
    parent = np.full(cap, -1, dtype=np.int64)
    position = np.full(cap, -1, dtype=np.int64)
    region = np.full(cap, -1, dtype=np.int64)
    n_nodes = K0
    E, cost, node = _merge_and_prune(E, cost, node, diam)
    peak, events = E.shape[0], 0
    for j in range(m):  # sequential in the string: each step works on the states the last left
        s, t = src[j], tgt[j]
        K = E.shape[0]
        n_def = 0
        for r in range(K):
            if E[r, s] < 1:
                n_def += 1
        if n_def == 0:
            for r in range(K):
                E[r, s] -= 1
                E[r, t] += 1
            continue
        # deficit: states that cannot consume y[j] move an agent from an occupied region r
        n_new = 0
        for r in range(K):
            if E[r, s] < 1:
                for q in range(p):
                    if E[r, q] >= 1 and H[q, s] < far:
                        n_new += 1
        newE = np.empty((K - n_def + n_new, p), dtype=np.int32)
        newcost = np.empty(K - n_def + n_new, dtype=np.int64)
        newnode = np.empty(K - n_def + n_new, dtype=np.int64)
        w = 0
        for r in range(K):
            if E[r, s] >= 1:
                newE[w] = E[r]
                newE[w, s] -= 1
                newE[w, t] += 1
                newcost[w] = cost[r]
                newnode[w] = node[r]
                w += 1
        while n_nodes + n_new > parent.shape[0]:
            grow = parent.shape[0]
            parent = np.concatenate((parent, np.full(grow, -1, dtype=np.int64)))
            position = np.concatenate((position, np.full(grow, -1, dtype=np.int64)))
            region = np.concatenate((region, np.full(grow, -1, dtype=np.int64)))
        for r in range(K):
            if E[r, s] < 1:
                for q in range(p):
                    if E[r, q] >= 1 and H[q, s] < far:
                        newE[w] = E[r]
                        newE[w, q] -= 1
                        newE[w, t] += 1
                        newcost[w] = cost[r] + H[q, s]
                        newnode[w] = n_nodes
                        parent[n_nodes] = node[r]
                        position[n_nodes] = j
                        region[n_nodes] = q
                        n_nodes += 1
                        w += 1
        if w == 0:
            return -1, parent, position, region, -1, peak, events, j
        E, cost, node = _merge_and_prune(newE, newcost, newnode, diam)
        peak = max(peak, E.shape[0])
        events += 1
    best = 0
    for r in range(1, E.shape[0]):
        if cost[r] < cost[best] or (cost[r] == cost[best] and node[r] < node[best]):
            best = r
    q = node[best]
    while parent[q] >= 0:
        q = parent[q]
    return node[best], parent[:n_nodes].copy(), position[:n_nodes].copy(), region[:n_nodes].copy(), q, peak, events, -1
