"""Joint re-decoding of two users through a meeting: exact against brute force, never lowers
the model's log-likelihood, and puts a head-on crossing right where one-at-a-time decoding
bounced the users back."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.datasets.builtin import builtin_site
from onebit.models.graph_hmm.adaptive import joint_emission, second_order_tensor
from onebit.models.graph_hmm.eatg import hop_matrix, layout_eatg
from onebit.models.graph_hmm.joint import PairSpace, decode_pair, joint_table, meetings, redecode_meetings
from onebit.models.graph_hmm.likelihood import model_log_likelihood

G = builtin_site("hallway").sensor_graph
EATG = layout_eatg(G.nodes, hop_matrix(G.nodes, G.edges))
N = len(EATG.nodes)
IDX = EATG.index
LOG_A = second_order_tensor(EATG.a1, EATG.a2, np.arange(N))
SPACE = PairSpace(EATG.hops, LOG_A)


def _rows(seqs):
    return np.array([[IDX[str(n)] for n in s] for s in seqs], dtype=np.int64)


def _user_score(x0, c0, path, end):
    """Plain second-order score of one user's window path from state (x0, c0) and its move into ``end``."""
    tot, x, c = 0.0, x0, c0
    for y in [*path, *([end] if end >= 0 else [])]:
        tot += LOG_A[c if c >= 0 else x, x, y]
        if y != x:
            c, x = x, y
    return tot


def _emission(active, others, p1, p2):
    both = others.copy()
    for t, (a, b) in enumerate(zip(p1, p2)):
        both[t, a] += 1
        both[t, b] += 1
    return joint_emission(active, both, 0.9, 0.05) - joint_emission(active, others, 0.9, 0.05)


def _moves(x):
    return [x, *np.flatnonzero(EATG.hops[x] == 1).tolist()]


@settings(max_examples=25, deadline=None)
@given(data=st.data())
def test_decode_pair_finds_the_brute_force_optimum(data):
    w = data.draw(st.integers(1, 3))
    starts = []
    for _ in range(2):
        x = data.draw(st.integers(0, N - 1))
        nb = [-1, *np.flatnonzero(EATG.hops[x] == 1).tolist()]
        starts.append((x, nb[data.draw(st.integers(0, len(nb) - 1))]))
    active = np.array(data.draw(st.lists(st.booleans(), min_size=w * N, max_size=w * N))).reshape(w, N)
    others = np.array(data.draw(st.lists(st.integers(0, 1), min_size=w * N, max_size=w * N))).reshape(w, N)
    end = tuple(data.draw(st.sampled_from([-1, *_moves(s[0])])) for s in starts)

    def user_paths(x):
        out = [[]]
        for _ in range(w):
            out = [p + [y] for p in out for y in _moves(p[-1] if p else x)]
        return out

    best = -np.inf
    for p1, p2 in itertools.product(user_paths(starts[0][0]), user_paths(starts[1][0])):
        sc = _user_score(*starts[0], p1, end[0]) + _user_score(*starts[1], p2, end[1]) + _emission(active, others, p1, p2)
        best = max(best, sc)
    (got,) = decode_pair(SPACE, (SPACE.state(*starts[0]), SPACE.state(*starts[1])), active, others, [end], p_hit=0.9, p_false=0.05)
    if not np.isfinite(best):
        assert got is None
        return
    sc = _user_score(*starts[0], got[0].tolist(), end[0]) + _user_score(*starts[1], got[1].tolist(), end[1])
    sc += _emission(active, others, got[0].tolist(), got[1].tolist())
    assert np.isclose(sc, best), (sc, best)


def _crossing_activity(seqs):
    act = np.zeros((len(seqs[0]), N), bool)
    for s in seqs:
        act[np.arange(len(s)), [IDX[str(n)] for n in s]] = True
    return act


def test_a_head_on_crossing_bounced_by_the_decoder_is_walked_through():
    truth = _rows([
        [97, 97, 96, 96, 96, 95, 95, 95, 99, 99, 99, 111, 111, 111],
        [111, 111, 111, 99, 99, 99, 95, 95, 95, 96, 96, 96, 97, 97],
    ])  # fmt: skip
    active = _crossing_activity([[EATG.nodes[j] for j in r] for r in truth])
    # one user at a time: both turn back at 95 -- each keeps its side
    bounced = np.where(np.arange(14)[None, :] < 7, truth, truth[::-1])
    assert model_log_likelihood(bounced, active, EATG, p_hit=0.9, p_false=0.05) < model_log_likelihood(truth, active, EATG, p_hit=0.9, p_false=0.05)
    fixed, log = redecode_meetings(bounced, active, EATG, p_hit=0.9, p_false=0.05)
    assert log and any(r["gain"] > 0 for r in log)
    np.testing.assert_array_equal(fixed[:, -3:], truth[:, -3:])  # each leaves on its own side's far end
    table = joint_table(log, EATG.nodes, 0.0, 1.0)
    assert table.height == len(log) and (table["gain"] >= 0).all()


@settings(max_examples=15, deadline=None)
@given(data=st.data())
def test_redecoding_never_lowers_the_log_likelihood(data):
    d = data.draw(st.integers(4, 12))
    paths = np.zeros((2, d), np.int64)
    for u in range(2):
        x = data.draw(st.integers(0, N - 1))
        for t in range(d):
            if data.draw(st.booleans()):
                mv = _moves(x)
                x = mv[data.draw(st.integers(0, len(mv) - 1))]
            paths[u, t] = x
    paths[1, d // 2] = paths[0, d // 2]  # make them meet
    paths[1, d // 2 - 1] = paths[0, d // 2 - 1]
    active = np.array(data.draw(st.lists(st.booleans(), min_size=d * N, max_size=d * N))).reshape(d, N)
    before = model_log_likelihood(paths, active, EATG, p_hit=0.9, p_false=0.05)
    after_paths, _ = redecode_meetings(paths, active, EATG, p_hit=0.9, p_false=0.05)
    after = model_log_likelihood(after_paths, active, EATG, p_hit=0.9, p_false=0.05)
    assert after >= before - 1e-9 or not np.isfinite(before)


def test_meetings_are_runs_within_one_hop_padded():
    paths = _rows([[97, 96, 95, 99, 111, 110, 117, 117], [93, 94, 96, 95, 99, 111, 110, 110]])
    (m,) = meetings(paths, EATG.hops, pad=1)
    assert m[:2] == (0, 1) and m[2] >= 1 and m[3] <= 7
