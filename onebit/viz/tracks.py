"""Tracker output: tracks, per-region occupancy and localisation error.

Entities:

* ``<tracker>/tracks/<track>`` -- the estimate now: a dot in a shade of the tracker's colour
  (:func:`onebit.viz.colors.track_color`) labelled ``"track k"`` (``k`` = rank of the id in
  natural order), or ``"<tracker> estimate"`` for a tracker with one track. An estimate never
  carries a target's name: a tracker cannot know which true target it follows (the scores'
  association does, and the error plot says so: ``"track 1 ~ agent2"``). The table ids stay
  as they are (``agent1``, ``user2``, ``c3``) in the entity paths and tables;
* ``.../trail`` and ``.../path`` -- the recent trail and the hidden whole path
  (:mod:`onebit.viz.trails`); region-level tracks (``beams``) also have ``.../region`` (the
  region the track is in now, outlined in its colour) and ``.../regions`` (the whole region
  path, hidden) instead of ``.../path``;
* ``<tracker>/occupancy/<region>`` -- agents per region (Scalars, a step series);
* ``scores/<tracker>/<track>`` -- error of each track against its matched target (Scalars):
  hops for region and graph trackers, site units for the others
  (:func:`onebit.viz.families.error_column` of the tracker's :class:`~onebit.viz.families.Look`).

The tracker's colour is its look's ``rgb``, passed down by the pipeline (a palette colour from
its name without one).

Everything goes through ``send_columns``.
"""

from __future__ import annotations

import re

import numpy as np
import polars as pl
import shapely

from onebit.core.lazy import lazy_module
from onebit.core.region_graph import RegionGraph
from onebit.viz import bulk, colors, paths
from onebit.viz._series import is_empty, only_tracker, region_outlines, require, ring_table, strips_array
from onebit.viz.families import GENERIC, Look, error_column
from onebit.viz.frame import log_world_frame
from onebit.viz.radii import ui_points
from onebit.viz.trails import log_dots, log_full_paths, log_trails

rr = lazy_module("rerun")

#: Offset of a track's point from its region's representative point, as a fraction of the
#: region's size (square root of its area).
TRACK_OFFSET = 0.2
_GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))
REGION_WIDTH = ui_points(3.0)


def natural_key(value: str) -> list:
    """Sort key that orders ``"track2"`` before ``"track10"``."""
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", str(value))]


def track_labels(tracker: str, track_ids) -> dict[str, str]:
    """Display name of each track id: ``"track k"`` by natural order of the ids, or
    ``"<tracker> estimate"`` when the tracker has a single track.

    Examples
    --------
    >>> track_labels("beams", ["agent2", "agent10", "agent1"])
    {'agent1': 'track 1', 'agent2': 'track 2', 'agent10': 'track 3'}
    >>> track_labels("residents", ["resident2", "resident1"])  # known residents (a profile)
    {'resident1': 'resident 1', 'resident2': 'resident 2'}
    >>> track_labels("intruder", ["intruder"])
    {'intruder': 'intruder estimate'}
    """
    ids = sorted({str(i) for i in track_ids if i is not None}, key=natural_key)
    if ids and all(re.fullmatch(r"resident\S+", i) for i in ids):  # known residents keep their names
        return {i: f"resident {i.removeprefix('resident')}" for i in ids}
    if len(ids) == 1:
        return {ids[0]: f"{tracker} estimate"}
    return {tid: f"track {k + 1}" for k, tid in enumerate(ids)}


def track_colors(
    tracker: str, track_ids, *, rgb: tuple[int, int, int] | None = None
) -> dict[str, tuple[int, int, int, int]]:
    """Colour of each track id: shades of the tracker's colour ``rgb`` in the order of :func:`track_labels`."""
    ids = sorted({str(i) for i in track_ids if i is not None}, key=natural_key)
    return {tid: colors.track_color(tracker, k, len(ids), rgb=rgb) for k, tid in enumerate(ids)}


