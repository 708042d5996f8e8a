"""Algorithm 1 as a resumable pass (AssignmentState, used by ``onebit follow``): a crossing
string fed in random pieces gets the agents, unexplained crossings and reasons of one pass
over the whole string (the compiled kernel's and the reference's)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.trackers.beams.assignment import AssignmentState, Constraints, assign_agents

P = 4


@st.composite
def strings(draw):
    m = draw(st.integers(0, 30))
    src = draw(st.lists(st.integers(0, P - 1), min_size=m, max_size=m))
    tgt = [(s + draw(st.integers(1, P - 1))) % P for s in src]
    times = np.cumsum(draw(st.lists(st.sampled_from([0.5, 1.0, 3.0]), min_size=m, max_size=m)))
    kind = draw(st.sampled_from(["base", "capacity", "max_agents", "length", "time", "initial"]))
    c = None
    if kind == "capacity":
        c = Constraints(capacity=np.array(draw(st.lists(st.integers(-1, 3), min_size=P, max_size=P))))
    elif kind == "max_agents":
        c = Constraints(max_agents=draw(st.integers(1, 3)))
    elif kind == "length":
        c = Constraints(max_track_length=draw(st.integers(1, 4)), prefer_short=draw(st.booleans()))
    elif kind == "time":
        c = Constraints(min_traversal=np.full(P, draw(st.sampled_from([1.0, 2.0]))))
    elif kind == "initial":
        c = Constraints(initial_region=np.array(draw(st.lists(st.integers(0, P - 1), min_size=1, max_size=3))))
    cuts = sorted(draw(st.lists(st.integers(0, m), max_size=4)))
    return (
        np.array(src, np.int64),
        np.array(tgt, np.int64),
        times,
        c,
        [0, *cuts, m],
        draw(st.sampled_from(["fifo", "lifo"])),
    )


@settings(max_examples=60, deadline=None)
@given(strings())
def test_fed_in_pieces_equals_one_pass(case):
    src, tgt, times, c, bounds, policy = case
    whole = assign_agents(src, tgt, P, policy=policy, constraints=c, times=times, compiled=False)
    state = AssignmentState(P, policy, c)
    got = [state.feed(src[a:b], tgt[a:b], times[a:b]) for a, b in zip(bounds, bounds[1:])]
    agents = np.concatenate(got) if got else np.zeros(0, np.int64)
    res = state.assignment()
    assert agents.tolist() == whole.agents.tolist() == res.agents.tolist()
    assert res.n_agents == whole.n_agents
    assert res.initial_region.tolist() == whole.initial_region.tolist()
    assert res.unexplained.tolist() == whole.unexplained.tolist()
    assert res.reasons == whole.reasons
