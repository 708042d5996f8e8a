"""The PIR model deployed on the site's detection regions (onebit.models.pir)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import SiteError
from onebit.core.sensing import detection_regions
from onebit.core.site import load_site, site_from_dict
from onebit.datasets.builtin import builtin_site_path
from onebit.datasets.pir_sim import site_dict
from onebit.models.pir import WorldGrid, deploy, sensor_type, window_fraction

BOX = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]


def make_site(sensors, types=None, *, units="m", scale=1.0):
    d = {
        "name": "t",
        "units": units,
        "boundary": {"polygon": (np.asarray(BOX) * scale).tolist()},
        "motion_sensors": sensors,
    }
    if types:
        d["sensor_types"] = types
    return site_from_dict(d, source="t/site.toml")


def cell_boxes(grid: WorldGrid):
    cx, cy = grid.centres()
    h = grid.cell / 2
    return shapely.box(cx - h, cy - h, cx + h, cy + h)


@settings(max_examples=40, deadline=None)
# no subnormal coordinates (below 2.2e-308 m): GEOS's overlays of a disk centred at x = 5e-324
# miscount its area inside the room (8.96 against 8.48 m^2, found by hypothesis); no site has them
@given(
    x=st.floats(0, 10, allow_subnormal=False),
    y=st.floats(0, 10, allow_subnormal=False),
    r=st.floats(0.3, 6),
    cell=st.sampled_from([0.5, 1.0, 2.0]),
)
def test_range_only_sensor_detects_with_the_area_fraction_of_its_disk(x, y, r, cell):
    """No type: q_ij = |c_j cap disk| / |c_j| (perfect detection inside the disk), h = 0."""
    site = make_site([{"id": "m", "position": [x, y], "range": r}])
    dep = deploy(site, cell)
    q = dep.q[0]
    disk = detection_regions(site)["m"].window
    want = shapely.area(shapely.intersection(cell_boxes(dep.grid), disk)) / cell**2
    np.testing.assert_allclose(q, want, atol=1e-12)
    assert ((q >= 0) & (q <= 1)).all()
    assert dep.xi[0] == (q > 0).sum() and dep.p0[0] == 0.0
    # the deployed mass is the disk's area inside the room (in cells)
    assert q.sum() * cell**2 == pytest.approx(shapely.intersection(disk, site.boundary).area, rel=1e-9)


@settings(max_examples=30, deadline=None)
@given(
    x0=st.floats(0, 4.5),
    y0=st.floats(0, 4.5),
    x1=st.floats(5.5, 10),
    y1=st.floats(5.5, 10),
    heading=st.sampled_from([0.0, 45.0, 90.0, 200.0]),
)
def test_fov_polygon_restricts_the_characterisation(x0, y0, x1, y1, heading):
    """A typed sensor with a fov (a box around the sensor, so the two overlap):
    q_ij = q^type_ij * |c_j cap fov| / |c_j|."""
    w, h = x1 - x0, y1 - y0
    types = {"pir": {"kind": "pir-triangle", "range": 8.0, "fov": 60.0, "resolution": 1.0, "falloff": 0.5}}
    free = make_site([{"id": "m", "position": [5.0, 5.0], "heading": heading, "type": "pir"}], types)
    fov = [[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]]
    clipped = make_site([{"id": "m", "position": [5.0, 5.0], "heading": heading, "type": "pir", "fov": fov}], types)
    q_type = deploy(free, 1.0).q[0]
    dep = deploy(clipped, 1.0)
    a = window_fraction(dep.grid, shapely.Polygon(fov))
    np.testing.assert_allclose(dep.q[0], q_type * a, atol=1e-12)
    assert (dep.q[0] <= q_type + 1e-12).all()
    # cells wholly inside the fov keep the characterisation, cells outside it lose it
    assert np.array_equal(dep.q[0][a == 1.0], q_type[a == 1.0]) and (dep.q[0][a == 0.0] == 0).all()


def test_a_fov_covering_the_room_changes_nothing():
    d = site_dict("pir14-imperfect", 4.0)
    before = deploy(site_from_dict(d), 1.0)
    for s in d["motion_sensors"]:
        s["fov"] = [[-1.0, -1.0], [11.0, -1.0], [11.0, 11.0], [-1.0, 11.0]]
    after = deploy(site_from_dict(d), 1.0)
    assert (
        np.array_equal(before.q, after.q)
        and np.array_equal(before.p0, after.p0)
        and np.array_equal(before.xi, after.xi)
    )


def test_the_same_room_in_cm_deploys_the_same_grid():
    d = site_dict("pir14-imperfect", 4.0)
    m = site_from_dict(d)
    cm = dict(d, units="cm", boundary={"polygon": (np.asarray(d["boundary"]["polygon"]) * 100).tolist()})
    cm["motion_sensors"] = [
        dict(s, position=[100 * s["position"][0], 100 * s["position"][1]]) for s in d["motion_sensors"]
    ]
    cm["sensor_types"] = {
        k: dict(t, range=t["range"] * 100, resolution=t["resolution"] * 100) for k, t in d["sensor_types"].items()
    }
    a, b = deploy(m, 1.0), deploy(site_from_dict(cm), 100.0)
    np.testing.assert_allclose(a.q, b.q, atol=1e-12)
    np.testing.assert_allclose(a.p0, b.p0)
    assert np.array_equal(a.xi, b.xi)
    for ha, hb in zip(a.hulls, b.hulls):
        assert hb.area == pytest.approx(ha.area * 1e4)


def test_builtin_type_is_metres_on_a_cm_site():
    m = make_site([{"id": "p", "position": [5.0, 0.0], "heading": 90.0, "type": "pir"}])
    cm = make_site([{"id": "p", "position": [500.0, 0.0], "heading": 90.0, "type": "pir"}], units="cm", scale=100.0)
    np.testing.assert_allclose(deploy(m, 1.0).q, deploy(cm, 100.0).q, atol=1e-12)
    assert sensor_type("pir", units="cm").samples[:, 0].max() == pytest.approx(800.0)


def test_hallway_sensors_detect_in_their_range_disks_not_a_default_wedge():
    site = load_site(builtin_site_path("hallway"))
    dep = deploy(site, 1.0)
    cx, cy = dep.grid.centres()
    for i, m in enumerate(site.motion_sensors):
        nz = dep.q[i] > 0
        # every cell with q > 0 touches the disk: its centre is within range + half a cell diagonal
        d = np.hypot(cx[nz] - m.position[0], cy[nz] - m.position[1])
        assert (d <= m.range + math.sqrt(0.5)).all()
        # and every cell wholly inside the disk detects with probability 1
        corners = np.max(
            [np.hypot(cx + sx - m.position[0], cy + sy - m.position[1]) for sx in (-0.5, 0.5) for sy in (-0.5, 0.5)],
            axis=0,
        )
        assert (dep.q[i][corners <= m.range - 1e-9] == 1.0).all()


def test_wide_beam_type_samples_across_its_width():
    st_ = sensor_type("w", {"kind": "beam", "length": 4.0, "width": 2.0, "resolution": 1.0})
    assert sorted(set(st_.samples[:, 1].tolist())) == [-0.5, 0.5]
    assert sorted(set(st_.samples[:, 0].tolist())) == [0.5, 1.5, 2.5, 3.5]


def test_deploy_names_the_sensor_without_a_region():
    site = make_site([{"id": "ok", "position": [1.0, 1.0], "range": 1.0}, {"id": "bad", "position": [2.0, 2.0]}])
    with pytest.raises(SiteError, match=r"motion_sensors\[1\] \(id 'bad'\).*no detection region"):
        deploy(site, 1.0)
