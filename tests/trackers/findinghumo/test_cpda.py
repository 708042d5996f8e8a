"""CPDA: the paper's worked example (section III-C) and flow conservation; EATG invariants."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.datasets.builtin import builtin_site
from onebit.models.graph_hmm.eatg import hop_matrix, layout_eatg, trained_eatg
from onebit.trackers.findinghumo.cpda import colocation_events, cpda, interaction_graph


@pytest.fixture(scope="module")
def eatg():
    site = builtin_site("hallway")
    g = site.sensor_graph
    return layout_eatg(g.nodes, hop_matrix(g.nodes, g.edges))


def _paths(eatg, seqs):
    idx = eatg.index
    return np.array([[idx[str(n)] for n in s] for s in seqs])


def _names(eatg, paths):
    return [[int(eatg.nodes[i]) for i in row] for row in paths]


def test_paper_worked_example(eatg):
    decoded = [
        [97, 96, 95, 99, 111, 114],
        [114, 114, 111, 99, 111, 110],
        [97, 96, 95, 99, 95, 96],
    ]
    paths = _paths(eatg, decoded)
    # the interaction graph: 99 has incoming 95, 111 and outgoing 111, 95; 111 has 99 -> 114, 110
    gi = interaction_graph(paths, eatg.nodes)
    assert set(gi.predecessors("99")) == {"95", "111"} and set(gi.successors("99")) == {"111", "95"}
    assert set(gi.successors("111")) >= {"114", "110", "99"}
    # the inference prefers continuing through the kitchen over turning back
    i = eatg.index
    assert eatg.a2[i["111"], i["95"]] > eatg.a2[i["111"], i["111"]]
    res = cpda(paths, eatg.a2, horizon=2 * 5)
    assert _names(eatg, res.paths) == [
        [97, 96, 95, 99, 111, 114],
        [114, 114, 111, 99, 95, 96],
        [97, 96, 95, 99, 111, 110],
    ]
    assert len(res.switches) == 1 and eatg.nodes[res.switches[0][1]] == "99"
    # a second run is stable: nothing left to switch
    again = cpda(res.paths, eatg.a2, horizon=10)
    assert again.switches == [] and np.array_equal(again.paths, res.paths)


def _random_walks(eatg, rng, k, d):
    adj = eatg.hops == 1
    n = len(eatg.nodes)
    paths = np.zeros((k, d), dtype=np.int64)
    paths[:, 0] = rng.integers(0, n, size=k)
    for t in range(1, d):
        for u in range(k):
            nb = np.flatnonzero(adj[paths[u, t - 1]])
            paths[u, t] = paths[u, t - 1] if rng.random() < 0.4 else rng.choice(nb)
    return paths


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), k=st.integers(2, 5), adjacent=st.booleans())
def test_flow_conservation_and_continuity(eatg, seed, k, adjacent):
    rng = np.random.default_rng(seed)
    # force crossings: every user passes the kitchen 99 at slot 6
    paths = _random_walks(eatg, rng, k, 14)
    i99 = eatg.index["99"]
    paths[:, 6] = i99
    paths[:, 5] = rng.choice([eatg.index["95"], eatg.index["111"], i99], size=k)
    paths[:, 7] = rng.choice([eatg.index["95"], eatg.index["111"], i99], size=k)
    for t in range(8, 14):  # continue as walks from slot 7
        for u in range(k):
            nb = np.flatnonzero(eatg.hops[paths[u, t - 1]] <= 1)
            paths[u, t] = rng.choice(nb)
    for t in range(4, -1, -1):
        for u in range(k):
            nb = np.flatnonzero(eatg.hops[paths[u, t + 1]] <= 1)
            paths[u, t] = rng.choice(nb)
    before = paths.copy()
    hops = eatg.hops if adjacent else None
    res = cpda(paths, eatg.a2, horizon=10, hops=hops)
    out = res.paths
    # continuity: every corrected path still moves at most one hop per slot
    assert np.all(eatg.hops[out[:, :-1], out[:, 1:]] <= 1)
    # flow conservation: at every slot the multiset of occupied nodes is unchanged
    np.testing.assert_array_equal(np.sort(out, axis=0), np.sort(before, axis=0))
    # at every crossover event, as many paths leave the node as entered it
    for c, users in colocation_events(before, np.zeros(len(eatg.nodes), bool)):
        j = before[users[0], c]
        assert (before[:, c] == j).sum() == (out[:, c] == j).sum()
    # and the result is a fixed point
    assert cpda(out, eatg.a2, horizon=10, hops=hops).switches == []


def test_layout_eatg_is_stochastic_and_local(eatg):
    assert np.allclose(eatg.a1.sum(axis=1), 1) and np.allclose(eatg.a2.sum(axis=1), 1)
    assert np.all(eatg.a1[eatg.hops > 1] == 0)
    off = ~np.eye(len(eatg.nodes), dtype=bool)
    assert np.all(eatg.a2[off & (eatg.hops != 2)] == 0)
    i = eatg.index
    # 2-hop edge: 95 reaches 111 through the kitchen
    assert eatg.a2[i["95"], i["111"]] > 0
    g = eatg.to_networkx()
    assert "a1" in g.edges["96", "94"] and "a1" not in g.edges["96", "93"] and "a2" in g.edges["96", "93"]
    tab = eatg.table()
    assert set(tab["kind"].unique()) == {"a1", "a2"}


def test_trained_eatg_learns_walking_direction(eatg):
    # one user walks 97 -> 96 -> 95 -> 99 -> 111 -> 110 repeatedly, 3 slots per node
    i = eatg.index
    route = ["97", "96", "95", "99", "111", "110"]
    n = len(eatg.nodes)
    slots = []
    for _ in range(6):
        for node in route:
            for _ in range(3):
                row = np.zeros(n, bool)
                row[i[node]] = True
                slots.append(row)
        slots.append(np.zeros(n, bool))
    act = np.array(slots)
    tr = trained_eatg(act, eatg.nodes, eatg.hops, horizon=8)
    assert np.allclose(tr.a1.sum(axis=1), 1) and np.allclose(tr.a2.sum(axis=1), 1)
    # the trained 2-hop weight 95 -> 111 grows above the layout's, 95 -> 94 shrinks
    assert tr.a2[i["95"], i["111"]] > eatg.a2[i["95"], i["111"]]
    assert tr.a2[i["96"], i["99"]] > tr.a2[i["96"], i["92"]]
    # staying dominates a' at 3 slots per node
    assert tr.a1[i["99"], i["99"]] > tr.a1[i["99"], i["95"]]


def test_crossing_on_an_edge_is_switched_inside_the_meeting(eatg):
    """Two users cross on the edge 99-111 between slots; the decoder bounced both back, so the
    paths never share a node. CPDA switches them inside the meeting (where the joined paths
    stay continuous) and records the alternatives' posteriors."""
    decoded = [
        [96, 95, 95, 99, 99, 99, 95, 95, 96],
        [117, 110, 110, 111, 111, 111, 110, 110, 117],
    ]
    paths = _paths(eatg, decoded)
    res = cpda(paths, eatg.a2, horizon=10, hops=eatg.hops)
    out = _names(eatg, res.paths)
    assert out[0][0] == 96 and out[0][-1] == 117 and out[1][0] == 117 and out[1][-1] == 96
    assert np.all(eatg.hops[res.paths[:, :-1], res.paths[:, 1:]] <= 1)
    assert len(res.switches) == 1
    dec = res.decisions[0]
    assert np.isclose(dec["prob"].sum(), 1.0) and dec["sigma"] == (1, 0) and dec["prob"][1] > dec["prob"][0]


