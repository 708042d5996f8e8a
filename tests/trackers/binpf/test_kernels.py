"""binpf's compiled observation update against the numpy one it replaces on long logs: equal to
rounding (1e-9) on random frames -- near and far tracks, soft and hard footprints, with and
without silence -- the resampled particles' mean footprint equal to evaluating it again,
a whole compiled run giving the numpy run's tracks, and the compiled frame loop giving its
per-frame Python reference's every row, count and logged particle."""

from __future__ import annotations

import numpy as np
import pytest

from onebit.trackers.binpf import kernels
from onebit.trackers.binpf.filter import (
    FilterParams,
    footprint_probability,
    observation_update,
    run_filter,
    run_filter_reference,
)

SENSORS = np.c_[np.arange(12) * 1.5, np.zeros(12)]  # a 16.5 m line: far sensors for every track
RADII = np.full(len(SENSORS), 1.0)


def _frame(seed, I=4, N=50):
    rng = np.random.default_rng(seed)
    centres = rng.uniform([-1.0, -0.5], [18.0, 0.5], (I, 1, 2))
    x = np.concatenate([centres + rng.normal(0, 0.4, (I, N, 2)), rng.normal(size=(I, N, 2))], axis=-1)
    r = rng.uniform(0.05, 0.95, I)
    z = rng.random(len(SENSORS)) < 0.3
    return x, r, z


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize(("edge", "silent"), [(0.3, 0.3), (0.05, 0.0), (0.0, 0.2)])
def test_compiled_update_equals_numpy_to_rounding(seed, edge, silent):
    x, r, z = _frame(seed)
    p = FilterParams(pd=0.8, pf=0.02, edge=edge, silent=silent)
    ell, r_new = observation_update(x, r, z, SENSORS, RADII, p)
    ell_c, r_c, d = kernels.observation_update(x, r, z, SENSORS, RADII, p.pd, p.pf, p.edge, p.silent)
    np.testing.assert_allclose(r_c, r_new, rtol=1e-9, atol=1e-12)
    # log-weights are defined up to a per-track constant (the far sensors' terms)
    np.testing.assert_allclose(ell_c - ell_c.max(1, keepdims=True), ell - ell.max(1, keepdims=True), atol=1e-9)
    full = footprint_probability(x[..., :2], SENSORS, RADII, pd=p.pd, edge=p.edge)
    # the same footprints to rounding, zero only where the footprint is below 2^-54
    np.testing.assert_allclose(d.transpose(0, 2, 1), full, rtol=1e-14, atol=2.0**-54)
    if edge > 0:
        assert np.any((d.transpose(0, 2, 1) == 0) & (full > 0))  # and the far sensors were skipped


@pytest.mark.parametrize("seed", range(4))
def test_exp_into_is_the_library_exp_within_two_ulp(seed):
    y = np.random.default_rng(seed).uniform(-700.0, 700.0, 5000)
    y[:6] = [0.0, -50.0, 50.0, 1e-300, -1e-17, 709.0]
    out = np.empty_like(y)
    kernels.exp_into(y, out, np.empty(y.size, dtype=np.int64))
    np.testing.assert_array_less(np.abs(out - np.exp(y)), 2.0 * np.spacing(np.exp(y)))


@pytest.mark.parametrize("seed", range(6))
def test_resampled_mean_is_the_mean_footprint_of_the_copies(seed):
    x, r, z = _frame(seed)
    p = FilterParams(pd=0.8, pf=0.02, edge=0.3)
    _, _, d = kernels.observation_update(x, r, z, SENSORS, RADII, p.pd, p.pf, p.edge, p.silent)
    idx = np.random.default_rng(seed).integers(0, x.shape[1], x.shape[:2])
    xs = np.take_along_axis(x, idx[..., None], axis=1)
    ref = footprint_probability(xs[..., :2], SENSORS, RADII, pd=p.pd, edge=p.edge).mean(axis=1)
    np.testing.assert_allclose(kernels.resampled_mean(d, idx), ref, rtol=1e-12, atol=2.0**-54)


def test_compiled_run_gives_the_numpy_runs_tracks():
    rng = np.random.default_rng(5)
    T = 60
    walk = np.c_[np.linspace(0.0, 16.0, T), np.zeros(T)]
    p_on = 0.9 * (np.abs(walk[:, None, 0] - SENSORS[None, :, 0]) <= 1.0)
    on = rng.random(p_on.shape) < np.maximum(p_on, 0.005)
    p = FilterParams(particles=80, pd=0.9, pf=0.005, edge=0.2, period=1.0, max_out=1, max_tracks=3)
    lo, hi = np.array([-1.0, -1.0]), np.array([18.0, 1.0])
    a = run_filter(on, SENSORS, RADII, lo, hi, p, seed=2, compiled=True)
    b = run_filter(on, SENSORS, RADII, lo, hi, p, seed=2, compiled=False)
    assert a.reported.any()
    np.testing.assert_array_equal(a.label, b.label)
    np.testing.assert_array_equal(a.reported, b.reported)
    np.testing.assert_allclose(a.x, b.x, atol=1e-9)
    np.testing.assert_allclose(a.y, b.y, atol=1e-9)
    np.testing.assert_allclose(a.r, b.r, atol=1e-9)


