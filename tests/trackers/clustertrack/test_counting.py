"""Section 3 of Singh et al.: feasible space, Theorem 4, positively independent sensors, Lemma 1."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, box

from onebit.trackers.clustertrack.counting import greedy_min_targets, positively_independent, snapshot_bounds_1d
from onebit.trackers.clustertrack.feasible import (
    disk_masks,
    feasible_1d,
    feasible_raster,
    make_raster,
    raster_components,
    sample_intervals,
    union_intervals,
)

R = 1.0


def ideal_readings(sx: np.ndarray, targets: np.ndarray, r: float = R) -> np.ndarray:
    return np.any(np.abs(sx[:, None] - targets[None, :]) <= r, axis=1)


instances = st.tuples(
    st.lists(st.floats(0.0, 12.0, allow_nan=False), min_size=1, max_size=9, unique=True),
    st.lists(st.floats(0.0, 12.0, allow_nan=False), min_size=0, max_size=6),
)


def brute_min_hitting(lo: np.ndarray, hi: np.ndarray) -> int:
    """Smallest number of points hitting every interval (candidates: the right end points)."""
    if lo.size == 0:
        return 0
    cand = np.unique(hi)
    for k in range(1, lo.size + 1):
        for pts in combinations(cand, k):
            p = np.asarray(pts)
            if np.all(np.any((p[None, :] >= lo[:, None] - 1e-12) & (p[None, :] <= hi[:, None] + 1e-12), axis=1)):
                return k
    raise AssertionError("no hitting set")


def brute_max_independent(rel: np.ndarray) -> int:
    n = rel.shape[0]
    best = 0
    for k in range(1, n + 1):
        for sub in combinations(range(n), k):
            if all(rel[a, b] for a, b in combinations(sub, 2)):
                best = k
                break
        else:
            break
    return best


@settings(max_examples=120, deadline=None)
@given(instances)
def test_theorem4_greedy_equals_max_independent_and_min_hitting_set(inst):
    sx = np.sort(np.asarray(inst[0]))
    targets = np.asarray(inst[1])
    on = ideal_readings(sx, targets)
    r = np.full(sx.size, R)
    f = feasible_1d(sx, on, r, r, -2.0, 14.0)
    hull, s = f.hulls()
    picked, pos = greedy_min_targets(hull[:, 0], hull[:, 1])
    # every g_i is one interval under ideal sensing, and the greedy positions hit them all
    assert np.all(np.any((pos[None, :] >= hull[:, :1] - 1e-9) & (pos[None, :] <= hull[:, 1:] + 1e-9), axis=1))
    assert picked.size == brute_min_hitting(hull[:, 0], hull[:, 1])
    sensors, rel = positively_independent(f, sx, r)
    assert picked.size == brute_max_independent(rel)
    # the picked sensors are pairwise positively independent
    k = np.searchsorted(sensors, s[picked])
    assert all(rel[a, b] for a, b in combinations(k, 2))
    # the true targets explain F, so the minimum cannot exceed their number
    assert picked.size <= targets.size
    lb, per_comp, _ = snapshot_bounds_1d(f)
    assert lb == picked.size == per_comp.sum()


@settings(max_examples=150, deadline=None)
@given(st.lists(st.floats(0.0, 20.0, allow_nan=False), min_size=0, max_size=8), st.floats(0.3, 2.0))
def test_lemma1_components_at_least_2R_apart(targets, pitch_r):
    sx = np.arange(-2.0, 22.0 + pitch_r * R, pitch_r * R)  # covering the site [-2, 22]: pitch <= 2R
    on = ideal_readings(sx, np.asarray(targets))
    r = np.full(sx.size, R)
    f = feasible_1d(sx, on, r, r, -2.0, 22.0)
    if len(f.components) > 1 and on.any():
        gaps = f.components[1:, 0] - f.components[:-1, 1]
        assert np.all(gaps >= 2 * R - 1e-9)
    # every target lies in F
    if len(targets) and on.any():
        assert np.all(f.component_of(np.asarray(targets)) >= 0)


@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(0, 3)), min_size=1, max_size=10))
def test_union_intervals_matches_shapely(iv):
    lo = np.array([a for a, _ in iv])
    hi = lo + np.array([b for _, b in iv])
    u = union_intervals(lo, hi)
    assert np.all(np.diff(u[:, 0]) > 0) and np.all(u[1:, 0] > u[:-1, 1])
    exact = shapely.union_all([box(a, 0, b, 1) if b > a else box(a, 0, a + 1e-12, 1) for a, b in zip(lo, hi)])
    assert abs(float(np.sum(u[:, 1] - u[:, 0])) - exact.area) < 1e-6


def test_nonideal_feasible_space_uses_outer_on_and_inner_off_ranges():
    sx = np.array([0.0, 1.0, 2.0, 3.0])
    on = np.array([False, True, False, False])
    f = feasible_1d(sx, on, np.full(4, 0.5), np.full(4, 1.5), -2.0, 5.0)
    # on-range [-0.5, 2.5] minus off-ranges (-0.5, 0.5), (1.5, 2.5); single points dropped
    np.testing.assert_allclose(f.components, [[0.5, 1.5]])


def test_sampling_is_uniform_on_F():
    rng = np.random.default_rng(0)
    iv = np.array([[0.0, 1.0], [3.0, 6.0]])
    x = sample_intervals(iv, 40000, rng)
    assert np.all(((x >= 0) & (x <= 1)) | ((x >= 3) & (x <= 6)))
    assert abs(np.mean(x <= 1.0) - 0.25) < 0.01


def test_2d_raster_matches_shapely_disks_and_counts_components():
    bnd = box(0, 0, 10, 10)
    g = np.arange(0.5, 10, 1.0)
    xy = np.array([[a, b] for a in g for b in g])
    targets = np.array([[2.2, 2.7], [7.6, 7.1]])
    d = np.linalg.norm(xy[:, None] - targets[None], axis=-1)
    on = np.any(d <= 1.0, axis=1)
    rast = make_raster(bnd, 0.05)
    r = np.ones(len(xy))
    F = feasible_raster(
        on[None], disk_masks(rast, xy, r, closed=True), disk_masks(rast, xy, r, closed=False), rast.inside
    )[0]
    exact = shapely.difference(
        shapely.union_all([Point(p).buffer(1.0, 64) for p in xy[on]]),
        shapely.union_all([Point(p).buffer(1.0, 64) for p in xy[~on]]),
    ).intersection(bnd)
    assert abs(F.sum() * 0.05**2 - exact.area) < 0.05 * exact.area + 0.05
    n, lab = raster_components(F, rast)
    assert n == 2
    c = rast.centres[F]
    comp = []
    for t in targets:  # each target lies in (within a cell of) F, in a component of its own
        d = np.linalg.norm(c - t, axis=1)
        assert d.min() <= 0.05 * np.sqrt(2)
        comp.append(int(lab[np.flatnonzero(F)[np.argmin(d)]]))
    assert sorted(comp) == [1, 2]
