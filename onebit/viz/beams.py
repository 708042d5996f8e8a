"""Rerun logging of the ``beams`` tracker (Bobadilla et al.): agents known only to a region.

Entities (``<tracker>`` = ``beams``):

* ``<tracker>/tracks/<track>`` -- each reconstructed agent now, a dot labelled ``"track k"``
  near its region's label; ``.../region`` the region it is in, outlined in its colour (the
  paper's estimate *is* that region); ``.../trail`` its recent moves; ``.../regions`` the whole
  region path (hidden by default) -- see :func:`onebit.viz.tracks.log_region_tracks`;
* ``<tracker>/occupancy/<region>`` -- agents per region (a step series);
* ``<tracker>/assignments`` -- the crossing log of the method: one line per explained,
  unambiguous crossing, ``"#3 b^-1  r4 -> r3: track 1"``;
* ``<tracker>/<kind>`` (kind = ``ambiguous`` or ``unexplained``) -- a marker on the beam's
  midpoint at the time of each such crossing, and ``<tracker>/<kind>/log`` its log line
  (FIFO and LIFO disagree on the agent / the reason it cannot be explained).
"""

from __future__ import annotations

import numpy as np
import polars as pl
import shapely

from onebit.core.lazy import lazy_module
from onebit.core.region_graph import RegionGraph
from onebit.core.site import Site
from onebit.viz import colors, paths
from onebit.viz._series import choice_text, in_time_order, is_empty, repeat_text, require, text_array
from onebit.viz.families import GENERIC, Look
from onebit.viz.frame import log_world_frame
from onebit.viz.radii import ui_points
from onebit.viz.tracks import (
    log_occupancy,
    log_region_tracks,
    track_colors,
    track_labels,
)

rr = lazy_module("rerun")

MARK_RADIUS = ui_points(9.0)
_MARK_COLOR = {"ambiguous": colors.WARNING, "unexplained": (230, 0, 230, 255)}
_MARK_TEXT = {"ambiguous": "ambiguous", "unexplained": "unexplained"}


def beam_midpoints(site: Site, beams: list[str] | pl.Series) -> np.ndarray:
    """``(n, 2)`` midpoint of each named beam's segment.

    The midpoints of the site's beams are computed once (shapely, vectorised over beams) and
    gathered by index: no Python work per crossing. An id that is not a beam of the site
    raises ``ValueError`` naming it.
    """
    ids = [b.id for b in site.beams]
    names = pl.Series("beam", beams, dtype=pl.String)
    if not ids:
        if names.len():
            raise ValueError(f"beam(s) {names.unique().sort().to_list()} not in the site (it has no beams)")
        return np.zeros((0, 2), dtype=np.float64)
    mids = shapely.get_coordinates(shapely.line_interpolate_point([b.line for b in site.beams], 0.5, normalized=True))
    try:  # codes: no string per row; the cast fails on an id that is not a beam
        k = names.cast(pl.Enum(list(dict.fromkeys(ids)))).to_physical().to_numpy()
    except pl.exceptions.InvalidOperationError:
        unknown = names.filter(~names.is_in(ids)).unique().sort()
        raise ValueError(f"beam(s) {unknown.to_list()} not in the site; beams are {ids}") from None
    return mids[k].astype(np.float64).reshape(-1, 2)


def _crossing_label() -> pl.Expr:
    return pl.when(pl.col("direction") > 0).then(pl.col("beam")).otherwise(pl.col("beam") + "^-1")


def crossing_labels(df: pl.DataFrame, suffix: str = "") -> list[str]:
    """``"a"`` / ``"a^-1"`` (beam, then ``^-1`` unless the direction is positive) + ``suffix`` of
    each row of ``df`` (``beam``, ``direction``): the reference of :func:`crossing_label_array`."""
    return df.select((_crossing_label() + pl.lit(suffix)).alias("s"))["s"].to_list()


def crossing_label_array(df: pl.DataFrame, suffix: str = ""):
    """:func:`crossing_labels` as UTF-8 Arrow strings built from the few distinct labels (a beam
    and a direction each; :func:`~onebit.viz._series.choice_text`), no string per row."""
    beam = df["beam"].cast(pl.String)
    names = beam.unique(maintain_order=True)
    code = beam.cast(pl.Enum(names.to_list())).to_physical().cast(pl.Int64).to_numpy()
    backward = (~(df["direction"] > 0).fill_null(False)).to_numpy()
    options = [f"{b}{sfx}{suffix}" for b in names.to_list() for sfx in ("", "^-1")]
    return choice_text(options, 2 * code + backward)


def _track_label(labels: dict[str, str]) -> pl.Expr:
    return pl.col("track").replace_strict(labels, default="no track", return_dtype=pl.String)


