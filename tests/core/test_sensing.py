"""The base layer's sensor model: one detection region per sensor (onebit.core.sensing)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import SiteError
from onebit.core.sensing import (
    BUILTIN_TYPES,
    covers,
    current_node,
    detection_regions,
    sensor_to_world,
    type_geometry,
)
from onebit.core.site import site_from_dict

BOX = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]


def make_site(motion=(), proximity=(), beams=(), types=None, units="m", boundary=BOX):
    d = {"name": "t", "units": units, "boundary": {"polygon": boundary}}
    if motion:
        d["motion_sensors"] = list(motion)
    if proximity:
        d["proximity_sensors"] = list(proximity)
    if beams:
        d["beams"] = list(beams)
    if types:
        d["sensor_types"] = types
    return site_from_dict(d, source="t/site.toml")


finite = st.floats(-50, 50, allow_nan=False, allow_infinity=False)
radius = st.floats(0.05, 20, allow_nan=False, allow_infinity=False)
heading = st.floats(-360, 360, allow_nan=False, allow_infinity=False)
points = st.lists(st.tuples(finite, finite), min_size=1, max_size=40)


# --------------------------------------------------------------------------- regions


@settings(max_examples=60, deadline=None)
@given(x=st.floats(1, 9), y=st.floats(1, 9), r=radius, pts=points)
def test_range_region_is_the_closed_disk(x, y, r, pts):
    site = make_site(motion=[{"id": "m", "position": [x, y], "range": r}])
    reg = detection_regions(site)["m"]
    xy = np.asarray(pts)
    assert reg.kind == "motion" and reg.radius == r and reg.fov is None and reg.extent is None
    np.testing.assert_array_equal(reg.covers_xy(xy[:, 0], xy[:, 1]), np.hypot(xy[:, 0] - x, xy[:, 1] - y) <= r)
    # the polygon is inscribed in the disk and close to it
    assert reg.geometry.area <= math.pi * r * r
    assert reg.geometry.area == pytest.approx(math.pi * r * r, rel=2e-3)


@settings(max_examples=60, deadline=None)
@given(x=st.floats(0, 10), y=st.floats(0, 10), h=heading, rng=st.floats(0.5, 30), fov=st.floats(5, 170), pts=points)
def test_pir_triangle_region_is_the_rotated_triangle(x, y, h, rng, fov, pts):
    types = {"w": {"kind": "pir-triangle", "range": rng, "fov": fov}}
    site = make_site(motion=[{"id": "m", "position": [x, y], "heading": h, "type": "w"}], types=types)
    reg = detection_regions(site)["m"]
    half = math.tan(math.radians(fov / 2)) * rng
    assert reg.geometry.area == pytest.approx(rng * half, rel=1e-9)
    # a point is inside iff, in the sensor frame, 0 <= u <= range and |v| <= u tan(fov / 2)
    xy = np.asarray(pts)
    th = math.radians(h)
    d = xy - [x, y]
    u = d[:, 0] * math.cos(th) + d[:, 1] * math.sin(th)
    v = -d[:, 0] * math.sin(th) + d[:, 1] * math.cos(th)
    want = (u >= 0) & (u <= rng) & (np.abs(v) <= u * math.tan(math.radians(fov / 2)))
    margin = np.minimum(np.abs(u - rng), np.abs(np.abs(v) - u * math.tan(math.radians(fov / 2))))
    clear = margin > 1e-7 * max(1.0, rng)  # away from the edges, where rounding decides
    np.testing.assert_array_equal(reg.covers_xy(xy[clear, 0], xy[clear, 1]), want[clear])
    # the apex is the sensor, the axis points along the heading
    tip = sensor_to_world(np.array([[rng / 2, 0.0]]), (x, y), h)
    assert reg.covers_xy(tip[:, 0], tip[:, 1]).all()


@settings(max_examples=40, deadline=None)
@given(r=st.floats(0.5, 5), pts=points)
def test_fov_and_range_intersect(r, pts):
    fov = [[5.0, 5.0], [10.0, 5.0], [10.0, 10.0], [5.0, 10.0]]
    site = make_site(motion=[{"id": "m", "position": [5.0, 5.0], "fov": fov, "range": r}])
    reg = detection_regions(site)["m"]
    xy = np.asarray(pts)
    want = (
        (xy[:, 0] >= 5)
        & (xy[:, 0] <= 10)
        & (xy[:, 1] >= 5)
        & (xy[:, 1] <= 10)
        & (np.hypot(xy[:, 0] - 5, xy[:, 1] - 5) <= r)
    )
    np.testing.assert_array_equal(reg.covers_xy(xy[:, 0], xy[:, 1]), want)
    assert reg.geometry.area == pytest.approx(math.pi * r * r / 4, rel=2e-3)  # a quarter disk
    assert reg.window.equals(reg.geometry)  # no type: the window is the whole region


@settings(max_examples=40, deadline=None)
@given(
    k=st.sampled_from([0.01, 0.3048, 2.54, 100.0, 1000.0]),
    x=st.floats(1, 9),
    y=st.floats(1, 9),
    r=st.floats(0.2, 4),
    h=heading,
)
def test_regions_scale_with_the_site(k, x, y, r, h):
    """The same site drawn k times larger has every region k times larger (types included)."""

    def site(f):
        types = {
            "w": {"kind": "pir-triangle", "range": 6 * f, "fov": 60.0, "resolution": 2 * f},
            "g": {"samples": [[f, 0, 1], [2 * f, f, 0.5], [2 * f, -f, 0.2]]},
        }
        return make_site(
            motion=[
                {"id": "a", "position": [x * f, y * f], "range": r * f},
                {"id": "b", "position": [x * f, y * f], "heading": h, "type": "w"},
                {"id": "c", "position": [x * f, y * f], "heading": h, "type": "g", "range": 1.5 * f},
            ],
            proximity=[{"id": "p", "position": [y * f, x * f], "r_inner": 0.5 * r * f, "r_outer": r * f}],
            beams=[{"id": "b1", "segment": [[5 * f, 0], [5 * f, 10 * f]], "spacing": 0.2 * f}],
            types=types,
            boundary=(np.asarray(BOX) * f).tolist(),
        )

    a, b = detection_regions(site(1.0)), detection_regions(site(k))
    assert list(a) == list(b) == ["a", "b", "c", "p", "b1"]
    for sid in a:
        ga, gb = a[sid].geometry, b[sid].geometry
        assert gb.area == pytest.approx(ga.area * k * k, rel=1e-9, abs=1e-12)
        scaled = shapely.affinity.scale(ga, k, k, origin=(0, 0))
        assert shapely.hausdorff_distance(scaled, gb) <= 1e-9 * k * 20


def test_proximity_and_beam_regions():
    site = make_site(
        proximity=[
            {"id": "p", "position": [2.0, 2.0], "r_inner": 1.0, "r_outer": 2.0},
            {"id": "q", "position": [8.0, 2.0], "radius": 1.5},
        ],
        beams=[{"id": "b", "segment": [[5.0, 0.0], [5.0, 10.0]], "spacing": 0.4}],
    )
    r = detection_regions(site) | detection_regions(
        make_site(beams=[{"id": "c", "segment": [[0.0, 5.0], [10.0, 5.0]]}])
    )
    assert (r["p"].radius, r["p"].inner_radius, r["q"].radius, r["q"].inner_radius) == (2.0, 1.0, 1.5, 1.5)
    assert r["b"].kind == "beam" and r["b"].radius == pytest.approx(0.2)
    assert r["b"].covers_xy(np.array([5.19, 5.21, 4.81]), np.array([3.0, 3.0, 9.0])).tolist() == [True, False, True]
    assert r["b"].position == (5.0, 5.0)
    # spacing 0: the region is the segment itself
    assert r["c"].geometry.geom_type == "LineString" and r["c"].geometry.length == pytest.approx(10.0)
    assert r["c"].covers_xy(np.array([2.0, 2.0]), np.array([5.0, 5.01])).tolist() == [True, False]


def test_regions_are_built_once_per_site():
    site = make_site(motion=[{"id": "m", "position": [1.0, 1.0], "range": 2.0}])
    assert detection_regions(site) is detection_regions(site) is site.detection_regions


def test_builtin_types_are_metres_converted_to_the_site_units():
    m = make_site(motion=[{"id": "m", "position": [0.0, 0.0], "heading": 45.0, "type": "pir"}])
    cm = make_site(
        motion=[{"id": "m", "position": [0.0, 0.0], "heading": 45.0, "type": "pir"}],
        units="cm",
        boundary=(np.asarray(BOX) * 100).tolist(),
    )
    rng, fov = BUILTIN_TYPES["pir"]["range"], BUILTIN_TYPES["pir"]["fov"]
    area_m = rng * rng * math.tan(math.radians(fov / 2))
    assert detection_regions(m)["m"].geometry.area == pytest.approx(area_m)
    assert detection_regions(cm)["m"].geometry.area == pytest.approx(area_m * 1e4)


def test_debounce_only_type_declares_no_extent():
    types = {"x10": {"chatter_window": 0.1, "min_on": 0.1}}
    assert type_geometry("x10", types["x10"]) is None
    site = make_site(motion=[{"id": "m", "position": [3.0, 3.0], "type": "x10", "range": 1.0}], types=types)
    reg = detection_regions(site)["m"]
    assert reg.extent is None and reg.radius == 1.0


def test_beam_and_grid_type_extents():
    types = {
        "thin": {"kind": "beam", "length": 4.0, "width": 0.0},
        "wide": {"kind": "beam", "length": 4.0, "width": 1.0},
        "default": {"kind": "beam", "length": 4.0, "resolution": 0.5},
        "g": {"kind": "grid", "samples": [[1, 0, 1.0], [3, 1, 0.5], [3, -1, 0.2], [9, 0, 0.0]]},
    }
    site = make_site(
        motion=[
            {"id": "a", "position": [0.0, 5.0], "type": "thin"},
            {"id": "b", "position": [0.0, 5.0], "type": "wide"},
            {"id": "d", "position": [0.0, 5.0], "type": "default"},
            {"id": "c", "position": [5.0, 0.0], "heading": 90.0, "type": "g"},
        ],
        types=types,
    )
    r = detection_regions(site)
    assert r["a"].geometry.geom_type == "LineString" and r["a"].geometry.length == pytest.approx(4.0)
    assert r["b"].geometry.area == pytest.approx(4.0)
    assert r["d"].geometry.area == pytest.approx(2.0)  # width = resolution: the blocks its samples stand for
    # the hull of the samples with eta > 0, rotated by 90 degrees: (u, v) -> (5 - v, u)
    assert r["c"].geometry.area == pytest.approx(2.0)
    assert r["c"].covers_xy(np.array([5.0, 5.0]), np.array([2.0, 8.0])).tolist() == [True, False]


# --------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    "sensor, types, field, words",
    [
        ({"id": "m", "position": [1, 1]}, None, "motion_sensors[0] (id 'm')", "no detection region"),
        (
            {"id": "m", "position": [1, 1], "type": "x10"},
            {"x10": {"chatter_window": 0.1}},
            "motion_sensors[0] (id 'm')",
            "declares no geometry",
        ),
        (
            {"id": "m", "position": [1, 1], "type": "nope"},
            None,
            "motion_sensors[0] (id 'm').type",
            "unknown sensor type",
        ),
        (
            {"id": "m", "position": [1, 1], "type": "w"},
            {"w": {"kind": "pir-triangle", "fov": 60.0}},
            "sensor_types.w.range",
            "missing",
        ),
        ({"id": "m", "position": [1, 1], "type": "w"}, {"w": {"range": 5.0}}, "sensor_types.w.fov", "missing"),
        ({"id": "m", "position": [1, 1], "type": "w"}, {"w": {"kind": "beam"}}, "sensor_types.w.length", "missing"),
        ({"id": "m", "position": [1, 1], "type": "w"}, {"w": {"kind": "grid"}}, "sensor_types.w.samples", "missing"),
        (
            {"id": "m", "position": [1, 1], "type": "w"},
            {"w": {"kind": "cone", "range": 2}},
            "sensor_types.w.kind",
            "cone",
        ),
        (
            {"id": "m", "position": [1, 1], "type": "w"},
            {"w": {"kind": "beam", "length": 2, "width": -1}},
            "sensor_types.w.width",
            "non-negative",
        ),
        (
            {"id": "m", "position": [1, 1], "fov": [[6, 6], [9, 6], [9, 9]], "range": 1.0},
            None,
            "motion_sensors[0] (id 'm')",
            "empty detection region",
        ),
    ],
)
def test_a_sensor_without_a_usable_region_is_an_error_naming_it(sensor, types, field, words):
    site = make_site(motion=[sensor], types=types)  # loading never needs the regions
    with pytest.raises(SiteError) as exc:
        detection_regions(site)
    msg = str(exc.value)
    assert "t/site.toml" in msg and f"field '{field}'" in msg and words in msg


# --------------------------------------------------------------------------- which node a position is at


def test_current_node_nearest_region_then_forward_fill():
    site = make_site(
        motion=[{"id": "a", "position": [2.0, 5.0], "range": 2.0}, {"id": "b", "position": [5.0, 5.0], "range": 2.0}],
    )
    regs = list(detection_regions(site).values())
    xy = np.array([[0.5, 9.0], [1.0, 5.0], [3.4, 5.0], [3.6, 5.0], [5.0, 9.0], [5.0, 9.5]])
    tg = np.array(["u", "u", "u", "u", "u", "v"])
    # before any region: -1; inside a only; both (nearer a, then nearer b); outside: last one; v never inside
    assert current_node(xy, tg, regs).tolist() == [-1, 0, 0, 1, 1, -1]
    assert covers(regs, xy).tolist() == [
        [False, False],
        [True, False],
        [True, True],
        [True, True],
        [False, False],
        [False, False],
    ]


@settings(max_examples=30, deadline=None)
@given(pts=st.lists(st.tuples(st.floats(0, 10), st.floats(0, 10)), min_size=1, max_size=30))
def test_current_node_of_fov_sensors_is_the_polygon_holding_it(pts):
    fovs = {"w": [[0, 0], [5, 0], [5, 10], [0, 10]], "e": [[5, 0], [10, 0], [10, 10], [5, 10]]}
    site = make_site(motion=[{"id": k, "position": [2.5 if k == "w" else 7.5, 5.0], "fov": v} for k, v in fovs.items()])
    xy = np.asarray(pts)
    cur = current_node(xy, np.zeros(len(xy), dtype=int), list(detection_regions(site).values()))
    # every point of the box is in a polygon; on the shared edge x = 5 both are equally near
    away = np.abs(xy[:, 0] - 5.0) > 1e-9
    assert (cur[away] == (xy[away, 0] > 5).astype(int)).all()
