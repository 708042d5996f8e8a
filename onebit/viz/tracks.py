"""Tracker output: tracks, per-region occupancy and localisation error.

Entities: ``<tracker>/tracks/<track>`` (a point over time) and ``<tracker>/tracks/<track>/path``
(its decimated path so far, see :mod:`onebit.viz.truth`), ``<tracker>/occupancy/<region>``
and ``scores/<tracker>/<track>`` (Scalars). Everything goes through ``send_columns``.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import rerun as rr
import shapely

from onebit.core.region_graph import RegionGraph
from onebit.viz import colors, paths
from onebit.viz._series import groups, is_empty, only_tracker, require
from onebit.viz.truth import MAX_PATH_UPDATES, MAX_PATH_VERTICES, log_moving_points

#: Offset of a track's point from its region's representative point, as a fraction of the
#: region's size (square root of its area).
TRACK_OFFSET = 0.2
_GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def region_anchors(region_graph: RegionGraph) -> tuple[np.ndarray, np.ndarray]:
    """``(p, 2)`` representative points and ``(p,)`` sizes (sqrt of area) of the regions."""
    rp = np.array([[q.x, q.y] for q in (p.representative_point() for p in region_graph.polygons)], float)
    size = np.sqrt(np.array([p.area for p in region_graph.polygons], float))
    return rp.reshape(-1, 2), size


def region_positions(region_graph: RegionGraph, regions: np.ndarray, slot: int) -> np.ndarray:
    """``(n, 2)`` display positions of a track in ``regions`` (names): each region's
    representative point, offset by a small per-track vector (``slot`` picks the direction),
    falling back to the representative point where the offset point would leave the region."""
    idx = region_graph.index
    unknown = sorted({str(r) for r in regions if r not in idx})
    if unknown:
        raise ValueError(f"tracks name region(s) {unknown} not in the region graph; regions are {list(region_graph.names)}")
    k = np.fromiter((idx[r] for r in regions), dtype=np.int64, count=len(regions))
    rp, size = region_anchors(region_graph)
    angle = slot * _GOLDEN_ANGLE
    direction = np.array([np.cos(angle), np.sin(angle)])
    xy = rp[k] + (TRACK_OFFSET * size[k])[:, None] * direction
    inside = np.zeros(len(k), dtype=bool)
    for i, poly in enumerate(region_graph.polygons):
        sel = k == i
        if sel.any():
            inside[sel] = shapely.contains_xy(poly, xy[sel, 0], xy[sel, 1])
    return np.where(inside[:, None], xy, rp[k])


def log_region_tracks(
    rec: rr.RecordingStream,
    tracker: str,
    tracks: pl.DataFrame | None,
    region_graph: RegionGraph,
    *,
    max_path_updates: int = MAX_PATH_UPDATES,
    max_path_vertices: int = MAX_PATH_VERTICES,
) -> None:
    """Log region-level tracks ``(track, t, region)``: row = the region a track entered at ``t``.

    Each track is a point at its region's representative point (offset per track so tracks in
    one region do not overlap) on ``<tracker>/tracks/<track>``, and its region path on
    ``.../path``. Rows of other trackers (when a ``tracker`` column exists) and rows with a
    null region are skipped; a region not in ``region_graph`` raises ``ValueError``.
    """
    if is_empty(tracks):
        return
    require(tracks, ("track", "t", "region"), name="tracks")
    tracks = only_tracker(tracks, tracker).drop_nulls(["t", "region"])
    for slot, (track, g) in enumerate(groups(tracks, "track")):
        xy = region_positions(region_graph, g["region"].to_numpy(), slot)
        log_moving_points(
            rec,
            paths.track(tracker, track),
            paths.track_path(tracker, track),
            track,
            g["t"].to_numpy(),
            xy,
            max_path_updates=max_path_updates,
            max_path_vertices=max_path_vertices,
            alpha=220,
        )


def log_point_tracks(
    rec: rr.RecordingStream,
    tracker: str,
    tracks: pl.DataFrame | None,
    *,
    max_path_updates: int = MAX_PATH_UPDATES,
    max_path_vertices: int = MAX_PATH_VERTICES,
) -> None:
    """Log tracks with positions ``(track, t, x, y)`` on ``<tracker>/tracks/<track>`` (+ ``/path``).

    Rows with a null ``x`` or ``y`` and rows of other trackers are skipped.
    """
    if is_empty(tracks):
        return
    require(tracks, ("track", "t", "x", "y"), name="tracks")
    tracks = only_tracker(tracks, tracker).drop_nulls(["t", "x", "y"])
    for track, g in groups(tracks, "track"):
        log_moving_points(
            rec,
            paths.track(tracker, track),
            paths.track_path(tracker, track),
            track,
            g["t"].to_numpy(),
            g.select("x", "y").to_numpy().astype(np.float64),
            max_path_updates=max_path_updates,
            max_path_vertices=max_path_vertices,
            alpha=220,
        )


def _log_series(rec: rr.RecordingStream, entity: str, name: str, t: np.ndarray, values: np.ndarray) -> None:
    rec.log(entity, rr.SeriesLines(colors=colors.color_of(name), names=[name]), static=True)
    rec.send_columns(entity, indexes=[paths.time_column(t)], columns=rr.Scalars.columns(scalars=values))


def log_occupancy(rec: rr.RecordingStream, tracker: str, occupancy: pl.DataFrame | None) -> None:
    """Log agents per region ``(t, region, count)`` as Scalars on ``<tracker>/occupancy/<region>``."""
    if is_empty(occupancy):
        return
    require(occupancy, ("t", "region", "count"), name="occupancy")
    occupancy = only_tracker(occupancy, tracker).drop_nulls(["t", "count"])
    for region, g in groups(occupancy, "region"):
        _log_series(
            rec, paths.occupancy(tracker, region), region, g["t"].to_numpy(), g["count"].cast(pl.Float64).to_numpy()
        )


def log_scores(rec: rr.RecordingStream, tracker: str, scores: pl.DataFrame | None) -> None:
    """Log localisation error ``(track, t, error)`` as Scalars on ``scores/<tracker>/<track>``."""
    if is_empty(scores):
        return
    require(scores, ("track", "t", "error"), name="scores")
    scores = only_tracker(scores, tracker).drop_nulls(["t", "error"])
    for track, g in groups(scores, "track"):
        _log_series(rec, paths.score(tracker, track), track, g["t"].to_numpy(), g["error"].cast(pl.Float64).to_numpy())
