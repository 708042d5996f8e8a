"""The ``correct`` stage in Rerun: observed and inserted (corrected) crossings, told apart.

Entities (timeline ``t``):

* ``correct/crossings/observed`` -- Points2D at the crossed beam's midpoint, small, grey
  (hidden by default in the blueprint: the crossing log and the flashing beams show them);
* ``correct/crossings/inserted`` -- Points2D at the inserted crossing's beam, large, magenta,
  labelled ``"a^-1 inserted"``, shown for a trail window after its time;
* ``correct/log`` -- a TextLog line (level WARN) per inserted crossing, in the crossing log
  beside the observed ones (``sensors/<beam>``).

Each entity is sent with one ``send_columns`` call (one point per time step; the points' colour
and size logged once, static).
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.core.site import Site
from onebit.viz import paths
from onebit.viz._series import in_time_order, is_empty, repeat_text, require
from onebit.viz.beams import beam_midpoints, crossing_label_array
from onebit.viz.frame import log_world_frame

rr = lazy_module("rerun")

ROOT = "correct"
OBSERVED = (150, 150, 150, 255)
INSERTED = (230, 0, 200, 255)


def observed_path() -> str:
    return paths.join(ROOT, "crossings", "observed")


def inserted_path() -> str:
    return paths.join(ROOT, "crossings", "inserted")


def log_path() -> str:
    return paths.join(ROOT, "log")


def log_corrected_crossings(rec: rr.RecordingStream, corrected: pl.DataFrame | None, site: Site) -> None:
    """Log the corrected string ``(t, beam, direction, inserted)``: observed and inserted crossings
    on separate entities with distinct colours and sizes, and a text line for each."""
    if is_empty(corrected):
        return
    require(corrected, ("t", "beam", "direction", "inserted"), name="corrected crossings")
    log_world_frame(rec, ROOT)
    for inserted, entity, color, radius, suffix in (
        (False, observed_path(), OBSERVED, rr.Radius.ui_points(4.0), ""),
        (True, inserted_path(), INSERTED, rr.Radius.ui_points(9.0), " inserted"),
    ):
        g = in_time_order(corrected.filter(pl.col("inserted") == inserted))
        if g.height == 0:
            continue
        xy = beam_midpoints(site, g["beam"])
        rec.log(entity, rr.Points2D.from_fields(colors=color, radii=radius), static=True)  # the style, once
        rec.send_columns(
            entity,
            indexes=[paths.time_column(g["t"].to_numpy())],
            columns=rr.Points2D.columns(positions=xy, labels=crossing_label_array(g, suffix)),
        )
    ins = in_time_order(corrected.filter(pl.col("inserted")))
    if ins.height == 0:
        return
    rec.send_columns(
        log_path(),
        indexes=[paths.time_column(ins["t"].to_numpy())],
        columns=rr.TextLog.columns(
            text=crossing_label_array(ins, " inserted (missed crossing restored by the counting automaton)"),
            level=repeat_text("WARN", ins.height),
            color=np.tile(np.asarray(INSERTED, np.uint8), (ins.height, 1)),
        ),
    )
