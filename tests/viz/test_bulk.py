"""Tracks logged in bulk (the rows of all tracks converted once, each entity a slice) give the
same recording as logging one track at a time: same entities, components, descriptors, values
and times, read back from the ``.rrd`` files and compared row for row.

The oracle below is the per-track code the bulk path replaced (one ``groups`` part per track,
one archetype conversion per entity), kept here only to check the bulk path against it.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
import rerun as rr
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.viz import bulk, colors, paths
from onebit.viz._series import groups, only_tracker, region_outlines, ring_table, strips_array, update_indices
from onebit.viz.families import GENERIC, error_column
from onebit.viz.frame import log_world_frame
from onebit.viz.inspect import recording_rows
from onebit.viz.recording import stage_recording
from onebit.viz.tracks import (
    _GOLDEN_ANGLE,
    REGION_WIDTH,
    TRACK_OFFSET,
    log_occupancy,
    log_point_tracks,
    log_region_tracks,
    log_scores,
    region_anchors,
    region_indices,
    region_positions,
    track_colors,
    track_labels,
)
from onebit.viz.trails import (
    DOT_ORDER,
    DOT_RADIUS,
    LABEL_ANCHOR,
    LABEL_OFFSET,
    PATH_WIDTH,
    RING_ORDER,
    RING_WIDTH,
    TRAIL_ORDER,
    TRAIL_WIDTH,
    TRUTH_TRAIL_WIDTH,
    log_full_paths,
    log_moving,
    marker_size,
    segments,
)
from onebit.viz.truth import log_truth

# --------------------------------------------------------------------------- the per-track oracle


def _dot(rec, entity, t, xy, *, color, label):
    rec.log(
        entity,
        rr.Points2D.from_fields(radii=DOT_RADIUS, colors=color, labels=[label], show_labels=True, draw_order=DOT_ORDER),
        static=True,
    )
    rec.send_columns(entity, indexes=[paths.time_column(t)], columns=rr.Points2D.columns(positions=xy))


def _trail(rec, entity, t, xy, *, color, width=TRAIL_WIDTH):
    seg = segments(xy, np.float32)
    if len(seg) == 0:
        return
    trail = paths.trail(entity)
    rec.log(trail, rr.LineStrips2D.from_fields(colors=color, radii=width, draw_order=TRAIL_ORDER), static=True)
    rec.send_columns(
        trail,
        indexes=[paths.time_column(np.asarray(t)[1:])],
        columns=rr.LineStrips2D.columns(strips=strips_array(seg, 2)),
    )


def _full_path(rec, entity, xy, *, color, max_vertices=5000):
    if len(xy) < 2:
        return
    keep = update_indices(len(xy), max_vertices)
    rec.log(
        paths.full_path(entity),
        rr.LineStrips2D([xy[keep]], colors=color, radii=PATH_WIDTH, draw_order=TRAIL_ORDER - 1),
        static=True,
    )


def _ring(rec, entity, t, xy, *, size, label):
    rec.log(
        entity,
        rr.Ellipses2D.from_fields(
            half_sizes=[[size, size]], colors=colors.TRUTH, line_radii=RING_WIDTH, draw_order=RING_ORDER
        ),
        rr.Points2D.from_fields(
            radii=LABEL_ANCHOR, colors=colors.TRUTH, labels=[label], show_labels=True, draw_order=RING_ORDER
        ),
        static=True,
    )
    rec.send_columns(
        entity,
        indexes=[paths.time_column(t)],
        columns=[*rr.Ellipses2D.columns(centers=xy), *rr.Points2D.columns(positions=xy + LABEL_OFFSET * size)],
    )


def oracle_truth(rec, truth, *, diagonal):
    truth = truth.drop_nulls(["t", "x", "y"])
    log_world_frame(rec, paths.TRUTH)
    size = marker_size(truth.select("x", "y").to_numpy(), diagonal=diagonal)
    for target, g in groups(truth, "target"):
        entity = paths.truth(target)
        t, xy = g["t"].to_numpy().astype(np.float64), g.select("x", "y").to_numpy().astype(np.float64)
        _ring(rec, entity, t, xy, size=size, label=target)
        _trail(rec, entity, t, xy, color=colors.TRUTH_TRAIL, width=TRUTH_TRAIL_WIDTH)
        _full_path(rec, entity, xy, color=colors.TRUTH_TRAIL)


def _position(region_graph, regions, slot):
    k = region_indices(region_graph, regions)
    rp, size = region_anchors(region_graph)
    angle = slot * _GOLDEN_ANGLE
    direction = np.array([np.cos(angle), np.sin(angle)])
    xy = rp + (TRACK_OFFSET * size)[:, None] * direction
    inside = np.array([shapely.contains_xy(poly, *p) for poly, p in zip(region_graph.polygons, xy)], dtype=bool)
    return np.where(inside[:, None], xy, rp)[k].reshape(-1, 2)


def oracle_point_tracks(rec, tracker, tracks, *, rgb=None):
    tracks = only_tracker(tracks, tracker).drop_nulls(["t", "x", "y"])
    log_world_frame(rec, paths.tracker_root(tracker))
    labels = track_labels(tracker, tracks["track"].unique().to_list())
    shades = track_colors(tracker, labels, rgb=rgb)
    gaps = [np.diff(g["t"].to_numpy().astype(np.float64)) for _, g in groups(tracks, "track")]
    every = np.concatenate([d[d > 0] for d in gaps]) if gaps else np.empty(0)
    for track, g in groups(tracks, "track"):
        entity = paths.track(tracker, track)
        t, xy = g["t"].to_numpy().astype(np.float64), g.select("x", "y").to_numpy().astype(np.float64)
        _dot(rec, entity, t, xy, color=shades[track], label=labels[track])
        _trail(rec, entity, t, xy, color=shades[track])
        _full_path(rec, entity, xy, color=shades[track])
        # the dot and label cleared one of the track's own steps after its last row (the
        # median step of every track for a track of one row; never when no step is known)
        own = np.diff(t)[np.diff(t) > 0]
        step = float(np.median(own)) if own.size else (float(np.median(every)) if every.size else np.nan)
        if np.isfinite(step):
            rec.send_columns(
                entity,
                indexes=[paths.time_column(np.array([t[-1] + step]))],
                columns=rr.Clear.columns(is_recursive=[False]),
            )


def oracle_region_tracks(rec, tracker, tracks, region_graph, *, rgb=None):
    tracks = only_tracker(tracks, tracker).select("track", "t", "region").drop_nulls(["t", "region"])
    log_world_frame(rec, paths.tracker_root(tracker))
    labels = track_labels(tracker, tracks["track"].unique().to_list())
    shades = track_colors(tracker, labels, rgb=rgb)
    for slot, (track, g) in enumerate(groups(tracks, "track")):
        t = g["t"].to_numpy()
        xy = _position(region_graph, g["region"], slot)
        entity = paths.track(tracker, track)
        _dot(rec, entity, t, xy, color=shades[track], label=labels[track])
        _trail(rec, entity, t, xy, color=shades[track])
        k = region_indices(region_graph, g["region"])
        points, lengths, per_row = region_outlines(ring_table(region_graph.polygons), k)
        region = paths.track_region(tracker, track)
        rec.log(
            region, rr.LineStrips2D.from_fields(colors=shades[track], radii=REGION_WIDTH, draw_order=8.0), static=True
        )
        rec.send_columns(
            region,
            indexes=[paths.time_column(t)],
            columns=rr.LineStrips2D.columns(strips=strips_array(points, lengths)).partition(per_row),
        )
        if len(xy) >= 2:
            rec.log(
                paths.track_region_path(tracker, track),
                rr.LineStrips2D(
                    [xy],
                    colors=(*shades[track][:3], 150),
                    radii=rr.Radius.ui_points(1.0),
                    labels=[f"{labels[track]}: whole region path"],
                    show_labels=False,
                    draw_order=20.0,
                ),
                static=True,
            )


def _series(rec, entity, name, color, t, values, *, step):
    style = rr.SeriesLines(
        colors=color,
        names=[name],
        widths=[2.0],
        interpolation_mode=rr.components.InterpolationMode.StepAfter if step else None,
    )
    rec.log(entity, style, static=True)
    rec.send_columns(entity, indexes=[paths.time_column(t)], columns=rr.Scalars.columns(scalars=values))


def oracle_occupancy(rec, tracker, occupancy):
    occupancy = only_tracker(occupancy, tracker).drop_nulls(["t", "count"])
    for region, g in groups(occupancy, "region"):
        _series(
            rec,
            paths.occupancy(tracker, region),
            region,
            colors.color_of(region),
            g["t"].to_numpy(),
            g["count"].cast(pl.Float64).to_numpy(),
            step=True,
        )


def oracle_scores(rec, tracker, scores, *, track_ids=None, look=GENERIC):
    column = error_column(look)
    if column not in scores.columns:
        column = "error"
    scores = only_tracker(scores, tracker).drop_nulls(["t", column])
    ids = (list(track_ids) if track_ids is not None else []) + scores["track"].unique().to_list()
    labels = track_labels(tracker, ids)
    shades = track_colors(tracker, labels, rgb=look.rgb)
    for track, g in groups(scores, "track"):
        targets = g["target"].drop_nulls().unique().sort().to_list() if "target" in g.columns else []
        name = f"{labels[track]} ~ {'/'.join(map(str, targets))}" if targets else labels[track]
        _series(
            rec,
            paths.score(tracker, track),
            name,
            shades[track],
            g["t"].to_numpy(),
            g[column].cast(pl.Float64).to_numpy(),
            step=False,
        )


# --------------------------------------------------------------------------- fixtures and helpers


def _rows(tmp_path, name, log):
    with stage_recording(tmp_path / name, "x", "run-1") as rec:
        log(rec)
    return recording_rows(tmp_path / name / "rrd" / "x.rrd")


def _same_recording(tmp_path, bulk_log, oracle_log):
    got, want = _rows(tmp_path, "bulk", bulk_log), _rows(tmp_path, "oracle", oracle_log)
    assert set(got) == set(want)
    for key in want:
        assert got[key] == want[key], key
    return got


def point_table(seed: int = 3) -> pl.DataFrame:
    """Several tracks (string ids, out of time order in the table), one-row tracks, rows with
    null x / y / t / track, rows of another tracker and two rows at the same time."""
    rng = np.random.default_rng(seed)
    n = 60
    ids = rng.choice(["a", "b", "track10", "track2", "c d/e"], n)
    t = np.round(rng.uniform(0, 30, n), 1)
    t[5] = t[6]
    ids[6] = ids[5]
    x, y = rng.uniform(0, 9, n), rng.uniform(0, 7, n)
    df = pl.DataFrame({"track": ids, "t": t, "x": x, "y": y, "tracker": ["binpf"] * n})
    extra = pl.DataFrame(
        {
            "track": ["solo", "b", None, "a", "a", "z"],
            "t": [3.0, None, 4.0, 8.0, 9.0, 1.0],
            "x": [1.0, 2.0, 3.0, None, 4.0, 5.0],
            "y": [1.0, 2.0, 3.0, 4.0, None, 5.0],
            "tracker": ["binpf"] * 5 + ["other"],
        }
    )
    return pl.concat([df, extra])


# --------------------------------------------------------------------------- tests


def test_track_spans_are_the_groups_in_one_frame():
    df = point_table().filter(pl.col("t").is_not_null())
    spans = bulk.track_spans(df, "track")
    parts = groups(df, "track")
    assert spans.keys == [k for k, _ in parts]
    assert spans.bounds[-1] == sum(g.height for _, g in parts)
    for i, (_, g) in enumerate(parts):
        assert spans.frame[int(spans.bounds[i]) : int(spans.bounds[i + 1])].equals(g)
    ints = df.with_columns(track=pl.col("track").rank("dense").cast(pl.Int64) * 7)
    assert bulk.track_spans(ints, "track").keys == [k for k, _ in groups(ints, "track")]
    for frame in (  # one key; all in time order; in (key, time) order; each key in time order, interleaved
        df.filter(pl.col("track") == "a"),
        df.sort("t"),
        df.sort("track", "t"),
        df.sort("track", "t").sort("track", descending=True, maintain_order=True),
        df.sort("t").with_columns(t=pl.col("t") * pl.when(pl.col("track") == "a").then(1.0).otherwise(2.0)),
    ):
        spans = bulk.track_spans(frame, "track")
        assert pl.concat([g for _, g in groups(frame, "track")]).equals(spans.frame)
    many = pl.DataFrame({"track": [f"k{i % 11}" for i in range(60)], "t": np.arange(60.0)})
    assert pl.concat([g for _, g in groups(many, "track")]).equals(bulk.track_spans(many, "track").frame)


def test_point_tracks_in_bulk_equal_one_track_at_a_time(tmp_path):
    tracks = point_table()
    got = _same_recording(
        tmp_path,
        lambda rec: log_point_tracks(rec, "binpf", tracks, rgb=(20, 120, 220)),
        lambda rec: oracle_point_tracks(rec, "binpf", tracks, rgb=(20, 120, 220)),
    )
    solo = paths.track("binpf", "solo")
    assert (solo, "Points2D:positions", "rerun.components.Position2D") in got  # a one-row track: a dot,
    assert not any(k[0] in (paths.trail(solo), paths.full_path(solo)) for k in got)  # no trail, no path
    assert not any(k[0] == paths.track("binpf", "z") for k in got)  # the other tracker's row


def test_point_tracks_with_integer_ids_in_bulk_equal_one_track_at_a_time(tmp_path):
    tracks = (
        point_table(7)
        .filter(pl.col("track").is_not_null())
        .with_columns(track=pl.col("track").rank("dense").cast(pl.Int64) * 5)
    )
    _same_recording(
        tmp_path,
        lambda rec: log_point_tracks(rec, "binpf", tracks),
        lambda rec: oracle_point_tracks(rec, "binpf", tracks),
    )


def test_long_paths_are_thinned_per_track_as_one_at_a_time(tmp_path):
    rng = np.random.default_rng(1)
    lengths = [1, 12, 3, 30, 2]
    xy = rng.normal(size=(sum(lengths), 2))
    bounds = np.concatenate([[0], np.cumsum(lengths)])
    shades = [colors.track_color("binpf", i, len(lengths)) for i in range(len(lengths))]
    entities = [f"binpf/tracks/{i}" for i in range(len(lengths))]

    def one_at_a_time(rec):
        for i, e in enumerate(entities):
            _full_path(rec, e, xy[bounds[i] : bounds[i + 1]], color=shades[i], max_vertices=5)

    got = _same_recording(
        tmp_path, lambda rec: log_full_paths(rec, entities, xy, bounds, colors=shades, max_vertices=5), one_at_a_time
    )
    strips = got[(paths.full_path(entities[3]), "LineStrips2D:strips", "rerun.components.LineStrip2D")]
    assert len(strips[0][1][0]) == 5


def test_region_tracks_in_bulk_equal_one_track_at_a_time(tmp_path, lab):
    _, rg = lab
    rng = np.random.default_rng(5)
    n = 40
    names = list(rg.names)
    tracks = pl.DataFrame(
        {
            "track": rng.choice(["agent1", "agent2", "agent10", "x"], n).tolist() + ["lone", "agent1"],
            "t": np.round(rng.uniform(0, 20, n), 2).tolist() + [4.0, 5.0],
            "region": [names[i] for i in rng.integers(0, len(names), n)] + [names[0], None],
        }
    )
    _same_recording(
        tmp_path,
        lambda rec: log_region_tracks(rec, "beams", tracks, rg, rgb=(200, 100, 0)),
        lambda rec: oracle_region_tracks(rec, "beams", tracks, rg, rgb=(200, 100, 0)),
    )


def test_region_positions_per_row_slots_equal_one_slot_at_a_time(lab):
    _, rg = lab
    names = np.array(list(rg.names))[np.arange(30) % len(rg.names)]
    slots = np.arange(30) % 7
    got = region_positions(rg, names, slots)
    for s in range(7):
        np.testing.assert_array_equal(got[slots == s], _position(rg, names[slots == s], s))


def test_scores_and_occupancy_in_bulk_equal_one_series_at_a_time(tmp_path):
    rng = np.random.default_rng(2)
    n = 50
    scores = pl.DataFrame(
        {
            "track": rng.choice(["t1", "t2", "t3"], n),
            "t": np.round(rng.uniform(0, 10, n), 1),
            "error": pl.Series(rng.uniform(0, 2, n)).scatter([3, 17], None),
            "target": pl.Series(rng.choice(["agent1", "agent2", ""], n)).replace("", None),
        }
    )
    occupancy = pl.DataFrame(
        {
            "t": np.sort(rng.uniform(0, 10, n)),
            "region": rng.choice(["r1", "r2", "hall"], n),
            "count": rng.integers(0, 3, n),
        }
    )

    def bulk_log(rec):
        log_scores(rec, "binpf", scores, track_ids=["t1", "t2", "t3", "t4"])
        log_occupancy(rec, "beams", occupancy)

    def oracle_log(rec):
        oracle_scores(rec, "binpf", scores, track_ids=["t1", "t2", "t3", "t4"])
        oracle_occupancy(rec, "beams", occupancy)

    got = _same_recording(tmp_path, bulk_log, oracle_log)
    assert any(k[0] == paths.occupancy("beams", "hall") for k in got)


def test_log_styles_names_a_component_the_template_lacks():
    template = rr.Points2D.from_fields(radii=1.0)
    with pytest.raises(ValueError, match="not components of Points2D"):
        bulk.log_styles(None, ["a"], template, {"Points2D:colorz": bulk.color_array([(1, 2, 3, 4)])})


def test_truth_in_bulk_equals_one_target_at_a_time(tmp_path):
    truth = point_table(11).drop("tracker").rename({"track": "target"})
    _same_recording(
        tmp_path,
        lambda rec: log_truth(rec, truth, diagonal=12.0),
        lambda rec: oracle_truth(rec, truth, diagonal=12.0),
    )


def test_one_moving_estimate_without_a_colour_equals_the_per_entity_calls(tmp_path):
    t, xy = np.array([0.0, 1.0, 2.5]), np.array([[0.0, 0.0], [1.0, 0.5], [2.0, 2.0]])

    def one(rec):
        _dot(rec, "e", t, xy, color=None, label="e estimate")
        _trail(rec, "e", t, xy, color=None)
        _full_path(rec, "e", xy, color=None)

    got = _same_recording(tmp_path, lambda rec: log_moving(rec, "e", t, xy, label="e estimate"), one)
    assert not any(k[1].endswith(":colors") for k in got)


def test_space_time_paths_in_bulk_equal_one_path_at_a_time(tmp_path):
    from onebit.viz.clustertrack import SpaceTime, _log_space_time_paths

    tracks = point_table(13).drop_nulls(["track", "t", "x"]).drop("y", "tracker")
    truth = tracks.rename({"track": "target"})
    st = SpaceTime(0.0, 9.0, np.sort(tracks["t"].unique().to_numpy()))
    labels = track_labels("clustertrack", tracks["track"].unique().to_list())
    shades = track_colors("clustertrack", labels, rgb=(10, 200, 90))

    def bulk_log(rec):
        _log_space_time_paths(
            rec, "ct/space_time", "truth", truth, "target", st, radius=1.0, shades=None, labels=None, show_labels=False
        )
        _log_space_time_paths(
            rec,
            "ct/space_time",
            "tracks",
            tracks,
            "track",
            st,
            radius=2.0,
            shades=shades,
            labels=labels,
            show_labels=True,
        )

    def oracle_log(rec):  # the per-id loops the bulk path replaced
        for ident, g in groups(truth, "target"):
            rec.log(
                paths.join("ct/space_time", "truth", paths.part(ident)),
                rr.LineStrips2D(
                    [np.c_[g["x"].to_numpy(), st.y(g["t"].to_numpy())]],
                    radii=rr.Radius.ui_points(1.0),
                    colors=colors.TRUTH_TRAIL,
                    labels=[f"true {ident}"],
                    show_labels=False,
                ),
                static=True,
            )
        for tid, g in groups(tracks, "track"):
            rec.log(
                paths.join("ct/space_time", "tracks", paths.part(tid)),
                rr.LineStrips2D(
                    [np.c_[g["x"].to_numpy(), st.y(g["t"].to_numpy())]],
                    radii=rr.Radius.ui_points(2.0),
                    colors=shades[tid],
                    labels=[labels[tid]],
                    show_labels=True,
                ),
                static=True,
            )

    got = _same_recording(tmp_path, bulk_log, oracle_log)
    assert any(k[0].startswith("ct/space_time/truth/") for k in got)


def test_decoded_paths_in_bulk_equal_one_user_at_a_time(tmp_path):
    from onebit.viz.findinghumo import log_decoded

    tracks = point_table(17).drop("tracker").drop_nulls(["t"])

    def oracle_log(rec):  # log_point_tracks, then the per-user loop the bulk path replaced
        log_point_tracks(rec, "findinghumo", tracks)
        labels = track_labels("findinghumo", tracks["track"].drop_nulls().unique().to_list())
        shades = track_colors("findinghumo", labels)
        for user, g in groups(tracks.drop_nulls(["x", "y"]), "track"):
            rec.log(
                paths.decoded("findinghumo", user),
                rr.LineStrips2D(
                    [g.select("x", "y").to_numpy()],
                    colors=shades[user],
                    radii=rr.Radius.ui_points(2.0),
                    labels=[f"{labels[user]}: whole decoded path"],
                ),
                static=True,
            )

    got = _same_recording(tmp_path, lambda rec: log_decoded(rec, "findinghumo", tracks), oracle_log)
    assert any(k[0].startswith("findinghumo/decoded/") for k in got)


@settings(max_examples=40, deadline=None)
@given(
    st.one_of(
        st.lists(st.integers(-5, 40), max_size=30),
        st.lists(st.sampled_from(["b1", "b2", "agent10", "ü", ""]), max_size=30),
        st.lists(st.floats(-3, 3, allow_nan=False).map(lambda v: round(v, 1)), max_size=30),
    ),
    st.booleans(),
)
def test_colors_of_distinct_keys_equal_one_key_at_a_time(keys, as_array):
    got = colors.colors_of(np.array(keys) if as_array else keys, alpha=140)
    want = np.array([colors.color_of(k, alpha=140) for k in keys], np.uint8).reshape(-1, 4)
    np.testing.assert_array_equal(got, want)