def region_anchors(region_graph: RegionGraph) -> tuple[np.ndarray, np.ndarray]:
    """``(p, 2)`` representative points and ``(p,)`` sizes (sqrt of area) of the regions."""
    rp = np.array([[q.x, q.y] for q in (p.representative_point() for p in region_graph.polygons)], float)
    size = np.sqrt(np.array([p.area for p in region_graph.polygons], float))
    return rp.reshape(-1, 2), size


def region_indices(region_graph: RegionGraph, regions) -> np.ndarray:
    """``(n,)`` index in ``region_graph`` of each region name; a name not in it raises
    ``ValueError`` naming it (vectorised with polars: no Python work per row)."""
    names = regions.cast(pl.String) if isinstance(regions, pl.Series) else pl.Series("region", regions, dtype=pl.String)
    known = list(region_graph.names)
    try:  # one pass: the cast fails on a name that is not a region
        codes = names.cast(pl.Enum(known))
    except pl.exceptions.InvalidOperationError:
        unknown = names.filter(~names.is_in(known)).unique().sort().to_list()
        raise ValueError(f"tracks name region(s) {unknown} not in the region graph; regions are {known}") from None
    return codes.to_physical().cast(pl.Int64).to_numpy()


def region_positions(region_graph: RegionGraph, regions, slot, *, index: np.ndarray | None = None) -> np.ndarray:
    """``(n, 2)`` display positions of tracks in ``regions`` (names): each region's
    representative point, offset by a small per-track vector (``slot``, an int or one per row,
    picks the direction), falling back to the representative point where the offset point
    would leave the region (``index``: :func:`region_indices` of ``regions``, when already
    known). The offset points are computed once per (slot, region) pair (every pair when they
    are fewer than the rows, else those that occur)."""
    k = region_indices(region_graph, regions) if index is None else np.asarray(index, np.int64).reshape(-1)
    rp, size = region_anchors(region_graph)
    slots = (
        np.broadcast_to(np.asarray(slot, np.int64).reshape(-1), k.shape)
        if np.ndim(slot)
        else np.full(k.shape, int(slot))
    )
    cells = (int(slots.max()) + 1) * len(rp) if len(slots) else 0
    if cells <= max(len(k), 4096):  # every (slot, region) pair: a table, no sort of the rows
        pair, row_pair = np.arange(cells), slots * len(rp) + k
    else:  # many tracks: only the pairs that occur
        pair, row_pair = np.unique(slots * len(rp) + k, return_inverse=True)
    s, r = pair // max(len(rp), 1), pair % max(len(rp), 1)
    angle = s * _GOLDEN_ANGLE
    direction = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    xy = rp[r] + (TRACK_OFFSET * size)[r][:, None] * direction
    inside = np.zeros(len(pair), bool)
    for j in np.unique(r).tolist():  # one vectorised test per region that occurs
        sel = np.flatnonzero(r == j)
        inside[sel] = shapely.contains_xy(region_graph.polygons[j], xy[sel, 0], xy[sel, 1])
    return np.where(inside[:, None], xy, rp[r])[row_pair.reshape(-1)].reshape(-1, 2)


def log_current_regions(
    rec: rr.RecordingStream,
    entities: list[str],
    t: np.ndarray,
    index: np.ndarray,
    region_graph: RegionGraph,
    bounds: np.ndarray,
    *,
    colors,
) -> None:
    """``entities[i]``: the outline of the region a track is in, from each time it enters one
    (rows ``bounds[i]:bounds[i + 1]`` of ``t`` and ``index``, the :func:`region_indices` of the
    regions entered; one row per entry holding the region's rings, gathered from the rings of
    every region), in ``colors[i]``. The outlines of all rows are built once."""
    bounds = np.asarray(bounds, np.int64)
    has = np.flatnonzero(np.diff(bounds) >= 1)
    if len(has) == 0:
        return
    template = rr.LineStrips2D.from_fields(colors=colors[has[0]], radii=REGION_WIDTH, draw_order=8.0)
    bulk.log_styles(rec, entities, template, {"LineStrips2D:colors": bulk.color_array(colors)}, which=has.tolist())
    points, lengths, per_row = region_outlines(ring_table(region_graph.polygons), index)
    outlines = bulk.column_arrays(rr.LineStrips2D.columns(strips=strips_array(points, lengths)).partition(per_row))
    bulk.send_spans(rec, entities, bulk.time_array(t), outlines, bounds[:-1], bounds[1:])


