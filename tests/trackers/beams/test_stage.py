"""Algorithm 1 and Proposition 3.1 (Bobadilla et al., section III)."""

from __future__ import annotations

import networkx as nx
import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import ConfigError
from onebit.core.region_graph import build_region_graph
from onebit.datasets.builtin import builtin_site
from onebit.trackers.beams import BeamsConfig, assign_agents, is_consistent_partition, minimum_agents, run


def _crossings(word: str) -> pl.DataFrame:
    toks = word.split()
    return pl.DataFrame(
        {
            "t": [float(i) for i in range(len(toks))],
            "beam": [tok[0] for tok in toks],
            "direction": pl.Series([-1 if tok.endswith("^-1") else 1 for tok in toks], dtype=pl.Int8),
        }
    )


def test_building_region_graph_matches_fig2(building):
    _, rg = building
    assert len(rg.names) == 6
    assert len(rg.beam_source) == 7
    assert rg.graph.number_of_edges() == 14
    # section IV-F-1: the visitors of r4 are counted by the characters d, f, g^-1
    into_r4 = {k for _, v, k in rg.graph.in_edges("r4", keys=True)}
    assert into_r4 == {"d", "f", "g^-1"}
    # every forward edge has its reverse labelled beta^-1
    for u, v, _k, data in rg.graph.edges(keys=True, data=True):
        rev = f"{data['beam']}^-1" if data["direction"] == 1 else data["beam"]
        assert rg.graph.has_edge(v, u, key=rev)


def test_lab_region_graph_fig8():
    rg = build_region_graph(builtin_site("lab"))
    assert len(rg.names) == 5 and len(rg.beam_source) == 4 and rg.graph.number_of_edges() == 8
    assert nx.is_connected(nx.Graph(rg.graph))


def test_fig1_agents_strings_are_walks(building):
    _, rg = building
    word = "g^-1 a^-1 d^-1 e^-1 b b^-1 c^-1 c e f"
    cr = _crossings(word)
    src, tgt = rg.endpoint_arrays(cr["beam"].to_numpy(), cr["direction"].to_numpy())
    toks = word.split()
    paper = [["g^-1", "d^-1", "c^-1"], ["a^-1", "b", "e", "f"], ["e^-1", "b^-1", "c"]]
    groups = [[toks.index(x) for x in g] for g in paper]
    assert is_consistent_partition(src, tgt, groups)
    assert minimum_agents(src, tgt, len(rg.names)) == 3


@pytest.mark.parametrize("policy", ["fifo", "lifo"])
def test_fig3_ambiguity_two_agents(building, policy):
    site, rg = building
    cr = _crossings("c e^-1 d b^-1")
    out = run({"crossings": cr, "region_graph": rg}, site, BeamsConfig(policy=policy))
    assert out["agents"].height == 2
    src, tgt = rg.endpoint_arrays(cr["beam"].to_numpy(), cr["direction"].to_numpy())
    # both partitions the paper lists are consistent: {c d, e^-1 b^-1} and {c b^-1, e^-1 d}
    assert is_consistent_partition(src, tgt, [[0, 2], [1, 3]])
    assert is_consistent_partition(src, tgt, [[0, 3], [1, 2]])
    assert not is_consistent_partition(src, tgt, [[0, 1], [2, 3]])
    # the tracker's own answer is one of the two
    a = out["assignment"]["track"].to_list()
    assert {frozenset(i for i in range(4) if a[i] == t) for t in set(a)} in (
        {frozenset({0, 2}), frozenset({1, 3})},
        {frozenset({0, 3}), frozenset({1, 2})},
    )


def test_fifo_and_lifo_differ_where_queue_order_matters(building):
    _, rg = building
    # two agents enter r3 (b then c), then one leaves by d: FIFO takes the first, LIFO the second
    cr = _crossings("b c d")
    src, tgt = rg.endpoint_arrays(cr["beam"].to_numpy(), cr["direction"].to_numpy())
    fifo = assign_agents(src, tgt, len(rg.names), policy="fifo").agents
    lifo = assign_agents(src, tgt, len(rg.names), policy="lifo").agents
    assert fifo.tolist() == [0, 1, 0]
    assert lifo.tolist() == [0, 1, 1]


def test_config_rejects_unknown_policy():
    with pytest.raises(ConfigError, match="policy"):
        BeamsConfig(policy="random")


# ----------------------------------------------------------------- Proposition 3.1 by brute force


def _brute_min_agents(src, tgt) -> int:
    """Smallest k such that the crossings split into k walks (exhaustive over labelings)."""
    m = len(src)
    if m == 0:
        return 0
    for k in range(1, m + 1):
        # canonical labelings: crossing 0 -> agent 0, new agents in order of first use
        def rec(i, last_target, used):
            if i == m:
                return True
            for a in range(min(used + 1, k)):
                if a < used and last_target[a] != src[i]:
                    continue
                prev = last_target[a] if a < used else None
                last_target[a] = tgt[i]
                if rec(i + 1, last_target, max(used, a + 1)):
                    return True
                if prev is None:
                    del last_target[a]
                else:
                    last_target[a] = prev
            return False

        if rec(0, {}, 0):
            return k
    return m


@st.composite
def graph_and_string(draw):
    n = draw(st.integers(2, 5))
    n_beams = draw(st.integers(1, 6))
    beams = [tuple(draw(st.lists(st.integers(0, n - 1), min_size=2, max_size=2, unique=True))) for _ in range(n_beams)]
    agents = draw(st.integers(1, 3))
    pos = [draw(st.integers(0, n - 1)) for _ in range(agents)]
    m = draw(st.integers(0, 8))
    src, tgt = [], []
    for _ in range(m):
        a = draw(st.integers(0, agents - 1))
        options = [(s, t) for s, t in beams if s == pos[a]] + [(t, s) for s, t in beams if t == pos[a]]
        if not options:
            continue
        s, t = options[draw(st.integers(0, len(options) - 1))]
        src.append(s)
        tgt.append(t)
        pos[a] = t
    return n, np.array(src, dtype=np.int64), np.array(tgt, dtype=np.int64)


@settings(max_examples=150, deadline=None)
@given(graph_and_string())
def test_proposition_3_1_minimum_agents(case):
    n, src, tgt = case
    best = _brute_min_agents(src.tolist(), tgt.tolist())
    assert minimum_agents(src, tgt, n) == best
    for policy in ("fifo", "lifo"):
        res = assign_agents(src, tgt, n, policy=policy)
        assert res.n_agents == best
        groups = [np.flatnonzero(res.agents == a).tolist() for a in range(res.n_agents)]
        assert is_consistent_partition(src, tgt, groups)
