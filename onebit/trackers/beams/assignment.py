"""Algorithm 1 (AgentsAssignment) of Bobadilla et al., with FIFO and LIFO region queues.

Each crossing ``y[j]`` is a directed edge ``source -> target`` of the region graph. Every
region ``r`` keeps a queue ``Q_r`` of the agents currently in it (all empty at the start)::

    for j in 1..|y|:
        agent <- Q_source.GetFirst()          # FIFO: longest waiting; LIFO: last arrived
        if agent is NIL: agent <- new agent  # numberOfAgents += 1
        A[j] <- agent;  Q_target.Insert(agent)

Time O(|y| + |R|), space O(|y| + |R|) here (queues hold agent ids, not copies of strings).

This algorithm is inherently sequential: the agent chosen for crossing ``j`` depends on every
queue operation before it, so it is one pass over the string with O(1) deque operations;
the inputs are converted to plain integer lists first so the loop does no numpy indexing.

Proposition 3.1: with either policy the number of agents is the minimum that explains ``y``,
``sum_r max(0, max_k (exits_r(k) - entries_r(k)))`` over prefixes ``k``
(:func:`minimum_agents`, computed vectorised).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

POLICIES = ("fifo", "lifo")


@dataclass(frozen=True)
class Assignment:
    """Output of Algorithm 1.

    agents : (m,) int64, ``A[j]`` = agent (0-based) of crossing ``j``.
    n_agents : number of agents created.
    initial_region : (n_agents,) int64, region each agent was in before its first crossing.
    """

    agents: np.ndarray
    n_agents: int
    initial_region: np.ndarray


def assign_agents(source: np.ndarray, target: np.ndarray, n_regions: int, *, policy: str = "fifo") -> Assignment:
    """Run Algorithm 1 on crossings given as region indices ``source[j] -> target[j]``.

    Parameters
    ----------
    source, target : (m,) integer arrays of region indices in ``[0, n_regions)``.
    n_regions : |R|.
    policy : ``"fifo"`` (agent waiting longest leaves first) or ``"lifo"`` (last in, first out).
    """
    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {POLICIES}, got {policy!r}")
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
    return Assignment(np.asarray(out, dtype=np.int64), len(initial), np.asarray(initial, dtype=np.int64))


def minimum_agents(source: np.ndarray, target: np.ndarray, n_regions: int) -> int:
    """Minimum number of agents that explains the crossings (Proposition 3.1), vectorised.

    Region ``r`` must initially hold at least ``max(0, max_k D_r(k))`` agents, where
    ``D_r(k)`` = exits from ``r`` minus entries into ``r`` among the first ``k`` crossings;
    these bounds are independent across regions and jointly achievable.
    """
    src = np.asarray(source, dtype=np.int64)
    tgt = np.asarray(target, dtype=np.int64)
    m = len(src)
    if m == 0:
        return 0
    delta = np.zeros((m, n_regions), dtype=np.int64)
    rows = np.arange(m)
    np.add.at(delta, (rows, src), 1)
    np.add.at(delta, (rows, tgt), -1)
    deficit = np.cumsum(delta, axis=0).max(axis=0)
    return int(np.maximum(deficit, 0).sum())


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