@pytest.mark.parametrize("seed", range(10))
def test_compiled_resampling_draws_the_numpy_indices_and_copies(seed):
    from onebit.trackers.binpf.filter import systematic_resample

    rng = np.random.default_rng(seed)
    logw = rng.normal(0, 3, (int(rng.integers(1, 6)), int(rng.integers(1, 200))))
    logw[0, : logw.shape[1] // 2] = -800.0  # weights that underflow to 0 next to the others
    ref = systematic_resample(logw, np.random.default_rng(seed + 100))
    idx = kernels.systematic_resample(logw, np.random.default_rng(seed + 100).random((logw.shape[0], 1)))
    np.testing.assert_array_equal(idx, ref)
    x = rng.random((*logw.shape, 4))
    hist = rng.random((*logw.shape, 5, 2))
    xo, ho = kernels.gather_particles(x, hist, idx)
    np.testing.assert_array_equal(xo, np.take_along_axis(x, idx[..., None], axis=1))
    np.testing.assert_array_equal(ho, np.take_along_axis(hist, idx[..., None, None], axis=1))


def _two_walkers(seed, T=300):
    rng = np.random.default_rng(seed)
    walk = np.c_[8 + 8 * np.sin(np.linspace(0.0, 6, T)), 8 - 8 * np.sin(np.linspace(0.0, 9, T))]
    near = (np.abs(walk[:, :, None] - SENSORS[None, None, :, 0]) <= 1.0).any(axis=1)
    return rng.random(near.shape) < np.where(near, 0.9, 0.02)


@pytest.mark.parametrize(("seed", "edge", "lag", "log"), [(1, 0.2, 4, 10), (2, 0.0, 0, 0), (3, 0.3, 2, 500)])
def test_compiled_frame_loop_equals_its_per_frame_reference(seed, edge, lag, log):
    on = _two_walkers(seed)
    p = FilterParams(particles=60, pd=0.9, pf=0.005, edge=edge, period=1.0, max_out=2, max_tracks=4, smooth_lag=lag)
    lo, hi = np.array([-1.0, -1.0]), np.array([18.0, 1.0])
    a = run_filter(on, SENSORS, RADII, lo, hi, p, seed=seed, compiled=True, log_particles=log)
    b = run_filter_reference(on, SENSORS, RADII, lo, hi, p, seed=seed, compiled=True, log_particles=log)
    assert a.births.sum() > 2 and a.merges.sum() + a.deaths.sum() > 0 and a.reported.any()
    for f in ("frame", "label", "reported", "births", "deaths", "merges", "live"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    for f in ("particles_frame", "particles_label", "particles_xy", "x", "y", "r"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)


def test_compiled_frame_loop_in_chunks_is_one_loop(monkeypatch):
    from onebit.trackers.binpf import filter as F

    on = _two_walkers(4, T=120)
    p = FilterParams(particles=40, pd=0.9, pf=0.005, edge=0.2, period=1.0, max_out=2, max_tracks=3)
    lo, hi = np.array([-1.0, -1.0]), np.array([18.0, 1.0])
    seen = []
    a = run_filter(on, SENSORS, RADII, lo, hi, p, seed=4, compiled=True, log_particles=5)
    monkeypatch.setattr(F, "CHUNK_FRAMES", 7)
    b = run_filter(
        on, SENSORS, RADII, lo, hi, p, seed=4, compiled=True, log_particles=5, progress=lambda d, t: seen.append(d)
    )
    assert seen[0] == 7 and seen[-1] == 120
    for f in ("frame", "label", "reported", "x", "y", "r", "particles_xy", "live"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("edge", [0.3, 0.0])
def test_newborn_update_is_the_concatenated_updates_newborn_rows_bit_for_bit(seed, edge):
    x, r, z = _frame(seed, I=5, N=40)
    p = FilterParams(pd=0.8, pf=0.02, edge=edge, silent=0.3)
    args = (SENSORS, RADII, p.pd, p.pf, p.edge, p.silent)
    ell, r1, d = kernels.observation_update(x[:3], r[:3], z, *args)
    idx = kernels.systematic_resample(ell, np.random.default_rng(seed).random((3, 1)))
    old, _ = kernels.gather_particles(x[:3], np.zeros((3, 40, 1, 2)), idx)
    q_old = 1.0 - r1[:, None] * kernels.resampled_mean(d, idx)
    ell_b, r_b = kernels.newborn_update(x[3:], r[3:], q_old, z, *args)
    ell_all, r_all, _ = kernels.observation_update(np.concatenate([old, x[3:]]), np.r_[r1, r[3:]], z, *args)
    np.testing.assert_array_equal(ell_b, ell_all[3:])
    np.testing.assert_array_equal(r_b, r_all[3:])


@pytest.mark.parametrize("lag", [0, 1, 4])
def test_gather_shift_is_the_shift_then_the_gather(lag):
    rng = np.random.default_rng(lag)
    x = rng.random((3, 20, 4))
    hist = rng.random((3, 20, lag + 1, 2))
    idx = np.sort(rng.integers(0, 20, (3, 20)), axis=1)
    shifted = np.concatenate([hist[:, :, 1:], x[:, :, None, :2]], axis=2)
    want_x, want_h = kernels.gather_particles(x, shifted, idx)
    xo, ho = np.empty_like(x), np.empty_like(hist)
    kernels.gather_shift(x, hist, idx, xo, ho)
    np.testing.assert_array_equal(xo, want_x)
    np.testing.assert_array_equal(ho, want_h)
