"""Algorithm 1 (AgentsAssignment) of Bobadilla et al. with FIFO/LIFO queues and the
variations A-E of section IV.

Each crossing ``y[j]`` is a directed edge ``source -> target`` of the region graph. Every
region ``r`` keeps a queue ``Q_r`` of the agents currently in it (all empty at the start)::

    for j in 1..|y|:
        agent <- Q_source.GetFirst()          # FIFO: longest waiting; LIFO: last arrived
        if agent is NIL: agent <- new agent  # numberOfAgents += 1
        A[j] <- agent;  Q_target.Insert(agent)

Time O(|y| + |R|), space O(|y| + |R|) here (queues hold agent ids, not copies of strings).

This algorithm is inherently sequential: the agent chosen for crossing ``j`` depends on every
queue operation before it, so it is one compiled pass over the string
(:mod:`onebit.trackers.beams.kernels`, queues as linked lists, O(1) per operation); the
plain Python pass (:func:`assign_agents_reference`, deques) is its reference and test oracle.

Proposition 3.1: with either policy the number of agents is the minimum that explains ``y``,
``sum_r max(0, max_k (exits_r(k) - entries_r(k)))`` over prefixes ``k``
(:func:`minimum_agents`, computed vectorised).

Variations (section IV), given as :class:`Constraints`, combinable
------------------------------------------------------------------
A. **capacity** ``u_r``: ``|Q_r| <= u_r`` is checked before every insertion (lines 8, 12). A
   new agent created in ``r`` (line 10) has been in ``r`` since the start, so it raises every
   past occupancy of ``r`` by one: it is admitted only if ``peak_r + 1 <= u_r`` where
   ``peak_r = max_{t' <= t} |Q_r(t')|`` (kept in O(1) per crossing).
B. **track length**: agent ``a`` keeps ``c_a`` = regions visited (its initial region counts 1);
   an agent with ``c_a >= L`` may not leave (line 5), since the move would make ``c_a = L + 1``.
   Option ``prefer_short``: among the eligible agents the one with the smallest ``c_a`` leaves.
C. **initial condition**: ``n`` and each agent's initial region fill the queues before the
   pass; no agent is ever created (``n`` is known). ``max_agents`` caps creation when only
   ``n`` is known.
D. **teams** ``l: A -> T``, ``|T| = m``: each region has an m-tuple of bounds
   ``U_r = [u_r^1..u_r^m]``; an agent of team ``k`` is eligible for ``y[j]`` only if
   ``|Q_target^k| < u_target^k`` (checked before the insertion, line 8). With
   ``team_rank`` the exit policy (line 5) prefers the eligible agent of the best-ranked team.
E. **time stamps**: region ``r`` has a minimum traversal time ``tau_r``; an agent that entered
   ``r`` at ``t_in`` is eligible to leave at ``t`` only if ``t - t_in >= tau_r`` (agents there
   from the start have ``t_in = -inf``).

Line 5 then picks, among the *eligible* agents of ``Q_source``, the minimum of the key
``(team rank, c_a if prefer_short, queue order)`` with queue order = arrival order (FIFO) or
reversed arrival order (LIFO). When no agent is eligible:

* a new agent is created in ``source`` (line 10) if creation is allowed (``n`` unknown or
  fewer than ``max_agents`` agents so far) and region ``source`` has room for it (A);
* otherwise the crossing is **unexplainable**: it is reported (index and reason), assigned to
  no agent (``A[j] = -1``) and leaves every queue unchanged.

A crossing into a full region (A) is unexplainable whatever the agent. Complexity: O(1) per
crossing for the base algorithm and for A and C; B (track length), D and E scan ``Q_source``
for an eligible agent, O(|Q_source|) <= O(n) per crossing, so O(|y| n + |R|) in all.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from onebit.trackers.beams import kernels

POLICIES = ("fifo", "lifo")

#: Crossings from which :func:`assign_agents` runs the compiled pass by default (base,
#: with variations): below them the Python pass takes less than numba's start in a fresh
#: process (0.3-1 s, once per process).
COMPILED_MIN = {False: 200_000, True: 5_000}


@dataclass(frozen=True)
class Assignment:
    """Output of Algorithm 1.

    agents : (m,) int64, ``A[j]`` = agent (0-based) of crossing ``j``; -1 = unexplainable.
    n_agents : number of agents (created or given by the initial condition).
    initial_region : (n_agents,) int64, region each agent was in before its first crossing.
    unexplained : (k,) int64 indices of the unexplainable crossings, in order.
    reasons : why each unexplained crossing could not be explained (same order).
    team : (n_agents,) int64 team index of each agent, -1 = unknown.
    """

    agents: np.ndarray
    n_agents: int
    initial_region: np.ndarray
    unexplained: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    reasons: tuple[str, ...] = ()
    team: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))


@dataclass(frozen=True, kw_only=True)
class Constraints:
    """Section IV variations in index form (see the module docstring); every field optional.

    capacity : (p,) int64 ``u_r`` (A); -1 = unbounded.
    max_track_length : ``L`` (B), regions an agent may visit including its initial one; 0 = none.
    prefer_short : (B) the eligible agent with the fewest regions visited leaves first.
    initial_region : (n,) int64 initial region of each agent (C); ``None`` = unknown.
    max_agents : most agents that may exist when ``initial_region`` is ``None``; 0 = unbounded.
    team : (n,) int64 team of each initial agent (D); needs ``initial_region``.
    team_capacity : (p, m) int64 ``U_r`` (D); -1 = unbounded.
    team_rank : (m,) int64 exit priority of each team (D), lower leaves first; ``None`` = none.
    min_traversal : (p,) float64 ``tau_r`` in seconds (E); needs crossing times.
    region_names : names used in the reasons (default ``r<index>``).
    """

    capacity: np.ndarray | None = None
    max_track_length: int = 0
    prefer_short: bool = False
    initial_region: np.ndarray | None = None
    max_agents: int = 0
    team: np.ndarray | None = None
    team_capacity: np.ndarray | None = None
    team_rank: np.ndarray | None = None
    min_traversal: np.ndarray | None = None
    region_names: tuple[str, ...] | None = None

    @property
    def trivial(self) -> bool:
        """True when nothing differs from the base algorithm."""
        return (
            (self.capacity is None or bool(np.all(np.asarray(self.capacity) < 0)))
            and self.max_track_length == 0
            and not self.prefer_short
            and self.initial_region is None
            and self.max_agents == 0
            and self.team is None
            and self.team_capacity is None
            and self.team_rank is None
            and (self.min_traversal is None or not bool(np.any(np.asarray(self.min_traversal) > 0)))
        )


def assign_agents(
    source: np.ndarray,
    target: np.ndarray,
    n_regions: int,
    *,
    policy: str = "fifo",
    constraints: Constraints | None = None,
    times: np.ndarray | None = None,
    compiled: bool | None = None,
) -> Assignment:
    """Run Algorithm 1 on crossings given as region indices ``source[j] -> target[j]``.

    Parameters
    ----------
    source, target : (m,) integer arrays of region indices in ``[0, n_regions)``.
    n_regions : |R|.
    policy : ``"fifo"`` (agent waiting longest leaves first) or ``"lifo"`` (last in, first out).
    constraints : the section IV variations; ``None`` runs the base algorithm.
    times : (m,) crossing times in seconds, needed by ``constraints.min_traversal`` (E).
    compiled : run the compiled pass (:mod:`onebit.trackers.beams.kernels`); ``None`` = from
        :data:`COMPILED_MIN` crossings on (below it the Python pass, :func:`assign_agents_reference`,
        is as fast as starting numba in a fresh process). Same result either way.

    Examples
    --------
    >>> assign_agents([1, 1, 2], [2, 2, 3], 4).agents.tolist()
    [0, 1, 0]
    >>> assign_agents([1, 1, 2], [2, 2, 3], 4, policy="lifo").agents.tolist()
    [0, 1, 1]
    """
    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {POLICIES}, got {policy!r}")
    constrained = constraints is not None and not constraints.trivial
    if compiled is None:
        compiled = len(source) >= COMPILED_MIN[constrained]
    if not compiled:
        return assign_agents_reference(source, target, n_regions, policy=policy, constraints=constraints, times=times)
    if constrained:
        return _assign_constrained(source, target, n_regions, policy, constraints, times)
    src = np.ascontiguousarray(source, dtype=np.int64)
    tgt = np.ascontiguousarray(target, dtype=np.int64)
    out, initial = kernels.assign_base(src, tgt, int(n_regions), policy == "lifo")
    n = len(initial)
    return Assignment(out, n, initial, team=np.full(n, -1, np.int64))


def assign_agents_reference(
    source: np.ndarray,
    target: np.ndarray,
    n_regions: int,
    *,
    policy: str = "fifo",
    constraints: Constraints | None = None,
    times: np.ndarray | None = None,
) -> Assignment:
    """:func:`assign_agents` as a plain Python pass (deques / lists as region queues): the
    reference of the compiled kernels and their test oracle (same arguments, same result)."""
    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {POLICIES}, got {policy!r}")
    if constraints is not None and not constraints.trivial:
        return assign_constrained_reference(source, target, n_regions, policy, constraints, times)
    src = np.asarray(source, dtype=np.int64).tolist()
    tgt = np.asarray(target, dtype=np.int64).tolist()
    queues = [deque() for _ in range(n_regions)]
    out = [0] * len(src)
    initial: list[int] = []
    lifo = policy == "lifo"
    for j, (s, t) in enumerate(zip(src, tgt)):
        q = queues[s]
        if q:
            agent = q.pop() if lifo else q.popleft()
        else:
            agent = len(initial)
            initial.append(s)
        out[j] = agent
        queues[t].append(agent)
    n = len(initial)
    return Assignment(
        np.asarray(out, dtype=np.int64), n, np.asarray(initial, dtype=np.int64), team=np.full(n, -1, np.int64)
    )


def _assign_constrained(source, target, n_regions: int, policy: str, c: Constraints, times) -> Assignment:
    """Algorithm 1 with the variations of :class:`Constraints` (see the module docstring):
    the compiled :func:`onebit.trackers.beams.kernels.assign_constrained`, then the reasons
    of the unexplained crossings written in words. Same result as
    :func:`assign_constrained_reference`.
    """
    src = np.ascontiguousarray(source, dtype=np.int64)
    tgt = np.ascontiguousarray(target, dtype=np.int64)
    m = len(src)
    p = int(n_regions)
    names = list(c.region_names) if c.region_names is not None else [f"r{i}" for i in range(p)]
    cap = np.asarray(c.capacity, np.int64) if c.capacity is not None else np.full(p, -1, np.int64)
    tau = np.asarray(c.min_traversal, np.float64) if c.min_traversal is not None else np.zeros(p)
    use_time = bool(np.any(tau > 0))
    if use_time:
        if times is None or len(times) != m:
            raise ValueError("min_traversal (variation E) needs one time stamp per crossing")
        tt = np.ascontiguousarray(times, dtype=np.float64)
    else:
        tt = np.zeros(m)
    team_cap = (
        np.asarray(c.team_capacity, np.int64).reshape(p, -1)
        if c.team_capacity is not None
        else np.zeros((p, 0), np.int64)
    )
    rank = np.asarray(c.team_rank, np.int64) if c.team_rank is not None else np.zeros(0, np.int64)
    n_teams = team_cap.shape[1] if c.team_capacity is not None else (len(rank) if c.team_rank is not None else 0)
    if c.initial_region is not None:
        init = np.asarray(c.initial_region, np.int64)
        tm = np.asarray(c.team, np.int64) if c.team is not None else np.full(len(init), -1, np.int64)
        if len(tm) != len(init):
            raise ValueError(f"team has {len(tm)} entries but initial_region has {len(init)}")
    else:
        init, tm = np.zeros(0, np.int64), np.zeros(0, np.int64)
    max_agents = len(init) if c.initial_region is not None else int(c.max_agents)
    out, initial, team, un, code, why, why_order, q_len = kernels.assign_constrained(
        src,
        tgt,
        p,
        policy == "lifo",
        np.ascontiguousarray(cap),
        np.ascontiguousarray(tau),
        use_time,
        tt,
        int(c.max_track_length),
        bool(c.prefer_short),
        np.ascontiguousarray(team_cap),
        c.team_capacity is not None,
        np.ascontiguousarray(rank),
        c.team_rank is not None,
        int(n_teams),
        np.ascontiguousarray(init),
        np.ascontiguousarray(tm),
        c.initial_region is not None,
        int(max_agents),
    )
    reasons = []
    for j, k, w, wo, ql in zip(un.tolist(), code.tolist(), why.tolist(), why_order.tolist(), q_len.tolist()):
        s, t = int(src[j]), int(tgt[j])
        if k == kernels.CAPACITY:
            reasons.append(f"capacity of {names[t]} ({cap[t]}) reached")
        elif k == kernels.NO_ELIGIBLE:
            met = sorted((o, r) for r, o in enumerate(wo) if o >= 0)
            detail = ", ".join(f"{w[r]} {kernels.WHY[r]}" for _, r in met)
            reasons.append(f"no eligible agent among the {ql} in {names[s]} ({detail})")
        elif k == kernels.LENGTH_ONE:
            reasons.append(f"no agent in {names[s]}; a new one would exceed max_track_length 1")
        elif k == kernels.ALL_KNOWN:
            reasons.append(f"no agent in {names[s]} and all {max_agents} agents are known")
        else:
            reasons.append(f"no agent in {names[s]} and no room for a new one (capacity {cap[s]})")
    return Assignment(out, len(initial), initial, un, tuple(reasons), team)


def assign_constrained_reference(source, target, n_regions: int, policy: str, c: Constraints, times) -> Assignment:
    """Algorithm 1 with the variations of :class:`Constraints` (see the module docstring) as
    a plain Python pass: the reference of the compiled kernel and its test oracle.

    Inherently sequential, one pass (:class:`AssignmentState` over the whole string); Line 5
    scans ``Q_source`` when B, D or E is active.
    """
    state = AssignmentState(n_regions, policy, c)
    state.feed(source, target, times)
    return state.assignment()


class AssignmentState:
    """Algorithm 1 (with the variations of :class:`Constraints`) as a resumable pass: the
    queues ``Q_r`` and every agent's counters are kept between calls of :meth:`feed`, so a
    string fed in pieces gets, crossing by crossing, the agents one pass over the whole string
    gives (the crossing-by-crossing algorithm of the paper; ``onebit follow`` feeds each
    crossing once it is final). ``c = None``: the base algorithm."""

    def __init__(self, n_regions: int, policy: str, c: Constraints | None = None):
        if policy not in POLICIES:
            raise ValueError(f"policy must be one of {POLICIES}, got {policy!r}")
        c = c if c is not None else Constraints()
        p = self.p = int(n_regions)
        self.names = list(c.region_names) if c.region_names is not None else [f"r{i}" for i in range(p)]
        self.cap = np.asarray(c.capacity, np.int64).tolist() if c.capacity is not None else [-1] * p
        self.tau = np.asarray(c.min_traversal, np.float64).tolist() if c.min_traversal is not None else [0.0] * p
        self.use_time = any(x > 0 for x in self.tau)
        self.L = int(c.max_track_length)
        self.prefer_short = c.prefer_short
        self.team_cap = np.asarray(c.team_capacity, np.int64).tolist() if c.team_capacity is not None else None
        self.rank = np.asarray(c.team_rank, np.int64).tolist() if c.team_rank is not None else None
        tc, rk = self.team_cap, self.rank
        self.n_teams = len(tc[0]) if tc else (len(rk) if rk else 0)
        self.scan = self.L > 0 or c.prefer_short or self.use_time or tc is not None or rk is not None
        self.lifo = policy == "lifo"
        self.queues: list[list[int]] = [[] for _ in range(p)]
        self.team_count = [[0] * self.n_teams for _ in range(p)]
        self.initial: list[int] = []
        self.visits: list[int] = []
        self.entered: list[float] = []
        self.team: list[int] = []
        if c.initial_region is not None:
            init = np.asarray(c.initial_region, np.int64).tolist()
            tm = np.asarray(c.team, np.int64).tolist() if c.team is not None else [-1] * len(init)
            if len(tm) != len(init):
                raise ValueError(f"team has {len(tm)} entries but initial_region has {len(init)}")
            for a, (r, k) in enumerate(zip(init, tm)):
                self.queues[r].append(a)
                self.initial.append(r)
                self.visits.append(1)
                self.entered.append(float("-inf"))
                self.team.append(k)
                if k >= 0 and self.n_teams:
                    self.team_count[r][k] += 1
            self.allow_new = False
        else:
            self.allow_new = True
        self.max_agents = len(self.initial) if c.initial_region is not None else int(c.max_agents)
        self.peak = [len(q) for q in self.queues]
        self.agents: list[int] = []  # A[j] of every crossing fed
        self.unexplained: list[int] = []
        self.reasons: list[str] = []

    def _eligible(self, q: list, s: int, t: int, tj: float) -> tuple[int, dict[str, int]]:
        """``(position, refusals)``: the eligible agent of ``Q_source`` (``q``, of region ``s``;
        the crossing goes to ``t`` at ``tj``) with the smallest key (-1: none), and how many
        agents each reason refused."""
        L, visits, entered, team, tau = self.L, self.visits, self.entered, self.team, self.tau
        team_cap, team_count, rank, n_teams = self.team_cap, self.team_count, self.rank, self.n_teams
        best, pos = None, -1
        why: dict[str, int] = {}
        order = range(len(q) - 1, -1, -1) if self.lifo else range(len(q))
        for i in order:
            a = q[i]
            if L and visits[a] >= L:
                why["track length"] = why.get("track length", 0) + 1
                continue
            if self.use_time and tj - entered[a] < tau[s]:
                why["in region < traversal time"] = why.get("in region < traversal time", 0) + 1
                continue
            k = team[a]
            if team_cap is not None and k >= 0 and 0 <= team_cap[t][k] <= team_count[t][k]:
                why["team bound of target"] = why.get("team bound of target", 0) + 1
                continue
            key = (rank[k] if (rank is not None and k >= 0) else n_teams, visits[a] if self.prefer_short else 0)
            if best is None or key < best:
                best, pos = key, i
        return pos, why

    def _reason(self, q: list, s: int, can_create: bool, why: dict[str, int]) -> str:
        """Why a crossing out of region ``s`` (its queue ``q``) has no agent."""
        names = self.names
        if q:
            detail = ", ".join(f"{v} {k}" for k, v in why.items())
            return f"no eligible agent among the {len(q)} in {names[s]} ({detail})"
        if self.L == 1:
            return f"no agent in {names[s]}; a new one would exceed max_track_length 1"
        if not can_create:
            return f"no agent in {names[s]} and all {self.max_agents} agents are known"
        return f"no agent in {names[s]} and no room for a new one (capacity {self.cap[s]})"

    def feed(self, source, target, times=None) -> np.ndarray:
        """Assign the next crossings ``source[j] -> target[j]`` (``times`` for variation E);
        returns their agents (-1 = unexplainable)."""
        src = np.asarray(source, dtype=np.int64).tolist()
        tgt = np.asarray(target, dtype=np.int64).tolist()
        m = len(src)
        if self.use_time:
            if times is None or len(times) != m:
                raise ValueError("min_traversal (variation E) needs one time stamp per crossing")
            tt = np.asarray(times, np.float64).tolist()
        else:
            tt = [0.0] * m
        queues, team_count, visits, entered, team, peak = (
            self.queues,
            self.team_count,
            self.visits,
            self.entered,
            self.team,
            self.peak,
        )
        cap, L, names, n_teams = self.cap, self.L, self.names, self.n_teams
        out = [-1] * m
        base = len(self.agents)
        for j in range(m):
            s, t = src[j], tgt[j]
            q = queues[s]
            if cap[t] >= 0 and len(queues[t]) >= cap[t]:
                self.unexplained.append(base + j)
                self.reasons.append(f"capacity of {names[t]} ({cap[t]}) reached")
                continue
            pos, why = -1, {}
            if q and not self.scan:
                pos = len(q) - 1 if self.lifo else 0
            elif q:
                pos, why = self._eligible(q, s, t, tt[j])
            if pos >= 0:
                agent = q.pop(pos)
            else:
                initial = self.initial
                can_create = self.allow_new and (self.max_agents == 0 or len(initial) < self.max_agents) and L != 1
                room = cap[s] < 0 or peak[s] + 1 <= cap[s]
                if can_create and room:
                    agent = len(initial)
                    initial.append(s)
                    visits.append(1)
                    entered.append(float("-inf"))
                    team.append(-1)
                    peak[s] += 1
                else:
                    self.unexplained.append(base + j)
                    self.reasons.append(self._reason(q, s, can_create, why))
                    continue
            k = team[agent]
            if k >= 0 and n_teams:
                team_count[s][k] -= 1
                team_count[t][k] += 1
            out[j] = agent
            visits[agent] += 1
            entered[agent] = tt[j]
            queues[t].append(agent)
            if len(queues[t]) > peak[t]:
                peak[t] = len(queues[t])
        self.agents += out
        return np.asarray(out, dtype=np.int64)

    @property
    def n_agents(self) -> int:
        return len(self.initial)

    def assignment(self) -> Assignment:
        """The :class:`Assignment` of every crossing fed so far."""
        return Assignment(
            np.asarray(self.agents, dtype=np.int64),
            len(self.initial),
            np.asarray(self.initial, dtype=np.int64),
            np.asarray(self.unexplained, dtype=np.int64),
            tuple(self.reasons),
            np.asarray(self.team, dtype=np.int64),
        )


def ambiguous_crossings(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Crossings whose agent differs between two assignments, up to agent relabelling.

    The agents of ``second`` are relabelled to those of ``first`` by the matching that
    maximises the number of crossings they share (``scipy.optimize.linear_sum_assignment`` on
    the contingency table); a crossing is ambiguous when its relabelled agent differs from its
    agent in ``first`` (-1 = unexplained counts as an agent of its own). Vectorised, (m,) bool.

    Examples
    --------
    >>> ambiguous_crossings(np.array([0, 1, 0]), np.array([1, 0, 1])).tolist()
    [False, False, False]
    >>> ambiguous_crossings(np.array([0, 1, 0]), np.array([0, 1, 1])).tolist()
    [False, False, True]
    """
    from scipy.optimize import linear_sum_assignment

    a = np.asarray(first, np.int64) + 1
    b = np.asarray(second, np.int64) + 1
    if len(a) == 0:
        return np.zeros(0, dtype=bool)
    table = np.zeros((a.max() + 1, b.max() + 1), dtype=np.int64)
    np.add.at(table, (a, b), 1)
    # unexplained (index 0) only maps to unexplained
    big = len(a) + 1
    table[0, 1:] -= big
    table[1:, 0] -= big
    r, c = linear_sum_assignment(table, maximize=True)
    relabel = np.full(b.max() + 1, -2, dtype=np.int64)
    relabel[c] = r
    return relabel[b] != a


