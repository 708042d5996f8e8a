"""The intruder filter senses through the site's detection regions: a ``fov`` polygon or a
``range`` disk is honoured, a sensor without a region is an error, never a built-in wedge."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.errors import SiteError
from onebit.core.site import site_from_dict
from onebit.core.tables import MOTION
from onebit.core.units import config_in_site_units
from onebit.trackers.intruder.stage import IntruderConfig, run

QUADRANTS = {
    "sw": [[0, 0], [5, 0], [5, 5], [0, 5]],
    "se": [[5, 0], [10, 0], [10, 5], [5, 5]],
    "ne": [[5, 5], [10, 5], [10, 10], [5, 10]],
    "nw": [[0, 5], [5, 5], [5, 10], [0, 10]],
}
CENTRES = {"sw": (2.5, 2.5), "se": (7.5, 2.5), "ne": (7.5, 7.5), "nw": (2.5, 7.5)}


def quadrant_site(scale: float = 1.0, units: str = "m"):
    """Four sensors, each seeing one quadrant of a 10 x 10 m room through its ``fov`` only
    (heading 0 and no type: the old built-in 8 m wedge would look along +x from each)."""
    sensors = [
        {
            "id": k,
            "position": [scale * CENTRES[k][0], scale * CENTRES[k][1]],
            "fov": (np.asarray(v, float) * scale).tolist(),
        }
        for k, v in QUADRANTS.items()
    ]
    box = (np.asarray([[0, 0], [10, 0], [10, 10], [0, 10]], float) * scale).tolist()
    return site_from_dict(
        {"name": "q", "units": units, "targets": 1, "boundary": {"polygon": box}, "motion_sensors": sensors}
    )


def walk_motion(visits: list[str], period: float = 2.0) -> pl.DataFrame:
    """The intruder in quadrant ``visits[k]`` during iteration ``k``: that sensor fires once."""
    t_on = (np.arange(len(visits)) + 0.5) * period
    t = np.r_[t_on, t_on + 0.2 * period]
    sensor = visits + visits
    on = [True] * len(visits) + [False] * len(visits)
    return pl.DataFrame({"t": t, "sensor": sensor, "on": on}, schema=MOTION).sort("t")


VISITS = ["sw"] * 4 + ["se"] * 4 + ["ne"] * 4 + ["nw"] * 4 + ["sw"] * 3


def test_fov_polygons_are_the_deployed_regions():
    out = run({"motion": walk_motion(VISITS)}, quadrant_site(), IntruderConfig(particles=300, seed=1))
    cov = out["coverage"]
    for sid, poly in QUADRANTS.items():
        c = cov.filter(pl.col("sensor") == sid)
        (x0, y0), (x1, y1) = poly[0], poly[2]
        assert c.height == 25 and (c["p_detect"] == 1.0).all()
        assert c["x"].is_between(x0, x1).all() and c["y"].is_between(y0, y1).all()


def test_the_filter_follows_the_quadrant_that_fired():
    out = run({"motion": walk_motion(VISITS)}, quadrant_site(), IntruderConfig(particles=300, seed=1))
    tr = out["tracks"].sort("t")
    want = np.array([CENTRES[v] for v in VISITS])
    got = tr.select("x", "y").to_numpy()
    # the estimate is the cell maximising the particles in the box: in the fired quadrant
    inside = np.all(np.abs(got - want) <= 2.5 + 1e-9, axis=1)
    assert inside.mean() >= 0.9


def test_cm_site_same_estimates():
    motion = walk_motion(VISITS)
    a = run({"motion": motion}, quadrant_site(), IntruderConfig(particles=300, seed=1))
    site_cm = quadrant_site(100.0, "cm")
    b = run({"motion": motion}, site_cm, config_in_site_units(IntruderConfig(particles=300, seed=1), site_cm))
    np.testing.assert_allclose(a["tracks"]["x"].to_numpy() * 100, b["tracks"]["x"].to_numpy(), rtol=1e-9)
    np.testing.assert_allclose(a["tracks"]["y"].to_numpy() * 100, b["tracks"]["y"].to_numpy(), rtol=1e-9)
    np.testing.assert_allclose(a["coverage"]["p_detect"].to_numpy(), b["coverage"]["p_detect"].to_numpy())


def test_a_sensor_without_a_region_is_an_error_not_a_default_wedge():
    site = site_from_dict(
        {
            "name": "bad",
            "units": "m",
            "targets": 1,
            "boundary": {"polygon": [[0, 0], [10, 0], [10, 10], [0, 10]]},
            "motion_sensors": [{"id": "a", "position": [1.0, 1.0], "range": 2.0}, {"id": "b", "position": [9.0, 9.0]}],
        },
        source="bad/site.toml",
    )
    with pytest.raises(SiteError, match=r"bad/site.toml: field 'motion_sensors\[1\] \(id 'b'\)': no detection region"):
        run({"motion": walk_motion(["a", "b"])}, site, IntruderConfig(particles=50))
