"""The compiled SIR iteration against the named numpy steps it fuses (the plain reference):
same seed -> same particles, redraws, estimates and resampling; ESS, spread and log
weights equal to 1e-9."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from onebit.core.site import site_from_dict
from onebit.datasets.pir_sim import simulate
from onebit.models.motion import Motion, Room, prior
from onebit.models.pir import Deployment, WorldGrid, deploy, log_weights
from onebit.trackers.intruder import kernels
from onebit.trackers.intruder.filter import run_filter, run_filter_reference

MOTION = Motion(period=2.0, v_max=4.0, speed_sigma=1.5, turn_scale=4.0, max_retries=50)


def _random_deployment(rng, n, *, nx=10, ny=8, cell=1.0, h=None) -> Deployment:
    """``n`` sensors with random detection grids (each a random blob of cells) and random
    false-positive rates ``h`` (including 0 and 1: a sensor that always fires)."""
    q = np.zeros((n, ny, nx))
    for i in range(n):
        cx, cy = rng.uniform(0, nx), rng.uniform(0, ny)
        xs, ys = np.meshgrid(np.arange(nx) + 0.5, np.arange(ny) + 0.5)
        r = rng.uniform(1.0, 4.0)
        inside = (xs - cx) ** 2 + (ys - cy) ** 2 <= r * r
        q[i][inside] = rng.uniform(0.2, 1.0, inside.sum())
        if not inside.any():
            q[i, int(cy) % ny, int(cx) % nx] = 0.7
    xi = (q > 0).sum(axis=(1, 2))
    hs = rng.choice([0.0, 0.0, 0.1, 0.25, 1.0], size=n) if h is None else np.full(n, h)
    p0 = 1.0 - (1.0 - hs) ** (1.0 / xi)
    return Deployment(
        tuple(f"s{i}" for i in range(n)),
        WorldGrid(0.0, 0.0, cell, nx, ny),
        q,
        p0,
        np.full(n, 1e-6),
        np.zeros(n),
        xi,
        (),
    )


@pytest.mark.parametrize("seed", range(6))
def test_log_likelihood_equals_reference(seed):
    rng = np.random.default_rng(seed)
    dep = _random_deployment(rng, int(rng.integers(1, 12)))
    n = 3000
    x = rng.uniform(-0.5, 10.5, n)
    y = rng.uniform(-0.5, 8.5, n)
    x[:20] = np.round(x[:20])  # box edges exactly on cell edges
    g = dep.grid
    grid = np.array([g.x0, g.y0, g.cell, g.nx, g.ny], float)
    ptr, sensor, q = kernels.cell_lists(dep.q)
    a = np.array([math.exp(v) for v in np.log1p(-np.minimum(dep.p0, 1 - 1e-12))])
    for trial in range(6):
        fired = rng.random(len(dep.ids)) < 0.4
        blind = rng.random(len(dep.ids)) < (0.0 if trial == 0 else 0.3)
        half_w, half_d = rng.choice([0.5, 1.0, 1.3]), rng.choice([0.5, 1.0, 2.0])
        ref = log_weights(x, y, fired, blind, dep, half_w, half_d)
        out = np.empty(n)
        kernels._log_likelihood(
            x, y, fired, blind, grid, ptr, sensor, q, dep.p0, dep.xi.astype(float), a, half_w, half_d, out
        )
        np.testing.assert_allclose(out, ref, rtol=1e-9, atol=1e-9)


def test_cell_lists_round_trip():
    rng = np.random.default_rng(1)
    dep = _random_deployment(rng, 5)
    ptr, sensor, q = kernels.cell_lists(dep.q)
    back = np.zeros_like(dep.q).reshape(5, -1)
    cells = np.repeat(np.arange(len(ptr) - 1), np.diff(ptr))
    back[sensor, cells] = q
    np.testing.assert_array_equal(back.reshape(dep.q.shape), dep.q)
    for c in range(len(ptr) - 1):  # sensors in order within a cell
        assert np.all(np.diff(sensor[ptr[c] : ptr[c + 1]]) > 0)


def _same(a, b):
    np.testing.assert_array_equal(a.estimates, b.estimates)
    np.testing.assert_array_equal(a.redraws, b.redraws)
    np.testing.assert_array_equal(a.clamped, b.clamped)
    np.testing.assert_array_equal(a.resampled, b.resampled)
    np.testing.assert_array_equal(a.logged_xy, b.logged_xy)
    np.testing.assert_allclose(a.logged_w, b.logged_w, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a.ess, b.ess, rtol=1e-9)
    np.testing.assert_allclose(a.spread, b.spread, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("resample, when", [("systematic", "always"), ("multinomial", "always"), ("systematic", "ess")])
def test_run_filter_equals_reference_in_a_box_room(seed, resample, when):
    rng = np.random.default_rng(seed)
    dep = _random_deployment(rng, 8)
    T = 12
    fired = rng.random((T, 8)) < 0.3
    blind = rng.random((T, 8)) < 0.3
    room = Room(shapely.box(0, 0, 10, 8))
    kw = dict(n_particles=700, half_w=1.0, half_d=1.0, resample=resample, resample_when=when, log_particles=25)
    a = run_filter(fired, blind, dep, room, MOTION, rng=np.random.default_rng(seed), compiled=True, **kw)
    b = run_filter_reference(fired, blind, dep, room, MOTION, rng=np.random.default_rng(seed), **kw)
    _same(a, b)


def test_run_filter_equals_reference_around_an_obstacle():
    """A room that is not a box: numpy/shapely propagation, the kernel for the rest."""
    rng = np.random.default_rng(5)
    dep = _random_deployment(rng, 6)
    room = Room(shapely.box(0, 0, 10, 8).difference(shapely.box(4, 2, 6, 6)))
    assert not room.is_box
    fired = rng.random((10, 6)) < 0.3
    blind = rng.random((10, 6)) < 0.2
    kw = dict(n_particles=500, half_w=1.0, half_d=1.0, log_particles=10)
    _same(
        run_filter(fired, blind, dep, room, MOTION, rng=np.random.default_rng(2), compiled=True, **kw),
        run_filter_reference(fired, blind, dep, room, MOTION, rng=np.random.default_rng(2), **kw),
    )


def test_run_filter_equals_reference_on_a_simulated_pir_run():
    d, sim = simulate("pir8", seed=3, duration=40.0, refractory=4.0)
    site = site_from_dict(d)
    dep = deploy(site, 1.0)
    rng = np.random.default_rng(0)
    fired = rng.random((20, len(dep.ids))) < 0.25
    blind = rng.random((20, len(dep.ids))) < 0.4
    room = Room(site.free_space)
    kw = dict(n_particles=2000, half_w=1.0, half_d=1.0, log_particles=100)
    _same(
        run_filter(fired, blind, dep, room, MOTION, rng=np.random.default_rng(9), compiled=True, **kw),
        run_filter_reference(fired, blind, dep, room, MOTION, rng=np.random.default_rng(9), **kw),
    )


def test_run_filter_without_iterations_or_sensors():
    dep = _random_deployment(np.random.default_rng(0), 3)
    room = Room(shapely.box(0, 0, 10, 8))
    res = run_filter(
        np.zeros((0, 3), bool),
        np.zeros((0, 3), bool),
        dep,
        room,
        MOTION,
        n_particles=10,
        half_w=1,
        half_d=1,
        rng=np.random.default_rng(0),
        compiled=True,
    )
    assert res.estimates.shape == (0, 2)
    none = Deployment(
        (), dep.grid, np.zeros((0, 8, 10)), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, np.int64), ()
    )
    kw = dict(n_particles=50, half_w=1.0, half_d=1.0)
    _same(
        run_filter(
            np.zeros((3, 0), bool),
            np.zeros((3, 0), bool),
            none,
            room,
            MOTION,
            rng=np.random.default_rng(1),
            compiled=True,
            **kw,
        ),
        run_filter_reference(
            np.zeros((3, 0), bool), np.zeros((3, 0), bool), none, room, MOTION, rng=np.random.default_rng(1), **kw
        ),
    )


def test_prior_unchanged():
    """The kernel starts from the same prior draw as the reference (shared rng stream)."""
    room = Room(shapely.box(0, 0, 10, 8))
    a = prior(100, room, MOTION, np.random.default_rng(3))
    b = prior(100, room, MOTION, np.random.default_rng(3))
    np.testing.assert_array_equal(a.x, b.x)


@pytest.mark.parametrize("retries", [0, 1, 3])
def test_propagation_with_few_rounds_equals_reference(retries):
    """Few rejection rounds: many particles are never placed (kept with speed 0)."""
    rng = np.random.default_rng(retries)
    dep = _random_deployment(rng, 5)
    motion = Motion(period=2.0, v_max=4.0, speed_sigma=1.5, turn_scale=4.0, max_retries=retries)
    fired = rng.random((6, 5)) < 0.3
    blind = np.zeros((6, 5), bool)
    room = Room(shapely.box(0, 0, 10, 8))
    kw = dict(n_particles=400, half_w=1.0, half_d=1.0, log_particles=400)
    _same(
        run_filter(fired, blind, dep, room, motion, rng=np.random.default_rng(1), compiled=True, **kw),
        run_filter_reference(fired, blind, dep, room, motion, rng=np.random.default_rng(1), **kw),
    )


@pytest.mark.parametrize("n_sensors", [16, 17, 24])
def test_log_likelihood_equals_reference_with_many_live_sensors(n_sensors):
    """Up to 16 live sensors the batch is combined sensor by sensor, above one particle at a time."""
    rng = np.random.default_rng(n_sensors)
    dep = _random_deployment(rng, n_sensors)
    n = 2000
    x, y = rng.uniform(-0.5, 10.5, n), rng.uniform(-0.5, 8.5, n)
    g = dep.grid
    grid = np.array([g.x0, g.y0, g.cell, g.nx, g.ny], float)
    ptr, sensor, q = kernels.cell_lists(dep.q)
    a = np.array([math.exp(v) for v in np.log1p(-np.minimum(dep.p0, 1 - 1e-12))])
    for fired in (rng.random(n_sensors) < 0.5, np.ones(n_sensors, bool), np.zeros(n_sensors, bool)):
        blind = np.zeros(n_sensors, bool)
        out = np.empty(n)
        kernels._log_likelihood(
            x, y, fired, blind, grid, ptr, sensor, q, dep.p0, dep.xi.astype(float), a, 1.0, 1.0, out
        )
        np.testing.assert_allclose(out, log_weights(x, y, fired, blind, dep, 1.0, 1.0), rtol=1e-9, atol=1e-9)
