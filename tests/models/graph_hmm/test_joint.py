"""Joint re-decoding of two users through a meeting: exact against brute force, never lowers
the model's log-likelihood, and puts a head-on crossing right where one-at-a-time decoding
bounced the users back."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.datasets.builtin import builtin_site
from onebit.models.graph_hmm.adaptive import joint_emission
from onebit.models.graph_hmm.eatg import hop_matrix, layout_eatg
from onebit.models.graph_hmm.joint import PairSpace, decode_pair, joint_table, meetings, redecode_meetings
from onebit.models.graph_hmm.likelihood import model_log_likelihood
from onebit.models.graph_hmm.window import second_order_tensor

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
        sc = (
            _user_score(*starts[0], p1, end[0])
            + _user_score(*starts[1], p2, end[1])
            + _emission(active, others, p1, p2)
        )
        best = max(best, sc)
    (got,) = decode_pair(
        SPACE, (SPACE.state(*starts[0]), SPACE.state(*starts[1])), active, others, [end], p_hit=0.9, p_false=0.05
    )
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
    truth = _rows(
        [
            [97, 97, 96, 96, 96, 95, 95, 95, 99, 99, 99, 111, 111, 111],
            [111, 111, 111, 99, 99, 99, 95, 95, 95, 96, 96, 96, 97, 97],
        ]
    )
    active = _crossing_activity([[EATG.nodes[j] for j in r] for r in truth])
    # one user at a time: both turn back at 95 -- each keeps its side
    bounced = np.where(np.arange(14)[None, :] < 7, truth, truth[::-1])
    assert model_log_likelihood(bounced, active, EATG, p_hit=0.9, p_false=0.05) < model_log_likelihood(
        truth, active, EATG, p_hit=0.9, p_false=0.05
    )
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


@settings(max_examples=30, deadline=None)
@given(data=st.data())
def test_compiled_pair_recursion_equals_the_numpy_reference(data):
    from onebit.models.graph_hmm.joint import pair_viterbi, pair_viterbi_reference

    w = data.draw(st.integers(1, 5))
    s = SPACE.x.size
    seed = data.draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    delta = np.where(rng.random((s, s)) < 0.05, rng.normal(size=(s, s)), -np.inf)
    g, h = rng.normal(size=(w, N)), rng.normal(size=(w, N))
    d1, p1 = pair_viterbi(delta, SPACE.pred, SPACE.lp, SPACE.x, g, h)
    d0, p0 = pair_viterbi_reference(delta, SPACE.pred, SPACE.lp, SPACE.x, g, h)
    np.testing.assert_allclose(d1, d0, rtol=0, atol=1e-9)
    ok = np.isfinite(d0)
    np.testing.assert_array_equal(p1[-1][ok], p0[-1][ok])


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_the_local_log_likelihood_difference_is_the_full_difference(data):
    """What a re-decoding compares (the pair's transitions up to where their tails settle, the
    window's emissions) differs between two labellings exactly as the full log L does."""
    from onebit.models.graph_hmm.joint import _local_log_likelihood, _settled
    from onebit.models.graph_hmm.likelihood import came_from

    d = data.draw(st.integers(8, 16))
    users = data.draw(st.integers(2, 3))
    paths = np.zeros((users, d), np.int64)
    for u in range(users):
        x = data.draw(st.integers(0, N - 1))
        for t in range(d):
            if data.draw(st.integers(0, 2)) == 0:
                mv = _moves(x)
                x = mv[data.draw(st.integers(0, len(mv) - 1))]
            paths[u, t] = x
    w0 = data.draw(st.integers(1, d - 3))
    w1 = data.draw(st.integers(w0, d - 2))
    y = paths.copy()
    for t in range(w0, w1 + 1):  # any re-decoded window for users 0 and 1 (jumps allowed: -inf both ways)
        y[0, t] = data.draw(st.integers(0, N - 1))
        y[1, t] = data.draw(st.integers(0, N - 1))
    if data.draw(st.booleans()):
        y[0, w1 + 1 :], y[1, w1 + 1 :] = paths[1, w1 + 1 :], paths[0, w1 + 1 :]
    active = np.array(data.draw(st.lists(st.booleans(), min_size=d * N, max_size=d * N))).reshape(d, N)
    ctx = came_from(paths[[0, 1], :w0])[:, -1]
    kw = dict(
        rows=(0, 1),
        a=w0 - 1,
        b=_settled(paths[[0, 1]], w1),
        w=(w0, w1),
        ctx0=ctx,
        active=active,
        n=N,
        log_a=LOG_A,
        p_hit=0.9,
        p_false=0.05,
    )
    full = [model_log_likelihood(p, active, EATG, p_hit=0.9, p_false=0.05) for p in (paths, y)]
    local = [_local_log_likelihood(p, **kw) for p in (paths, y)]
    if np.isfinite(full).all():
        assert np.isclose(local[1] - local[0], full[1] - full[0])
    else:
        assert np.isfinite(local).tolist() == np.isfinite(full).tolist()


def test_gains_add_up_to_the_full_log_likelihood_change_on_a_simulated_run():
    """On a real decoding (hallway, 3 users, seed 25): each kept re-decoding's gain is its exact
    change of the full log L, so they sum to log L(after) - log L(before) > 0."""
    from onebit.experiments.findinghumo_diagnose import simulate
    from onebit.models.graph_hmm.decoding import decode_motion
    from onebit.trackers.findinghumo.stage import FindingHumoConfig

    site, motion, _ = simulate(25)
    cfg = FindingHumoConfig()
    run = decode_motion("full2", {"motion": motion}, site, cfg)
    before = run.result.paths
    after, log = redecode_meetings(before, run.active, run.eatg, p_hit=cfg.p_hit, p_false=cfg.p_false)
    full = [
        model_log_likelihood(p, run.active, run.eatg, p_hit=cfg.p_hit, p_false=cfg.p_false) for p in (before, after)
    ]
    gains = sum(r["gain"] for r in log)
    assert gains > 0 and np.isclose(full[1] - full[0], gains), (full, gains)


@settings(max_examples=200, deadline=None)
@given(
    row=st.lists(st.integers(-1, 3), min_size=1, max_size=400).map(lambda r: np.repeat(np.array(r, np.int64), 3)),
    data=st.data(),
)
def test_bounded_context_and_change_searches_equal_the_whole_row(row, data):
    """The meeting's start context and its tails' first moves are found looking a growing way
    back / ahead (a meeting costs its dwell, not the run): the same as over the whole row."""
    from onebit.models.graph_hmm.joint import _context, _first_change
    from onebit.models.graph_hmm.likelihood import came_from

    t = data.draw(st.integers(0, row.size - 1))
    assert _context(row, t) == int(came_from(row[None, : t + 1])[0, -1])
    ch = np.flatnonzero(row[t + 1 :] != row[t:-1])
    assert _first_change(row, t) == (t + 1 + int(ch[0]) if ch.size else row.size - 1)


def test_a_meeting_after_an_exchange_of_tails_is_listed_on_the_new_paths():
    """Regression (issue #22, real CASAS logs: ``KeyError: (-1, -1)``): meetings were listed once on
    the initial paths; after an exchange of tails, a later meeting named a user who had left."""
    truth = _rows(
        [
            [97, 97, 96, 96, 96, 95, 95, 95, 99, 99, 99, 111, 111, 111],
            [111, 111, 111, 99, 99, 99, 95, 95, 95, 96, 96, 96, 97, 97],
        ]
    )
    d = 24
    x = np.full((3, d), -1, np.int64)
    x[:2, :14] = np.where(np.arange(14)[None, :] < 7, truth, truth[::-1])  # bounced at 95
    x[1, 14:] = IDX["111"]  # user 1 (on the bounced path) stays at 111; user 0 leaves after slot 13
    x[2, 15:] = [IDX[str(n)] for n in [117, 110, 111, 111, 111, 110, 117, 117, 117]]  # a third user meets user 1 there
    active = np.zeros((d, N), bool)
    active[:14] = _crossing_activity([[EATG.nodes[j] for j in r] for r in truth])
    for u in (1, 2):
        on = x[u, 14:] >= 0
        active[14 + np.flatnonzero(on), x[u, 14:][on]] = True
    assert (1, 2) in [m[:2] for m in meetings(x, EATG.hops, pad=4)]  # listed on the initial paths
    fixed, log = redecode_meetings(x, active, EATG, p_hit=0.9, p_false=0.05)
    assert log[0]["exchanged"]  # the crossing is walked through: user 1 now leaves after slot 13
    assert (fixed[1, 14:] == -1).all()
    later = [r for r in log if r["slot"] >= 14]
    assert later and all(r["users"] == (0, 2) for r in later)  # the later meeting is user 0's now
    before = model_log_likelihood(x, active, EATG, p_hit=0.9, p_false=0.05)
    assert model_log_likelihood(fixed, active, EATG, p_hit=0.9, p_false=0.05) >= before


# --- the meeting's neighbourhood (JointSpaces) and the entries without the N^3 tensor ---------


@settings(max_examples=30, deadline=None)
@given(
    n=st.integers(2, 12),
    seed=st.integers(0, 2**31 - 1),
    density=st.floats(0.0, 1.0),
)
def test_second_order_entries_equal_the_dense_tensor_bit_for_bit(n, seed, density):
    from onebit.models.graph_hmm.window import SecondOrderEntries

    rng = np.random.default_rng(seed)
    a1 = rng.random((n, n)) * (rng.random((n, n)) < density)  # rows without moves too
    a2 = rng.random((n, n)) * (rng.random((n, n)) < density)
    dense = second_order_tensor(a1, a2, np.arange(n))
    i = np.indices((n, n, n)).reshape(3, -1)
    got = SecondOrderEntries(a1, a2)[i[0], i[1], i[2]]
    np.testing.assert_array_equal(got, dense.ravel())
    entries = SecondOrderEntries(a1, a2)
    entries.CHUNK = 3  # z summed a few rows at a time: the same values
    np.testing.assert_array_equal(entries[i[0], i[1], i[2]], dense.ravel())


def test_a_subset_space_holds_the_whole_graphs_states_and_moves_inside_it():
    from onebit.models.graph_hmm.window import SecondOrderEntries

    nodes = np.flatnonzero(EATG.hops[IDX["95"]] <= 2)  # a neighbourhood of 95
    sub = PairSpace(EATG.hops, SecondOrderEntries(EATG.a1, EATG.a2), nodes)
    whole = SPACE
    where = np.array([whole.index[(x, c)] for x, c in zip(sub.x.tolist(), sub.c.tolist())])
    assert np.all(np.diff(where) > 0)  # the same order
    np.testing.assert_array_equal(whole.x[where], sub.x)
    for i, w in enumerate(where):  # each state's predecessors inside the subset, in the whole graph's order
        keep = [k for k in range(whole.pred.shape[1]) if np.isfinite(whole.lp[w, k]) or k == 0]
        wp = [(int(whole.pred[w, k]), whole.lp[w, k]) for k in keep if whole.x[whole.pred[w, k]] in set(nodes.tolist())]
        sp = [(int(where[sub.pred[i, k]]), sub.lp[i, k]) for k in range(sub.pred.shape[1]) if np.isfinite(sub.lp[i, k])]
        assert [p for p, v in wp if np.isfinite(v)] == [p for p, _ in sp]
        np.testing.assert_array_equal([v for _, v in wp if np.isfinite(v)], [v for _, v in sp])
    np.testing.assert_array_equal(sub.nodes[sub.local], sub.x)


def test_the_paper_neighbourhood_holds_the_pair_and_its_chained_activations_not_far_ones():
    from onebit.models.graph_hmm.joint import JointSpaces

    spaces = JointSpaces(EATG, reach=2)
    pair = _rows([[95, 95, 99], [96, 95, 95]])
    active = np.zeros((2, N), bool)
    far = int(np.argmax(EATG.hops[IDX["95"]]))  # the node farthest from the meeting
    near = int(np.flatnonzero(EATG.hops[IDX["99"]] == 2)[0])
    active[0, far] = active[1, near] = True
    got = set(np.flatnonzero(spaces.neighbourhood(pair, active)).tolist())
    p = {IDX["95"], IDX["96"], IDX["99"]}
    within = lambda src, r: {int(j) for s in src for j in np.flatnonzero(EATG.hops[s] <= r)}  # noqa: E731
    assert got == within(p | {near}, 2)
    assert far not in got and EATG.hops[IDX["95"], far] > 4


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_the_reachable_set_holds_every_path_from_the_starts_into_the_tails(data):
    """Every node of every walk of W slots (a hop at most per slot) from a start node into a
    tail is in the exact set; a node the set leaves out is on no such walk."""
    from onebit.models.graph_hmm.joint import JointSpaces

    spaces = JointSpaces(EATG)
    w = data.draw(st.integers(1, 6))
    starts = (data.draw(st.integers(0, N - 1)), data.draw(st.integers(0, N - 1)))
    tails = (data.draw(st.integers(-1, N - 1)), data.draw(st.integers(-1, N - 1)))
    ok = spaces.reachable(starts, tails, w)
    h = EATG.hops
    for x in range(N):  # by the definition: some user, some pairing's tail (or none)
        ys = [y for y in tails if y >= 0]
        on_walk = any(
            any(h[s, x] <= t + 1 and (y < 0 or h[x, y] <= w - t) for t in range(w))
            for s in starts
            for y in ([*ys, -1] if len(ys) < 2 else ys)
        )
        assert bool(ok[x]) == on_walk, (x, starts, tails, w)


def test_a_meeting_decoded_on_what_its_users_reach_is_decoded_as_on_the_whole_graph():
    """Seed 25 of the hallway (3 users): every meeting re-decoded on the nodes its users can
    reach gives the same paths and records as on every node; with a silent wing of 100 more
    nodes chained to the hallway's last node the spaces hold what the pairs can reach (a part
    of the wing on long meetings) and the paths are the same."""
    from onebit.experiments.findinghumo_diagnose import simulate
    from onebit.models.graph_hmm.decoding import decode_motion
    from onebit.models.graph_hmm.eatg import Eatg
    from onebit.models.graph_hmm.joint import JointSpaces
    from onebit.trackers.findinghumo.stage import FindingHumoConfig

    site, motion, _ = simulate(25)
    cfg = FindingHumoConfig()
    run = decode_motion("full2", {"motion": motion}, site, cfg)
    kw = dict(p_hit=cfg.p_hit, p_false=cfg.p_false)
    whole, log0 = redecode_meetings(
        run.result.paths, run.active, run.eatg, spaces=JointSpaces(run.eatg, whole=True), **kw
    )
    local, log2 = redecode_meetings(run.result.paths, run.active, run.eatg, **kw)
    np.testing.assert_array_equal(whole, local)
    assert [(r["slot"], r["users"], r["exchanged"]) for r in log0] == [
        (r["slot"], r["users"], r["exchanged"]) for r in log2
    ]
    assert np.allclose([r["gain"] for r in log0], [r["gain"] for r in log2])
    # the same run on a graph grown by 100 silent nodes chained to the last node
    e, n, extra = run.eatg, len(run.eatg.nodes), 100
    m = n + extra
    hops = np.full((m, m), 10**6, dtype=e.hops.dtype)
    hops[:n, :n] = e.hops
    a1 = np.zeros((m, m))
    a1[:n, :n] = e.a1
    a2 = np.zeros((m, m))
    a2[:n, :n] = e.a2
    chain = [n - 1, *range(n, m)]
    for a, b in zip(chain, chain[1:]):  # silent: no moves learned on the wing (its rows stay)
        hops[a, b] = hops[b, a] = 1
    import networkx as nx

    g = nx.from_numpy_array((hops == 1).astype(int))
    hops = np.array(nx.floyd_warshall_numpy(g), dtype=e.hops.dtype)
    grown = Eatg(nodes=(*e.nodes, *[f"W{k}" for k in range(extra)]), hops=hops, a1=a1, a2=a2)
    active = np.zeros((run.active.shape[0], m), bool)
    active[:, :n] = run.active
    spaces = JointSpaces(grown)
    big, _ = redecode_meetings(run.result.paths, active, grown, spaces=spaces, **kw)
    sizes = [sp.nodes.size for sp in spaces._cache.values()]
    assert max(sizes) < m // 3  # what the pairs can reach in their windows, not the building
    np.testing.assert_array_equal(big, local)
