"""Habits: the interval orientation against all 2^K orientations, hard EM undoing planted swaps."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.trackers.residents.decode import preds_from_tracks, tracks_from_pred
from onebit.trackers.residents.habits import last_nodes, meeting_cuts, objective, orient, orient_exhaustive, reorient


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 12), switch=st.sampled_from([0.0, 0.7, 3.0]))
def test_orientation_is_the_brute_force_minimum(seed, n, switch):
    rng = np.random.default_rng(seed)
    cost = rng.exponential(1.0, size=(n, 2))
    cut = rng.random(n) < 0.4
    cut[0] = False
    a, best = orient(cost, cut, switch=switch)
    _, brute = orient_exhaustive(cost, cut, switch=switch)
    assert best == pytest.approx(brute, abs=1e-9)
    # the orientation it returns changes only at cuts and costs what it says
    change = np.flatnonzero(a[1:] != a[:-1]) + 1
    assert cut[change].all()
    total = cost[np.arange(n), a].sum() + switch * len(change)
    assert total == pytest.approx(best, abs=1e-9)


def test_no_cut_keeps_the_decoder_and_a_free_interval_takes_its_likelier_side():
    cost = np.array([[0.0, 9.0], [5.0, 0.0], [1.0, 0.0]])  # kept 6, swapped 9
    assert orient(cost, np.array([False, False, False]))[0].tolist() == [0, 0, 0]
    assert orient(cost, np.array([False, True, False]))[0].tolist() == [0, 1, 1]
    # a swap cost larger than what the flip gains keeps it
    assert orient(cost, np.array([False, True, False]), switch=20.0)[0].tolist() == [0, 0, 0]


def _two_habits(seed: int, n: int = 400):
    """Two people with distinct sensor habits (person 0 mostly nodes 0-4, person 1 nodes 5-9),
    their events interleaved; cuts at random; the decoded track = the truth with the names
    exchanged in a random half of the intervals."""
    rng = np.random.default_rng(seed)
    truth = rng.integers(0, 2, size=n)
    node = np.where(rng.random(n) < 0.85, rng.integers(0, 5, size=n) + 5 * truth, rng.integers(0, 10, size=n))
    cut = rng.random(n) < 0.08
    cut[0] = False
    interval = np.cumsum(cut)
    swapped = rng.integers(0, 2, size=interval[-1] + 1)
    return node, truth, truth ^ swapped[interval], cut, interval


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_hard_em_undoes_swaps_between_cuts_without_labels(seed):
    node, truth, decoded, cut, interval = _two_habits(seed)
    z = reorient(node, decoded, cut, 10, alpha=1.0, restarts=4)
    if np.mean(z == truth) < 0.5:  # the names are arbitrary
        z_true = 1 - z
    else:
        z_true = z
    sizes = np.bincount(interval)
    wrong = {int(k) for k in interval[z_true != truth]}
    assert all(sizes[k] < 5 for k in wrong)  # every interval of 5 events or more oriented right
    assert np.mean(z_true == truth) >= 0.98
    assert np.mean(decoded == truth) < 0.9  # and the decoder's answer was not
    # inside an interval the two fragments stay two people: the flip is one per interval
    flip = z ^ decoded
    assert all(len(np.unique(flip[interval == k])) == 1 for k in np.unique(interval))
    # the first event keeps the decoder's name
    assert z[0] == decoded[0]


def test_hard_em_never_ends_below_the_decoders_orientation():
    rng = np.random.default_rng(5)
    for _ in range(10):
        n = 60
        node = rng.integers(0, 6, size=n)
        track = rng.integers(0, 2, size=n)
        cut = rng.random(n) < 0.2
        cut[0] = False
        z = reorient(node, track, cut, 6, alpha=0.5, switch=1.0, restarts=2)
        kw = dict(alpha=0.5, switch=1.0, cut=cut)
        assert (
            objective(node, track, z ^ track, 6, **kw) >= objective(node, track, np.zeros(n, np.int64), 6, **kw) - 1e-9
        )


def test_cuts_where_the_two_people_are_together():
    # a line of sensors 1 m apart; person 0 walks 0 -> 3, person 1 walks 6 -> 4
    D = np.abs(np.subtract.outer(np.arange(7.0), np.arange(7.0)))
    node = np.array([0, 6, 1, 5, 2, 4, 3, 4])
    track = np.array([0, 1, 0, 1, 0, 1, 0, 1])
    u = last_nodes(node, track)
    assert u[:, 6].tolist() == [2, 4]
    cut = meeting_cuts(node, track, D, meet=2.0)
    # before event i the two are at u[:, i]: together (<= 2 m) from event 6 on (2 and 4, then 3 and 4)
    assert np.flatnonzero(cut).tolist() == [6, 7]
    assert not meeting_cuts(node, track, D, meet=0.5).any()


def test_predecessors_from_tracks_round_trip():
    rng = np.random.default_rng(0)
    track = rng.integers(0, 3, size=50)
    pred = preds_from_tracks(track)
    back = tracks_from_pred(pred)
    # the same partition (names in order of first appearance)
    assert all(len(np.unique(back[track == k])) == 1 for k in np.unique(track))
    assert len(np.unique(back)) == len(np.unique(track))
