"""Identity per event (issue 22 item 3): hand-computed cases, silent and perfect trackers, baselines."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.scoring.identity import (
    adjusted_rand_index,
    baseline_rows,
    busier_events,
    identity_scores,
    nearest_events,
    presence_count,
)
from onebit.trackers.attribution import attribute_events

TE = pl.DataFrame(
    {
        "t": [0.0, 10.0, 20.0, 30.0, 40.0, 50.0],
        "sensor": ["a", "b", "c", "a", "b", "c"],
        "residents": ["1", "2", "1", "2", "1;2", "1"],
    }
)


def _ev(tracks: list[str | None]) -> pl.DataFrame:
    return TE.select("t", "sensor").with_columns(track=pl.Series(tracks, dtype=pl.String))


def test_perfect_tracker_scores_one():
    s = identity_scores(TE, _ev(["x", "y", "x", "y", "x", "x"]), constant_count=2.0)
    assert s.accuracy == 1.0 and s.mapping == {"x": "1", "y": "2"}
    assert s.ari == 1.0 and s.switches_per_hour == 0.0 and s.attributed == 1.0


def test_silent_tracker_scores_all_its_misses():
    s = identity_scores(TE, _ev([None] * 6), constant_count=0.0)
    assert s.accuracy == 0.0 and s.attributed == 0.0 and s.switches_per_hour == 0.0
    assert s.ari == 0.0  # every unattributed event is a cluster of its own
    s2 = identity_scores(TE, TE.head(0).select("t", "sensor").with_columns(track=pl.lit(None, pl.String)))
    assert s2.accuracy == 0.0 and s2.events == 6


def test_hand_computed_relabelling_and_switches():
    # track x: events 0 (1), 1 (2), 4 (1;2); track y: 2 (1), 3 (2), 5 (1)
    # G = x: {1: 2, 2: 2}, y: {1: 2, 2: 1}; best map x->2, y->1: 2 + 2 = 4 of 6
    s = identity_scores(TE, _ev(["x", "x", "y", "y", "x", "y"]))
    assert s.accuracy == pytest.approx(4 / 6)
    assert s.mapping == {"x": "2", "y": "1"}
    # resident 1's single events 0, 2, 5 -> x, y, y: 1 switch; resident 2's 1, 3 -> x, y: 1; over 50 s
    assert s.switches_per_hour == pytest.approx(2 / (50 / 3600))
    # one track can only be one resident: all to one track = the busier resident's share (1: 4 of 6 events)
    assert identity_scores(TE, busier_events(TE)).accuracy == pytest.approx(4 / 6)


def test_events_are_matched_by_sensor_and_time():
    ev = _ev(["x", "y", "x", "y", "x", "x"]).with_columns(pl.col("t") + 5e-4)  # within 1 ms: the same events
    assert identity_scores(TE, ev).accuracy == 1.0
    wrong_sensor = ev.with_columns(sensor=pl.lit("z"))
    assert identity_scores(TE, wrong_sensor).accuracy == 0.0


def test_ari_hand_cases():
    a = np.array([0, 0, 1, 1])
    assert adjusted_rand_index(a, np.array([5, 5, 7, 7])) == 1.0
    assert adjusted_rand_index(a, np.array([0, 1, 0, 1])) == pytest.approx(-0.5)
    # sklearn's value for this pair: 0.24242424...
    assert adjusted_rand_index(np.array([0, 0, 0, 1, 1, 1]), np.array([0, 0, 1, 1, 2, 2])) == pytest.approx(
        0.242424, abs=1e-6
    )


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(0, 3), min_size=2, max_size=40), st.integers(0, 1000))
def test_ari_is_symmetric_and_invariant_to_renaming(labels, seed):
    a = np.array(labels)
    rng = np.random.default_rng(seed)
    b = rng.integers(0, 3, a.size)
    perm = rng.permutation(10)
    assert adjusted_rand_index(a, b) == pytest.approx(adjusted_rand_index(b, a))
    assert adjusted_rand_index(a, b) == pytest.approx(adjusted_rand_index(perm[a], b))
    assert adjusted_rand_index(a, b) <= 1.0 + 1e-12


def test_presence_and_count_error():
    te = pl.DataFrame(
        {"t": [0.0, 120.0, 60.0, 2000.0, 2030.0], "sensor": ["a"] * 5, "residents": ["1", "1", "2", "2", "2"]}
    )
    minutes = np.array([0.0, 60.0, 120.0])
    # resident 1 present 0..120; resident 2 present at 60 only (gap 1940 s > 600 s), then again from 2000
    assert presence_count(te, minutes).tolist() == pytest.approx([1.0, 1.0, 0.0])
    s = identity_scores(te, te.select("t", "sensor", pl.col("residents").alias("track")), constant_count=1.0)
    assert s.count_error is not None and 0.0 <= s.count_error <= 1.0


def test_nearest_baseline_follows_two_walkers():
    # two people far apart on a line a-b-c ... x-y-z, interleaved events
    line = ["a", "b", "c", "d", "x", "y", "z"]
    hops = {(p, q): abs(line.index(p) - line.index(q)) for p in line for q in line}
    seq = [("a", "1"), ("z", "2"), ("b", "1"), ("y", "2"), ("c", "1"), ("x", "2")]
    te = pl.DataFrame(
        {"t": [float(i) for i in range(6)], "sensor": [s for s, _ in seq], "residents": [r for _, r in seq]}
    )
    ev = nearest_events(te, hops, 2)
    assert ev["track"].to_list() == ["p1", "p2", "p1", "p2", "p1", "p2"]
    rows = {(st, m): v for st, m, v, _ in baseline_rows(te, hops)}
    assert (
        rows[("identity-nearest", "identity_accuracy")] == 1.0 and rows[("identity-busier", "identity_accuracy")] == 0.5
    )


def test_attribution_at_the_sensor_then_nearest_then_none():
    nodes = ("a", "b", "c", "d")
    hops = np.array([[0, 1, 2, 5], [1, 0, 1, 5], [2, 1, 0, 5], [5, 5, 5, 0]])  # d unreachable (> N)
    t0, period = 0.0, 1.0
    tracks = pl.DataFrame({"track": ["user1", "user2", "user1"], "t": [0.5, 0.5, 2.5], "node": ["a", "c", "a"]})
    motion = pl.DataFrame(
        {
            "t": [0.2, 0.3, 0.4, 0.6, 1.5, 2.2],
            "sensor": ["c", "b", "d", "a", "a", "zz"],
            "on": [True, True, True, False, True, True],
        }
    )
    ev = attribute_events(motion, tracks, nodes, hops, t0=t0, period=period)
    assert ev.rows() == [
        (0.2, "c", "user2"),  # at its sensor
        (0.3, "b", "user1"),  # nearest: both 1 hop, the first by name
        (0.4, "d", None),  # nobody reachable
        (1.5, "a", None),  # nobody decoded in slot 1
        (2.2, "zz", None),  # not a node
    ]


def test_a_repeated_on_takes_the_track_of_its_sensors_previous_event_within_5_s():
    te = pl.DataFrame({"t": [0.0, 0.3, 7.0, 20.0], "sensor": ["a", "a", "a", "b"], "residents": ["1", "1", "1", "2"]})
    ev = pl.DataFrame({"t": [0.0, 20.0], "sensor": ["a", "b"], "track": ["p", "q"]})
    m = identity_scores(te, ev)
    # 0.3 s after a's event: the same firing (the reader rejected the repeated ON); 7 s after: none
    assert m.accuracy == pytest.approx(3 / 4)
    assert m.attributed == pytest.approx(3 / 4)


def test_the_supervised_habits_baseline():
    from onebit.scoring.identity import habits_events

    prof = pl.DataFrame(
        {
            "resident": ["1", "2", "1", "2"],
            "from": [None, None, "a", None],
            "to": ["a", "a", "b", "c"],
            "count": [5.0, 2.0, 9.0, 1.0],
            "bin": [None, None, None, None],
        }
    )
    ev = habits_events(TE, prof)
    # a -> 1 (5 vs 2), b -> the most events overall (1: 5), c -> 2 (habit rows only: 'from' null)
    assert ev["track"].to_list() == ["1", "1", "2", "1", "1", "2"]
    rows = {r[0]: r for r in baseline_rows(TE, {}, profile=prof) if r[1] == "identity_accuracy"}
    assert set(rows) == {"identity-busier", "identity-nearest", "identity-habits"}
    assert rows["identity-habits"][2] == pytest.approx(identity_scores(TE, ev).accuracy)


def test_error_table_by_hand():
    from onebit.scoring.identity import RESOLVED_BY, error_table

    te = pl.DataFrame(
        {
            "t": [0.0, 1.0, 2.0, 100.0, 200.0],
            "sensor": ["a", "b", "a", "c", "d"],
            "residents": ["1", "2", "1", "1", "2"],
        }
    )
    ev = te.select("t", "sensor").with_columns(track=pl.Series(["x", "y", "y", "x", None]))
    hops = {("a", "b"): 1, ("b", "a"): 1, ("c", "a"): 2, ("d", "c"): 5}
    err = error_table(te, ev, hops)
    # x -> 1, y -> 2: wrong are t=2 (a, given 2; the other, 2, fired at b 1 s before, 1 hop: a meeting)
    # and t=200 (unattributed; the other resident 1 fired at c 100 s before, 5 hops: apart)
    assert err["t"].to_list() == [2.0, 200.0]
    assert err["decoded"].to_list() == ["2", None]
    assert err["other_sensor"].to_list() == ["b", "c"]
    assert err["other_hops"].to_list() == [1, 5]
    assert err["kind"].to_list() == ["meeting", "apart"]
    assert err["run"].to_list() == [0, 1] and err["run_length"].to_list() == [1, 1]
    # where they met: at the meeting error itself; for t=200 the last meeting before it (t=2 at a,
    # resident 2 at b 1 s before), and where they parted after it (t=100 at c: 2 hops or more)
    assert err["met_t"].to_list() == [2.0, 2.0] and err["met_sensor"].to_list() == ["a", "a"]
    assert err["parted_t"].to_list() == [None, 100.0] and err["parted_sensor"].to_list() == [None, "c"]
    assert err["resolved_by"].to_list() == [RESOLVED_BY["meeting"], RESOLVED_BY["apart"]]
    perfect = te.select("t", "sensor").with_columns(track=te["residents"])
    assert error_table(te, perfect, hops).height == 0


def test_the_habits_baseline_by_the_profiles_clock():
    from onebit.scoring.identity import habits_events

    prof = pl.DataFrame(
        {
            "resident": ["1", "2", "2"],
            "from": [None, None, None],
            "to": ["a", "a", "a"],
            "count": [5.0, 2.0, 2.0],
            "bin": [None, None, "session 1/2"],  # late in the session, a is resident 2's
        }
    )
    ev = habits_events(TE, prof)  # TE's a events at t = 0 (bin 0) and t = 30 (bin 1)
    assert ev.filter(pl.col("sensor") == "a")["track"].to_list() == ["1", "2"]
