"""The PIR's toggle log (onebit.models.pir: hold, edges, lost bursts), as both simulators use it."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from onebit.models.pir import hold_on, hold_samples, keep_bursts, pir_on, toggle_edges


def on_by_loop(sample, detected, n, hold):
    """The definition, one sample at a time: on while a detection is at most hold - 1 samples old."""
    on = np.zeros((n, detected.shape[1]), bool)
    for r, k in enumerate(sample):
        for j in np.flatnonzero(detected[r]):
            on[k : min(n, k + hold), j] = True
    return on


detections = st.integers(1, 40).flatmap(
    lambda n: st.tuples(
        st.just(n),
        st.integers(1, 4).flatmap(
            lambda s: st.integers(0, 60).flatmap(
                lambda m: st.tuples(
                    arrays(np.int64, m, elements=st.integers(0, n - 1)),
                    arrays(bool, (m, s)),
                )
            )
        ),
        st.integers(1, 8),
    )
)


@settings(max_examples=200, deadline=None)
@given(detections)
def test_pir_on_is_the_hold_of_the_definition(case):
    n, (sample, detected), hold = case
    assert np.array_equal(pir_on(sample, detected, n, hold), on_by_loop(sample, detected, n, hold))
    hit = on_by_loop(sample, detected, n, 1)  # a hold of one sample: the triggers themselves
    assert np.array_equal(hold_on(hit, hold), on_by_loop(sample, detected, n, hold))


@settings(max_examples=200, deadline=None)
@given(arrays(bool, st.tuples(st.integers(1, 30), st.integers(1, 4))))
def test_edges_give_back_the_on_states_and_pair_into_bursts(on):
    n, s = on.shape
    e = toggle_edges(on)
    order = np.lexsort((e.sensor, e.sample))
    assert np.array_equal(order, np.arange(len(order)))  # ordered by (sample, sensor)
    rebuilt = np.zeros((n + 1, s), bool)
    for j in range(s):
        mine = e.sensor == j
        assert np.all(e.value[mine][::2]) and not np.any(e.value[mine][1::2])  # on, off, on, off, ...
        for k, v in zip(e.sample[mine], e.value[mine]):
            rebuilt[k:, j] = v
    assert np.array_equal(rebuilt[:n], on) and not rebuilt[n].any()  # every PIR off after the last sample
    ids, counts = np.unique(e.burst, return_counts=True)
    assert np.all(counts == 2)  # one on and one off edge per burst
    for b in ids:
        pair = e.burst == b
        assert e.value[pair].sum() == 1 and len(set(e.sensor[pair])) == 1


def test_a_lost_burst_loses_its_on_and_its_off_edge():
    on = np.zeros((50, 3), bool)
    for j in range(3):
        on[j::5, j] = True  # ten one-sample bursts per sensor
    e = toggle_edges(on)
    keep = keep_bursts(e.burst, 0.5, np.random.default_rng(1))
    for b in np.unique(e.burst):
        assert len(set(keep[e.burst == b])) == 1
    assert 0 < keep.sum() < len(keep)
    assert keep_bursts(e.burst, 0.0, np.random.default_rng(1)).all()
    assert not keep_bursts(e.burst, 1.0, np.random.default_rng(1)).any()


def test_the_draws_do_not_depend_on_drop():
    e = toggle_edges(np.tile([[True], [False]], (10, 2)))
    after = []
    for drop in (0.0, 0.3):
        rng = np.random.default_rng(5)
        keep_bursts(e.burst, drop, rng)
        after.append(rng.random())
    assert after[0] == after[1]


def test_hold_samples():
    assert hold_samples(0.6, 10.0) == 6
    assert hold_samples(2.0, 2.0) == 4
    assert hold_samples(0.01, 2.0) == 1  # a detection holds at least its own sample
