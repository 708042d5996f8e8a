"""The online intruder filter: fed growing prefixes of a log, it publishes exactly the batch
stage's rows, never a row before the log has passed it by ``settle``, and each row once."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.config import config_from_mapping
from onebit.core.site import load_site
from onebit.core.units import config_in_site_units
from onebit.datasets.catalogue import get_scenario
from onebit.readers.motion import read_motion_csv
from onebit.trackers.intruder import online
from onebit.trackers.intruder.stage import IntruderConfig, run


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    d = get_scenario("pir14").write(
        tmp_path_factory.mktemp("pir") / "d", seed=4, duration=40.0, agents=None, drop=0.0, camera=False, params={}
    )
    site = load_site(d / "site.toml")
    motion = read_motion_csv(d / "motion.csv", [m.id for m in site.motion_sensors]).motion
    return site, motion


@pytest.mark.parametrize("step", [0.3, 1.7, 6.0])
def test_prefixes_give_the_batch_rows_without_look_ahead(log, step):
    site, motion = log
    cfg = config_in_site_units(
        config_from_mapping(IntruderConfig, {"particles": 300, "camera_position": [1.0, 1.0, 2.5]}, section="intruder"),
        site,
    )
    batch = run({"motion": motion}, site, cfg)
    state = online.start(site, cfg)
    settle = 1.0
    parts = {"tracks": [], "iterations": [], "camera": []}
    for h in np.arange(0.0, float(motion["t"].max()) + 3.0, step):
        got = online.advance(state, motion.filter(pl.col("t") <= h), horizon=float(h), settle=settle)
        if got["tracks"].height:  # nothing published before the log passed it by settle
            assert got["tracks"]["t"].max() <= h - settle + 1e-9
        for k in parts:
            parts[k].append(got[k])
    last = online.advance(state, motion, horizon=float("inf"), settle=settle, final=True)
    for k in parts:
        parts[k].append(last[k])
        whole = pl.concat(parts[k])
        assert whole["t"].is_unique().all(), k  # each row once
        ref = batch[k]
        if k == "iterations":  # floating sums of the weights: equal to rounding
            assert whole.select("t", "redraws", "clamped", "resampled", "fired", "blind").equals(
                ref.select("t", "redraws", "clamped", "resampled", "fired", "blind")
            )
            np.testing.assert_allclose(whole["ess"].to_numpy(), ref["ess"].to_numpy(), rtol=1e-12)
        else:
            assert whole.equals(ref), k
    assert online.advance(state, motion, horizon=float("inf"), settle=settle, final=True)["tracks"].height == 0  # ended
