"""Sensor graphs from geometry (issue 22 item 2): radius, connecting distance, walls, rooms, joins."""

from __future__ import annotations

import itertools
import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, box

from onebit.core.errors import SiteError
from onebit.core.sensor_graph import geometric_sensor_graph
from onebit.core.site import site_from_dict

points = st.dictionaries(
    st.from_regex(r"M[0-9]{1,3}", fullmatch=True),
    st.tuples(st.floats(0, 20, allow_nan=False), st.floats(0, 20, allow_nan=False)),
    min_size=2,
    max_size=12,
)


@settings(max_examples=60, deadline=None)
@given(points)
def test_connecting_radius_is_the_smallest_that_connects(pos):
    g = geometric_sensor_graph(pos)
    assert g.connected
    assert all(math.dist(pos[a], pos[b]) <= g.radius + 1e-9 for a, b in g.edges)
    if g.radius > 1e-9:
        smaller = geometric_sensor_graph(pos, radius=g.radius * (1 - 1e-6))
        assert not smaller.connected  # any less and it falls apart


@settings(max_examples=60, deadline=None)
@given(points, st.floats(0.5, 10))
def test_radius_links_exactly_the_close_pairs(pos, r):
    g = geometric_sensor_graph(pos, radius=r)
    want = {
        tuple(sorted((a, b), key=list(pos).index))
        for a, b in itertools.combinations(pos, 2)
        if math.dist(pos[a], pos[b]) <= r
    }
    assert set(g.edges) == want
    assert sum(len(c) for c in g.components) == len(pos)


@settings(max_examples=40, deadline=None)
@given(points, st.floats(0.1, 3))
def test_joined_components_are_connected_with_few_extra_edges(pos, r):
    base = geometric_sensor_graph(pos, radius=r)
    g = geometric_sensor_graph(pos, radius=r, join_components=True)
    assert g.connected and len(g.joins) == len(base.components) - 1
    assert set(g.edges) == set(base.edges) | set(g.joins)


def test_walls_cut_edges_and_rooms_need_a_doorway():
    pos = {"a": (0, 0), "b": (1, 0), "c": (3, 0)}
    g = geometric_sensor_graph(pos, radius=2.5, walls=LineString([(2, -1), (2, 1)]))
    assert g.edges == (("a", "b"),) and not g.connected
    with pytest.raises(SiteError, match="not connected: 2 components"):
        g.require_connected()
    rooms = {"r1": box(-1, -1, 1.5, 1), "r2": box(2.5, -1, 5, 1)}
    assert geometric_sensor_graph({**pos, "d": (4, 0)}, radius=10, rooms=rooms).edges == (("a", "b"), ("c", "d"))
    touching = {"r1": box(-1, -1, 2, 1), "r2": box(2, -1, 5, 1)}
    assert ("b", "c") in geometric_sensor_graph(pos, radius=2.5, rooms=touching).edges
    # an opening (a door) between rooms that do not touch lets an edge through
    g = geometric_sensor_graph(pos, radius=2.5, rooms=rooms, openings=[box(1.8, -0.2, 2.2, 0.2)])
    assert ("b", "c") in g.edges


def test_site_toml_geometry_option():
    base = {
        "boundary": {"polygon": [[0, 0], [10, 0], [10, 4], [0, 4]]},
        "motion_sensors": [{"id": f"m{i}", "position": [1 + 2 * i, 1], "range": 1} for i in range(5)],
    }
    s = site_from_dict({**base, "sensor_graph": {"geometry": "connected"}})
    assert set(s.sensor_graph.edges) == {("m0", "m1"), ("m1", "m2"), ("m2", "m3"), ("m3", "m4")}
    walled = {
        **base,
        "obstacles": [{"polygon": [[5.9, 0], [6.1, 0], [6.1, 3], [5.9, 3]]}],
        "sensor_graph": {"geometry": "connected"},
    }
    with pytest.raises(SiteError, match="sensor_graph.geometry.*not connected"):
        site_from_dict(walled)
    with pytest.raises(SiteError, match="either 'edges' or 'geometry'"):
        site_from_dict({**base, "sensor_graph": {"geometry": 2.0, "edges": []}})
    with pytest.raises(SiteError, match="sensor_graph.geometry"):
        site_from_dict({**base, "sensor_graph": {"geometry": -1}})


