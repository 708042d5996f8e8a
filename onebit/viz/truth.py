"""Ground-truth positions on ``truth/<target>`` and their paths on ``truth/<target>/path``.

The path so far is logged at decimated times: at most ``max_path_updates`` updates per
target, each strip thinned to at most ``max_path_vertices`` vertices and ending at the
current position, so a long run stays small. Positions are logged at every sample.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import rerun as rr

from onebit.viz import colors, paths
from onebit.viz._series import groups, is_empty, paths_so_far, require, update_indices

POINT_RADIUS = rr.Radius.ui_points(5.0)
PATH_WIDTH = rr.Radius.ui_points(1.0)

#: Defaults for the decimated path so far.
MAX_PATH_UPDATES = 200
MAX_PATH_VERTICES = 1000


def log_moving_points(
    rec: rr.RecordingStream,
    entity: str,
    path_entity: str,
    label: str,
    t: np.ndarray,
    xy: np.ndarray,
    *,
    max_path_updates: int = MAX_PATH_UPDATES,
    max_path_vertices: int = MAX_PATH_VERTICES,
    alpha: int = 255,
) -> None:
    """One moving point on ``entity`` and its decimated path so far on ``path_entity``.

    ``t`` is ``(n,)`` seconds, ``xy`` is ``(n, 2)``; the colour is :func:`colors.color_of` of ``label``.
    """
    if len(t) == 0:
        return
    color = colors.color_of(label, alpha=alpha)
    rec.log(
        entity,
        rr.Points2D.from_fields(radii=POINT_RADIUS, colors=color, labels=[label], show_labels=True, draw_order=30.0),
        static=True,
    )
    rec.send_columns(entity, indexes=[paths.time_column(t)], columns=rr.Points2D.columns(positions=xy))
    at = update_indices(len(t), max_path_updates)
    rec.log(path_entity, rr.LineStrips2D.from_fields(radii=PATH_WIDTH, colors=color, draw_order=25.0), static=True)
    rec.send_columns(
        path_entity,
        indexes=[paths.time_column(t[at])],
        columns=rr.LineStrips2D.columns(strips=paths_so_far(xy, at, max_vertices=max_path_vertices)),
    )


def log_truth(
    rec: rr.RecordingStream,
    truth: pl.DataFrame | None,
    *,
    prefix: str = paths.TRUTH,
    max_path_updates: int = MAX_PATH_UPDATES,
    max_path_vertices: int = MAX_PATH_VERTICES,
) -> None:
    """Log a truth frame ``(t, target, x, y)``: ``<prefix>/<target>`` and ``<prefix>/<target>/path``.

    Rows with a null ``x`` or ``y`` are skipped. An empty or ``None`` frame logs nothing.
    """
    if is_empty(truth):
        return
    require(truth, ("t", "target", "x", "y"), name="truth")
    truth = truth.drop_nulls(["t", "x", "y"])
    for target, g in groups(truth, "target"):
        log_moving_points(
            rec,
            paths.truth(target, prefix=prefix),
            paths.truth_path(target, prefix=prefix),
            target,
            g["t"].to_numpy(),
            g.select("x", "y").to_numpy().astype(np.float64),
            max_path_updates=max_path_updates,
            max_path_vertices=max_path_vertices,
        )
