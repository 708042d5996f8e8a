"""Beam crossings and aborted passes as text logs and scalars on ``sensors/<beam>``."""

from __future__ import annotations

import numpy as np
import polars as pl
import rerun as rr

from onebit.viz import colors, paths
from onebit.viz._series import groups, is_empty, require


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
) -> None:
    """Log crossings ``(t, beam, direction)`` and aborted passes ``(t, beam, side)``.

    Per beam, on ``<entity_prefix>/<beam>``: a :class:`rerun.TextLog` (level INFO, coloured by
    direction) and a :class:`rerun.Scalars` of the direction (+1 / -1), in one
    ``send_columns`` call each; aborted passes as a TextLog of level WARN. Empty or ``None``
    frames log nothing.
    """
    if not is_empty(crossings):
        require(crossings, ("t", "beam", "direction"), name="crossings")
        for beam, g in groups(crossings, "beam"):
            entity = paths.sensor(beam, prefix=entity_prefix)
            direction = g["direction"].cast(pl.Float64).to_numpy()
            color = np.where(direction[:, None] > 0, colors.FORWARD, colors.BACKWARD).astype(np.uint8)
            rec.log(
                entity,
                rr.SeriesPoints(colors=colors.color_of(beam), names=[beam], markers=["circle"], marker_sizes=[3.0]),
                static=True,
            )
            rec.send_columns(
                entity,
                indexes=[paths.time_column(g["t"].to_numpy())],
                columns=[
                    *rr.TextLog.columns(
                        text=crossing_texts(g).to_list(), level=[rr.TextLogLevel.INFO] * g.height, color=color
                    ),
                    *rr.Scalars.columns(scalars=direction),
                ],
            )
    if not is_empty(aborted):
        require(aborted, ("t", "beam", "side"), name="aborted")
        for beam, g in groups(aborted, "beam"):
            texts = g.select(
                (pl.lit(f"{beam} aborted pass, side ") + pl.col("side").cast(pl.Int64).cast(pl.String)).alias("text")
            ).to_series()
            rec.send_columns(
                paths.sensor(beam, prefix=entity_prefix),
                indexes=[paths.time_column(g["t"].to_numpy())],
                columns=rr.TextLog.columns(
                    text=texts.to_list(),
                    level=[rr.TextLogLevel.WARN] * g.height,
                    color=np.tile(np.asarray(colors.WARNING, np.uint8), (g.height, 1)),
                ),
            )