LOG = "".join(
    f"2008-11-10\t14:{m:02d}:{s:02d}.5\t{sid}\t{val} {r} 1\n"
    for m in range(2)
    for s, (sid, val, r) in enumerate(
        [
            ("M01", "ON", 1),
            ("M02", "ON", 2),
            ("M01", "OFF", 1),
            ("M03", "ON", 2),
            ("M02", "OFF", 2),
            ("D07", "OPEN", 1),
            ("M03", "OFF", 2),
            ("D07", "CLOSE", 1),
            ("M09", "ON", 1),
            ("M09", "OFF", 1),
        ]
    )
)


@pytest.mark.parametrize("fmt", ["kyoto", "csv", "sitejson"])
def test_floor_plan_layouts(tmp_path, fmt):
    from onebit.core.site import load_site
    from onebit.datasets.importers import import_casas

    px = {
        "M001": (100, 100),
        "M002": (180, 100),
        "M003": (260, 100),
        "D007": (100, 180),
        "M099": (900, 900),
    }  # M099 not in the log
    log = tmp_path / "P01.txt"
    log.write_text(LOG)
    if fmt == "kyoto":
        lay = tmp_path / "sensors.json"
        lay.write_text(json.dumps({k: {"x": x, "y": y} for k, (x, y) in px.items()}))
        scale = 0.02
    elif fmt == "csv":
        lay = tmp_path / "sensors.csv"
        lay.write_text("id,x,y\n" + "".join(f"{k},{x},{y}\n" for k, (x, y) in px.items()))
        scale = 0.02
    else:
        lay = tmp_path / "site.json"
        lay.write_text(
            json.dumps(
                {
                    "sensors": [
                        {"name": k, "locX": x / 1000, "locY": y / 1000, "types": ["Motion"]} for k, (x, y) in px.items()
                    ]
                }
            )
        )
        scale = 20.0  # metres per plan width
    u = 1000.0 if fmt == "sitejson" else 1.0  # rooms in the plan's own coordinates
    rooms = tmp_path / "partitions.json"
    rooms.write_text(
        json.dumps(
            {
                "hall": [{"top_left": {"x": 50 / u, "y": 50 / u}, "width": 300 / u, "height": 100 / u}],
                "closet": [[50 / u, 160 / u], [150 / u, 160 / u], [150 / u, 220 / u], [50 / u, 220 / u]],
                "far": [[800 / u, 800 / u], [990 / u, 800 / u], [990 / u, 990 / u], [800 / u, 990 / u]],
            }
        )
    )
    with pytest.raises(Exception, match="--scale"):
        import_casas(log, tmp_path / "noscale", layout=lay)
    s = import_casas(log, tmp_path / "ds", layout=lay, rooms=rooms, scale=scale)
    site = load_site(tmp_path / "ds" / "site.toml")
    pos = {m.id: m.position for m in site.motion_sensors}
    assert set(pos) == {"M01", "M02", "M03", "D07"}  # padded ids matched to the log's; the unlogged M099 left out
    assert pos["M02"] == pytest.approx((3.6, -2.0)) and pos["D07"][1] < pos["M01"][1]  # scaled, y axis flipped
    assert s.info["layout"]["unplaced"] == ["M09"] and s.info["graph"]["source"] == "geometry"
    edges = {tuple(sorted(e)) for e in site.sensor_graph.edges}
    assert (
        ("M01", "M02") in edges and ("M02", "M03") in edges and ("D07", "M01") in edges
    )  # closet touches the hall: a doorway
    assert site.sensor_graph.entries == ()  # the cupboard D07 is no door
    assert ("D07", "M02") not in edges  # 2.26 m apart: beyond the connecting radius (1.6 m)