def log_current_region(
    rec: rr.RecordingStream,
    entity: str,
    t: np.ndarray,
    regions,
    region_graph: RegionGraph,
    *,
    color,
    index: np.ndarray | None = None,
) -> None:
    """``entity``: the outline of the region a track is in, from each time it enters one
    (:func:`log_current_regions` of one track; ``index``: :func:`region_indices` of
    ``regions``, when already known)."""
    k = region_indices(region_graph, regions) if index is None else index
    log_current_regions(rec, [entity], t, k, region_graph, np.array([0, len(k)]), colors=[color])


def log_region_tracks(
    rec: rr.RecordingStream,
    tracker: str,
    tracks: pl.DataFrame | None,
    region_graph: RegionGraph,
    *,
    rgb: tuple[int, int, int] | None = None,
) -> None:
    """Log region-level tracks ``(track, t, region)``: row = the region a track entered at ``t``.

    Per track: a labelled dot at its region's representative point (offset per track so tracks
    in one region do not overlap) on ``<tracker>/tracks/<track>``, its trail, the region it is
    in now outlined in its colour (``.../region``) and its whole region path, hidden
    (``.../regions``). Rows of other trackers (when a ``tracker`` column exists) and rows with
    a null region are skipped; a region not in ``region_graph`` raises ``ValueError``.

    The rows of all tracks are converted together and each track's entities are slices of
    them (:mod:`onebit.viz.bulk`): the cost follows rows, not tracks.
    """
    if is_empty(tracks):
        return
    require(tracks, ("track", "t", "region"), name="tracks")
    tracks = only_tracker(tracks, tracker).select("track", "t", "region")  # no copy of the other columns
    if tracks["t"].null_count() or tracks["region"].null_count():
        tracks = tracks.drop_nulls(["t", "region"])
    if tracks.height == 0:
        return
    log_world_frame(rec, paths.tracker_root(tracker))
    labels = track_labels(tracker, tracks["track"].unique().to_list())
    shades = track_colors(tracker, labels, rgb=rgb)
    spans = bulk.track_spans(tracks, "track")
    if not spans.keys:
        return
    frame, bounds = spans.frame, spans.bounds
    k = region_indices(region_graph, frame["region"])  # once: positions and outlines
    t = frame["t"].to_numpy().astype(np.float64)
    xy = region_positions(region_graph, None, spans.group_of_rows(), index=k)  # slot = the track's rank
    entities = [paths.track(tracker, track) for track in spans.keys]
    track_shades = [shades[track] for track in spans.keys]
    log_dots(rec, entities, t, xy, bounds, colors=track_shades, labels=[labels[track] for track in spans.keys])
    log_trails(rec, entities, t, xy, bounds, colors=track_shades)
    log_current_regions(
        rec,
        [paths.track_region(tracker, track) for track in spans.keys],
        t,
        k,
        region_graph,
        bounds,
        colors=track_shades,
    )
    whole = np.flatnonzero(spans.lengths >= 2)
    if len(whole) == 0:
        return
    faint = [(*shade[:3], 150) for shade in track_shades]
    names = [f"{labels[track]}: whole region path" for track in spans.keys]
    i0 = int(whole[0])
    template = rr.LineStrips2D(
        [xy[bounds[i0] : bounds[i0 + 1]]],
        colors=faint[i0],
        radii=rr.Radius.ui_points(1.0),
        labels=[names[i0]],
        show_labels=False,
        draw_order=20.0,
    )
    per_track = {
        "LineStrips2D:strips": strips_array(xy, spans.lengths),
        "LineStrips2D:colors": bulk.color_array(faint),
        "LineStrips2D:labels": bulk.text_batch(names),
    }
    region_paths = [paths.track_region_path(tracker, track) for track in spans.keys]
    bulk.log_styles(rec, region_paths, template, per_track, which=whole.tolist())


