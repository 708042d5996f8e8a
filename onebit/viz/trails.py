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

from collections.abc import Sequence

import numpy as np

from onebit.core.lazy import lazy_module
from onebit.viz import bulk, colors, paths
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


def log_trails(
    rec: rr.RecordingStream,
    entities: Sequence[str],
    t: np.ndarray,
    xy: np.ndarray,
    bounds: np.ndarray,
    *,
    colors,
    width=TRAIL_WIDTH,
) -> None:
    """``<entity>/trail`` of many moving things at once: entity ``i`` has rows
    ``bounds[i]:bounds[i + 1]`` of ``t`` (``(n,)`` s) and ``xy`` (``(n, 2)``) and colour
    ``colors[i]``; its trail is the segment ending at each of its samples but the first, at
    that sample's time. The segments of all rows are built once and sliced per entity
    (:mod:`onebit.viz.bulk`)."""
    bounds = np.asarray(bounds, np.int64)
    lengths = np.diff(bounds)
    has = np.flatnonzero(lengths >= 2)
    if len(has) == 0:
        return
    trails = [paths.trail(e) for e in entities]
    template = rr.LineStrips2D.from_fields(colors=colors[has[0]], radii=width, draw_order=TRAIL_ORDER)
    bulk.log_styles(rec, trails, template, {"LineStrips2D:colors": bulk.color_array(colors)}, which=has.tolist())
    seg = segments(xy, np.float32)  # segment j: row j to row j + 1 (across two entities: never sent)
    strips = bulk.column_arrays(rr.LineStrips2D.columns(strips=strips_array(seg, 2)))
    times = bulk.time_array(np.asarray(t, np.float64)[1:])
    starts = bounds[:-1]
    stops = np.maximum(bounds[1:] - 1, starts)  # entity i: segments (and times) starts[i]:stops[i]
    bulk.send_spans(rec, trails, times, strips, starts, stops)


def log_trail(rec: rr.RecordingStream, entity: str, t: np.ndarray, xy: np.ndarray, *, color, width=TRAIL_WIDTH) -> None:
    """``<entity>/trail``: the segment ending at each sample ``i >= 1``, at time ``t[i]``."""
    log_trails(rec, [entity], t, xy, np.array([0, len(np.asarray(t))]), colors=[color], width=width)


def full_path_vertices(bounds: np.ndarray, max_vertices: int = MAX_PATH_VERTICES) -> tuple[np.ndarray, np.ndarray]:
    """The rows kept on the whole paths of entities with rows ``bounds[i]:bounds[i + 1]``:
    ``(row indices, vertices per entity)``; an entity with more than ``max_vertices`` rows is
    thinned to :func:`onebit.viz._series.update_indices` of them, the others keep every row."""
    bounds = np.asarray(bounds, np.int64)
    lengths = np.diff(bounds)
    keep = np.repeat(lengths <= max_vertices, lengths)
    for i in np.flatnonzero(lengths > max_vertices).tolist():  # few: the long tracks
        keep[bounds[i] + update_indices(int(lengths[i]), max_vertices)] = True
    rows = np.flatnonzero(keep)
    count = np.bincount(np.repeat(np.arange(len(lengths)), lengths)[rows], minlength=len(lengths))
    return rows, count


def log_full_paths(
    rec: rr.RecordingStream,
    entities: Sequence[str],
    xy: np.ndarray,
    bounds: np.ndarray,
    *,
    colors,
    max_vertices: int = MAX_PATH_VERTICES,
) -> None:
    """``<entity>/path`` of many moving things: entity ``i`` (rows ``bounds[i]:bounds[i + 1]``
    of ``xy``, at least two) gets its whole path thinned to ``max_vertices`` as one static strip
    in ``colors[i]``; the strips of all entities are built in one go."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    rows, count = full_path_vertices(bounds, max_vertices)
    has = np.flatnonzero(np.diff(np.asarray(bounds, np.int64)) >= 2)
    if len(has) == 0:
        return
    strips = strips_array(xy[rows], count)
    i0 = int(has[0])
    first = xy[rows][int(count[:i0].sum()) : int(count[: i0 + 1].sum())]
    template = rr.LineStrips2D([first], colors=colors[i0], radii=PATH_WIDTH, draw_order=TRAIL_ORDER - 1)
    per_entity = {"LineStrips2D:strips": strips, "LineStrips2D:colors": bulk.color_array(colors)}
    bulk.log_styles(rec, [paths.full_path(e) for e in entities], template, per_entity, which=has.tolist())


def log_full_path(
    rec: rr.RecordingStream, entity: str, xy: np.ndarray, *, color, max_vertices: int = MAX_PATH_VERTICES
) -> None:
    """``<entity>/path``: the whole path, thinned to ``max_vertices``, as one static strip."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    log_full_paths(rec, [entity], xy, np.array([0, len(xy)]), colors=[color], max_vertices=max_vertices)