def region_events(source: np.ndarray, target: np.ndarray, n_regions: int):
    """The crossings as per-region events, grouped by region: ``(region, j, running)``.

    Crossing ``j`` is an entry into ``target[j]`` and an exit from ``source[j]``; the ``2m``
    events are ordered by region, then by ``j`` with the entry first (one stable radix sort of
    the region index), and ``running`` is ``D_r`` after each event: exits minus entries of
    region ``r`` so far. O(m) memory, where a dense ``(m, |R|)`` table of prefix sums would be
    O(m |R|). Returns ``(region, j, running, starts, counts)`` with ``starts``/``counts`` the
    slice of every region.
    """
    src = np.asarray(source, dtype=np.int64)
    tgt = np.asarray(target, dtype=np.int64)
    m = len(src)
    reg = np.empty(2 * m, dtype=np.int64)
    reg[0::2], reg[1::2] = tgt, src
    delta = np.empty(2 * m, dtype=np.int64)
    delta[0::2], delta[1::2] = -1, 1
    key = reg.astype(np.uint16) if n_regions <= np.iinfo(np.uint16).max else reg
    order = np.argsort(key, kind="stable")
    reg, delta = reg[order], delta[order]
    counts = np.bincount(reg, minlength=n_regions)
    starts = np.cumsum(counts) - counts
    cs = np.cumsum(delta)
    base = np.where(starts > 0, cs[np.maximum(starts - 1, 0)], 0)  # cumsum before each region's slice
    running = cs - np.repeat(base, counts)
    return reg, order // 2, running, starts, counts


