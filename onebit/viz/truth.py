"""Ground truth on ``truth/<target>``: a neutral hollow ring now, a trail of the recent past
(``truth/<target>/trail``) and the whole path, hidden by default (``truth/<target>/path``).

Truth is never in a tracker's colour: estimates are (:mod:`onebit.viz.tracks`), so a true
target and an estimate that share an id do not look alike. See :mod:`onebit.viz.trails`.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import paths
from onebit.viz._series import groups, is_empty, require
from onebit.viz.frame import log_world_frame
from onebit.viz.trails import log_moving, marker_size

rr = lazy_module("rerun")


def log_truth(
    rec: rr.RecordingStream,
    truth: pl.DataFrame | None,
    *,
    prefix: str = paths.TRUTH,
    diagonal: float | None = None,
) -> None:
    """Log a truth frame ``(t, target, x, y)``: ``<prefix>/<target>`` (+ ``/trail``, ``/path``).

    ``diagonal`` (the site's, world units) sizes the rings; without it the truth's own extent
    does. Rows with a null ``x`` or ``y`` are skipped. An empty or ``None`` frame logs nothing.
    """
    if is_empty(truth):
        return
    require(truth, ("t", "target", "x", "y"), name="truth")
    truth = truth.drop_nulls(["t", "x", "y"])
    if truth.height == 0:
        return
    log_world_frame(rec, prefix)
    size = marker_size(truth.select("x", "y").to_numpy(), diagonal=diagonal)
    for target, g in groups(truth, "target"):
        log_moving(
            rec,
            paths.truth(target, prefix=prefix),
            g["t"].to_numpy(),
            g.select("x", "y").to_numpy().astype(np.float64),
            label=target,
            truth_size=size,
        )
