"""Ground truth on ``truth/<target>``: a neutral hollow ring now, a trail of the recent past
(``truth/<target>/trail``) and the whole path, hidden by default (``truth/<target>/path``).

Truth is never in a tracker's colour: estimates are (:mod:`onebit.viz.tracks`), so a true
target and an estimate that share an id do not look alike. See :mod:`onebit.viz.trails`.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import bulk, paths
from onebit.viz._series import is_empty, require
from onebit.viz.frame import log_world_frame
from onebit.viz.trails import log_movers, marker_size

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
    spans = bulk.track_spans(truth.select("target", "t", "x", "y"), "target")
    if not spans.keys:
        return
    log_movers(
        rec,
        [paths.truth(target, prefix=prefix) for target in spans.keys],
        spans.frame["t"].to_numpy(),
        spans.frame.select("x", "y").to_numpy().astype(np.float64),
        spans.bounds,
        labels=spans.keys,
        truth_size=size,
    )
