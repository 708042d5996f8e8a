"""The residents decoder against brute force: every attribution of short event sequences."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.trackers.residents.decode import attribution_cost, decode_events, decode_exhaustive, tracks_from_pred
from onebit.trackers.residents.model import birth_cost, move_cost, node_distances


def _case(seed: int, n: int, nodes: int):
    """Random events on random sensor positions, the model's costs (eq. 2-4)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 8, size=(nodes, 2))
    ids = [f"s{k}" for k in range(nodes)]
    D = node_distances(ids, dict(zip(ids, map(tuple, xy))), [], how="straight")
    t = np.cumsum(rng.uniform(0.2, 20.0, size=n))
    node = rng.integers(0, nodes, size=n)
    entry = rng.random(nodes) < 0.3
    birth = birth_cost(t, entry[node], t_first=float(t[0]), start_window_s=10.0, door=2.0, inside=6.0)
    kw = dict(l0=1.0, v=float(rng.choice([0.0, 0.7])), l_max=3.0, w=float(rng.choice([0.0, 0.5])), tau=5.0)

    def row(J, i):
        return move_cost(D, node[J], np.full(len(J), node[i]), t[i] - t[J], **kw)

    def one(j, i):
        return float(row(np.array([j]), i)[0])

    return row, one, birth


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 10_000), n=st.integers(1, 7), people=st.integers(1, 3), stay=st.sampled_from([None, 0.6, 0.9])
)
def test_exact_decoder_finds_the_brute_force_minimum(seed, n, people, stay):
    row, one, birth = _case(seed, n, 5)
    exact = decode_events(row, birth, people=people, beam=None, stay=stay)
    brute = decode_exhaustive(one, birth, people=people, stay=stay)
    assert exact.cost == pytest.approx(brute.cost, abs=1e-9)
    # the attribution it reads back costs what it says, and respects the bound
    assert attribution_cost(exact.pred, one, birth, stay=stay) == pytest.approx(exact.cost, abs=1e-9)
    assert 1 <= exact.people <= people
    assert np.array_equal(exact.track, tracks_from_pred(exact.pred))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 7), beam=st.integers(1, 4))
def test_a_narrow_beam_never_beats_the_exact_minimum_and_reads_back_its_own_cost(seed, n, beam):
    row, one, birth = _case(seed, n, 4)
    exact = decode_events(row, birth, people=2, beam=None)
    narrow = decode_events(row, birth, people=2, beam=beam)
    assert narrow.cost >= exact.cost - 1e-9
    assert attribution_cost(narrow.pred, one, birth) == pytest.approx(narrow.cost, abs=1e-9)
    assert narrow.states.max() <= beam


def test_a_wide_enough_beam_is_exact():
    row, one, birth = _case(3, 9, 5)
    exact = decode_events(row, birth, people=2, beam=None)
    # two people: at most i + 1 states after event i, so a beam of n is the exact search
    assert exact.states.max() <= 9
    wide = decode_events(row, birth, people=2, beam=9)
    assert wide.cost == pytest.approx(exact.cost) and np.array_equal(wide.pred, exact.pred)


def test_two_people_far_apart_are_two_tracks_and_one_person_is_one():
    ids = ["a", "b", "c", "d"]
    D = node_distances(ids, {"a": (0, 0), "b": (1, 0), "c": (20, 0), "d": (21, 0)}, [], how="straight")
    node = np.array([0, 2, 1, 3, 0, 2, 1, 3])  # alternating between two places 20 m apart
    t = np.arange(8, dtype=float)
    birth = np.full(8, 5.0)

    def row(J, i):
        return move_cost(D, node[J], np.full(len(J), node[i]), t[i] - t[J], l0=1.0, v=0.0, l_max=1.0, w=0.0, tau=1.0)

    res = decode_events(row, birth, people=4, beam=None)
    assert res.people == 2
    assert np.array_equal(res.track, [0, 1, 0, 1, 0, 1, 0, 1])
    capped = decode_events(row, birth, people=1, beam=None)  # the bound is the decoder's own
    assert capped.people == 1 and np.all(capped.track == 0)
    one_place = np.array([0, 1, 0, 1, 0, 1, 0, 1])

    def row1(J, i):
        return move_cost(
            D, one_place[J], np.full(len(J), one_place[i]), t[i] - t[J], l0=1.0, v=0.0, l_max=1.0, w=0.0, tau=1.0
        )

    # one person pacing between two sensors 1 m apart: without the who-fires term (5) two
    # people parked at the two sensors explain it more cheaply (the Occam factor is missing);
    # with it, one person
    assert decode_events(row1, birth, people=4, beam=None).people == 2
    assert decode_events(row1, birth, people=4, beam=None, stay=0.7).people == 1
    # and the two places 20 m apart stay two people with it
    assert decode_events(row, birth, people=4, beam=None, stay=0.7).people == 2


def test_no_events_no_people_and_a_bound_below_one_is_refused():
    res = decode_events(lambda J, i: np.zeros(len(J)), np.zeros(0), people=2)
    assert res.people == 0 and res.pred.size == 0
    with pytest.raises(ValueError, match="people = 0"):
        decode_events(lambda J, i: np.zeros(len(J)), np.zeros(3), people=0)


def test_graph_distances_follow_the_edges_and_fall_back_to_straight_lines():
    pos = {"a": (0.0, 0.0), "b": (3.0, 0.0), "c": (3.0, 4.0), "z": (0.0, 1.0)}
    D = node_distances(list(pos), pos, [("a", "b"), ("b", "c")], how="graph")
    assert D[0, 2] == pytest.approx(7.0)  # around the corner, not the 5 m diagonal
    assert D[0, 3] == pytest.approx(1.0)  # z is on no edge: the straight line
    assert np.allclose(D, D.T)
