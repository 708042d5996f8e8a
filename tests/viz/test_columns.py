"""The Arrow columns the loggers build from flat arrays equal Rerun's own per-item conversion,
and what they log reads back from the .rrd as the rows of the frame (no object per row)."""

from __future__ import annotations

import numpy as np
import polars as pl
import pyarrow as pa
import pytest
import rerun as rr
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.tables import ABORTED
from onebit.viz import paths
from onebit.viz._series import (
    blobs_array,
    choice_text,
    gather_ranges,
    only_tracker,
    region_outlines,
    repeat_text,
    ring_table,
    rings,
    strips_array,
    text_array,
)
from onebit.viz.events import log_crossings
from onebit.viz.inspect import timed_rows
from onebit.viz.recording import stage_recording
from onebit.viz.tracks import log_current_region, region_indices
from onebit.viz.trails import segments


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 5), max_size=12), st.integers(0, 2**31))
def test_strips_array_equals_rerun_per_strip_conversion(lengths, seed):
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(sum(lengths), 2)) * 100
    strips = np.split(points, np.cumsum(lengths)[:-1]) if lengths else []
    ours = strips_array(points, lengths)
    assert ours.equals(rr.components.LineStrip2DBatch(strips).as_arrow_array())
    assert rr.LineStrips2D.columns(strips=ours).partition(np.ones(len(lengths), np.int64)) is not None


@settings(max_examples=60, deadline=None)
@given(st.lists(st.binary(max_size=40), max_size=12), st.data())
def test_blobs_array_equals_rerun_per_blob_conversion(blobs, data):
    repeated = (
        blobs + [blobs[i] for i in data.draw(st.lists(st.integers(0, max(0, len(blobs) - 1)), max_size=5))]
        if blobs
        else []
    )
    ours = blobs_array(repeated)
    assert ours.equals(rr.components.BlobBatch(repeated).as_arrow_array())
    assert rr.EncodedImage.columns(blob=ours) is not None


@settings(max_examples=60, deadline=None)
@given(st.lists(st.text(max_size=6), max_size=10), st.text(max_size=5), st.integers(0, 20))
def test_text_arrays_equal_rerun_string_conversion(values, word, n):
    assert text_array(pl.Series(values, dtype=pl.String)).equals(rr.components.TextBatch(values).as_arrow_array())
    assert text_array(values).equals(rr.components.TextBatch(values).as_arrow_array())
    assert repeat_text(word, n).equals(pa.array([word] * n, type=pa.utf8()))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.text(max_size=6), min_size=1, max_size=4), st.data())
def test_choice_text_equals_the_strings_it_picks(options, data):
    index = data.draw(st.lists(st.integers(0, len(options) - 1), max_size=30))
    got = choice_text(options, np.array(index, np.int64))
    assert got.equals(text_array([options[i] for i in index]))


def test_choice_text_rejects_an_index_outside_the_options():
    with pytest.raises(ValueError, match="outside the 2 options"):
        choice_text(["a", "b"], np.array([0, 2]))


_SHAPES = [  # a square, a square with a hole, two parts (one with a hole), a triangle, nothing
    shapely.box(0, 0, 1, 1),
    shapely.box(0, 0, 4, 4).difference(shapely.box(1, 1, 2, 2)),
    shapely.MultiPolygon([shapely.box(5, 5, 6, 6), shapely.box(7, 0, 9, 3).difference(shapely.box(7.5, 1, 8, 2))]),
    shapely.Polygon([(0, 0), (3, 0), (0, 2)]),
    shapely.Polygon(),
]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from(range(len(_SHAPES))), min_size=1, max_size=4), st.lists(st.integers(0, 3), max_size=25))
def test_region_outlines_are_the_rings_of_each_row_polygon(chosen, picks):
    """One gather per row (and per ring only with holes or parts) equals the rings concatenated row by row."""
    polys = [_SHAPES[i] for i in chosen]
    k = np.array([p % len(polys) for p in picks], np.int64)
    pts, lengths, per_row = region_outlines(ring_table(polys), k)
    want = [r for i in k for r in rings(polys[i])]
    assert pts.dtype == np.float32
    assert per_row.tolist() == [len(rings(polys[i])) for i in k]
    assert lengths.tolist() == [len(r) for r in want]
    flat = np.concatenate(want).astype(np.float32) if want else np.zeros((0, 2), np.float32)
    assert np.array_equal(pts, flat.reshape(-1, 2))


def test_segments_in_float32_are_the_float64_segments_cast():
    xy = np.random.default_rng(3).normal(size=(7, 2)) * 1e3
    assert np.array_equal(segments(xy, np.float32), segments(xy).astype(np.float32))


def test_only_tracker_keeps_a_tracker_own_table_and_drops_other_and_nulltimed_rows():
    own = pl.DataFrame({"tracker": ["beams", "beams"], "t": [0.0, 1.0]})
    assert only_tracker(own, "beams") is own
    mixed = pl.DataFrame({"tracker": ["beams", None, "istate", "beams"], "t": [0.0, 1.0, 2.0, 3.0]})
    assert only_tracker(mixed, "beams")["t"].to_list() == [0.0, 3.0]
    assert only_tracker(pl.DataFrame({"t": [0.0]}), "beams").height == 1


def test_region_indices_name_the_unknown_regions(lab):
    _, rg = lab
    assert region_indices(rg, [rg.names[1], rg.names[0]]).tolist() == [1, 0]
    with pytest.raises(ValueError, match=r"\['nowhere'\] not in the region graph"):
        region_indices(rg, [rg.names[0], "nowhere", "nowhere"])


