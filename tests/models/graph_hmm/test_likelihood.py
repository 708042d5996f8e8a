"""The decoders' joint log-likelihood of labelled paths, and what it can tell about who is who."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.datasets.builtin import builtin_site
from onebit.models.graph_hmm.adaptive import joint_emission
from onebit.models.graph_hmm.eatg import hop_matrix, layout_eatg
from onebit.models.graph_hmm.likelihood import (
    came_from,
    claims,
    colocations,
    exchange_margin,
    model_log_likelihood,
    path_log_prior,
    tie_relabelling,
)
from onebit.models.graph_hmm.window import second_order_tensor


def _eatg():
    g = builtin_site("hallway").sensor_graph
    return layout_eatg(g.nodes, hop_matrix(g.nodes, g.edges))


EATG = _eatg()
IDX = EATG.index
LOG_A = second_order_tensor(EATG.a1, EATG.a2, np.arange(len(EATG.nodes)))


def _rows(seqs):
    return np.array([[IDX[str(n)] if n is not None else -1 for n in s] for s in seqs], dtype=np.int64)


def _came_from_reference(paths):
    out = np.full(paths.shape, -1, np.int64)
    for u in range(paths.shape[0]):
        ctx = -1
        for t in range(paths.shape[1]):
            x = paths[u, t]
            if x < 0 or t == 0 or paths[u, t - 1] < 0:
                ctx = -1
            elif x != paths[u, t - 1]:
                ctx = paths[u, t - 1]
            out[u, t] = ctx
    return out


def _prior_reference(paths):
    ctx = _came_from_reference(paths)
    tot = 0.0
    for u in range(paths.shape[0]):
        for t in range(1, paths.shape[1]):
            j2, j1 = paths[u, t - 1], paths[u, t]
            if j2 < 0 or j1 < 0:
                continue
            j3 = ctx[u, t - 1] if ctx[u, t - 1] >= 0 else j2
            tot += LOG_A[j3, j2, j1]
    return tot


def _walks(draw, users, slots):
    """Random walks on the hallway graph (stay or step to a neighbour), some slots absent."""
    n = len(EATG.nodes)
    nbr = [np.flatnonzero(EATG.hops[j] == 1) for j in range(n)]
    out = np.full((users, slots), -1, np.int64)
    for u in range(users):
        x = draw(st.integers(0, n - 1))
        for t in range(slots):
            move = draw(st.integers(0, 3))
            if move == 3 and draw(st.booleans()):
                out[u, t] = -1
                continue
            if move == 2:
                x = int(nbr[x][draw(st.integers(0, len(nbr[x]) - 1))])
            out[u, t] = x
    return out


@st.composite
def walks(draw):
    return _walks(draw, draw(st.integers(1, 3)), draw(st.integers(2, 14)))


@settings(max_examples=60, deadline=None)
@given(paths=walks())
def test_vectorised_context_and_prior_equal_the_plain_loops(paths):
    np.testing.assert_array_equal(came_from(paths), _came_from_reference(paths))
    assert np.isclose(path_log_prior(paths, LOG_A), _prior_reference(paths))


@settings(max_examples=60, deadline=None)
@given(paths=walks(), data=st.data())
def test_exchanging_tails_at_a_shared_node_changes_only_the_direction_factor(paths, data):
    """Two users at one node at slot e: exchanging their tails keeps who is where in every slot
    (the emission term) and every first-order factor; the log-likelihood changes only through
    a'' (from where each came against where each goes)."""
    if paths.shape[0] < 2:
        return
    e = data.draw(st.integers(1, paths.shape[1] - 1))
    paths = paths.copy()
    paths[1, e] = paths[0, e] = max(paths[0, e], 0)
    x = paths.copy()
    x[0, e:], x[1, e:] = paths[1, e:], paths[0, e:]
    n = len(EATG.nodes)
    np.testing.assert_array_equal(claims(x, n), claims(paths, n))
    active = data.draw(st.lists(st.booleans(), min_size=paths.shape[1] * n, max_size=paths.shape[1] * n))
    active = np.array(active).reshape(paths.shape[1], n)
    e0, e1 = (joint_emission(active, claims(p, n), 0.9, 0.05) for p in (paths, x))
    assert e0 == e1
    first = second_order_tensor(EATG.a1, EATG.a2, np.arange(n))[np.arange(n), np.arange(n)]  # j3 = j2: first order

    def first_order(p):
        a, b = p[:, :-1], p[:, 1:]
        ok = (a >= 0) & (b >= 0)
        return first[a[ok], b[ok]].sum()

    assert np.isclose(first_order(paths), first_order(x))


def test_a_head_on_crossing_is_told_apart_and_a_shared_arrival_is_a_tie():
    active = np.zeros((9, len(EATG.nodes)), bool)
    # head-on through 111: one from 99 to 110, the other from 110 to 99 -- a'' prefers walking on
    cross = _rows([[99, 99, 111, 111, 111, 110, 110, 110, 110], [110, 110, 111, 111, 111, 99, 99, 99, 99]])
    margin, _ = exchange_margin(cross, 0, 1, [2, 3, 4], active, EATG, p_hit=0.9, p_false=0.05)
    assert margin > np.log(3)
    # both arrive from 99 and leave apart (to 110, to 114): the model cannot say who took which way
    same_in = _rows([[99, 99, 111, 111, 111, 110, 110, 110, 110], [99, 99, 111, 111, 111, 114, 114, 114, 114]])
    margin, _ = exchange_margin(same_in, 0, 1, [2, 3, 4], active, EATG, p_hit=0.9, p_false=0.05)
    assert abs(margin) < 1e-9


def test_tie_relabelling_keeps_what_the_model_decides_and_flips_coins_at_ties():
    active = np.zeros((9, len(EATG.nodes)), bool)
    cross = _rows([[99, 99, 111, 111, 111, 110, 110, 110, 110], [110, 110, 111, 111, 111, 99, 99, 99, 99]])
    same_in = _rows([[99, 99, 111, 111, 111, 110, 110, 110, 110], [99, 99, 111, 111, 111, 114, 114, 114, 114]])
    assert colocations(cross) == [(2, (0, 1))]
    rng = np.random.default_rng(0)
    for _ in range(10):
        x, changed = tie_relabelling(cross, active, EATG, p_hit=0.9, p_false=0.05, rng=rng)
        np.testing.assert_array_equal(x, cross)
        assert changed == 0
    outcomes = {tie_relabelling(same_in, active, EATG, p_hit=0.9, p_false=0.05, rng=rng)[1] for _ in range(20)}
    assert outcomes == {0, 1}  # both labellings are drawn


def test_log_likelihood_is_minus_infinity_for_a_jump():
    active = np.zeros((3, len(EATG.nodes)), bool)
    jump = _rows([[95, 117, 117]])  # not neighbours
    assert model_log_likelihood(jump, active, EATG, p_hit=0.9, p_false=0.05) == -np.inf
    still = _rows([[95, 95, None]])
    assert np.isfinite(model_log_likelihood(still, active, EATG, p_hit=0.9, p_false=0.05))