def log_point_tracks(
    rec: rr.RecordingStream, tracker: str, tracks: pl.DataFrame | None, *, rgb: tuple[int, int, int] | None = None
) -> None:
    """Log tracks with positions ``(track, t, x, y)`` on ``<tracker>/tracks/<track>`` (+ ``/trail``,
    ``/path``), each a dot in a shade of the tracker's colour ``rgb`` labelled ``"track k"``.

    Rows with a null ``x`` or ``y`` and rows of other trackers are skipped. The rows of all
    tracks are converted together and each track's entities are slices of them
    (:mod:`onebit.viz.bulk`): the cost follows rows, not tracks.
    """
    if is_empty(tracks):
        return
    require(tracks, ("track", "t", "x", "y"), name="tracks")
    tracks = only_tracker(tracks, tracker).drop_nulls(["t", "x", "y"])
    if tracks.height == 0:
        return
    log_world_frame(rec, paths.tracker_root(tracker))
    labels = track_labels(tracker, tracks["track"].unique().to_list())
    shades = track_colors(tracker, labels, rgb=rgb)
    spans = bulk.track_spans(tracks.select("track", "t", "x", "y"), "track")
    if not spans.keys:
        return
    frame, bounds = spans.frame, spans.bounds
    t = frame["t"].to_numpy().astype(np.float64)
    xy = frame.select("x", "y").to_numpy().astype(np.float64)
    entities = [paths.track(tracker, track) for track in spans.keys]
    track_shades = [shades[track] for track in spans.keys]
    log_dots(rec, entities, t, xy, bounds, colors=track_shades, labels=[labels[track] for track in spans.keys])
    log_trails(rec, entities, t, xy, bounds, colors=track_shades)
    log_full_paths(rec, entities, xy, bounds, colors=track_shades)
    log_track_ends(rec, entities, t, bounds)


