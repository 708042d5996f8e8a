"""Viterbi decoders: first order equals hmmlearn's decode, second order equals brute force."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.models.graph_hmm.viterbi import (
    log_safe,
    viterbi_first_order,
    viterbi_first_order_batch,
    viterbi_motion_second_order,
    viterbi_second_order,
)


def _random_model(rng, n_states, n_symbols):
    pi = rng.dirichlet(np.ones(n_states))
    a = rng.dirichlet(np.ones(n_states), size=n_states)
    b = rng.dirichlet(np.ones(n_symbols), size=n_states)
    return pi, a, b


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("n_states", [2, 5, 20])
def test_first_order_equals_hmmlearn(seed, n_states):
    from hmmlearn.hmm import CategoricalHMM

    rng = np.random.default_rng(seed)
    pi, a, b = _random_model(rng, n_states, 6)
    obs = rng.integers(0, 6, size=40)
    model = CategoricalHMM(n_components=n_states, init_params="", params="")
    model.startprob_, model.transmat_, model.emissionprob_ = pi, a, b
    model.n_features = 6
    ref_logp, ref_path = model.decode(obs.reshape(-1, 1), algorithm="viterbi")
    path, logp = viterbi_first_order(np.log(pi), np.log(a), np.log(b[:, obs].T))
    np.testing.assert_array_equal(path, ref_path)
    assert logp == pytest.approx(ref_logp, rel=1e-9)


def test_batch_equals_single():
    rng = np.random.default_rng(7)
    pi, a, b = _random_model(rng, 6, 4)
    obs = rng.integers(0, 4, size=(3, 25))
    log_b = np.log(b[:, obs].transpose(1, 2, 0))  # (U, D, S)
    log_pi = np.log(np.stack([pi, pi[::-1] / pi.sum(), pi]))
    paths, logps = viterbi_first_order_batch(log_pi, np.log(a), log_b)
    for u in range(3):
        p, lp = viterbi_first_order(log_pi[u], np.log(a), log_b[u])
        np.testing.assert_array_equal(paths[u], p)
        assert logps[u] == pytest.approx(lp)


def _brute_second(log_pi, log_a1, log_a2, log_b):
    n_slots, n_states = log_b.shape
    best, best_path = -np.inf, None
    for q in itertools.product(range(n_states), repeat=n_slots):
        s = log_pi[q[0]] + log_b[0, q[0]]
        if n_slots > 1:
            s += log_a1[q[0], q[1]] + log_b[1, q[1]]
        for d in range(2, n_slots):
            s += log_a2[q[d - 2], q[d - 1], q[d]] + log_b[d, q[d]]
        if s > best:
            best, best_path = s, q
    return np.array(best_path), best


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n_states=st.integers(1, 4), n_slots=st.integers(1, 6), sparse=st.booleans())
def test_second_order_equals_brute_force(seed, n_states, n_slots, sparse):
    rng = np.random.default_rng(seed)
    pi = rng.dirichlet(np.ones(n_states))
    a1 = rng.dirichlet(np.ones(n_states), size=n_states)
    a2 = rng.dirichlet(np.ones(n_states), size=(n_states, n_states))
    if sparse and n_states > 1:  # structural zeros, as in a sensor graph
        mask = rng.random(a2.shape) < 0.3
        mask[..., 0] = False
        a2 = np.where(mask, 0.0, a2)
    log_b = np.log(rng.random((n_slots, n_states)) + 1e-3)
    args = (log_safe(pi), log_safe(a1), log_safe(a2), log_b)
    path, logp = viterbi_second_order(*args)
    ref_path, ref = _brute_second(*args)
    assert logp == pytest.approx(ref)
    # the returned path must reach the optimum (ties may pick another optimal path)
    _, again = _brute_path_score(path, *args)
    assert again == pytest.approx(ref)


def _brute_path_score(q, log_pi, log_a1, log_a2, log_b):
    s = log_pi[q[0]] + log_b[0, q[0]]
    if len(q) > 1:
        s += log_a1[q[0], q[1]] + log_b[1, q[1]]
    for d in range(2, len(q)):
        s += log_a2[q[d - 2], q[d - 1], q[d]] + log_b[d, q[d]]
    return q, s


def test_second_order_reduces_to_first_order_when_memoryless():
    rng = np.random.default_rng(3)
    pi, a, b = _random_model(rng, 7, 5)
    obs = rng.integers(0, 5, size=30)
    log_b = np.log(b[:, obs].T)
    a2 = np.broadcast_to(a[None], (7, 7, 7))
    p2, l2 = viterbi_second_order(np.log(pi), np.log(a), np.log(a2), log_b)
    p1, l1 = viterbi_first_order(np.log(pi), np.log(a), log_b)
    np.testing.assert_array_equal(p1, p2)
    assert l1 == pytest.approx(l2)


def _motion_path_score(q, log_pi, log_stay, log_move, log_b):
    """Score of a path under the distinct-node second-order model (brute-force reference)."""
    s = log_pi[q[0]] + log_b[0, q[0]]
    came = q[0]  # previous distinct node; == current node while none is known
    for d in range(1, len(q)):
        if q[d] == q[d - 1]:
            s += log_stay[q[d]]
        else:
            s += log_move[came, q[d - 1], q[d]]
            came = q[d - 1]
        s += log_b[d, q[d]]
    return s


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), n_states=st.integers(1, 4), n_slots=st.integers(1, 6), sparse=st.booleans())
def test_motion_second_order_equals_brute_force(seed, n_states, n_slots, sparse):
    """The context of a move is the last *different* node, however long the user dwelt."""
    rng = np.random.default_rng(seed)
    pi = rng.dirichlet(np.ones(n_states))
    stay = rng.uniform(0.2, 0.8, size=n_states)
    move = rng.dirichlet(np.ones(n_states), size=(n_states, n_states))
    if sparse and n_states > 1:
        move = np.where(rng.random(move.shape) < 0.3, 0.0, move)
    log_b = np.log(rng.random((n_slots, n_states)) + 1e-3)
    args = (log_safe(pi), np.log(stay), log_safe(move), log_b)
    path, logp = viterbi_motion_second_order(*args)
    ref = max(_motion_path_score(q, *args) for q in itertools.product(range(n_states), repeat=n_slots))
    assert logp == pytest.approx(ref)
    assert _motion_path_score(path, *args) == pytest.approx(ref)


def test_motion_second_order_remembers_direction_through_a_dwell():
    """A user that came 0 -> 1 and dwelt at 1 continues to 2 (straight) rather than back to 0,
    even when the observation of the move is ambiguous; the slot-literal model forgets."""
    n = 3
    stay = np.full(n, 0.6)
    move = np.zeros((n, n, n))
    move[:, 1, 0] = move[:, 1, 2] = 0.2  # no direction known: either way
    move[0, 1, 2], move[0, 1, 0] = 0.38, 0.02  # came from 0: go on to 2
    move[2, 1, 0], move[2, 1, 2] = 0.38, 0.02
    move[1, 0, 1] = move[1, 2, 1] = move[0, 0, 1] = move[2, 2, 1] = 0.4
    obs = np.log(np.array([[0.9, 0.05, 0.05]] + [[0.05, 0.9, 0.05]] * 4 + [[0.5, 0.05, 0.5]]))
    path, _ = viterbi_motion_second_order(np.log(np.full(n, 1 / 3)), np.log(stay), log_safe(move), obs)
    assert path.tolist() == [0, 1, 1, 1, 1, 2]
