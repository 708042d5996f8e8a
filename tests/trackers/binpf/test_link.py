"""binpf's tracklet joining: the gate, the min-cost assignment (against enumeration), the
interpolated gaps and the bound on reported tracks."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from onebit.trackers.binpf.link import (
    best_joins,
    best_joins_sparse,
    join_costs,
    join_pairs,
    link_tracklets,
    tracklet_ends,
)


def _rows(*tracklets):
    f, lab, x, y = [], [], [], []
    for name, frames, xs, ys in tracklets:
        f += list(frames)
        lab += [name] * len(frames)
        x += list(xs)
        y += list(ys)
    return np.array(f), np.array(lab), np.array(x, float), np.array(y, float)


def test_a_person_silent_for_two_frames_keeps_one_label_and_the_gap_is_filled():
    a = ("a", range(0, 5), [0.0, 0.5, 1.0, 1.5, 2.0], [0.0] * 5)
    b = ("b", range(7, 10), [3.5, 4.0, 4.5], [0.0] * 3)
    far = ("c", range(7, 10), [3.5, 4.0, 4.5], [20.0] * 3)
    f, lab, x, y, joins = link_tracklets(*_rows(a, b, far), period=0.5, max_gap=6, max_speed=1.5, slack=1.0)
    assert joins == 1
    assert set(lab[f >= 7].tolist()) == {"a", "c"}  # b continues a; c is 20 m away
    gap = (lab == "a") & (f >= 5) & (f <= 6)
    np.testing.assert_allclose(x[gap], [2.5, 3.0])
    assert len(f) == 5 + 3 + 3 + 2 and np.all(np.diff(f) >= 0)


def test_no_join_beyond_the_gap_or_the_reach():
    a = ("a", range(0, 3), [0.0, 0.1, 0.2], [0.0] * 3)
    late = ("b", range(12, 14), [0.2, 0.2], [0.0] * 2)  # 8 frames missing > max_gap 6
    _, lab, _, _, joins = link_tracklets(*_rows(a, late), period=0.5, max_gap=6, max_speed=1.5, slack=1.0)
    assert joins == 0 and set(lab.tolist()) == {"a", "b"}
    jump = ("b", range(4, 6), [5.0, 5.0], [0.0] * 2)  # 4.8 m in 2 frames > 1.5 m/s * 1 s + 1 m
    _, _, _, _, joins = link_tracklets(*_rows(a, jump), period=0.5, max_gap=6, max_speed=1.5, slack=1.0)
    assert joins == 0


def test_filling_respects_the_bound():
    a = ("a", range(0, 3), [0.0, 0.1, 0.2], [0.0] * 3)
    b = ("b", range(6, 8), [0.3, 0.4], [0.0] * 2)
    other = ("z", range(0, 8), [5.0] * 8, [5.0] * 8)  # always reported: frames 3-5 already hold one track
    f, lab, _, _, joins = link_tracklets(
        *_rows(a, b, other), period=0.5, max_gap=6, max_speed=1.5, slack=1.0, max_out=1
    )
    assert joins == 1 and np.bincount(f).max() <= 2
    assert not np.any((lab == "a") & (f >= 3) & (f <= 5))  # the bound of 1 leaves the gap empty
    f2, _, _, _, _ = link_tracklets(*_rows(a, b, other), period=0.5, max_gap=6, max_speed=1.5, slack=1.0, max_out=2)
    assert np.bincount(f2).tolist() == [2] * 8


def test_the_joins_are_the_largest_then_cheapest_matching():
    rng = np.random.default_rng(0)
    for _trial in range(40):
        n = 5
        parts = []
        for i in range(n):
            s = int(rng.integers(0, 12))
            L = int(rng.integers(1, 4))
            parts.append((f"t{i}", range(s, s + L), rng.uniform(0, 4, L), rng.uniform(0, 4, L)))
        f, lab, x, y = _rows(*parts)
        labs, sf, sxy, ef, exy = tracklet_ends(f, lab, x, y)
        cost = join_costs(sf, sxy, ef, exy, period=0.5, max_gap=4, max_speed=1.5, slack=1.0)
        pairs = [(i, j) for i in range(n) for j in range(n) if np.isfinite(cost[i, j])]
        best = (0, 0.0)
        for k in range(len(pairs), 0, -1):  # largest matchings first, then cheapest
            costs = [
                sum(cost[i, j] for i, j in m)
                for m in itertools.combinations(pairs, k)
                if len({i for i, _ in m}) == k and len({j for _, j in m}) == k
            ]
            if costs:
                best = (k, min(costs))
                break
        r, c = best_joins(cost)
        assert r.size == best[0]
        assert float(cost[r, c].sum()) == pytest.approx(best[1])
        _, new_lab, _, _, joins = link_tracklets(f, lab, x, y, period=0.5, max_gap=4, max_speed=1.5, slack=1.0)
        assert joins == best[0] and len(set(new_lab.tolist())) == n - joins


@pytest.mark.parametrize("seed", range(30))
def test_the_sparse_pairs_and_assignment_are_the_dense_ones(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 60))
    parts = []
    for i in range(n):
        s = int(rng.integers(0, 80))
        L = int(rng.integers(1, 5))
        parts.append((f"t{i:02d}", range(s, s + L), rng.uniform(0, 6, L), rng.uniform(0, 2, L)))
    f, lab, x, y = _rows(*parts)
    labs, sf, sxy, ef, exy = tracklet_ends(f, lab, x, y)
    kw = {"period": 0.5, "max_gap": int(rng.integers(0, 8)), "max_speed": 1.5, "slack": 1.0}
    dense = join_costs(sf, sxy, ef, exy, **kw)
    pe, ps, pc = join_pairs(sf, sxy, ef, exy, **kw)
    assert set(zip(pe.tolist(), ps.tolist())) == set(zip(*np.nonzero(np.isfinite(dense))))
    np.testing.assert_array_equal(pc, dense[pe, ps])
    r, c = best_joins(dense)
    r2, c2 = best_joins_sparse(pe, ps, pc, labs.size, labs.size)
    assert r2.size == r.size and float(dense[r2, c2].sum()) == pytest.approx(float(dense[r, c].sum()))
    assert sorted(zip(r2.tolist(), c2.tolist())) == sorted(zip(r.tolist(), c.tolist()))  # costs are distinct