def test_crossing_texts_by_choice_equal_the_polars_texts():
    from onebit.viz.events import crossing_texts

    g = pl.DataFrame({"beam": ["b2"] * 5, "direction": [1, -1, -1, 1, 1]})
    want = text_array(crossing_texts(g))
    assert choice_text(["b2 forward", "b2^-1 backward"], g["direction"].to_numpy() <= 0).equals(want)


@given(st.lists(st.tuples(st.integers(0, 50), st.integers(0, 4)), max_size=10))
def test_gather_ranges_is_concatenated_aranges(pairs):
    starts = np.array([a for a, _ in pairs], np.int64)
    lengths = np.array([b for _, b in pairs], np.int64)
    want = np.concatenate([np.arange(a, a + b) for a, b in pairs]) if pairs else np.zeros(0)
    assert gather_ranges(starts, lengths).tolist() == want.tolist()


def test_current_region_rows_hold_the_rings_of_the_region_entered(tmp_path, lab):
    site, rg = lab
    regions = np.array([rg.names[i % len(rg.names)] for i in (0, 2, 1, 4, 0)])
    t = np.array([1.0, 2.5, 4.0, 7.0, 9.5])
    with stage_recording(tmp_path, "beams", "run-1") as rec:
        log_current_region(rec, "beams/tracks/a/region", t, regions, rg, color=(255, 0, 0, 255))
    rows = timed_rows(tmp_path / "rrd" / "beams.rrd", "beams/tracks/a/region", "LineStrips2D:strips")
    assert [r[0] for r in rows] == t.tolist()
    table = ring_table(rg.polygons)
    for (_, strips), name in zip(rows, regions):
        want = rings(rg.polygons[rg.index[name]])
        assert len(strips) == len(want)
        for got, ring in zip(strips, want):
            assert np.allclose(np.array(got), ring.astype(np.float32))
    pts, lengths, per_row = region_outlines(table, region_indices(rg, regions))
    assert per_row.sum() == len(lengths) and lengths.sum() == len(pts)


def test_crossings_log_one_text_row_and_one_flash_per_crossing(tmp_path, lab):
    site, _ = lab
    beam = site.beam_ids[0]
    cr = pl.DataFrame(
        {"t": [0.5, 1.5, 3.0], "beam": [beam] * 3, "direction": [1, -1, 1]},
        schema={"t": pl.Float64, "beam": pl.String, "direction": pl.Int8},
    )
    with stage_recording(tmp_path, "crossings", "run-1") as rec:
        log_crossings(rec, cr, site=site)
    rrd = tmp_path / "rrd" / "crossings.rrd"
    texts = timed_rows(rrd, paths.sensor(beam), "TextLog:text")
    assert texts == [(0.5, [f"{beam} forward"]), (1.5, [f"{beam}^-1 backward"]), (3.0, [f"{beam} forward"])]
    levels = timed_rows(rrd, paths.sensor(beam), "TextLog:level")
    assert [v for _, v in levels] == [["INFO"]] * 3
    flashes = timed_rows(rrd, paths.sensor_crossed(beam), "LineStrips2D:strips")
    b = site.beam(beam)
    with stage_recording(tmp_path, "aborted", "run-1") as rec:
        ab = pl.DataFrame({"t": [0.7, 2.0, 2.2], "beam": [beam] * 3, "side": [1, -1, 1]}, schema=ABORTED)
        log_crossings(rec, cr, aborted=ab, site=site)
    warned = [
        r
        for r in timed_rows(tmp_path / "rrd" / "aborted.rrd", paths.sensor(beam), "TextLog:text")
        if r[0] in (0.7, 2.0, 2.2)
    ]
    assert warned == [(t, [f"{beam} aborted pass, side {s}"]) for t, s in ((0.7, 1), (2.0, -1), (2.2, 1))]
    assert [r[0] for r in flashes] == [0.5, 1.5, 3.0]
    for _, strips in flashes:
        assert np.allclose(np.array(strips[0]), np.array([b.p0, b.p1], np.float32))


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["a", "b2", "é"]), st.sampled_from([1, -1, 0, None])), max_size=25))
def test_crossing_labels_from_buffers_equal_the_polars_labels(rows):
    from onebit.viz.beams import crossing_label_array, crossing_labels

    df = pl.DataFrame(rows, schema={"beam": pl.String, "direction": pl.Int8}, orient="row")
    for suffix in ("", " inserted", " ambiguous"):
        assert crossing_label_array(df, suffix).equals(text_array(crossing_labels(df, suffix)))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.sampled_from(["b", "a", "c10", "c2", None]), st.integers(0, 20)), max_size=40),
    st.sampled_from(["string", "categorical", "enum", "int"]),
)
def test_groups_by_filters_equal_groups_by_partition(rows, kind):
    """groups() with a few keys (one filter each) gives the parts of one hash partition:
    the same keys in the same order, each with its rows in order and sorted by t."""
    import onebit.viz._series as S

    df = pl.DataFrame(rows, schema={"k": pl.String, "t": pl.Float64}, orient="row").with_row_index("i")
    if kind == "categorical":
        df = df.with_columns(pl.col("k").cast(pl.Categorical))
    elif kind == "enum":
        df = df.with_columns(pl.col("k").cast(pl.Enum(["a", "b", "c10", "c2"])))
    elif kind == "int":
        df = df.with_columns(pl.col("k").str.len_bytes().cast(pl.Int64))
    few = S.groups(df, "k")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(S, "FEW_GROUPS", -1)
        many = S.groups(df, "k")
    assert [k for k, _ in few] == [k for k, _ in many]
    for (_, a), (_, b) in zip(few, many):
        assert a.equals(b)
