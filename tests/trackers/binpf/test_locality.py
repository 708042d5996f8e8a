"""binpf's frame cost follows the sensors near the tracks: the local update (footprints of the
near sensors only, in a buffer whose other rows are never read) gives the dense update's
log-weights, existences and resampled mean footprints bit for bit, on wide arrays where most
sensors are far from every track."""

from __future__ import annotations

import numpy as np
import pytest

from onebit.trackers.binpf import kernels
from onebit.trackers.binpf.filter import FilterParams, run_filter, run_filter_reference

# a 40 x 40 m floor under a 20 x 20 array: a track's reach (R + 38 w = 12.4 m) is a part of it
XS, YS = np.meshgrid(1.0 + 2.0 * np.arange(20), 1.0 + 2.0 * np.arange(20))
SENSORS = np.c_[XS.ravel(), YS.ravel()]
RADII = np.full(len(SENSORS), 1.0)


def _state(seed, I=6, N=40):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0.0, 40.0, (I, 1, 2))
    x = np.concatenate([centres + rng.normal(0, 0.5, (I, N, 2)), rng.normal(size=(I, N, 2))], axis=-1)
    return x, rng.uniform(0.05, 0.95, I), rng.random(len(SENSORS)) < 0.05


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize(("edge", "silent"), [(0.3, 0.3), (0.05, 0.0), (0.0, 0.2)])
def test_local_update_equals_dense_bit_for_bit(seed, edge, silent):
    x, r, z = _state(seed)
    args = (z, SENSORS, RADII, 0.75, 0.01, edge, silent)
    ell, r_new, d = kernels.observation_update(x, r, *args)
    dbuf = np.full((x.shape[0] + 2, len(SENSORS), x.shape[1]), np.nan)  # unset rows: NaN if read
    ell_l, r_l, d_l, near = kernels.observation_update_local(x, r, *args, dbuf)
    assert near.mean() < 0.9  # far sensors exist
    np.testing.assert_array_equal(ell_l, ell)
    np.testing.assert_array_equal(r_l, r_new)
    np.testing.assert_array_equal(d_l[near], d[near])
    idx = np.random.default_rng(seed).integers(0, x.shape[1], (x.shape[0], x.shape[1]))
    np.testing.assert_array_equal(kernels.resampled_mean_near(d_l, idx, near), kernels.resampled_mean(d, idx))


def test_whole_run_on_a_wide_array_equals_the_dense_per_frame_reference():
    """The compiled loop (local update, a buffer kept over the frames) against the per-frame
    reference (dense footprints, zero away from the tracks): every row, bit for bit."""
    rng = np.random.default_rng(3)
    T = 30
    people = np.stack([np.linspace([3.0, 3.0], [15.0, 9.0], T), np.linspace([35.0, 30.0], [25.0, 36.0], T)], axis=1)
    d = np.hypot(people[:, :, None, 0] - SENSORS[None, None, :, 0], people[:, :, None, 1] - SENSORS[None, None, :, 1])
    on = (d < 0.9).any(axis=1) & (rng.random((T, len(SENSORS))) < 0.9)
    p = FilterParams(particles=60, max_tracks=4, max_out=3, period=0.5)
    a = run_filter(on, SENSORS, RADII, np.zeros(2), np.full(2, 40.0), p, seed=1, compiled=True)
    b = run_filter_reference(on, SENSORS, RADII, np.zeros(2), np.full(2, 40.0), p, seed=1, compiled=True)
    assert len(np.unique(a.label[a.reported])) >= 2
    for f in ("frame", "label", "x", "y", "r", "reported", "births", "deaths", "merges", "live"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
