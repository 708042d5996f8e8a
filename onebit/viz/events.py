"""Beam crossings and aborted passes on ``sensors/<beam>``.

* ``sensors/<beam>`` -- a :class:`rerun.TextLog` line per crossing (``"a forward"``,
  ``"a^-1 backward"``, coloured by direction) and per aborted pass (level WARN): the crossing log;
* ``sensors/<beam>/crossed`` (when the site is given) -- the beam's segment at the time of each
  crossing, green forward / orange backward; the blueprint shows it for a couple of seconds
  after the crossing, so on the map a beam flashes when it is crossed.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.core.site import Site
from onebit.viz import colors, paths
from onebit.viz._series import choice_text, groups, is_empty, repeat_text, require, strips_array, text_array
from onebit.viz.frame import log_world_frame
from onebit.viz.radii import ui_points

rr = lazy_module("rerun")

CROSSED_WIDTH = ui_points(4.0)


def crossing_texts(crossings: pl.DataFrame) -> pl.Series:
    """``"a forward"`` for a forward crossing of beam ``a``, ``"a^-1 backward"`` for a backward one."""
    return crossings.select(
        pl.when(pl.col("direction") > 0)
        .then(pl.col("beam") + pl.lit(" forward"))
        .otherwise(pl.col("beam") + pl.lit("^-1 backward"))
        .alias("text")
    ).to_series()


def log_crossings(
    rec: rr.RecordingStream,
    crossings: pl.DataFrame | None,
    *,
    entity_prefix: str = paths.SENSORS,
    aborted: pl.DataFrame | None = None,
    site: Site | None = None,
) -> None:
    """Log crossings ``(t, beam, direction)`` and aborted passes ``(t, beam, side)``.

    Per beam, on ``<entity_prefix>/<beam>``: a :class:`rerun.TextLog` (level INFO, coloured by
    direction) in one ``send_columns`` call, aborted passes as a TextLog of level WARN; with
    ``site``, the crossed beam's segment on ``<entity_prefix>/<beam>/crossed``. Empty or
    ``None`` frames log nothing.
    """
    if not is_empty(crossings):
        require(crossings, ("t", "beam", "direction"), name="crossings")
        known = set(site.beam_ids) if site is not None else set()
        palette = np.array([colors.FORWARD, colors.BACKWARD], np.uint8)
        for beam, g in groups(crossings, "beam"):
            entity = paths.sensor(beam, prefix=entity_prefix)
            backward = (g["direction"].cast(pl.Float64).to_numpy() <= 0).astype(np.intp)
            color = palette[backward]  # green forward, orange backward
            t = paths.time_column(g["t"].to_numpy())
            texts = choice_text([f"{beam} forward", f"{beam}^-1 backward"], backward)  # as crossing_texts
            rec.send_columns(
                entity,
                indexes=[t],
                columns=rr.TextLog.columns(text=texts, level=repeat_text("INFO", g.height), color=color),
            )
            if beam in known:
                b = site.beam(beam)
                log_world_frame(rec, entity_prefix)
                segment = np.array([b.p0, b.p1], np.float32)
                rec.log(
                    paths.sensor_crossed(beam, prefix=entity_prefix),
                    rr.LineStrips2D.from_fields(radii=CROSSED_WIDTH, labels=[beam], show_labels=False, draw_order=22.0),
                    static=True,
                )
                rec.send_columns(
                    paths.sensor_crossed(beam, prefix=entity_prefix),
                    indexes=[t],
                    columns=rr.LineStrips2D.columns(
                        strips=strips_array(np.tile(segment, (g.height, 1)), 2), colors=color
                    ),
                )
    if not is_empty(aborted):
        require(aborted, ("t", "beam", "side"), name="aborted")
        for beam, g in groups(aborted, "beam"):
            if g["side"].null_count():
                texts = text_array(
                    g.select(
                        pl.lit(f"{beam} aborted pass, side ") + pl.col("side").cast(pl.Int64).cast(pl.String)
                    ).to_series()
                )
            else:  # a few sides (-1, 1): the texts from buffers
                side = g["side"].cast(pl.Int64).to_numpy()
                values = np.unique(side)
                texts = choice_text(
                    [f"{beam} aborted pass, side {v}" for v in values.tolist()], np.searchsorted(values, side)
                )
            rec.send_columns(
                paths.sensor(beam, prefix=entity_prefix),
                indexes=[paths.time_column(g["t"].to_numpy())],
                columns=rr.TextLog.columns(
                    text=texts,
                    level=repeat_text("WARN", g.height),
                    color=np.tile(np.asarray(colors.WARNING, np.uint8), (g.height, 1)),
                ),
            )
