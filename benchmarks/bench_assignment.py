"""Algorithm 1 (agent assignment) speed, side by side with a plain Python peer.

For ``m`` in (10^4, 10^5, 10^6) crossings a valid crossing string on the building site's
region graph is generated (seeded): 3-5 agents start in random regions and, one random agent
at a time, each takes a random edge out of the region it is in (generation is not timed).

Timed:

* **ours**: :meth:`RegionGraph.endpoint_arrays` (beam, direction -> region indices) +
  :func:`onebit.trackers.beams.assignment.assign_agents`, FIFO and LIFO;
* **peer**: Algorithm 1 in plain Python over the label strings (``"a"``, ``"a^-1"``) with a
  dict lookup of each label's source and target region and Python lists as queues
  (``list.pop(0)`` for FIFO, ``list.pop()`` for LIFO);
* **min**: :func:`minimum_agents` (Proposition 3.1, vectorised prefix sums).

The agent sequences of ours and the peer must be identical, and ``minimum_agents`` must equal
the number of agents Algorithm 1 created (both asserted). Printed: seconds, crossings per
second, peer/ours speed-up and the growth of ours' time from the previous ``m`` (10 = linear).

**variations**: for ``m`` in (10^4, 10^5), Algorithm 1 with every section IV variation on
(A capacity, B track length + shortest-first queues, C known initial condition, D two teams with
per-team bounds and a team-preferring exit policy, E minimum traversal times) against the base
algorithm on the same string, as a ratio. The bounds are set so none binds (capacities = agents,
``L = m + 1``, ``tau`` below every gap, initial regions = the base run's), so both explain the
same crossings and the ratio is the pure cost of checking the constraints: line 5 becomes a scan of
``Q_source`` (O(n) per crossing instead of O(1)).

Run with ``python -m benchmarks.bench_assignment``.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from benchmarks.bench_reader import timed as _best_of
from onebit.core.region_graph import RegionGraph, build_region_graph
from onebit.datasets.builtin import builtin_site
from onebit.trackers.beams.assignment import Constraints, assign_agents, minimum_agents

SIZES = (10_000, 100_000, 1_000_000)
SEED = 0


def random_crossings(rg: RegionGraph, m: int, *, seed: int = SEED) -> tuple[np.ndarray, np.ndarray, list[str], int]:
    """Interleaved random walks of 3-5 agents: (beams, directions, labels, number of agents)."""
    rng = np.random.default_rng(seed)
    idx = rg.index
    out_edges: list[list[tuple[str, int, int]]] = [[] for _ in rg.names]
    for s, t, data in rg.graph.edges(data=True):
        out_edges[idx[s]].append((data["beam"], int(data["direction"]), idx[t]))
    k = int(rng.integers(3, 6))
    pos = rng.integers(0, len(rg.names), k).tolist()
    who = rng.integers(0, k, m).tolist()
    pick = rng.random(m).tolist()
    beams: list[str] = [""] * m
    dirs = [0] * m
    for j in range(m):
        a = who[j]
        edges = out_edges[pos[a]]
        beam, d, tgt = edges[int(pick[j] * len(edges))]
        beams[j], dirs[j] = beam, d
        pos[a] = tgt
    labels = [rg.label(b, d) for b, d in zip(beams, dirs)]
    # the pipeline hands the crossings' beam column over as a polars Series; so does the benchmark
    return pl.Series("beam", beams, dtype=pl.String), np.array(dirs, dtype=np.int8), labels, k


def peer_assign(labels: list[str], ends: dict[str, tuple[str, str]], policy: str) -> tuple[list[int], int]:
    """Algorithm 1, plain Python: list queues per region name, dict lookups per label."""
    queues: dict[str, list[int]] = {}
    agents: list[int] = []
    n = 0
    lifo = policy == "lifo"
    for label in labels:
        src, tgt = ends[label]
        q = queues.get(src)
        if q:
            agent = q.pop() if lifo else q.pop(0)
        else:
            agent = n
            n += 1
        agents.append(agent)
        queues.setdefault(tgt, []).append(agent)
    return agents, n


def main() -> None:
    rg = build_region_graph(builtin_site("building"))
    n_regions = len(rg.names)
    ends = {}
    for beam in rg.beam_source:
        for d in (1, -1):
            ends[rg.label(beam, d)] = rg.endpoints(beam, d)
    print(f"Algorithm 1 vs plain-Python peer, building region graph ({n_regions} regions, {len(ends)} labels)")
    print(
        f"{'m':>9} {'policy':>6} {'ours s':>8} {'(ends s)':>9} {'peer s':>8} {'peer/ours':>9} "
        f"{'ours cross/s':>13} {'peer cross/s':>13} {'growth':>7} {'min s':>7} {'agents':>6} {'walkers':>7}"
    )
    prev: dict[str, float] = {}
    for m in SIZES:
        beams, dirs, labels, k = random_crossings(rg, m)
        repeats = 3 if m < 1_000_000 else 2
        t_ends, (src, tgt) = _best_of(lambda: rg.endpoint_arrays(beams, dirs), repeats)
        t_min, n_min = _best_of(lambda: minimum_agents(src, tgt, n_regions), repeats)
        for policy in ("fifo", "lifo"):

            def ours():
                s, t = rg.endpoint_arrays(beams, dirs)
                return assign_agents(s, t, n_regions, policy=policy)

            t_ours, res = _best_of(ours, repeats)
            t_peer, (peer_agents, peer_n) = _best_of(lambda: peer_assign(labels, ends, policy), repeats)
            assert res.agents.tolist() == peer_agents, f"{policy}: agent sequences differ"
            assert res.n_agents == peer_n == n_min, (policy, res.n_agents, peer_n, n_min)
            growth = f"{t_ours / prev[policy]:.1f}" if policy in prev else "-"
            prev[policy] = t_ours
            print(
                f"{m:>9} {policy:>6} {t_ours:>8.3f} {t_ends:>9.3f} {t_peer:>8.3f} {t_peer / t_ours:>9.2f} "
                f"{m / t_ours:>13.3g} {m / t_peer:>13.3g} {growth:>7} {t_min:>7.3f} {res.n_agents:>6} {k:>7}"
            )
    variations(rg)
    print(
        "ours = endpoint_arrays + assign_agents (ends s: endpoint_arrays alone); peer/ours: speed-up of ours; "
        "growth: ours' time over the previous m (10 = linear).\n"
        "min s: minimum_agents; agents (Algorithm 1, FIFO and LIFO, and the peer) = minimum_agents (asserted); "
        "walkers: agents that generated the string (Algorithm 1 may need fewer)."
    )


def all_variations(src: np.ndarray, tgt: np.ndarray, n_regions: int, initial: np.ndarray) -> Constraints:
    """Every section IV variation on, with bounds that never bind (see the module docstring)."""
    n = len(initial)
    return Constraints(
        capacity=np.full(n_regions, n, np.int64),
        max_track_length=len(src) + 1,
        prefer_short=True,
        initial_region=initial,
        team=np.arange(n, dtype=np.int64) % 2,
        team_capacity=np.full((n_regions, 2), n, np.int64),
        team_rank=np.array([0, 1], np.int64),
        min_traversal=np.full(n_regions, 0.5),
    )


def variations(rg: RegionGraph) -> None:
    n_regions = len(rg.names)
    print("\nAlgorithm 1 with variations A-E all on vs the base algorithm (same string, FIFO)")
    print(f"{'m':>9} {'base s':>8} {'A-E s':>8} {'A-E/base':>8} {'growth':>7} {'agents':>6} {'unexpl.':>7}")
    prev = None
    for m in (10_000, 100_000):
        beams, dirs, _, _ = random_crossings(rg, m)
        src, tgt = rg.endpoint_arrays(beams, dirs)
        times = np.arange(m, dtype=np.float64)  # one crossing per second: every tau = 0.5 s is met
        t_base, base = _best_of(lambda: assign_agents(src, tgt, n_regions, policy="fifo"), 3)
        cons = all_variations(src, tgt, n_regions, base.initial_region)
        t_all, res = _best_of(
            lambda: assign_agents(src, tgt, n_regions, policy="fifo", constraints=cons, times=times), 3
        )
        assert len(res.unexplained) == 0 and res.n_agents == base.n_agents, "non-binding constraints must explain all"
        growth = f"{t_all / prev:.1f}" if prev else "-"
        prev = t_all
        print(
            f"{m:>9} {t_base:>8.3f} {t_all:>8.3f} {t_all / t_base:>8.2f} {growth:>7} {res.n_agents:>6} {len(res.unexplained):>7}"
        )
    print(
        "A-E/base: cost of the variations over the base algorithm; growth: A-E time over the previous m (10 = linear)."
    )


if __name__ == "__main__":
    main()
