"""The compiled Algorithm 1 (base and variations A-E) against the plain Python passes it
replaces, on random crossing strings and random constraints: equal agents, initial
regions, teams, unexplained crossings and reasons."""

from __future__ import annotations

import numpy as np
import pytest

from onebit.trackers.beams.assignment import Constraints, assign_agents, assign_agents_reference


def _random_string(rng, p, m):
    """A random walk of a few agents over a random graph of ``p`` regions, with noise
    crossings from random regions (so some crossings cannot be explained)."""
    k = int(rng.integers(1, 5))
    pos = rng.integers(0, p, k)
    src, tgt = np.empty(m, np.int64), np.empty(m, np.int64)
    for j in range(m):
        a = int(rng.integers(0, k))
        s = int(pos[a]) if rng.random() < 0.9 else int(rng.integers(0, p))
        t = int(rng.integers(0, p - 1))
        t += t >= s
        src[j], tgt[j] = s, t
        pos[a] = t
    return src, tgt


def _same(a, b):
    np.testing.assert_array_equal(a.agents, b.agents)
    assert a.n_agents == b.n_agents
    np.testing.assert_array_equal(a.initial_region, b.initial_region)
    np.testing.assert_array_equal(a.unexplained, b.unexplained)
    assert a.reasons == b.reasons
    np.testing.assert_array_equal(a.team, b.team)


@pytest.mark.parametrize("seed", range(10))
@pytest.mark.parametrize("policy", ["fifo", "lifo"])
def test_base_kernel_equals_reference(seed, policy):
    rng = np.random.default_rng(seed)
    src, tgt = _random_string(rng, int(rng.integers(2, 9)), int(rng.integers(0, 400)))
    p = int(max(src.max(initial=0), tgt.max(initial=0)) + 1)
    _same(assign_agents(src, tgt, p, policy=policy, compiled=True), assign_agents_reference(src, tgt, p, policy=policy))


def _random_constraints(rng, p, m, base):
    n = base.n_agents
    known = rng.random() < 0.5 and n > 0
    teams = known and rng.random() < 0.6
    n_teams = int(rng.integers(1, 4))
    return Constraints(
        capacity=np.where(rng.random(p) < 0.5, rng.integers(0, 4, p), -1) if rng.random() < 0.6 else None,
        max_track_length=int(rng.choice([0, 0, 1, 2, 5, 40])),
        prefer_short=bool(rng.random() < 0.5),
        initial_region=base.initial_region if known else None,
        max_agents=0 if known else int(rng.choice([0, 1, 2, 5])),
        team=rng.integers(-1, n_teams, n) if teams else None,
        team_capacity=np.where(rng.random((p, n_teams)) < 0.5, rng.integers(0, 3, (p, n_teams)), -1)
        if teams and rng.random() < 0.7
        else None,
        team_rank=rng.permutation(n_teams) if teams and rng.random() < 0.7 else None,
        min_traversal=np.where(rng.random(p) < 0.5, rng.uniform(0, 3, p), 0.0) if rng.random() < 0.5 else None,
        region_names=tuple(f"room{i}" for i in range(p)),
    )


@pytest.mark.parametrize("seed", range(40))
def test_constrained_kernel_equals_reference(seed):
    rng = np.random.default_rng(1000 + seed)
    p = int(rng.integers(2, 8))
    m = int(rng.integers(0, 300))
    src, tgt = _random_string(rng, p, m)
    times = np.cumsum(rng.exponential(1.0, m))
    base = assign_agents(src, tgt, p)
    for _trial in range(4):
        cons = _random_constraints(rng, p, m, base)
        for policy in ("fifo", "lifo"):
            new = assign_agents(src, tgt, p, policy=policy, constraints=cons, times=times, compiled=True)
            ref = assign_agents_reference(src, tgt, p, policy=policy, constraints=cons, times=times)
            _same(new, ref)


def test_kernel_reasons_name_every_refusal():
    """Three agents in r0 refused for three different reasons: the message lists them in the
    order the scan met them, as the reference does."""
    src = np.array([1, 2, 1, 0, 0], np.int64)  # agents 0,1,2 walk into r0 ...
    tgt = np.array([0, 0, 0, 1, 2], np.int64)
    cons = Constraints(
        initial_region=np.array([1, 2, 1]),
        max_track_length=2,
        team=np.array([0, 1, 0]),
        team_capacity=np.array([[5, 5], [0, 5], [5, 5]]),
    )
    new = assign_agents(src, tgt, 3, constraints=cons, times=np.arange(5.0), compiled=True)
    ref = assign_agents_reference(src, tgt, 3, constraints=cons, times=np.arange(5.0))
    _same(new, ref)
    assert new.unexplained.size and "track length" in new.reasons[0]


# --------------------------------------------------------------------------- counting automaton


def _dropped_walks(edges, m, n, seed):
    rng = np.random.default_rng(seed)
    p = edges.n_regions
    out = [np.flatnonzero(edges.edge_source == r) for r in range(p)]
    pos = rng.integers(0, p, n)
    ids = np.empty(m, dtype=np.int64)
    for j in range(m):
        a = int(rng.integers(0, n))
        o = out[pos[a]]
        ids[j] = o[int(rng.integers(0, len(o)))]
        pos[a] = edges.edge_target[ids[j]]
    keep = rng.random(m) >= 0.08
    return edges.edge_source[ids][keep], edges.edge_target[ids][keep]


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("n", [1, 2, 4, 6])
def test_counting_dp_kernel_equals_reference(building, seed, n):
    from onebit.trackers.beams.counting import RegionEdges, correct, count_space_size, count_states

    _, rg = building
    edges = RegionEdges.from_region_graph(rg)
    src, tgt = _dropped_walks(edges, 300, n, 50 * n + seed)
    times = np.cumsum(np.random.default_rng(seed).exponential(1.0, len(src)))
    states = count_states(edges.n_regions, n)
    for kw in (dict(n_agents=n), dict(initial=states[seed % count_space_size(edges.n_regions, n)])):
        for placement, tt in (("midpoint", None), ("midpoint", times), ("earliest", None), ("latest", None)):
            try:
                ref = correct(src, tgt, edges, placement=placement, times=tt, compiled=False, **kw)
            except ValueError as exc:  # the known start cannot explain the string: both say so
                with pytest.raises(ValueError, match=str(exc).split(":")[0]):
                    correct(src, tgt, edges, placement=placement, times=tt, compiled=True, **kw)
                continue
            new = correct(src, tgt, edges, placement=placement, times=tt, compiled=True, **kw)
            assert (new.cost, new.peak_states, new.events) == (ref.cost, ref.peak_states, ref.events)
            for f in ("initial", "source", "target", "inserted", "observed_index", "edge"):
                np.testing.assert_array_equal(getattr(new, f), getattr(ref, f))
            if tt is not None:
                np.testing.assert_array_equal(new.time, ref.time)
