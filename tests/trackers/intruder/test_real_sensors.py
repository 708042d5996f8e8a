"""The intruder filter on real binary sensors (issue 23): a level sensor held on is presence
in every iteration, and a sensor whose characterisation states no false-alarm rate gets the
config's h > 0, so one reading far from every particle cannot zero them all."""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.site import site_from_dict
from onebit.core.tables import MOTION
from onebit.models.pir import deploy
from onebit.trackers.intruder.stage import IntruderConfig, observations, run


def _site(signal: str = "level", with_type: str | None = None) -> dict:
    d = {
        "units": "m",
        "boundary": {"polygon": [[0, 0], [10, 0], [10, 4], [0, 4]]},
        "binary_sensors": [
            {"id": f"s{i}", "position": [1.0 + 2.0 * i, 2.0], "radius": 1.0, "signal": signal} for i in range(5)
        ],
    }
    if with_type:
        d["sensor_types"] = {with_type: {"signal": signal}}
        for b in d["binary_sensors"]:
            b["type"] = with_type
    return d


def _motion(rows) -> pl.DataFrame:
    return pl.DataFrame(rows, schema=MOTION, orient="row")


def test_a_held_level_sensor_fires_in_every_iteration_it_is_on():
    site = site_from_dict(_site())
    motion = _motion([(0.1, "s0", True), (7.9, "s0", False), (9.0, "s4", True), (9.5, "s4", False)])
    edge, _, t_end = observations(motion, site, period=2.0, start=0.0, end=10.0)
    held, _, _ = observations(motion, site, period=2.0, start=0.0, end=10.0, held=True)
    assert edge[:, 0].tolist() == [True, False, False, False, False]
    assert held[:, 0].tolist() == [True, True, True, True, False]
    assert held[:, 4].tolist() == edge[:, 4].tolist() == [False, False, False, False, True]
    edge_site = site_from_dict(_site(signal="edge"))  # a PIR (edge) held on is not re-counted
    held_pir, _, _ = observations(motion, edge_site, period=2.0, start=0.0, end=10.0, held=True)
    assert held_pir[:, 0].tolist() == edge[:, 0].tolist()


def test_false_alarm_default_only_where_the_characterisation_is_silent():
    site = site_from_dict(_site())
    assert np.all(deploy(site, 0.5).p0 == 0.0)
    dep = deploy(site, 0.5, false_alarm=0.05)
    xi = (dep.q > 0).reshape(len(dep.ids), -1).sum(axis=1)
    np.testing.assert_allclose(1 - (1 - dep.p0) ** xi, 0.05)  # P(fires | nobody) = h
    typed = _site(with_type="ceiling")
    typed["sensor_types"]["ceiling"]["false_positive"] = 0.2  # a stated h is kept
    dep = deploy(site_from_dict(typed), 0.5, false_alarm=0.05)
    xi = (dep.q > 0).reshape(len(dep.ids), -1).sum(axis=1)
    np.testing.assert_allclose(1 - (1 - dep.p0) ** xi, 0.2)


def test_one_far_firing_does_not_lose_the_person():
    """A person held under s0 the whole run; one spurious firing of s4 (8 m away) mid-run.
    With h = 0 the firing is impossible away from s4 and drags the estimate there; with the
    default h the estimate stays by s0."""
    site = site_from_dict(_site())
    motion = _motion([(0.0, "s0", True), (20.5, "s4", True), (20.9, "s4", False), (39.0, "s0", False)])
    inputs = {"motion": motion}
    cfg = dict(particles=400, end=40.0, start=0.0, cell=1.0, log_particles=0)
    robust = run(inputs, site, IntruderConfig(**cfg))["tracks"]
    after = robust.filter((pl.col("t") > 22.0) & (pl.col("t") <= 30.0))
    assert after.height and (after["x"] - 1.0).abs().max() < 2.0
    naive = run(inputs, site, IntruderConfig(**cfg, false_alarm=0.0, held=False))["tracks"]
    worse = naive.filter((pl.col("t") > 22.0) & (pl.col("t") <= 30.0))
    assert (worse["x"] - 1.0).abs().mean() > (after["x"] - 1.0).abs().mean()