def log_assignments(
    rec: rr.RecordingStream,
    tracker: str,
    assignment: pl.DataFrame | None,
    labels: dict[str, str],
    *,
    rgb: tuple[int, int, int] | None = None,
) -> None:
    """``<tracker>/assignments``: a log line per explained, unambiguous crossing, in its track's colour."""
    if is_empty(assignment):
        return
    require(assignment, ("t", "beam", "direction", "track"), name="assignment")
    a = in_time_order(assignment.with_row_index("crossing"))  # the tracker's table is: no sort then
    keep = pl.col("track").is_not_null()
    if "ambiguous" in a.columns:
        keep = keep & ~pl.col("ambiguous").fill_null(False)
    a = a.filter(keep)  # one pass
    if a.height == 0:
        return
    move = (
        pl.format("  {} -> {}", pl.col("source"), pl.col("region"))
        if {"source", "region"} <= set(a.columns)
        else pl.lit("")
    )
    text = a.select(
        pl.format("#{} {}{}: {}", pl.col("crossing"), _crossing_label(), move, _track_label(labels)).alias("s")
    )
    shades = track_colors(tracker, labels, rgb=rgb)
    ids = list(shades)
    palette = np.array([*shades.values(), colors.WARNING], np.uint8).reshape(-1, 4)
    k = (
        a["track"]
        .cast(pl.String)
        .replace_strict(ids, list(range(len(ids))), default=len(ids), return_dtype=pl.Int64)
        .to_numpy()
    )
    rec.send_columns(
        paths.join(paths.tracker_root(tracker), "assignments"),
        indexes=[paths.time_column(a["t"].to_numpy())],
        columns=rr.TextLog.columns(text=text_array(text["s"]), level=repeat_text("INFO", a.height), color=palette[k]),
    )


def log_marked_crossings(
    rec: rr.RecordingStream,
    tracker: str,
    kind: str,
    marked: pl.DataFrame | None,
    site: Site,
    labels: dict[str, str] | None = None,
) -> None:
    """A marker on the beam and a text line at the time of each crossing in ``marked``
    (t, beam, direction and optionally crossing, track, source, region, reason), one
    ``send_columns`` each."""
    if is_empty(marked):
        return
    require(marked, ("t", "beam", "direction"), name=kind)
    m = in_time_order(marked)
    if "crossing" not in m.columns:
        m = m.with_row_index("crossing")
    if "reason" in m.columns:
        extra = pl.col("reason").fill_null("")
    elif "track" in m.columns:
        extra = pl.format("{} (FIFO and LIFO disagree)", _track_label(labels or {}))
    else:
        extra = pl.lit("")
    text = m.select(
        pl.format("#{} {} {}: {}", pl.col("crossing"), _crossing_label(), pl.lit(kind), extra).alias("text")
    )
    t = m["t"].to_numpy()
    xy = beam_midpoints(site, m["beam"])
    entity = paths.join(paths.tracker_root(tracker), kind)
    color = _MARK_COLOR.get(kind, colors.WARNING)
    log_world_frame(rec, entity)
    rec.log(
        entity, rr.Points2D.from_fields(radii=MARK_RADIUS, colors=color, show_labels=True, draw_order=40.0), static=True
    )
    marks = crossing_label_array(m, f" {_MARK_TEXT.get(kind, kind)}")
    rec.send_columns(
        entity,
        indexes=[paths.time_column(t)],
        columns=rr.Points2D.columns(positions=xy, labels=marks).partition(np.ones(len(t), dtype=np.int64)),
    )
    level = "WARN" if kind == "unexplained" else "INFO"
    rec.send_columns(
        paths.join(entity, "log"),
        indexes=[paths.time_column(t)],
        columns=rr.TextLog.columns(
            text=text_array(text["text"]),
            level=repeat_text(level, len(t)),
            color=np.tile(np.asarray(color, np.uint8), (len(t), 1)),
        ),
    )


def log_run(
    rec: rr.RecordingStream,
    tracker: str,
    out: dict,
    *,
    site: Site,
    region_graph: RegionGraph,
    config,
    tables: dict,
    look: Look = GENERIC,
) -> None:
    """Everything the ``beams`` tracker produced: region tracks (dot, trail, current region,
    whole region path), occupancy, the assignment log, ambiguous and unexplained crossings."""
    tracks = out["tracks"]
    labels = track_labels(tracker, tracks["track"].drop_nulls().unique().to_list() if not is_empty(tracks) else [])
    log_region_tracks(rec, tracker, tracks, region_graph, rgb=look.rgb)
    log_occupancy(rec, tracker, out["occupancy"])
    assignment = out["assignment"]
    log_assignments(rec, tracker, assignment, labels, rgb=look.rgb)
    if not is_empty(assignment) and "ambiguous" in assignment.columns:
        marked = assignment.with_row_index("crossing").filter(pl.col("ambiguous"))
        log_marked_crossings(rec, tracker, "ambiguous", marked, site, labels)
    log_marked_crossings(rec, tracker, "unexplained", out["unexplained"], site, labels)
