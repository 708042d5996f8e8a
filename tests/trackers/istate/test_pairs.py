"""The I-state filter's pairwise work done once: the memo of region-pair results and the
branch-and-bound cap give bit-for-bit the results of computing every pair."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, box

from onebit.trackers.istate.core import (
    IState,
    PairMemo,
    cap_elements,
    cap_elements_reference,
    clean_up,
    info_state_update,
    observation_update,
    overlap_areas,
    same_elements,
)

FREE = shapely.difference(box(0, 0, 10, 8), box(4, 3, 5, 5))


def _istate(rng, E, n, shape="exact"):
    rows = []
    for _ in range(E):
        c = rng.uniform([0, 0], [10, 8], (n, 2))
        r = rng.uniform(0.8, 3.0, n)
        if shape == "rect":
            rows.append([box(x - s, y - s * 0.7, x + s, y + s * 0.7) for (x, y), s in zip(c, r)])
        elif shape == "disk":
            rows.append([Point(x, y).buffer(s, quad_segs=4) for (x, y), s in zip(c, r)])
        else:
            rows.append([shapely.intersection(Point(x, y).buffer(s, quad_segs=4), FREE) for (x, y), s in zip(c, r)])
    return IState.from_elements(rows)


def _wkb(eta):
    return shapely.to_wkb(eta.regions.ravel()).tolist()


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("shape", ["exact", "disk"])
def test_cap_branch_and_bound_equals_reference(seed, shape):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 4))
    eta = _istate(rng, int(rng.integers(3, 16)), n, shape)
    # copies sharing regions, as an observation update makes them
    eta = observation_update(eta, box(*rng.uniform([0, 0, 5, 4], [5, 4, 10, 8])))
    for M in (1, 2, 5):
        a = cap_elements(eta, M, shape="exact")
        b = cap_elements_reference(eta, M, shape="exact")
        assert a.regions.shape == b.regions.shape and _wkb(a) == _wkb(b)


def test_overlap_areas_with_a_memo_are_the_same_bits():
    rng = np.random.default_rng(1)
    a = _istate(rng, 12, 3)
    b = IState(np.vstack([a.regions[:4], _istate(rng, 5, 3).regions, a.regions[:4]]))  # repeated rows
    fresh = overlap_areas(a.regions, b.regions)
    memo = PairMemo()
    once = overlap_areas(a.regions, b.regions, memo=memo)
    computed = memo.computed
    assert memo.looked_up > 0  # the repeated rows repeat region pairs within the call
    again = overlap_areas(a.regions, b.regions, memo=memo)  # every pair looked up
    assert np.array_equal(fresh, once) and np.array_equal(once, again)
    assert memo.computed == computed
    # equal geometries in different objects share one id
    copy = shapely.from_wkb(shapely.to_wkb(a.regions))
    assert np.array_equal(memo.keys(copy), memo.keys(a.regions))


def test_filter_steps_are_unchanged_by_the_memo():
    """A few filter steps (motion, observations, clean-up, cap) against the same steps with
    every clean-up and cap run on its own (no shared memo, every similarity computed)."""
    rng = np.random.default_rng(3)
    sensing = [box(x - 1.5, y - 1.5, x + 1.5, y + 1.5) for x, y in rng.uniform([0, 0], [10, 8], (6, 2))]
    eta = IState.initial(FREE, 2)
    ref = eta
    for k in range(6):
        det = [sensing[i] for i in rng.choice(6, size=int(rng.integers(1, 3)), replace=False)]
        eta = info_state_update(eta, det, step=0.6 if k else 0.0, free_space=FREE, max_elements=4)
        ref = info_state_update(ref, [], step=0.6 if k else 0.0, free_space=FREE, max_elements=4)
        for s in det:
            ref = cap_elements_reference(clean_up(observation_update(ref, s)), 4)
        assert _wkb(eta) == _wkb(ref) and same_elements(eta, ref)


def test_a_memo_kept_across_steps_gives_the_same_bits():
    """One memo passed to every filter step (as the stage does; regions recur across steps)
    gives the results of a fresh memo per step, also when it starts afresh (small capacity),
    and computes fewer pairs."""
    rng = np.random.default_rng(5)
    sensing = [box(x - 1.5, y - 1.5, x + 1.5, y + 1.5) for x, y in rng.uniform([0, 0], [10, 8], (6, 2))]
    steps = [[sensing[i] for i in rng.choice(6, size=int(rng.integers(1, 4)), replace=False)] for _ in range(10)]
    ref = IState.initial(FREE, 3)
    refs = []
    for k, det in enumerate(steps):
        ref = info_state_update(ref, det, step=0.5 if k else 0.0, free_space=FREE, max_elements=3)
        refs.append(_wkb(ref))
    computed = {}
    for capacity in (0, 30, 1 << 18):
        memo = PairMemo(capacity=capacity)
        eta = IState.initial(FREE, 3)
        for k, det in enumerate(steps):
            eta = info_state_update(eta, det, step=0.5 if k else 0.0, free_space=FREE, max_elements=3, memo=memo)
            assert _wkb(eta) == refs[k]
            if capacity == 0:  # dropped at every step
                assert len(memo.area) + len(memo.covers) + len(memo._rid) < 2000
        computed[capacity] = memo.computed
    assert computed[1 << 18] < computed[0]


class _EveryPair(PairMemo):
    """Remembers nothing: every region pair and every region's projection, intersection and
    union is computed, no observation step is recalled (the reference of the memo)."""

    remember_steps = False

    def pairs(self, left, right, kl, kr, table, op, dtype):
        return np.asarray(op(left, right), dtype=dtype) if len(left) else np.zeros(0, dtype=dtype)


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), shape=st.sampled_from(["exact", "disk", "rect"]), n=st.integers(1, 3))
def test_a_run_wide_memo_equals_computing_everything(seed, shape, n):
    """Filter steps sharing one memo (pair results, projected, intersected and merged regions
    looked up by WKB across steps) give the bits of steps that compute everything."""
    rng = np.random.default_rng(seed)
    sensing = [
        shapely.intersection(Point(x, y).buffer(1.8, quad_segs=4), FREE)
        for x, y in rng.uniform([0, 0], [10, 8], (5, 2))
    ]
    steps = [[sensing[i] for i in rng.choice(5, size=int(rng.integers(0, 4)), replace=False)] for _ in range(8)]
    negatives = [
        [box(*rng.uniform([0, 0], [9, 7]), *rng.uniform([9, 7], [10, 8]))] if rng.random() < 0.2 else [] for _ in steps
    ]
    memo = PairMemo()
    eta = ref = IState.initial(FREE, n)
    for k, det in enumerate(steps):
        kw = dict(step=0.6 if k else 0.0, free_space=FREE, shape=shape, max_elements=3, negatives=negatives[k])
        eta = info_state_update(eta, det, memo=memo, **kw)
        ref = info_state_update(ref, det, memo=_EveryPair(), **kw)
        assert _wkb(eta) == _wkb(ref)


@pytest.mark.parametrize("shape", ["exact", "disk", "rect"])
def test_observations_at_a_fixed_point_are_recalled(shape):
    """Targets staying in the reach of the same sensors: the I-state comes back stage after
    stage, its observation steps are looked up -- and equal the computed ones."""
    s1 = shapely.intersection(Point(2, 2).buffer(2.0, quad_segs=4), FREE)
    s2 = shapely.intersection(Point(7, 6).buffer(1.5, quad_segs=4), FREE)
    memo = PairMemo()
    eta = ref = IState.initial(FREE, 2)
    for k in range(6):
        kw = dict(step=0.3 if k else 0.0, free_space=FREE, shape=shape, max_elements=3)
        eta = info_state_update(eta, [s1, s2], memo=memo, **kw)
        ref = info_state_update(ref, [s1, s2], memo=_EveryPair(), **kw)
        assert _wkb(eta) == _wkb(ref)
    computed = sum(len(t) for name, t in memo._tables.items() if name[0] == "recall")
    assert computed < 6 * 2  # some of the 12 observations recalled
