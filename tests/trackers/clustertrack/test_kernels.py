"""CLUSTERTRACK's compiled scan and linear-time passes against the numpy versions they
replace: the scan kernel equals the vectorised numpy scan on random inputs (ties, 1-D and
2-D), the per-instant usage equals a loop over instants, and a whole run keeps its result."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import box

from onebit.datasets.proximity_sim import make_world
from onebit.trackers.clustertrack import algorithm, kernels
from onebit.trackers.clustertrack.algorithm import (
    _norm,
    candidate_costs_reference,
    cluster_track,
    clustertrack,
    consensus,
    fused_scan,
    ordered_prefix,
    rules_of_thumb,
    scan_clusters,
    scan_clusters_reference,
    scan_order,
    scan_selection,
    summed_distances_reference,
    usage,
)
from onebit.trackers.clustertrack.feasible import SensorArray
from onebit.trackers.clustertrack.space import FeasibleSpace


@pytest.mark.parametrize("seed", range(60))
def test_scan_kernel_equals_numpy_scan(seed):
    rng = np.random.default_rng(seed)
    dim = int(rng.integers(1, 3))
    t = int(rng.integers(1, 6))
    kprev, m = int(rng.integers(1, 15)), int(rng.integers(1, 30))
    prev = rng.uniform(0, 5, size=(kprev, max(t - 1, 1), dim))
    pd = np.sum(_norm(prev[:, None] - prev[None, :])[..., None], axis=(2, 3)) if t > 1 else np.zeros((kprev, kprev))
    parent = np.repeat(np.arange(kprev), m)
    x = rng.uniform(0, 5, size=(kprev * m, dim))
    # ties (all costs 0 at t <= 2) broken by the random permutation, or distinct costs
    cost = np.zeros(kprev * m) if seed % 3 == 0 else rng.random(kprev * m).round(int(rng.integers(1, 4)))
    kw = dict(
        H=int(rng.integers(1, 8)),
        K=int(rng.integers(1, 60)),
        L=int(rng.integers(1, 400)),
        D0=float(rng.uniform(0.05, 3.0)),
    )
    a = scan_clusters(cost, parent, x, pd, t, rng=np.random.default_rng(seed), compiled=True, **kw)
    b = scan_clusters_reference(cost, parent, x, pd, t, rng=np.random.default_rng(seed), **kw)
    for u, v in zip(a, b):
        np.testing.assert_array_equal(u, v)


def _space(name, seed, **params):
    w = make_world(name, seed=seed, params=params)
    sa = SensorArray(tuple(f"p{i}" for i in range(len(w.sensor_xy))), w.sensor_xy, w.r_inner, w.r_outer)
    dim = 1 if sa.is_1d else 2
    return FeasibleSpace.build(
        w.on, np.arange(w.on.shape[0], dtype=float), sa, box(*w.boundary), dim=dim, cell=0.25
    ), sa.radius


@pytest.mark.parametrize("name", ["proximity-line", "proximity-grid"])
def test_usage_equals_a_loop_over_instants(name):
    sp, R = _space(name, 3)
    rng = np.random.default_rng(0)
    lo, hi = (sp.raster.x0, sp.raster.x0 + sp.raster.width * sp.raster.cell) if sp.dim == 2 else (-2, 20)
    tracks = rng.uniform(lo, hi, size=(7, sp.T, sp.dim))
    got = usage(sp, tracks)
    for t in range(sp.T):
        nc = sp.comp_bounds_all[t].size
        c = sp.component_of(t, tracks[:, t, :])
        want = np.bincount(c[c >= 0], minlength=nc)[:nc]
        np.testing.assert_array_equal(got[t], want)
        np.testing.assert_array_equal(sp.components_of(tracks)[:, t], c)


def test_consensus_reuses_a_known_run():
    sp, R = _space("proximity-line", 1)
    p = rules_of_thumb(sp, H=10, m_o=8.0 / R)
    first = clustertrack(sp, p, np.random.default_rng(4))
    a = consensus(sp, p, [4, 5], known={4: first})
    b = consensus(sp, p, [4, 5])
    np.testing.assert_array_equal(a.tracks, b.tracks)
    np.testing.assert_array_equal(a.cluster, b.cluster)
    assert a.count == b.count


@pytest.mark.parametrize("seed", range(30))
def test_ordered_prefix_is_the_start_of_the_stable_argsort(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 300))
    key = (
        rng.integers(0, int(rng.integers(1, 20)), n).astype(float) if seed % 2 else rng.random(n)
    )  # many ties, or none
    full = np.argsort(key, kind="stable")
    for k in (0, 1, int(rng.integers(1, n + 1)), n, n + 5):
        np.testing.assert_array_equal(ordered_prefix(key, k), full[: max(0, min(k, n))])


@pytest.mark.parametrize("seed", range(10))
def test_scan_order_is_the_selection_sorted_by_cost(seed):
    rng = np.random.default_rng(seed)
    cost = rng.integers(0, 5, 200).astype(float)
    L = int(rng.integers(1, 250))
    sel = scan_selection(cost, L, np.random.default_rng(seed))
    np.testing.assert_array_equal(
        scan_order(cost, L, np.random.default_rng(seed)), sel[np.argsort(cost[sel], kind="stable")]
    )


@pytest.mark.parametrize("seed", range(20))
def test_cost_and_distance_kernels_equal_numpy(seed):
    rng = np.random.default_rng(seed)
    dim, kprev, m_t = int(rng.integers(1, 3)), int(rng.integers(1, 12)), int(rng.integers(1, 9))
    x = rng.uniform(-5, 5, (kprev * m_t, dim))
    last1, last2, cost = rng.uniform(-5, 5, (kprev, dim)), rng.uniform(-5, 5, (kprev, dim)), rng.random(kprev) * 10
    for curvature in (False, True):
        np.testing.assert_array_equal(
            kernels.candidate_costs(x, last1, last2, cost, m_t, curvature),
            candidate_costs_reference(x, last1, last2, cost, m_t, curvature),
        )
    pd = rng.random((kprev, kprev)) * 20
    par = rng.integers(0, kprev, int(rng.integers(1, 15)))
    xk = rng.uniform(-5, 5, (par.size, dim))
    np.testing.assert_array_equal(kernels.summed_distances(pd, par, xk), summed_distances_reference(pd, par, xk))


@pytest.mark.parametrize("name", ["proximity-line", "proximity-grid"])
def test_compiled_pass_equals_numpy_pass(name, monkeypatch):
    sp, R = _space(name, 2)
    p = rules_of_thumb(sp, H=10, m_o=8.0 / R)
    monkeypatch.setattr(algorithm, "PASS_COMPILED_MIN", 0)
    a = cluster_track(sp, p, np.random.default_rng(3))
    monkeypatch.setattr(algorithm, "PASS_COMPILED_MIN", 10**12)
    b = cluster_track(sp, p, np.random.default_rng(3))
    np.testing.assert_array_equal(a.tracks, b.tracks)
    np.testing.assert_array_equal(a.costs, b.costs)
    np.testing.assert_array_equal(a.scanned, b.scanned)


def test_sampling_from_listed_cell_centres_draws_what_the_mask_sampler_draws():
    from shapely.geometry import box as _box

    from onebit.trackers.clustertrack.feasible import make_raster, sample_cell_centres, sample_raster

    r = make_raster(_box(0, 0, 8, 14), 0.1)
    mask = np.zeros(r.width * r.height, dtype=bool)
    mask[np.random.default_rng(1).choice(mask.size, 500, replace=False)] = True
    a = sample_raster(mask, r, 1000, np.random.default_rng(3))
    b = sample_cell_centres(r.centres_of(np.flatnonzero(mask)), r.cell, 1000, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    c = sample_cell_centres(r.centres_of(np.flatnonzero(mask)), r.cell, 1000, np.random.default_rng(3), compiled=True)
    np.testing.assert_array_equal(a, c)


@pytest.mark.parametrize("seed", range(80))
def test_fused_step_kernel_equals_numpy_scan_and_distances(seed):
    """``fused_scan`` / ``kernels.scan_step`` (sorted prefix, then a heap of the live candidates of the unsorted
    rest) keeps, labels and counts exactly what the numpy scan does, and gives the same
    summed distances: ties, few and many clusters, H = 1, prefixes shorter than the scan."""
    rng = np.random.default_rng(seed)
    dim = int(rng.integers(1, 3))
    t = int(rng.integers(1, 6))
    kprev, m = int(rng.integers(1, 15)), int(rng.integers(1, 40)) + (30 if seed >= 60 else 0)
    prev = rng.uniform(0, 5, size=(kprev, max(t - 1, 1), dim))
    pd = np.sum(_norm(prev[:, None] - prev[None, :])[..., None], axis=(2, 3)) if t > 1 else np.zeros((kprev, kprev))
    parent = np.repeat(np.arange(kprev), m)
    x = rng.uniform(0, 5, size=(kprev * m, dim))
    cost = np.zeros(kprev * m) if seed % 3 == 0 else rng.random(kprev * m).round(int(rng.integers(1, 4)))
    H, K, L = int(rng.integers(1, 30)), int(rng.integers(1, 120)), int(rng.integers(1, 600))
    D0 = float(rng.choice([0.02, 0.1, 0.5, 1.5, 4.0]))
    prefix = int(rng.choice([1, 4]))
    if seed >= 60:  # small full clusters, many of them: many kept past the prefix, heads founded there
        H, K, L, D0, prefix = int(rng.integers(1, 3)), int(rng.integers(40, 120)), kprev * m, 0.3, 1
    ref_kept, ref_lab, ref_head, ref_scanned = scan_clusters_reference(
        cost, parent, x, pd, t, H=H, K=K, L=L, D0=D0, rng=np.random.default_rng(seed)
    )
    sel = scan_selection(cost, L, np.random.default_rng(seed))
    kept, lab, head, scanned, pd_new, biggest = fused_scan(cost, sel, x, m, pd, t, H=H, K=K, D0=D0, prefix=prefix)
    np.testing.assert_array_equal(kept, ref_kept)
    np.testing.assert_array_equal(lab, ref_lab)
    np.testing.assert_array_equal(head, ref_head)
    assert scanned == ref_scanned
    np.testing.assert_array_equal(pd_new, summed_distances_reference(pd, parent[kept], x[kept]))
    assert biggest == np.bincount(ref_lab).max()


@pytest.mark.parametrize("seed", range(20))
def test_compiled_prefix_and_interval_mapping_equal_numpy(seed):
    from onebit.trackers.clustertrack.feasible import sample_intervals

    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 300))
    key = rng.integers(0, int(rng.integers(1, 20)), n).astype(float) if seed % 2 else rng.random(n)
    for k in (0, 1, int(rng.integers(1, n + 1)), n, n + 5):
        np.testing.assert_array_equal(kernels.ordered_prefix(key, k), ordered_prefix(key, k))
    for k in range(0, n, max(1, n // 7)):
        assert kernels.kth_smallest(key, k) == np.partition(key, k)[k]
    c = int(rng.integers(1, 40))  # both the walk (<= 16 intervals) and the binary search
    ends = np.sort(rng.uniform(-10, 10, 2 * c)).reshape(c, 2)
    a = sample_intervals(ends, 500, np.random.default_rng(seed), compiled=True)
    b = sample_intervals(ends, 500, np.random.default_rng(seed))
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("name", ["proximity-line", "proximity-grid"])
def test_space_built_per_distinct_reading_equals_one_built_per_instant(name):
    """F, its components and bounds come from each distinct reading once; every instant gets
    what a space built from that instant alone has."""
    w = make_world(name, seed=1, params={})
    sa = SensorArray(tuple(f"p{i}" for i in range(len(w.sensor_xy))), w.sensor_xy, w.r_inner, w.r_outer)
    dim = 1 if sa.is_1d else 2
    on = np.concatenate([w.on, w.on[::-1], w.on[:3]])  # repeated readings, out of order
    sp = FeasibleSpace.build(on, np.arange(len(on), dtype=float), sa, box(*w.boundary), dim=dim, cell=0.25)
    assert len(np.unique(on, axis=0)) < len(on)
    for t in range(len(on)):
        one = FeasibleSpace.build(on[t : t + 1], np.zeros(1), sa, box(*w.boundary), dim=dim, cell=0.25)
        assert sp.sizes_all[t] == one.sizes_all[0] and sp.bounds_all[t] == one.bounds_all[0]
        np.testing.assert_array_equal(sp.comp_bounds_all[t], one.comp_bounds_all[0])
        if dim == 1:
            np.testing.assert_array_equal(sp.f1d[t].components, one.f1d[0].components)
            np.testing.assert_array_equal(sp.minimal_targets[t], one.minimal_targets[0])
        else:
            np.testing.assert_array_equal(sp.labels[t], one.labels[0])
            np.testing.assert_array_equal(sp.cell_xy[t], one.cell_xy[0])
