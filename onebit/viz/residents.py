"""Rerun logging of the ``residents`` stage.

Entity paths (under the tracker's root)::

    <tracker>/tracks/<person>    each person now: a dot at the node of their latest event, its
                                 trail and hidden whole path (:func:`onebit.viz.tracks.log_point_tracks`)
    <tracker>/events             every motion ON event at its sensor, in the colour of the person
                                 it was attributed to and labelled with them, at its time
    <tracker>/people             the number of people present (a step series, logged by the
                                 pipeline for every tracker: :func:`onebit.viz.occupancy.log_people`)

Bulk series go through one ``send_columns`` each.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import paths
from onebit.viz._series import is_empty
from onebit.viz.families import GENERIC, Look
from onebit.viz.frame import log_world_frame
from onebit.viz.tracks import log_point_tracks, track_colors, track_labels

rr = lazy_module("rerun")


def log_events(
    rec: rr.RecordingStream, tracker: str, events: pl.DataFrame | None, site, *, rgb: tuple[int, int, int] | None = None
) -> None:
    """ON events as points at their sensor, coloured and labelled by their person (one row each)."""
    if is_empty(events):
        return
    pos = {m.id: m.position for m in site.motion_sensors}
    ev = events.drop_nulls("track").filter(pl.col("sensor").is_in(list(pos)))
    if ev.height == 0:
        return
    ids = ev["track"].unique().to_list()
    shade, label = track_colors(tracker, ids, rgb=rgb), track_labels(tracker, ids)
    xy = np.array([pos[s] for s in ev["sensor"].to_list()], dtype=float).reshape(-1, 2)
    cols = np.array([shade[k] for k in ev["track"].to_list()], dtype=np.uint8).reshape(-1, 4)
    labels = [f"{label[k]}: {s}" for k, s in zip(ev["track"].to_list(), ev["sensor"].to_list())]
    entity = paths.join(paths.tracker_root(tracker), "events")
    log_world_frame(rec, entity)
    rec.log(
        entity, rr.Points2D.from_fields(radii=rr.Radius.ui_points(7.0), show_labels=False, draw_order=7.0), static=True
    )
    rec.send_columns(
        entity,
        indexes=[paths.time_column(ev["t"].to_numpy())],
        columns=rr.Points2D.columns(positions=xy, colors=cols, labels=labels).partition(
            np.ones(ev.height, dtype=np.int64)
        ),
    )


def log_run(
    rec: rr.RecordingStream,
    tracker: str,
    out: dict,
    *,
    site,
    region_graph=None,
    config=None,
    tables=None,
    look: Look = GENERIC,
) -> None:
    """The residents stage: people's tracks and the attributed events."""
    log_point_tracks(rec, tracker, out.get("tracks"), rgb=look.rgb)
    ev = out.get("events")
    if not is_empty(ev):
        on = ev.join(_on_rows(tables, ev), on=["t", "sensor"], how="semi") if tables else ev
        log_events(rec, tracker, on, site, rgb=look.rgb)


def _on_rows(tables: dict, events: pl.DataFrame) -> pl.DataFrame:
    """The ON edges of the run's motion table (the OFF edges carry no new position)."""
    motion = tables.get("motion") if tables else None
    if motion is None:
        return events.select("t", "sensor")
    return motion.filter("on").select("t", "sensor")
