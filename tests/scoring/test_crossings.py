"""Beams agents matched to true agents by shared crossings (the one association, cost -1 each)."""

from __future__ import annotations

import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.scoring.crossings import assignment_scores


def test_agents_take_the_true_agent_they_share_most_crossings_with():
    matched = pl.DataFrame({"target": ["A", "A", "B", "B", "B", None, "A"]})
    assignment = pl.DataFrame({"track": ["x", "x", "y", "y", "x", "y", None]})
    acc, mapping = assignment_scores(matched, assignment)
    assert mapping == {"x": "A", "y": "B"}
    assert acc == pytest.approx(4 / 7)  # x-A twice, y-B twice, of 7 crossings


def test_an_agent_sharing_no_crossing_stays_unmatched():
    matched = pl.DataFrame({"target": ["A", "A", None]})
    assignment = pl.DataFrame({"track": ["x", "x", "z"]})
    acc, mapping = assignment_scores(matched, assignment)
    assert mapping == {"x": "A"} and acc == pytest.approx(2 / 3)


def test_no_crossing_and_no_true_target():
    assert assignment_scores(
        pl.DataFrame({"target": []}, schema={"target": pl.String}),
        pl.DataFrame({"track": []}, schema={"track": pl.String}),
    ) == (1.0, {})
    assert assignment_scores(
        pl.DataFrame({"target": [None]}, schema={"target": pl.String}), pl.DataFrame({"track": ["x"]})
    ) == (0.0, {})


@pytest.mark.parametrize("seed", range(5))
def test_vectorised_region_scores_equal_the_row_by_row_reference(building, seed):
    """Random truth (some samples outside every region, ties in time) against random region
    tracks (some regions missing): the vectorised scores equal the reference's, bit for bit."""
    import numpy as np

    from onebit._testing.oracles import region_scores_reference
    from onebit.scoring.crossings import region_scores

    site, rg = building
    rng = np.random.default_rng(seed)
    minx, miny, maxx, maxy = site.boundary.bounds
    n = 3000
    truth = pl.DataFrame(
        {
            "t": np.sort(rng.integers(0, 400, n)).astype(float) / 4.0,
            "target": rng.choice(["A", "B", "C"], n),
            "x": rng.uniform(minx, maxx, n),
            "y": rng.uniform(miny, maxy, n),
        }
    )
    k = 600
    names = np.array(list(rg.names) + [None], dtype=object)
    tracks = pl.DataFrame(
        {
            "track": rng.choice(["x", "y", "z"], k),
            "t": np.sort(rng.uniform(-5, 100, k)).round(1),
            "region": pl.Series(names[rng.integers(0, len(names), k)].tolist(), dtype=pl.String),
        }
    )
    mapping = {"x": "A", "y": "B", "z": "D"}
    a = region_scores(tracks, truth, mapping, rg, tracker="beams")
    b = region_scores_reference(tracks, truth, mapping, rg, tracker="beams")
    assert a.height > 0 and a.equals(b)


def _random_polygons(rng):
    """Polygons of several kinds: boxes, a rotated ring with a hole, a multipolygon, a
    triangle with a repeated vertex (a zero-length segment), an empty polygon."""
    import numpy as np
    import shapely
    from shapely.geometry import MultiPolygon, Polygon, box

    cx, cy = rng.uniform(-5, 5, 2)
    outer = [(cx + 3 * np.cos(a), cy + 3 * np.sin(a)) for a in np.sort(rng.uniform(0, 2 * np.pi, 7))]
    ring = shapely.buffer(Polygon(outer), 0)
    holed = shapely.difference(ring, box(cx - 0.5, cy - 0.5, cx + 0.5, cy + 0.5))
    x0, y0 = rng.uniform(-6, 6, 2)
    tri = Polygon([(x0, y0), (x0 + 2, y0), (x0 + 2, y0), (x0 + 1, y0 + 1.7)])
    multi = MultiPolygon(
        [box(*rng.uniform(-8, -2, 2), *rng.uniform(-1, 0, 2)), box(*rng.uniform(1, 2, 2), *rng.uniform(3, 8, 2))]
    )
    return np.array([box(*rng.uniform(-6, 0, 2), *rng.uniform(0.1, 6, 2)), holed, multi, tri, Polygon()], dtype=object)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_polygon_distance_xy_is_shapelys_distance(seed):
    """Random points -- inside, outside, on vertices, on edges (segment points), at a vertex's
    projection -- against polygons with holes, parts and repeated vertices: the same bits as
    ``shapely.distance`` of point geometries."""
    import numpy as np
    import shapely

    from onebit.scoring.crossings import polygon_distance_xy

    rng = np.random.default_rng(seed)
    polys = _random_polygons(rng)
    coords = shapely.get_coordinates(shapely.boundary(polys[:4]))
    t = rng.uniform(0, 1, (50, 1))
    a, b = coords[rng.integers(0, len(coords), 50)], coords[rng.integers(0, len(coords), 50)]
    pts = np.vstack(
        [rng.uniform(-12, 12, (300, 2)), coords, a + t * (b - a), coords + rng.normal(0, 1e-9, coords.shape)]
    )
    which = rng.integers(0, len(polys), len(pts))
    ours = polygon_distance_xy(polys, which, pts[:, 0], pts[:, 1])
    ref = shapely.distance(polys[which], shapely.points(pts))
    assert np.array_equal(ours, ref, equal_nan=True)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_region_index_of_is_the_first_containing_region(seed, building):
    """The bounding-box prefilter changes nothing: the first region (in order) whose polygon
    contains each point, -1 for none; overlapping polygons and points on boundaries included."""
    from dataclasses import replace

    import numpy as np
    import shapely

    _, rg = building
    rng = np.random.default_rng(seed)
    polys = list(rg.polygons) + list(_random_polygons(rng))
    g = replace(rg, polygons=tuple(polys))
    bounds = shapely.bounds(np.array(polys, dtype=object))
    edges = shapely.get_coordinates(shapely.boundary(np.array(polys[:-1], dtype=object)))
    lo, hi = np.nanmin(bounds[:, :2], axis=0) - 1, np.nanmax(bounds[:, 2:], axis=0) + 1
    pts = np.vstack([rng.uniform(lo, hi, (500, 2)), edges, [[np.nan, 0.0]]])
    ref = np.full(len(pts), -1)
    for i in range(len(polys) - 1, -1, -1):
        ref[shapely.contains_xy(polys[i], pts[:, 0], pts[:, 1])] = i
    assert np.array_equal(g.region_index_of(pts[:, 0], pts[:, 1]), ref)
    assert np.array_equal(g.region_index_of(pts[:, 0].reshape(-1, 1), pts[:, 1].reshape(-1, 1)), ref.reshape(-1, 1))
