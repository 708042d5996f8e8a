"""The I-state recording: fill images (the label-table drawing equals the per-pixel blend, the
windowed masks the whole ones), outlines (array rings equal ring by ring) and rows only where
they change, read back the same at every stage."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from rerun.chunk import RrdReader

from onebit._testing.oracles import fill_images_reference
from onebit.viz import paths
from onebit.viz._series import rings
from onebit.viz.istate import (
    FillRaster,
    _strips_per_stage,
    _strips_per_stage_reference,
    fill_images,
    log_istate_regions,
    polygon_rings,
)
from onebit.viz.recording import close_recording, open_recording


def _box(x0, y0, w, h):
    return shapely.box(x0, y0, x0 + w, y0 + h)


@st.composite
def grids(draw):
    E, n, K = draw(st.integers(1, 3)), draw(st.integers(1, 3)), draw(st.integers(1, 4))
    grid = np.full((E, n, K), None, dtype=object)
    for e in range(E):
        for k in range(n):
            for s in range(K):
                if draw(st.booleans()):
                    x, y = draw(st.floats(0, 8)), draw(st.floats(0, 6))
                    w, h = draw(st.floats(0.5, 6)), draw(st.floats(0.5, 5))
                    g = _box(x, y, w, h)
                    if draw(st.booleans()):  # a region with a hole
                        g = g.difference(_box(x + w / 4, y + h / 4, w / 2, h / 2))
                    grid[e, k, s] = g
    return grid


@settings(max_examples=25, deadline=None)
@given(grids())
def test_label_table_drawing_equals_the_per_pixel_blend(grid):
    raster = FillRaster((0.0, 0.0, 14.0, 11.0), pixels=60)
    assert fill_images(grid, raster) == fill_images_reference(grid, raster)


def test_stages_with_the_same_key_share_the_image():
    a, b = _box(0, 0, 4, 3), _box(2, 1, 5, 5)
    grid = np.array([[[a, b, a]]], dtype=object)
    raster = FillRaster((0.0, 0.0, 8.0, 8.0), pixels=40)
    images = fill_images(grid, raster, keys=["A", "B", "A"])
    assert images == fill_images_reference(grid, raster)
    assert images[0] is images[2] and images[0] != images[1]


@st.composite
def shapes(draw):
    """A polygon (maybe with a hole, maybe partly outside the image), a multipolygon, an empty
    polygon or ``None``."""
    kind = draw(st.sampled_from(["box", "holed", "multi", "empty", "none"]))
    x, y = draw(st.floats(-4, 14)), draw(st.floats(-4, 11))
    w, h = draw(st.floats(0.05, 7)), draw(st.floats(0.05, 6))
    g = _box(x, y, w, h)
    if kind == "holed":
        return g.difference(_box(x + w / 4, y + h / 4, w / 2, h / 2))
    if kind == "multi":
        return shapely.MultiPolygon([g, _box(x + w + 0.5, y, w / 2 + 0.1, h / 2 + 0.1)])
    if kind == "empty":
        return shapely.Polygon()
    return None if kind == "none" else g


@settings(max_examples=60, deadline=None)
@given(shapes())
def test_the_window_is_the_whole_mask_cut_to_it(geom):
    raster = FillRaster((0.0, 0.0, 10.0, 7.0), pixels=50)
    whole = raster.mask(geom) if geom is not None else np.zeros((raster.height, raster.width), np.uint8)
    win = raster.window(geom)
    if win is None:
        assert not whole.any()
        return
    (r0, r1, c0, c1), m = win
    assert 0 <= r0 < r1 <= raster.height and 0 <= c0 < c1 <= raster.width
    np.testing.assert_array_equal(m, whole[r0:r1, c0:c1])
    outside = whole.copy()
    outside[r0:r1, c0:c1] = 0
    assert not outside.any()


@settings(max_examples=40, deadline=None)
@given(st.lists(shapes(), min_size=0, max_size=6))
def test_polygon_rings_equal_the_ring_by_ring_strips(geoms):
    arr = np.empty(len(geoms), dtype=object)
    arr[:] = geoms
    strips, counts = _strips_per_stage(arr)
    ref_strips, ref_counts = _strips_per_stage_reference(arr)
    assert counts == ref_counts
    assert strips.equals(ref_strips)


def test_polygon_rings_leave_other_geometries_to_the_reference():
    arr = np.empty(2, dtype=object)
    arr[:] = [_box(0, 0, 1, 1), shapely.LineString([(0, 0), (1, 1)])]
    assert polygon_rings(arr) is None
    strips, counts = _strips_per_stage(arr)
    assert counts == [1, 1] and strips.equals(_strips_per_stage_reference(arr)[0])


def _logged(rrd_path, entity: str, component: str) -> list[tuple[float, object]]:
    """``(t, value)`` of every timed row of ``component`` on ``entity``, in time order."""
    rows = []
    for chunk in RrdReader(str(rrd_path)).stream():
        if chunk.is_static or chunk.entity_path.strip("/") != entity:
            continue
        rb = chunk.to_record_batch()
        if component not in rb.schema.names:
            continue
        ts = rb.column(paths.TIMELINE).to_pylist()
        rows += zip(
            [t.total_seconds() if hasattr(t, "total_seconds") else t / 1e9 for t in ts],
            rb.column(component).to_pylist(),
        )
    return sorted(rows, key=lambda r: r[0])


def test_regions_are_logged_where_they_change_and_read_the_same_at_every_stage(tmp_path):
    """An I-state that holds still for stages: rows only where an entity's content changes, and
    the latest row at or before each stage's time shows that stage's regions (outlines) and
    image (fill), as a row per stage did."""
    a, b, c = _box(0, 0, 4, 3), _box(2, 1, 5, 5), _box(6, 4, 2, 2)
    per_stage = [[a, b], [a, b], [a, c], [a, c], [None, None], [a, b]]  # element 0, regions k = 0, 1
    rows = [
        {"t": float(s), "stage": s, "element": 0, "k": k, "area": g.area, "wkb": shapely.to_wkb(g)}
        for s, regs in enumerate(per_stage)
        for k, g in enumerate(regs)
        if g is not None
    ]
    regions = pl.DataFrame(
        rows,
        schema={
            "t": pl.Float64,
            "stage": pl.Int64,
            "element": pl.Int64,
            "k": pl.Int64,
            "area": pl.Float64,
            "wkb": pl.Binary,
        },
    )
    times = np.arange(len(per_stage), dtype=float)
    path = tmp_path / "i.rrd"
    rec = open_recording(path, recording_id="test")
    log_istate_regions(rec, "istate", regions, times, bounds=(0.0, 0.0, 10.0, 8.0))
    close_recording(rec, path)

    outline = _logged(path, "istate/istate/0/1", "LineStrips2D:strips")
    assert [t for t, _ in outline] == [0.0, 2.0, 4.0, 5.0]  # b, c, nothing, b
    fill = _logged(path, "istate/istate/fill", "EncodedImage:blob")
    assert [t for t, _ in fill] == [0.0, 2.0, 4.0, 5.0]
    raster = FillRaster((0.0, 0.0, 10.0, 8.0))
    grid = np.empty((1, 2, len(per_stage)), dtype=object)
    for s, regs in enumerate(per_stage):
        grid[0, :, s] = regs
    images = fill_images_reference(grid, raster)
    for s, t in enumerate(times):
        last = [v for u, v in fill if u <= t][-1]
        assert bytes(last[0]) == images[s]  # a row holds one blob
        strips = [v for u, v in outline if u <= t][-1]
        g = per_stage[s][1]
        want = [] if g is None else [np.asarray(g.exterior.coords, np.float32).tolist()]
        assert strips == want


@pytest.mark.parametrize("batch", [4096, 2])
def test_detections_are_logged_where_the_set_changes_and_read_the_same_at_every_stage(tmp_path, monkeypatch, batch):
    """Detections of stages (the same set in consecutive stages, none, a set of two in another
    order): rows only where a stage's set differs from the stage before, and the latest row at or
    before each stage's time holds that stage's sensing regions' rings in its order."""
    from onebit.viz import istate
    from onebit.viz.istate import _changed_sets, log_detections

    monkeypatch.setattr(istate, "SEND_ROWS", batch)  # rows of one send_columns call

    hole = shapely.Polygon([(0, 0), (4, 0), (4, 4), (0, 4)], [[(1, 1), (2, 1), (2, 2), (1, 2)]])
    sensing = {"p": _box(0, 0, 1, 1), "q": hole, "r": shapely.MultiPolygon([_box(5, 5, 1, 1), _box(7, 5, 1, 1)])}
    per_stage = [["p"], ["p"], [], [], ["q", "r"], ["r", "q"], ["r", "q"], ["p"], []]
    det = pl.DataFrame(
        {
            "stage": [s for s, ids in enumerate(per_stage) for _ in ids],
            "sensor": [i for ids in per_stage for i in ids],
        },
        schema={"stage": pl.Int64, "sensor": pl.String},
    )
    times = np.arange(len(per_stage), dtype=float) * 2.0
    path = tmp_path / "d.rrd"
    rec = open_recording(path, recording_id="test")
    log_detections(rec, "istate", det, sensing, times)
    close_recording(rec, path)
    got = _logged(path, "istate/detections", "LineStrips2D:strips")
    assert [t for t, _ in got] == [0.0, 4.0, 8.0, 10.0, 14.0, 16.0]
    for s, t in enumerate(times):
        strips = [v for u, v in got if u <= t][-1]
        want = [np.asarray(r, np.float32).tolist() for sid in per_stage[s] for r in rings(sensing[sid])]
        assert strips == want, s
    # the changed stages against a plain comparison of each stage's list with the one before
    rng = np.random.default_rng(1)
    for _ in range(50):
        K = int(rng.integers(1, 12))
        lists = [list(rng.integers(0, 3, size=int(rng.integers(0, 3)))) for _ in range(K)]
        stage = np.array([s for s, ids in enumerate(lists) for _ in ids], dtype=np.int64)
        code = np.array([c for ids in lists for c in ids], dtype=np.int64)
        plain = [s for s in range(K) if s == 0 or lists[s] != lists[s - 1]]
        assert _changed_sets(stage, code, K).tolist() == plain
