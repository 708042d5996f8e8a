"""Section IV variations A-E of the beams tracker, unexplained crossings and FIFO/LIFO ambiguity."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import ConfigError
from onebit.trackers.beams import BeamsConfig, run
from onebit.trackers.beams.assignment import Constraints, ambiguous_crossings, assign_agents

# building (Fig. 1/2): a: r2->r1, b, c: r2->r3, d: r3->r4, e: r3->r5, f: r5->r4, g: r4->r6


def _crossings(word: str, times: list[float] | None = None) -> pl.DataFrame:
    toks = word.split()
    return pl.DataFrame(
        {
            "t": [float(i) for i in range(len(toks))] if times is None else [float(x) for x in times],
            "beam": [tok[0] for tok in toks],
            "direction": pl.Series([-1 if tok.endswith("^-1") else 1 for tok in toks], dtype=pl.Int8),
        }
    )


def _run(building, word, times=None, **cfg):
    site, rg = building
    return run({"crossings": _crossings(word, times), "region_graph": rg}, site, BeamsConfig(**cfg))


def _tracks(out) -> list:
    return out["assignment"]["track"].to_list()


# ----------------------------------------------------------------- A: capacity


def test_capacity_refuses_the_extra_agent(building):
    base = _run(building, "b c d")
    assert base["agents"].height == 2 and base["unexplained"].height == 0
    cap = _run(building, "b c d", capacity={"r3": 1})
    assert _tracks(cap) == ["agent1", None, "agent1"]
    assert cap["agents"].height == 1
    un = cap["unexplained"].row(0, named=True)
    assert un["crossing"] == 1 and un["beam"] == "c" and un["region"] == "r3"
    assert "capacity of r3 (1)" in un["reason"]
    # the occupancy never exceeds the bound
    assert cap["occupancy"].filter(pl.col("region") == "r3")["count"].max() == 1


def test_capacity_of_the_source_bounds_new_agents(building):
    # a new agent created in r2 has been there since the start: r2 (capacity 1) cannot hold two
    out = _run(building, "b c", capacity={"r2": 1})
    assert _tracks(out) == ["agent1", None]
    assert "no room for a new one" in out["unexplained"]["reason"][0]


def test_site_capacity_is_used_and_config_overrides_it(building):
    from dataclasses import replace

    site, rg = building
    regions = tuple(replace(r, capacity=1) if r.name == "r3" else r for r in site.regions)
    site1 = replace(site, regions=regions)
    out = run({"crossings": _crossings("b c d"), "region_graph": rg}, site1, BeamsConfig())
    assert out["unexplained"].height == 1
    out = run({"crossings": _crossings("b c d"), "region_graph": rg}, site1, BeamsConfig(capacity={"r3": 2}))
    assert out["unexplained"].height == 0


# ----------------------------------------------------------------- B: track length


def test_max_track_length_forces_a_new_agent_or_is_unexplained(building):
    # agent1 visits r2, r3 (2 regions); with L = 2 it may not go on to r4
    assert _tracks(_run(building, "b d")) == ["agent1", "agent1"]
    out = _run(building, "b d", max_track_length=2)
    assert _tracks(out) == ["agent1", "agent2"]
    assert out["agents"]["initial_region"].to_list() == ["r2", "r3"]
    known = _run(building, "b d", max_track_length=2, initial_regions=["r2"])
    assert _tracks(known) == ["agent1", None]
    assert "1 track length" in known["unexplained"]["reason"][0]


def test_prefer_short_tracks_orders_the_queue(building):
    # r3 holds agent1 (initial, 1 region) and agent2 (came by b, 2 regions); LIFO takes agent2
    lifo = _run(building, "b d", policy="lifo", initial_regions=["r3", "r2"])
    assert _tracks(lifo) == ["agent2", "agent2"]
    short = _run(building, "b d", policy="lifo", initial_regions=["r3", "r2"], prefer_short_tracks=True)
    assert _tracks(short) == ["agent2", "agent1"]


# ----------------------------------------------------------------- C: known initial condition


def test_known_initial_condition_fills_queues_and_never_creates_agents(building):
    out = _run(building, "d e^-1", initial_regions=["r3", "r6"])
    assert out["agents"].height == 2
    assert out["agents"]["initial_region"].to_list() == ["r3", "r6"]
    assert _tracks(out) == ["agent1", None]
    assert "all 2 agents are known" in out["unexplained"]["reason"][0]
    # the agent that never moved still has a track row in its initial region
    assert out["tracks"].filter(pl.col("track") == "agent2")["region"].to_list() == ["r6"]
    # base algorithm explains e^-1 with a new agent instead
    assert _run(building, "d e^-1")["agents"].height == 2


# ----------------------------------------------------------------- D: teams


def test_team_policy_picks_the_preferred_team(building):
    cfg = dict(initial_regions=["r3", "r3"], teams=["human", "robot"], team_names=["robot", "human"])
    assert _tracks(_run(building, "d", **cfg)) == ["agent1"]  # FIFO: the human waited longest
    robots_first = _run(building, "d", prefer_team_order=True, **cfg)
    assert _tracks(robots_first) == ["agent2"]
    assert robots_first["agents"]["team"].to_list() == ["human", "robot"]


def test_team_bound_of_the_target_makes_the_other_team_leave(building):
    cfg = dict(initial_regions=["r3", "r3"], teams=["human", "robot"], team_names=["robot", "human"])
    # no robot may enter r4: the robot is preferred but not eligible
    out = _run(building, "d", prefer_team_order=True, team_capacity={"r4": [0, -1]}, **cfg)
    assert _tracks(out) == ["agent1"]
    # no human in r4 either: unexplained
    out = _run(building, "d", team_capacity={"r4": [0, 0]}, **cfg)
    assert _tracks(out) == [None] and "team bound" in out["unexplained"]["reason"][0]


# ----------------------------------------------------------------- E: traversal time


def test_traversal_time_skips_an_agent_that_just_entered(building):
    times = [0.0, 10.0, 12.0]
    assert _tracks(_run(building, "b c d", times, policy="lifo")) == ["agent1", "agent2", "agent2"]
    out = _run(building, "b c d", times, policy="lifo", min_traversal_s={"r3": 5.0})
    assert _tracks(out) == ["agent1", "agent2", "agent1"]
    # nobody has been in r3 long enough: with n known the crossing is unexplained
    out = _run(building, "b d", [0.0, 1.0], initial_regions=["r2"], min_traversal_s={"*": 5.0})
    assert _tracks(out) == ["agent1", None]
    assert "traversal time" in out["unexplained"]["reason"][0]


def test_variations_combine(building):
    out = _run(
        building,
        "b c d e^-1",
        [0.0, 1.0, 1.5, 3.0],
        policy="lifo",
        initial_regions=["r2", "r2", "r5"],
        teams=["robot", "human", "human"],
        team_names=["robot", "human"],
        prefer_team_order=True,
        capacity={"r3": 2},
        min_traversal_s={"r3": 1.0},
    )
    # b: robot (preferred) to r3; c: human to r3; d at 1.5: the human entered 0.5 s ago, the robot 1.5 s ago
    # e^-1: r3 is full again? it holds the human only -> the r5 human enters
    assert _tracks(out) == ["agent1", "agent2", "agent1", "agent3"]
    assert out["unexplained"].height == 0


# ----------------------------------------------------------------- ambiguity


def test_fig3_ambiguity_is_reported(building):
    out = _run(building, "c e^-1 d b^-1")
    assert out["assignment"]["ambiguous"].sum() == 2
    assert out["agents"]["ambiguous_crossings"].sum() == 2
    # independent walks are never ambiguous
    assert _run(building, "a a^-1 g g^-1")["assignment"]["ambiguous"].sum() == 0
    assert not _run(building, "c e^-1 d b^-1", ambiguity=False)["assignment"]["ambiguous"].any()


def test_ambiguous_crossings_is_invariant_to_relabelling():
    rng = np.random.default_rng(0)
    a = rng.integers(0, 4, 50)
    perm = rng.permutation(4)
    assert not ambiguous_crossings(a, perm[a]).any()
    b = perm[a].copy()
    b[[3, 7]] = 4  # two crossings moved to a new agent
    assert ambiguous_crossings(a, b).sum() == 2
    c = a.copy()
    c[5] = -1  # unexplained in one run only
    assert ambiguous_crossings(a, c)[5] and ambiguous_crossings(a, c).sum() == 1


# ----------------------------------------------------------------- config


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"max_track_length": -1}, "max_track_length"),
        ({"capacity": {"r1": -2}}, "capacity.r1"),
        ({"min_traversal_s": {"r1": "x"}}, "min_traversal_s.r1"),
        ({"min_traversal_s": {"r1": float("nan")}}, "min_traversal_s.r1"),
        ({"min_traversal_s": {"*": float("inf")}}, "min_traversal_s"),
        ({"traffic_bucket_s": float("inf")}, "traffic_bucket_s"),
        ({"teams": ["robot"]}, "teams"),
        ({"initial_regions": ["r1"], "teams": ["robot"], "team_names": ["human"]}, "teams"),
        ({"team_names": ["a", "b"], "team_capacity": {"r1": [1]}}, "team_capacity.r1"),
        ({"prefer_team_order": True}, "team_names"),
        ({"traffic_bucket_s": 0.0}, "traffic_bucket_s"),
        ({"ambiguity": "yes"}, "ambiguity"),
    ],
)
def test_config_errors_name_the_field(kwargs, field):
    with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
        BeamsConfig(**kwargs)


def test_unknown_region_in_config_is_named(building):
    with pytest.raises(ConfigError, match=r"capacity\.r9.*r9"):
        _run(building, "b", capacity={"r9": 1})
    with pytest.raises(ConfigError, match="over its capacity"):
        _run(building, "b", capacity={"r2": 1}, initial_regions=["r2", "r2"])


# ----------------------------------------------------------------- invariants on random strings


@st.composite
def walks(draw):
    """Random graph, agents walking on it; returns regions, crossings and the true starts."""
    n = draw(st.integers(2, 5))
    beams = [
        tuple(draw(st.lists(st.integers(0, n - 1), min_size=2, max_size=2, unique=True)))
        for _ in range(draw(st.integers(1, 6)))
    ]
    k = draw(st.integers(1, 4))
    start = [draw(st.integers(0, n - 1)) for _ in range(k)]
    pos = list(start)
    src, tgt = [], []
    for _ in range(draw(st.integers(0, 25))):
        a = draw(st.integers(0, k - 1))
        options = [(s, t) for s, t in beams if s == pos[a]] + [(t, s) for s, t in beams if t == pos[a]]
        if options:
            s, t = options[draw(st.integers(0, len(options) - 1))]
            src.append(s)
            tgt.append(t)
            pos[a] = t
    times = np.cumsum(draw(st.lists(st.floats(0.0, 3.0), min_size=len(src), max_size=len(src)))) if src else np.zeros(0)
    return n, np.array(src, np.int64), np.array(tgt, np.int64), np.array(start, np.int64), np.asarray(times, float)


def _check_walks(res, src, tgt):
    """Every agent's explained crossings chain from its initial region."""
    for a in range(res.n_agents):
        idx = np.flatnonzero(res.agents == a)
        if len(idx):
            assert src[idx[0]] == res.initial_region[a]
            assert np.all(tgt[idx[:-1]] == src[idx[1:]])


