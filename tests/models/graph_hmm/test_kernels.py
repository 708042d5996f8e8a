"""Compiled FindingHuMo kernels against their plain numpy references on random inputs:
equal paths, equal scores (to 1e-9), equal decoded runs."""

from __future__ import annotations

import itertools

import networkx as nx
import numpy as np
import pytest

from onebit.models.graph_hmm import ascent, kernels, viterbi
from onebit.models.graph_hmm.adaptive import DecoderParams, decode_run, decode_users, emission_gain
from onebit.models.graph_hmm.decoding import cap_users
from onebit.models.graph_hmm.eatg import hop_matrix, layout_eatg, trained_eatg
from onebit.models.graph_hmm.window import window_transitions


def _log_model(rng, s, d, *, sparse):
    """Random log-space model; ``sparse`` puts -inf in about a third of the transitions and
    emissions, as the restricted models of the decoder do."""
    log_pi = np.log(rng.dirichlet(np.ones(s)))
    log_a = np.log(rng.dirichlet(np.ones(s), size=s))
    log_b = np.log(rng.random((d, s)) + 1e-3)
    if sparse:
        log_a[rng.random((s, s)) < 0.33] = -np.inf
        log_b[rng.random((d, s)) < 0.33] = -np.inf
        log_pi[rng.random(s) < 0.33] = -np.inf
    return log_pi, log_a, log_b


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("s", [1, 2, 5, 17])
def test_first_order_kernel_equals_reference(seed, s):
    rng = np.random.default_rng(seed)
    for d in (0, 1, 2, 9):
        args = _log_model(rng, s, d, sparse=seed % 2 == 1)
        p_ref, lp_ref = viterbi.viterbi_first_order(*args)
        p, lp = kernels.viterbi_first_order(*args)
        np.testing.assert_array_equal(p, p_ref)
        assert lp == pytest.approx(lp_ref, rel=1e-9, abs=1e-9) or (np.isneginf(lp) and np.isneginf(lp_ref))


def test_first_order_kernel_ties_take_the_first_state():
    path, lp = kernels.viterbi_first_order(np.zeros(4), np.zeros((4, 4)), np.zeros((6, 4)))
    assert path.tolist() == [0] * 6 and lp == 0.0
    path, _ = kernels.viterbi_first_order(np.full(3, -np.inf), np.zeros((3, 3)), np.zeros((2, 3)))
    assert (
        path.tolist()
        == viterbi.viterbi_first_order(np.full(3, -np.inf), np.zeros((3, 3)), np.zeros((2, 3)))[0].tolist()
    )


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("s", [1, 3, 8])
def test_second_order_kernels_equal_reference(seed, s):
    rng = np.random.default_rng(100 + seed)
    for d in (0, 1, 2, 3, 8):
        log_pi, log_a1, log_b = _log_model(rng, s, d, sparse=seed % 2 == 0)
        log_a2 = np.log(rng.dirichlet(np.ones(s), size=(s, s)))
        if seed % 2 == 0:
            log_a2[rng.random((s, s, s)) < 0.3] = -np.inf
        p_ref, lp_ref = viterbi.viterbi_second_order(log_pi, log_a1, log_a2, log_b)
        p, lp = kernels.viterbi_second_order(log_pi, log_a1, log_a2, log_b)
        np.testing.assert_array_equal(p, p_ref)
        assert lp == lp_ref or abs(lp - lp_ref) <= 1e-9 * max(1.0, abs(lp_ref))
        log_stay = np.diag(log_a1).copy()
        p_ref, lp_ref = viterbi.viterbi_motion_second_order(log_pi, log_stay, log_a2, log_b)
        p, lp = kernels.viterbi_motion_second_order(log_pi, log_stay, log_a2, log_b)
        np.testing.assert_array_equal(p, p_ref)
        assert lp == lp_ref or abs(lp - lp_ref) <= 1e-9 * max(1.0, abs(lp_ref))