def log_dots(
    rec: rr.RecordingStream,
    entities: Sequence[str],
    t: np.ndarray,
    xy: np.ndarray,
    bounds: np.ndarray,
    *,
    colors,
    labels: Sequence[str],
    radius=DOT_RADIUS,
) -> None:
    """Estimates now, many at once: entity ``i`` is a filled dot in ``colors[i]`` labelled
    ``labels[i]`` at each of its rows ``bounds[i]:bounds[i + 1]`` of ``t`` and ``xy``."""
    bounds = np.asarray(bounds, np.int64)
    has = np.flatnonzero(np.diff(bounds) >= 1)
    if len(has) == 0:
        return
    i0 = int(has[0])
    template = rr.Points2D.from_fields(
        radii=radius, colors=colors[i0], labels=[labels[i0]], show_labels=True, draw_order=DOT_ORDER
    )
    per_entity = {"Points2D:colors": bulk.color_array(colors), "Points2D:labels": bulk.text_batch(labels)}
    bulk.log_styles(rec, entities, template, per_entity, which=has.tolist())
    positions = bulk.column_arrays(rr.Points2D.columns(positions=np.asarray(xy, np.float64).reshape(-1, 2)))
    bulk.send_spans(rec, entities, bulk.time_array(t), positions, bounds[:-1], bounds[1:])


def log_dot(
    rec: rr.RecordingStream, entity: str, t: np.ndarray, xy: np.ndarray, *, color, label: str, radius=DOT_RADIUS
) -> None:
    """An estimate now: a filled dot in ``color`` labelled ``label`` at every sample."""
    log_dots(rec, [entity], t, xy, np.array([0, len(np.asarray(t))]), colors=[color], labels=[label], radius=radius)


def log_rings(
    rec: rr.RecordingStream,
    entities: Sequence[str],
    t: np.ndarray,
    xy: np.ndarray,
    bounds: np.ndarray,
    *,
    size: float,
    labels: Sequence[str],
) -> None:
    """True targets now, many at once: entity ``i`` is a hollow neutral ring of radius ``size``
    (world units) with its label ``labels[i]`` to the left of it (a tiny point left of the ring
    carries it, so the label of an estimate on the target, drawn below the estimate's dot, does
    not cover it), at each of its rows ``bounds[i]:bounds[i + 1]`` of ``t`` and ``xy``."""
    bounds = np.asarray(bounds, np.int64)
    has = np.flatnonzero(np.diff(bounds) >= 1)
    if len(has) == 0:
        return
    ring = rr.Ellipses2D.from_fields(
        half_sizes=[[size, size]], colors=colors.TRUTH, line_radii=RING_WIDTH, draw_order=RING_ORDER
    )
    anchor = rr.Points2D.from_fields(
        radii=LABEL_ANCHOR, colors=colors.TRUTH, labels=[labels[has[0]]], show_labels=True, draw_order=RING_ORDER
    )
    bulk.log_styles(rec, entities, [ring, anchor], {"Points2D:labels": bulk.text_batch(labels)}, which=has.tolist())
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    marks = bulk.column_arrays(
        [*rr.Ellipses2D.columns(centers=xy), *rr.Points2D.columns(positions=xy + LABEL_OFFSET * size)]
    )
    bulk.send_spans(rec, entities, bulk.time_array(t), marks, bounds[:-1], bounds[1:])


def log_ring(rec: rr.RecordingStream, entity: str, t: np.ndarray, xy: np.ndarray, *, size: float, label: str) -> None:
    """A true target now: :func:`log_rings` of one target."""
    log_rings(rec, [entity], t, xy, np.array([0, len(np.asarray(t))]), size=size, labels=[label])


def log_movers(
    rec: rr.RecordingStream,
    entities: Sequence[str],
    t: np.ndarray,
    xy: np.ndarray,
    bounds: np.ndarray,
    *,
    labels: Sequence[str],
    shades=None,
    truth_size: float | None = None,
) -> None:
    """Many moving things: entity ``i`` (rows ``bounds[i]:bounds[i + 1]`` of ``t`` ``(n,)`` s and
    ``xy`` ``(n, 2)``) gets its marker now, its trail and its hidden full path (module
    docstring), the rows of all of them converted together (:mod:`onebit.viz.bulk`).

    With ``truth_size`` they are drawn as truth (neutral rings of that radius); otherwise as
    estimates (dots in ``shades[i]``)."""
    t = np.asarray(t, np.float64)
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    if len(t) == 0:
        return
    if truth_size is not None:
        trail = [colors.TRUTH_TRAIL] * len(entities)
        log_rings(rec, entities, t, xy, bounds, size=truth_size, labels=labels)
        log_trails(rec, entities, t, xy, bounds, colors=trail, width=TRUTH_TRAIL_WIDTH)
        log_full_paths(rec, entities, xy, bounds, colors=trail)
    else:
        shades = list(shades) if shades is not None else [None] * len(entities)
        log_dots(rec, entities, t, xy, bounds, colors=shades, labels=labels)
        log_trails(rec, entities, t, xy, bounds, colors=shades)
        log_full_paths(rec, entities, xy, bounds, colors=shades)


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
    """One moving thing: :func:`log_movers` of one entity (``t`` ``(n,)`` seconds, ``xy``
    ``(n, 2)``): a truth ring of radius ``truth_size`` or an estimate's dot in ``color``."""
    t = np.asarray(t, np.float64)
    log_movers(rec, [entity], t, xy, np.array([0, len(t)]), labels=[label], shades=[color], truth_size=truth_size)


def marker_size(xy: np.ndarray, *, diagonal: float | None = None) -> float:
    """Radius of a truth ring: 1.2 % of the site's ``diagonal``, else of the extent of ``xy``."""
    if diagonal is None or not np.isfinite(diagonal) or diagonal <= 0:
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        span = np.ptp(xy, axis=0) if len(xy) else np.ones(2)
        diagonal = float(np.hypot(*span)) or 1.0
    return 0.012 * float(diagonal)