def region_deficits(source: np.ndarray, target: np.ndarray, n_regions: int) -> np.ndarray:
    """``(|R|,)`` int64: ``max(0, max_k D_r(k))``, the fewest agents region ``r`` must start with.

    ``D_r(k)`` = exits from ``r`` minus entries into ``r`` among the first ``k`` crossings
    (Proposition 3.1). Vectorised over the per-region events of :func:`region_events`.
    """
    out = np.zeros(n_regions, dtype=np.int64)
    if len(source) == 0:
        return out
    _, _, running, starts, counts = region_events(source, target, n_regions)
    nz = counts > 0
    out[nz] = np.maximum(0, np.maximum.reduceat(running, starts[nz]))
    return out


def minimum_agents(source: np.ndarray, target: np.ndarray, n_regions: int) -> int:
    """Minimum number of agents that explains the crossings (Proposition 3.1), vectorised.

    Region ``r`` must initially hold at least ``max(0, max_k D_r(k))`` agents, where
    ``D_r(k)`` = exits from ``r`` minus entries into ``r`` among the first ``k`` crossings;
    these bounds are independent across regions and jointly achievable
    (:func:`region_deficits`, O(m) memory).
    """
    return int(region_deficits(source, target, n_regions).sum())


def is_consistent_partition(source, target, groups: list[list[int]]) -> bool:
    """True when every group of crossing indices (in time order) is a walk in the region graph.

    A group is one agent's string ``y_i``: consecutive crossings must chain, ``target`` of one
    equal to ``source`` of the next. The groups must partition ``range(m)``.
    """
    src = np.asarray(source)
    tgt = np.asarray(target)
    flat = sorted(i for g in groups for i in g)
    if flat != list(range(len(src))):
        return False
    for g in groups:
        g = sorted(g)
        if len(g) > 1 and np.any(tgt[g[:-1]] != src[g[1:]]):
            return False
    return True