def _random_graph(rng, n):
    """A connected random corridor graph of ``n`` nodes (a tree plus a few chords)."""
    g = (
        nx.random_labeled_tree(n, seed=int(rng.integers(1 << 30)))
        if hasattr(nx, "random_labeled_tree")
        else nx.random_tree(n, seed=int(rng.integers(1 << 30)))
    )
    for _ in range(n // 4):
        a, b = rng.integers(0, n, 2)
        if a != b:
            g.add_edge(int(a), int(b))
    nodes = tuple(str(i) for i in range(n))
    edges = tuple((str(a), str(b)) for a, b in g.edges)
    return nodes, edges


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("order", [1, 2])
def test_coordinate_ascent_kernel_equals_reference(seed, order):
    """decode_users (all restarts of the coordinate ascent) with the kernel and with the numpy
    reference, on random windows, users, prefixes, late starts and entry nodes."""
    rng = np.random.default_rng(seed)
    nodes, edges = _random_graph(rng, 12)
    hops = hop_matrix(nodes, edges)
    act = rng.random((60, len(nodes))) < 0.2
    eatg = trained_eatg(act, nodes, hops, horizon=5) if seed % 2 else layout_eatg(nodes, hops)
    for trial in range(8):
        k = int(rng.integers(1, 5))
        L = int(rng.integers(1, 7))
        states = np.sort(rng.choice(len(nodes), size=int(rng.integers(2, len(nodes) + 1)), replace=False))
        obs = rng.random((L, len(nodes))) < 0.3
        prefixes = [[int(v) for v in rng.choice(states, size=int(rng.integers(0, 3)), replace=False)] for _ in range(k)]
        starts = [int(rng.integers(0, L + 1)) if not p else 0 for p in prefixes]
        entries = [int(rng.choice(states)) if rng.random() < 0.5 else -1 for _ in range(k)]
        for restarts, sweeps in ((6, 3), (2, 1), (1, 2)):
            kw = dict(order=order, eatg=eatg)
            ref = decode_users(
                obs,
                states,
                prefixes,
                starts,
                entries,
                params=DecoderParams(restarts=restarts, sweeps=sweeps, compiled=False),
                **kw,
            )
            new = decode_users(
                obs, states, prefixes, starts, entries, params=DecoderParams(restarts=restarts, sweeps=sweeps), **kw
            )
            np.testing.assert_array_equal(new, ref, err_msg=f"trial {trial}, k={k}, L={L}, restarts={restarts}")


@pytest.mark.parametrize("mode", ["adaptive", "full1", "full2"])
def test_decode_run_compiled_equals_reference(mode):
    rng = np.random.default_rng(3)
    nodes, edges = _random_graph(rng, 16)
    hops = hop_matrix(nodes, edges)
    eatg = layout_eatg(nodes, hops)
    pos = rng.integers(0, len(nodes), 3)
    act = np.zeros((50, len(nodes)), bool)
    for t in range(50):  # three random walkers with misses and false alarms
        for u in range(3):
            if rng.random() < 0.4:
                nb = np.flatnonzero(hops[pos[u]] == 1)
                pos[u] = rng.choice(nb) if nb.size else pos[u]
        act[t, pos] = rng.random(3) < 0.9
    act |= rng.random(act.shape) < 0.02
    sigs = [(0, int(np.flatnonzero(hops[0] == 1)[0]))]
    ref = decode_run(act, eatg, signatures=sigs, params=DecoderParams(mode=mode, compiled=False))
    new = decode_run(act, eatg, signatures=sigs, params=DecoderParams(mode=mode))
    np.testing.assert_array_equal(new.paths, ref.paths)
    assert new.windows == ref.windows


def test_emission_table_matches_the_reference_gain():
    from onebit.models.graph_hmm.adaptive import emission_gain, joint_emission

    table = ascent.emission_tables(5, 0.9, 0.05, emission_gain)
    c = np.arange(7)[None, :]
    on = np.ones_like(c, bool)
    np.testing.assert_array_equal(table[0], emission_gain(on, c, 0.9, 0.05)[0])
    np.testing.assert_array_equal(table[1], emission_gain(~on, c, 0.9, 0.05)[0])
    for cc in range(7):
        claims = np.array([[cc]])
        assert table[2, cc] == joint_emission(np.array([[True]]), claims, 0.9, 0.05)
        assert table[3, cc] == joint_emission(np.array([[False]]), claims, 0.9, 0.05)


@pytest.mark.parametrize("seed", range(8))
def test_sparse_motion_kernel_equals_the_dense_one(seed):
    """The second-order Viterbi that keeps only the reachable (previous, current) pairs and the
    moves the tensor allows gives the dense kernel's path and score, bit for bit: on tensors of
    random sensor graphs (as the decoder builds them) and on random dense and sparse tensors,
    with random, clamped (a known last node) and all-equal emissions (ties)."""
    rng = np.random.default_rng(200 + seed)
    nodes, edges = _random_graph(rng, 14)
    hops = hop_matrix(nodes, edges)
    act = rng.random((80, len(nodes))) < 0.2
    eatg = trained_eatg(act, nodes, hops, horizon=5) if seed % 2 else layout_eatg(nodes, hops)
    for trial in range(6):
        if trial < 4:
            states = np.arange(len(nodes)) if trial == 0 else np.sort(rng.choice(len(nodes), 8, replace=False))
            log_a1, log_a2, _ = window_transitions(eatg, states, 2)
            s = len(states)
        else:
            s = 6
            log_a1 = np.log(rng.dirichlet(np.ones(s), size=s))
            log_a2 = np.log(rng.dirichlet(np.ones(s), size=(s, s)))
            log_a2[rng.random((s, s, s)) < 0.5 * (trial - 4)] = -np.inf
        log_stay = np.ascontiguousarray(np.diag(log_a1))
        for d in (1, 2, 5, 9):
            log_pi = np.log(rng.dirichlet(np.ones(s)))
            log_pi[rng.random(s) < 0.3] = -np.inf
            log_b = np.log(rng.random((d, s)) + 1e-3)
            log_b[rng.random((d, s)) < 0.2] = -np.inf
            k_ptr, k_idx = kernels.move_support(log_a2)
            clamped = log_b.copy()  # the decoder's prefix: the user's last node known
            clamped[0] = -np.inf
            clamped[0, rng.integers(s)] = 0.0
            flat = np.zeros_like(log_b)  # every emission equal: ties everywhere
            for pi, b in ((log_pi, log_b), (np.zeros(s), clamped), (np.zeros(s), flat)):
                p0, lp0 = kernels._viterbi_motion2(pi, log_stay, log_a2, b)
                p1, lp1 = kernels._viterbi_motion2_sparse(pi, log_stay, log_a2, b, k_ptr, k_idx)
                np.testing.assert_array_equal(p1, p0)
                assert lp1 == lp0 or (np.isneginf(lp0) and np.isneginf(lp1))
    # on a sensor graph the support is the neighbourhood, not the graph
    k_ptr, _ = kernels.move_support(window_transitions(eatg, np.arange(len(nodes)), 2)[1])
    assert np.diff(k_ptr).max() <= (hops == 1).sum(axis=1).max() + 1


@pytest.mark.parametrize("seed", range(10))
def test_cap_users_kernel_equals_reference(seed):
    """Random decoded paths (users appearing, vanishing, sharing nodes) on random graphs:
    the compiled cap keeps the same users under the same identities as the numpy one."""
    rng = np.random.default_rng(300 + seed)
    nodes, edges = _random_graph(rng, 9)
    hops = hop_matrix(nodes, edges)
    n_users, n_slots = int(rng.integers(2, 9)), int(rng.integers(1, 60))
    paths = rng.integers(0, len(nodes), (n_users, n_slots))
    paths[rng.random(paths.shape) < 0.35] = -1
    active = rng.random((n_slots, len(nodes))) < 0.3
    for cap in range(1, n_users + 1):
        ref = cap_users(paths, active, hops, cap, compiled=False)
        np.testing.assert_array_equal(cap_users(paths, active, hops, cap), ref)


def test_sparse_motion_kernel_breaks_ties_as_the_dense_one():
    """Every move equally likely and better than staying: every previous node ties, and both
    kernels take the smallest (the path depends on it)."""
    s = 5
    log_move = np.zeros((s, s, s))
    log_stay = np.full(s, -1.0)
    for b in (np.zeros((6, s)), np.where(np.eye(s, dtype=bool)[[3, 1, 4, 0, 2, 2]], 0.0, -0.5)):
        k_ptr, k_idx = kernels.move_support(log_move)
        p0, lp0 = kernels._viterbi_motion2(np.zeros(s), log_stay, log_move, b)
        p1, lp1 = kernels._viterbi_motion2_sparse(np.zeros(s), log_stay, log_move, b, k_ptr, k_idx)
        np.testing.assert_array_equal(p1, p0)
        assert lp1 == lp0


def _brute_force(on, table, prefix, entry, order, log_a1, log_a2):
    """The best score over every path of one user (no other user) by enumeration: the window's
    states at each slot after the clamped ``prefix``; first order ``a1``, second order the
    distinct-node context (:func:`viterbi.viterbi_motion_second_order`)."""
    n_slots, s = on.shape
    paths = np.array(list(itertools.product(range(s), repeat=n_slots)), dtype=np.int64).reshape(-1, n_slots)
    full = np.hstack([np.tile(np.asarray(prefix, np.int64), (len(paths), 1)), paths])
    score = np.zeros(len(paths))
    if not prefix and entry >= 0:
        score += np.where(full[:, 0] == entry, 0.0, -np.inf)
    rows = np.arange(n_slots)
    score += np.where(on[rows[None, :], paths], table[0, 0], table[1, 0]).sum(axis=1)
    log_stay = np.diag(log_a1)
    came = full[:, 0].copy()  # the last node different from the current one (itself: none yet)
    with np.errstate(invalid="ignore"):
        for d in range(1, full.shape[1]):
            a, b = full[:, d - 1], full[:, d]
            if order == 1:
                score = score + log_a1[a, b]
            else:
                score = score + np.where(a == b, log_stay[b], log_a2[came, a, b])
                came = np.where(a == b, came, a)
    return score.max(), dict(zip(map(tuple, paths.tolist()), score))


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("order", [1, 2])
def test_local_decodes_equal_brute_force(seed, order):
    """One user decoded on the states it can reach (ascent.coordinate_ascent) scores the best
    of every path, enumerated: with a known last node, an entry node or anywhere, on a graph
    larger than the window's reach; and with activations that repel (the certificate of a
    user that may start anywhere fails, and it is decoded again on every state)."""
    rng = np.random.default_rng(400 + seed)
    nodes, edges = _random_graph(rng, 20)
    hops = hop_matrix(nodes, edges)
    act = rng.random((60, len(nodes))) < 0.2
    eatg = trained_eatg(act, nodes, hops, horizon=5) if seed % 2 else layout_eatg(nodes, hops)
    states = np.arange(len(nodes))
    log_a1, log_a2, support = window_transitions(eatg, states, order)
    table = ascent.emission_tables(1, 0.9, 0.05, emission_gain)
    repel = table.copy()
    repel[0] = table[1, 0] - 3.0
    local = redone = 0
    for trial in range(12):
        n_slots = int(rng.integers(1, 4))
        on = rng.random((n_slots, len(nodes))) < 0.06
        kind = trial % 3
        last = int(rng.integers(len(nodes)))
        came = [int(rng.choice(np.flatnonzero(hops[last] == 1)))] if rng.random() < 0.5 else []
        prefix = came + [last] if kind == 0 else []
        entry = int(rng.integers(len(nodes))) if kind == 1 else -1
        for tab in (table, repel) if kind == 2 else (table,):
            before = ascent.DECODE_STATS.copy()
            best, _ = ascent.coordinate_ascent(
                on,
                [prefix],
                [0],
                [entry],
                [[0]],
                order=order,
                log_a1=log_a1,
                log_a2=log_a2,
                table=tab,
                sweeps=1,
                support=support,
            )
            stats = ascent.DECODE_STATS - before
            top, scores = _brute_force(on, tab, prefix, entry, order, log_a1, log_a2)
            got = scores[tuple(best[0].tolist())]
            assert got == pytest.approx(top, rel=1e-12, abs=1e-12), f"trial {trial}, kind {kind}"
            local += int(stats[0] - stats[1])
            if tab is repel and on.any():  # the local best cannot beat the quiet paths: redone on every state
                assert stats[1] == 1
                redone += int(stats[2])
    assert local > 0 and redone > 0  # decodes ran on part of the graph, and certificates failed


@pytest.mark.parametrize("order", [1, 2])
def test_local_decodes_equal_the_all_state_reference_on_a_large_graph(order):
    """Several users on windows of a 48-node graph (the window's reach is a small part of it):
    the compiled ascent, whose decodes run on the states each user can reach, gives the numpy
    reference's paths (every user decoded on every state), and most of its decodes are local."""
    rng = np.random.default_rng(500 + order)
    nodes, edges = _random_graph(rng, 48)
    hops = hop_matrix(nodes, edges)
    act = rng.random((120, len(nodes))) < 0.05
    eatg = trained_eatg(act, nodes, hops, horizon=5)
    states = np.arange(len(nodes))
    transitions = window_transitions(eatg, states, order)
    before = ascent.DECODE_STATS.copy()
    for trial in range(10):
        k = int(rng.integers(1, 4))
        n_slots = int(rng.integers(2, 6))
        obs = rng.random((n_slots, len(nodes))) < 0.04
        prefixes, starts, entries = [], [], []
        for _ in range(k):
            last = int(rng.integers(len(nodes)))
            kind = rng.integers(3)
            prefixes.append(([int(rng.choice(np.flatnonzero(hops[last] == 1)))] + [last]) if kind == 0 else [])
            starts.append(0 if kind == 0 else int(rng.integers(0, n_slots)))
            entries.append(int(rng.integers(len(nodes))) if kind == 1 else -1)
        for sweeps in (1, 3):
            kw = dict(order=order, eatg=eatg, transitions=transitions)
            ref = decode_users(
                obs, states, prefixes, starts, entries, params=DecoderParams(sweeps=sweeps, compiled=False), **kw
            )
            new = decode_users(obs, states, prefixes, starts, entries, params=DecoderParams(sweeps=sweeps), **kw)
            np.testing.assert_array_equal(new, ref, err_msg=f"trial {trial}, k={k}, sweeps={sweeps}")
    stats = ascent.DECODE_STATS - before
    assert stats[1] < stats[0] / 2  # most decodes on the user's reach, not on the 48 states


@pytest.mark.parametrize("seed", range(6))
def test_sparse_second_order_support_equals_the_dense_tensor(seed):
    """The second-order tensor built sparse (per node: its contexts x its next nodes, never the
    S^3 array) holds the dense tensor's values bit for bit, the same moves, contexts and bound;
    and a full-state hmm2 run on it decodes the numpy reference's paths (dense tensor)."""
    rng = np.random.default_rng(600 + seed)
    nodes, edges = _random_graph(rng, 15)
    hops = hop_matrix(nodes, edges)
    act = rng.random((80, len(nodes))) < 0.15
    eatg = trained_eatg(act, nodes, hops, horizon=5) if seed % 2 else layout_eatg(nodes, hops)
    for states in (np.arange(len(nodes)), np.sort(rng.choice(len(nodes), 9, replace=False))):
        log_a1, log_a2, dense = window_transitions(eatg, states, 2)
        a1_sparse, none, sparse = window_transitions(eatg, states, 2, dense=False)
        assert none is None
        np.testing.assert_array_equal(a1_sparse, log_a1)
        for a, b in zip(dense[:4], sparse[:4]):
            np.testing.assert_array_equal(a, b)
        assert dense[4] == sparse[4]
        for a, b in zip(dense[5], sparse[5]):
            np.testing.assert_array_equal(a, b)  # values bit for bit (-inf included)
        np.testing.assert_array_equal(dense[6], sparse[6])  # the stays
        p_ptr, p_idx, blk_ptr, k_ptr, vals, _, _ = sparse[5]
        k_idx = sparse[1]
        for j in range(len(states)):  # every stored value is the dense tensor's entry
            ks = k_idx[k_ptr[j] : k_ptr[j + 1]]
            block = vals[blk_ptr[j] : blk_ptr[j + 1]].reshape(-1, len(ks))
            np.testing.assert_array_equal(block, log_a2[np.ix_(p_idx[p_ptr[j] : p_ptr[j + 1]], [j], ks)][:, 0, :])
    pos = rng.integers(0, len(nodes), 2)
    walk = np.zeros((40, len(nodes)), bool)
    for t in range(40):
        for u in range(2):
            if rng.random() < 0.4:
                pos[u] = rng.choice(np.flatnonzero(hops[pos[u]] == 1))
        walk[t, pos] = True
    ref = decode_run(walk, eatg, params=DecoderParams(mode="full2", compiled=False))
    new = decode_run(walk, eatg, params=DecoderParams(mode="full2"))
    np.testing.assert_array_equal(new.paths, ref.paths)