def track_ends(t: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """When each track of rows ``bounds[i]:bounds[i + 1]`` of ``t`` has ended: one of its own
    steps (the median gap of its rows) after its last row; a track of one row takes the median
    step of all tracks (``NaN`` when no track has two rows: no step is known)."""
    bounds = np.asarray(bounds, np.int64)
    steps = [np.diff(t[lo:hi]) for lo, hi in zip(bounds[:-1], bounds[1:])]
    every = np.concatenate([d[d > 0] for d in steps]) if steps else np.empty(0)
    fallback = float(np.median(every)) if every.size else np.nan
    ends = np.full(len(steps), np.nan)
    for i, (d, hi) in enumerate(zip(steps, bounds[1:].tolist())):
        if hi <= bounds[i]:
            continue
        pos = d[d > 0]
        ends[i] = t[hi - 1] + (float(np.median(pos)) if pos.size else fallback)
    return ends


def log_track_ends(rec: rr.RecordingStream, entities: list[str], t: np.ndarray, bounds: np.ndarray) -> None:
    """Clear each track's dot and label when the track has ended (:func:`track_ends`), so a
    map shows the tracks alive now, not every track that ever was (the trail fades by its own
    time range; the hidden whole path, a child entity, stays). One ``send_columns`` per track."""
    ends = track_ends(np.asarray(t, np.float64), bounds)
    has = np.flatnonzero(np.isfinite(ends))
    if len(has) == 0:
        return
    clear = bulk.column_arrays(rr.Clear.columns(is_recursive=np.zeros(len(has), bool)))
    idx = np.arange(len(has))
    bulk.send_spans(rec, [entities[i] for i in has], bulk.time_array(ends[has]), clear, idx, idx + 1)


def log_series(
    rec: rr.RecordingStream,
    entities: list[str],
    names: list[str],
    colors,
    t: np.ndarray,
    values: np.ndarray,
    bounds: np.ndarray,
    *,
    step: bool,
) -> None:
    """Scalars on many entities: entity ``i`` is the series ``names[i]`` in ``colors[i]`` with
    rows ``bounds[i]:bounds[i + 1]`` of ``t`` and ``values`` (a step series if ``step``); the
    values of all rows are converted once."""
    bounds = np.asarray(bounds, np.int64)
    has = np.flatnonzero(np.diff(bounds) >= 1)
    if len(has) == 0:
        return
    i0 = int(has[0])
    template = rr.SeriesLines(
        colors=colors[i0],
        names=[names[i0]],
        widths=[2.0],
        interpolation_mode=rr.components.InterpolationMode.StepAfter if step else None,
    )
    per_entity = {"SeriesLines:colors": bulk.color_array(colors), "SeriesLines:names": bulk.text_batch(names)}
    bulk.log_styles(rec, entities, template, per_entity, which=has.tolist())
    scalars = bulk.column_arrays(rr.Scalars.columns(scalars=np.asarray(values, np.float64)))
    bulk.send_spans(rec, entities, bulk.time_array(t), scalars, bounds[:-1], bounds[1:])


def log_occupancy(rec: rr.RecordingStream, tracker: str, occupancy: pl.DataFrame | None) -> None:
    """Log agents per region ``(t, region, count)`` as step Scalars on ``<tracker>/occupancy/<region>``."""
    if is_empty(occupancy):
        return
    require(occupancy, ("t", "region", "count"), name="occupancy")
    occupancy = only_tracker(occupancy, tracker)
    if occupancy["t"].null_count() or occupancy["count"].null_count():
        occupancy = occupancy.drop_nulls(["t", "count"])
    spans = bulk.track_spans(occupancy.select("region", "t", "count"), "region")
    if not spans.keys:
        return
    log_series(
        rec,
        [paths.occupancy(tracker, region) for region in spans.keys],
        spans.keys,
        [colors.color_of(region) for region in spans.keys],
        spans.frame["t"].to_numpy(),
        spans.frame["count"].cast(pl.Float64).to_numpy(),
        spans.bounds,
        step=True,
    )


def log_scores(
    rec: rr.RecordingStream, tracker: str, scores: pl.DataFrame | None, *, track_ids=None, look: Look = GENERIC
) -> None:
    """Log each track's error ``(track, t, error | hop_error[, target])`` as Scalars on
    ``scores/<tracker>/<track>``: ``hop_error`` (hops) for region and graph trackers (``look.hops``),
    else ``error`` (site units) -- one unit per tracker, named in its plot's title.

    Series are named ``"track k ~ <target>"`` (the target the scoring matched it to) in the
    track's colour; ``track_ids`` (all ids of the tracker's tracks) keeps the ``k`` the same as
    on the map when some track has no score.
    """
    if is_empty(scores):
        return
    column = error_column(look)
    if column not in scores.columns:
        column = "error"
    require(scores, ("track", "t", column), name="scores")
    scores = only_tracker(scores, tracker).drop_nulls(["t", column])
    if scores.height == 0:
        return
    ids = list(track_ids) if track_ids is not None else []
    ids += scores["track"].unique().to_list()
    labels = track_labels(tracker, ids)
    shades = track_colors(tracker, labels, rgb=look.rgb)
    keep = ["track", "t", column] + (["target"] if "target" in scores.columns else [])
    spans = bulk.track_spans(scores.select(keep), "track")
    if not spans.keys:
        return
    targets: dict[str, list] = {}
    if "target" in scores.columns:
        matched = spans.frame.group_by("track").agg(pl.col("target").drop_nulls().unique().sort())
        targets = {str(k): v for k, v in zip(matched["track"].to_list(), matched["target"].to_list())}
    names = []
    for track in spans.keys:
        found = targets.get(track) or []
        names.append(f"{labels[track]} ~ {'/'.join(map(str, found))}" if found else labels[track])
    log_series(
        rec,
        [paths.score(tracker, track) for track in spans.keys],
        names,
        [shades[track] for track in spans.keys],
        spans.frame["t"].to_numpy(),
        spans.frame[column].cast(pl.Float64).to_numpy(),
        spans.bounds,
        step=False,
    )