@settings(max_examples=120, deadline=None)
@given(
    walks(), st.sampled_from(["fifo", "lifo"]), st.integers(1, 4), st.integers(0, 5), st.floats(0.0, 2.0), st.booleans()
)
def test_constrained_assignment_invariants(case, policy, u, L, tau, short):
    n, src, tgt, start, times = case
    c = Constraints(
        capacity=np.full(n, u, np.int64),
        max_track_length=L,
        prefer_short=short,
        min_traversal=np.full(n, tau),
    )
    res = assign_agents(src, tgt, n, policy=policy, constraints=c, times=times)
    _check_walks(res, src, tgt)
    assert len(res.unexplained) == len(res.reasons) == int((res.agents < 0).sum())
    # occupancy (with the agents' initial regions) never exceeds the capacity
    ok = res.agents >= 0
    delta = np.zeros((len(src) + 1, n), np.int64)
    np.add.at(delta[0], res.initial_region, 1)
    rows = np.flatnonzero(ok) + 1
    np.add.at(delta, (rows, src[ok]), -1)
    np.add.at(delta, (rows, tgt[ok]), 1)
    assert np.cumsum(delta, axis=0).max() <= u
    # no agent visits more than L regions
    if L:
        visits = 1 + np.bincount(res.agents[ok], minlength=res.n_agents)
        assert visits.max(initial=0) <= L
    # traversal time: an agent leaves a region at least tau after entering it
    for a in range(res.n_agents):
        ta = times[res.agents == a]
        assert np.all(np.diff(ta) >= tau - 1e-12)


@settings(max_examples=120, deadline=None)
@given(walks(), st.sampled_from(["fifo", "lifo"]))
def test_known_true_initial_condition_explains_everything(case, policy):
    n, src, tgt, start, times = case
    res = assign_agents(src, tgt, n, policy=policy, constraints=Constraints(initial_region=start))
    assert len(res.unexplained) == 0 and res.n_agents == len(start)
    _check_walks(res, src, tgt)
    # and non-binding constraints give the base algorithm's answer
    base = assign_agents(src, tgt, n, policy=policy)
    loose = Constraints(capacity=np.full(n, len(src) + 5), max_track_length=len(src) + 2, min_traversal=np.zeros(n))
    assert (
        assign_agents(src, tgt, n, policy=policy, constraints=loose, times=times).agents.tolist()
        == base.agents.tolist()
    )
    big = Constraints(capacity=np.full(n, len(src) + 5), max_track_length=len(src) + 2, region_names=tuple("x" * n))
    assert assign_agents(src, tgt, n, policy=policy, constraints=big).agents.tolist() == base.agents.tolist()
