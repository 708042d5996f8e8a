"""Rerun logging of the ``beams`` tracker's extras: agent region paths, ambiguous and
unexplained crossings. (Occupancy per region goes through :func:`onebit.viz.tracks.log_occupancy`.)

Entities:

* ``<tracker>/tracks/<track>/regions`` -- the agent's whole region path as one static line
  strip through the regions' display points (the same points, offsets and colour,
  :func:`onebit.viz.colors.color_of` of the track id, as ``<tracker>/tracks/<track>`` in every
  stage), labelled with its crossing string;
* ``<tracker>/<kind>`` (kind = ``ambiguous`` or ``unexplained``) -- a marker on the beam's
  midpoint at the time of each marked crossing, and ``<tracker>/<kind>/log`` a text log
  (``"#12 c^-1 agent2"``, or the reason for an unexplained one).
"""

from __future__ import annotations

import numpy as np
import polars as pl
import rerun as rr
import shapely

from onebit.core.region_graph import RegionGraph
from onebit.core.site import Site
from onebit.viz.tracks import log_occupancy, log_region_tracks
from onebit.viz import colors, paths
from onebit.viz._series import is_empty, require
from onebit.viz.tracks import region_positions

MARK_RADIUS = rr.Radius.ui_points(9.0)
PATH_WIDTH = rr.Radius.ui_points(2.0)
_MARK_COLOR = {"ambiguous": colors.WARNING, "unexplained": (200, 0, 200, 255)}


def log_agent_region_paths(rec: rr.RecordingStream, tracker: str, agents: pl.DataFrame | None, region_graph: RegionGraph) -> None:
    """Static line strip of each agent's region path (``agents``: track, regions, crossings)."""
    if is_empty(agents):
        return
    require(agents, ("track", "regions"), name="agents")
    rows = agents.drop_nulls("track").sort("track")
    for slot, row in enumerate(rows.iter_rows(named=True)):  # one entity per agent (few agents)
        regions = np.asarray((row["regions"] or "").split(), dtype=object)
        if len(regions) == 0:
            continue
        xy = region_positions(region_graph, regions, slot)
        label = row.get("crossings") or row["track"]
        rec.log(
            paths.join(paths.track(tracker, row["track"]), "regions"),
            rr.LineStrips2D(
                [xy], colors=colors.color_of(row["track"], alpha=160), radii=PATH_WIDTH, labels=[f"{row['track']}: {label}"]
            ),
            static=True,
        )


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
    unknown = names.filter(~names.is_in(ids)).unique().sort()
    if unknown.len():
        raise ValueError(f"beam(s) {unknown.to_list()} not in the site; beams are {ids}")
    k = names.replace_strict(ids, list(range(len(ids))), return_dtype=pl.Int64).to_numpy()
    return mids[k].astype(np.float64).reshape(-1, 2)


def log_marked_crossings(rec: rr.RecordingStream, tracker: str, kind: str, marked: pl.DataFrame | None, site: Site) -> None:
    """A marker on the beam and a text line at the time of each crossing in ``marked``
    (t, beam, direction and optionally crossing, track, reason), one ``send_columns`` each."""
    if is_empty(marked):
        return
    require(marked, ("t", "beam", "direction"), name=kind)
    m = marked.sort("t")
    if "crossing" not in m.columns:
        m = m.with_row_index("crossing")
    label = pl.when(pl.col("direction") > 0).then(pl.col("beam")).otherwise(pl.col("beam") + "^-1")
    extra = pl.col("reason") if "reason" in m.columns else pl.col("track").fill_null("") if "track" in m.columns else pl.lit("")
    text = m.select(pl.format("#{} {} {}", pl.col("crossing"), label, extra).alias("text"))["text"].to_list()
    t = m["t"].to_numpy()
    xy = beam_midpoints(site, m["beam"])
    entity = paths.join(paths.tracker_root(tracker), kind)
    color = _MARK_COLOR.get(kind, colors.WARNING)
    rec.log(entity, rr.Points2D.from_fields(radii=MARK_RADIUS, colors=color, draw_order=40.0), static=True)
    rec.send_columns(
        entity,
        indexes=[paths.time_column(t)],
        columns=rr.Points2D.columns(positions=xy, labels=text).partition(np.ones(len(t), dtype=np.int64)),
    )
    level = rr.TextLogLevel.WARN if kind == "unexplained" else rr.TextLogLevel.INFO
    rec.send_columns(
        paths.join(entity, "log"),
        indexes=[paths.time_column(t)],
        columns=rr.TextLog.columns(text=text, level=[level] * len(t), color=np.tile(np.asarray(color, np.uint8), (len(t), 1))),
    )


def log_run(rec: rr.RecordingStream, tracker: str, out: dict, *, site: Site, region_graph: RegionGraph, config, tables: dict) -> None:
    """Everything the ``beams`` tracker produced: region tracks, occupancy, agents' region
    paths, ambiguous and unexplained crossings."""
    log_region_tracks(rec, tracker, out["tracks"], region_graph)
    log_occupancy(rec, tracker, out["occupancy"])
    log_agent_region_paths(rec, tracker, out["agents"], region_graph)
    log_marked_crossings(rec, tracker, "ambiguous", out["assignment"].filter(pl.col("ambiguous")), site)
    log_marked_crossings(rec, tracker, "unexplained", out["unexplained"], site)
