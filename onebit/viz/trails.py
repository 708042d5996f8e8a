"""Moving things: a marker now, a trail of the recent past, the whole path hidden.

Every moving thing (a true target, an estimate) is three entities:

* ``<entity>`` -- the marker now, one sample per time step (latest-at: the viewer shows the
  last sample at or before the time cursor). Truth is a **hollow neutral ring**
  (:func:`log_ring`), an estimate a **dot in its tracker's colour** (:func:`log_dot`), each
  with its label;
* ``<entity>/trail`` -- one two-point segment per sample, from the previous position to this
  one, logged at the sample's time (:func:`log_trail`). The blueprint shows the trail entities
  through a visible time range ``[cursor - TRAIL_S, cursor]``, so the trail is the last
  ``TRAIL_S`` seconds and moves with the cursor;
* ``<entity>/path`` -- the whole path as one static line strip, hidden by default in the
  blueprint (tick its eye in the blueprint panel to show it).

The size of a recording therefore grows linearly with its duration: per sample, a marker
position and a segment; nothing is ever re-logged (``docs/viewing.md`` gives the bytes per
second of each demo run).
"""

from __future__ import annotations

import numpy as np

from onebit.core.lazy import lazy_module
from onebit.viz import colors, paths
from onebit.viz._series import strips_array, update_indices
from onebit.viz.radii import ui_points

rr = lazy_module("rerun")

#: Default trail window (s): the visible time range of every ``.../trail`` entity.
TRAIL_S = 10.0
#: The static full path is thinned to at most this many vertices.
MAX_PATH_VERTICES = 5000

DOT_RADIUS = ui_points(4.5)
TRAIL_WIDTH = ui_points(1.5)
TRUTH_TRAIL_WIDTH = ui_points(1.0)
PATH_WIDTH = ui_points(1.0)
RING_WIDTH = ui_points(1.5)
LABEL_ANCHOR = ui_points(0.75)
#: Where a truth label hangs, in ring radii from the ring's centre (left of the ring).
LABEL_OFFSET = np.array([-3.4, 0.7])

#: Draw order: truth under the estimates, trails under markers.
TRAIL_ORDER = 24.0
RING_ORDER = 28.0
DOT_ORDER = 32.0


def segments(xy: np.ndarray, dtype=np.float64) -> np.ndarray:
    """``(n - 1, 2, 2)`` segments from each position of ``xy`` (``(n, 2)``) to the next, in
    ``dtype`` (float32 for Rerun's strips: built in that type, no second copy)."""
    xy = np.asarray(xy, dtype).reshape(-1, 2)
    out = np.empty((max(len(xy) - 1, 0), 2, 2), dtype)
    out[:, 0] = xy[:-1]
    out[:, 1] = xy[1:]
    return out


def log_trail(rec: rr.RecordingStream, entity: str, t: np.ndarray, xy: np.ndarray, *, color, width=TRAIL_WIDTH) -> None:
    """``<entity>/trail``: the segment ending at each sample ``i >= 1``, at time ``t[i]``."""
    seg = segments(xy, np.float32)
    if len(seg) == 0:
        return
    trail = paths.trail(entity)
    rec.log(trail, rr.LineStrips2D.from_fields(colors=color, radii=width, draw_order=TRAIL_ORDER), static=True)
    rec.send_columns(
        trail,
        indexes=[paths.time_column(np.asarray(t)[1:])],
        columns=rr.LineStrips2D.columns(strips=strips_array(seg, 2)),
    )


def log_full_path(
    rec: rr.RecordingStream, entity: str, xy: np.ndarray, *, color, max_vertices: int = MAX_PATH_VERTICES
) -> None:
    """``<entity>/path``: the whole path, thinned to ``max_vertices``, as one static strip."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    if len(xy) < 2:
        return
    keep = update_indices(len(xy), max_vertices)
    rec.log(
        paths.full_path(entity),
        rr.LineStrips2D([xy[keep]], colors=color, radii=PATH_WIDTH, draw_order=TRAIL_ORDER - 1),
        static=True,
    )


def log_dot(
    rec: rr.RecordingStream, entity: str, t: np.ndarray, xy: np.ndarray, *, color, label: str, radius=DOT_RADIUS
) -> None:
    """An estimate now: a filled dot in ``color`` labelled ``label`` at every sample."""
    rec.log(
        entity,
        rr.Points2D.from_fields(radii=radius, colors=color, labels=[label], show_labels=True, draw_order=DOT_ORDER),
        static=True,
    )
    rec.send_columns(entity, indexes=[paths.time_column(t)], columns=rr.Points2D.columns(positions=xy))


def log_ring(rec: rr.RecordingStream, entity: str, t: np.ndarray, xy: np.ndarray, *, size: float, label: str) -> None:
    """A true target now: a hollow neutral ring of radius ``size`` (world units) with its label
    to the left of it (a tiny point left of the ring carries it, so the label of an estimate on
    the target, drawn below the estimate's dot, does not cover it), at every sample."""
    rec.log(
        entity,
        rr.Ellipses2D.from_fields(
            half_sizes=[[size, size]], colors=colors.TRUTH, line_radii=RING_WIDTH, draw_order=RING_ORDER
        ),
        rr.Points2D.from_fields(
            radii=LABEL_ANCHOR, colors=colors.TRUTH, labels=[label], show_labels=True, draw_order=RING_ORDER
        ),
        static=True,
    )
    rec.send_columns(
        entity,
        indexes=[paths.time_column(t)],
        columns=[*rr.Ellipses2D.columns(centers=xy), *rr.Points2D.columns(positions=xy + LABEL_OFFSET * size)],
    )


def log_moving(
    rec: rr.RecordingStream,
    entity: str,
    t: np.ndarray,
    xy: np.ndarray,
    *,
    label: str,
    color=None,
    truth_size: float | None = None,
) -> None:
    """One moving thing: the marker now, its trail and its hidden full path (module docstring).

    With ``truth_size`` it is drawn as truth (neutral ring of that radius); otherwise as an
    estimate (a dot in ``color``). ``t`` is ``(n,)`` seconds, ``xy`` ``(n, 2)``.
    """
    t = np.asarray(t, np.float64)
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    if len(t) == 0:
        return
    if truth_size is not None:
        log_ring(rec, entity, t, xy, size=truth_size, label=label)
        log_trail(rec, entity, t, xy, color=colors.TRUTH_TRAIL, width=TRUTH_TRAIL_WIDTH)
        log_full_path(rec, entity, xy, color=colors.TRUTH_TRAIL)
    else:
        log_dot(rec, entity, t, xy, color=color, label=label)
        log_trail(rec, entity, t, xy, color=color)
        log_full_path(rec, entity, xy, color=color)


def marker_size(xy: np.ndarray, *, diagonal: float | None = None) -> float:
    """Radius of a truth ring: 1.2 % of the site's ``diagonal``, else of the extent of ``xy``."""
    if diagonal is None or not np.isfinite(diagonal) or diagonal <= 0:
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        span = np.ptp(xy, axis=0) if len(xy) else np.ones(2)
        diagonal = float(np.hypot(*span)) or 1.0
    return 0.012 * float(diagonal)
