"""``onebit simulate ceiling-building``: a ceiling array over a floor, people walking inside it,
frames at 2 Hz from the truth; deterministic for a seed; bad --param named."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.errors import ConfigError
from onebit.core.site import load_site
from onebit.datasets.catalogue import get_scenario


def test_floor_array_walks_and_frames(tmp_path):
    sc = get_scenario("ceiling-building")
    d = sc.write(
        tmp_path / "a", seed=4, duration=20.0, agents=5, drop=0.0, camera=False, params={"cols": "6", "rows": "4"}
    )
    site = load_site(d / "site.toml")
    assert len(site.binary_sensors) == 24 and site.targets == 5
    truth = pl.read_csv(d / "truth.csv")
    assert truth["target"].n_unique() == 5
    minx, miny, maxx, maxy = site.boundary.bounds
    assert (maxx, maxy) == (9.0, 6.0)
    assert truth["x"].is_between(minx, maxx).all() and truth["y"].is_between(miny, maxy).all()
    steps = truth.sort("t").group_by("target").agg((pl.col("x").diff() ** 2 + pl.col("y").diff() ** 2).sqrt().max())
    assert steps["x"].max() <= 1.3 * 0.5 + 1e-6  # walking speed
    frames = pl.read_csv(d / "frames.csv", schema_overrides={"active": pl.String})
    assert np.allclose(np.diff(frames["t"].to_numpy()), 0.5)
    assert frames["active"].drop_nulls().str.len_chars().sum() > 0
    again = sc.write(
        tmp_path / "b", seed=4, duration=20.0, agents=5, drop=0.0, camera=False, params={"cols": "6", "rows": "4"}
    )
    assert (again / "frames.csv").read_bytes() == (d / "frames.csv").read_bytes()


def test_bad_param_is_named(tmp_path):
    with pytest.raises(ConfigError, match="cols"):
        get_scenario("ceiling-building").write(tmp_path / "x", seed=0, params={"cols": "0"})
    with pytest.raises(ConfigError, match="unknown --param"):
        get_scenario("ceiling-building").write(tmp_path / "y", seed=0, params={"size": "3"})