@settings(max_examples=200, deadline=None)
@given(m=st.integers(1, 6), data=st.data())
def test_connected_equals_connected_components(m, data):
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    from onebit.trackers.findinghumo.cpda import _connected

    adj = np.array(data.draw(st.lists(st.booleans(), min_size=m * m, max_size=m * m))).reshape(m, m)
    assert _connected(adj) == (connected_components(csr_matrix(adj), directed=False)[0] == 1)


@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_pair_meeting_equals_scoring_every_joined_path_whole(data):
    from onebit._testing.oracles import pair_meeting_reference
    from onebit.trackers.findinghumo.cpda import pair_meeting

    n = data.draw(st.integers(3, 6))
    m = data.draw(st.integers(2, 3))
    d = data.draw(st.integers(4, 14))
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    paths = rng.integers(-1, n, size=(m + 1, d))
    paths = np.where(
        rng.random((m + 1, d)) < 0.6, np.maximum.accumulate(np.arange(d)[None, :] * 0 + paths[:, :1], axis=1), paths
    )
    log_a2 = np.log(rng.dirichlet(np.ones(n), size=n))
    hops = None if data.draw(st.booleans()) else rng.integers(0, 3, size=(n, n))
    users = np.arange(m)
    c = data.draw(st.integers(1, d - 2))
    s0 = data.draw(st.integers(0, c))
    p1, l1, b1 = pair_meeting(paths, users, s0, c, log_a2, hops)
    p0, l0, b0 = pair_meeting_reference(paths, users, s0, c, log_a2, hops)
    assert p1 == p0
    assert l1[0] == 0.0  # relative to the HMM's pairing
    np.testing.assert_allclose(l1, l0 - l0[0], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(b1[np.isfinite(l0)], b0[np.isfinite(l0)])


@settings(max_examples=200, deadline=None)
@given(m=st.integers(1, 7), data=st.data())
def test_component_labels_equal_connected_components(m, data):
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    from onebit.trackers.findinghumo.cpda import _component_labels

    adj = np.array(data.draw(st.lists(st.booleans(), min_size=m * m, max_size=m * m))).reshape(m, m)
    n, lab = connected_components(csr_matrix(adj), directed=False)
    ours = _component_labels(adj)
    # the same partition: users share a label in one exactly when they do in the other
    assert ((ours[:, None] == ours[None, :]) == (lab[:, None] == lab[None, :])).all()
    assert len(np.unique(ours)) == n
