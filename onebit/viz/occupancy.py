"""Rerun logging of the ``occupancy`` stage: how many people are home, against the truth.

Entity paths::

    occupancy/present     the count model's people present (a step series over the whole run)
    occupancy/truth       the true count (``truth_count``), when the dataset has it (a step series)
    occupancy/doors       a cross at every bin with a door event, just below 0 (:data:`DOOR_Y`) so
                          the zero line does not hide it
    occupancy/sensors     every motion sensor at its place on the site, labelled with its id,
                          bright while on and dim while off (positions and labels static, the
                          colours one row per edge)

and, for every tracker that writes a ``people`` table (:func:`log_people`), and for a run with
tracked truth (:func:`log_truth_people`)::

    <tracker>/people      the tracker's people present (a step series in its colour)
    summary/truth         the true targets present, each from its first to its last truth row
                          (a step series, drawn as ``occupancy/truth``)

Each series is one ``send_columns``; the styles are static.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import colors, paths
from onebit.viz._series import is_empty, require
from onebit.viz.frame import log_world_frame

rr = lazy_module("rerun")

ROOT = "occupancy"
#: Root of the series only the summary tab shows (:data:`onebit.viz.blueprint.SUMMARY_ROOT`).
SUMMARY_ROOT = "summary"
#: Style of a true count: wide and translucent under the estimates' thin lines.
TRUTH_RGB, TRUTH_WIDTH = (120, 220, 120, 150), 5.0
#: Height of the door-event marks on the count plot: under the 0 line, above the axis.
DOOR_Y = -0.25
#: Colour of a sensor that is off on the home map (a sensor that is on has :data:`colors.FIRING`).
SENSOR_OFF = (110, 110, 110, 255)


def log_step_series(rec, entity: str, t: np.ndarray, v: np.ndarray, *, name: str, rgb, width: float = 2.0) -> None:
    """A step series (held until the next value) in one call, styled once."""
    if t.size == 0:
        return
    rec.log(
        entity,
        rr.SeriesLines(
            colors=[rgb],
            names=[name],
            widths=[width],
            interpolation_mode=rr.components.InterpolationMode.StepAfter,
            # a count is whole: zoomed out over days, the viewer's default averaging draws 0.5 and 1.5
            aggregation_policy=rr.components.AggregationPolicy.Off,
        ),
        static=True,
    )
    rec.send_columns(
        entity,
        indexes=[paths.time_column(np.asarray(t, dtype=np.float64))],
        columns=rr.Scalars.columns(scalars=np.asarray(v, dtype=np.float64)),
    )


def log_people(rec, tracker: str, people: pl.DataFrame | None, *, rgb: tuple[int, int, int] | None = None) -> None:
    """``<tracker>/people``: a tracker's people present (``t, present``) as one step series in
    its colour (a count holds until the next sample: steps, not lines sloping between sparse
    samples). The pipeline logs it for every tracker whose stage made ``<tracker>_people``."""
    if is_empty(people):
        return
    require(people, ("t", "present"), name=f"{tracker}_people")
    log_step_series(
        rec,
        paths.join(paths.tracker_root(tracker), "people"),
        people["t"].to_numpy(),
        people["present"].to_numpy(),
        name=f"{tracker}: people",
        rgb=colors.tracker_color(tracker, rgb=rgb),
    )


def truth_people_steps(truth: pl.DataFrame | None) -> tuple[np.ndarray, np.ndarray]:
    """The true targets present from a truth frame ``(t, target, ...)``: each target counts from
    its first row's time to its last's (a target that leaves and comes back between two rows is
    counted as present meanwhile). Returns the step corners ``(t, count)``, one per time."""
    if is_empty(truth):
        return np.zeros(0), np.zeros(0)
    spans = truth.drop_nulls(["t", "target"]).group_by("target").agg(a=pl.col("t").min(), b=pl.col("t").max())
    if spans.height == 0:
        return np.zeros(0), np.zeros(0)
    t = np.r_[spans["a"].to_numpy(), spans["b"].to_numpy()].astype(np.float64)
    d = np.r_[np.ones(spans.height), -np.ones(spans.height)]
    order = np.argsort(t, kind="stable")
    t, v = t[order], np.cumsum(d[order])
    last = np.r_[t[1:] != t[:-1], True]  # the count after every change at that time
    return t[last], v[last]


def log_truth_people(rec, truth: pl.DataFrame | None) -> None:
    """``summary/truth``: the true targets present (:func:`truth_people_steps`), one step series."""
    t, v = truth_people_steps(truth)
    log_step_series(
        rec, paths.join(SUMMARY_ROOT, "truth"), t, v, name="people (truth)", rgb=TRUTH_RGB, width=TRUTH_WIDTH
    )


def truth_steps(truth_count: pl.DataFrame | None) -> tuple[np.ndarray, np.ndarray]:
    """The truth's step corners: each interval's start at its count, a 0 where a gap starts."""
    if truth_count is None or truth_count.height == 0:
        return np.zeros(0), np.zeros(0)
    tc = truth_count.sort("t")
    t, end, c = tc["t"].to_numpy(), tc["end"].to_numpy(), tc["count"].to_numpy().astype(float)
    gap = np.r_[t[1:] > end[:-1] + 1e-9, True]
    ts = np.r_[t, end[gap]]
    vs = np.r_[c, np.zeros(int(gap.sum()))]
    order = np.argsort(ts, kind="stable")
    return ts[order], vs[order]


def log_occupancy(rec, ctx, made: dict) -> None:
    """The count, the truth, the door events and the sensors on the map (module docstring)."""
    log_sensor_map(rec, ctx.site, ctx.tables.get("motion"))
    people = made.get("occupancy_people")
    if people is not None and people.height:
        t, v = people["t"].to_numpy(), people["present"].to_numpy()
        bins = made.get("occupancy_bins")
        if bins is not None and bins.height:  # hold the last value to the end of the last bin
            t, v = (
                np.r_[t, bins["t"].max() + float(np.diff(bins["t"].to_numpy()[:2])[0] if bins.height > 1 else 60.0)],
                np.r_[v, v[-1]],
            )
        truth = ctx.tables.get("truth_count")
        if truth is not None and truth.height and float(truth["end"].max()) > t[-1]:  # to the truth's end too
            t, v = np.r_[t, float(truth["end"].max())], np.r_[v, v[-1]]
        log_step_series(rec, paths.join(ROOT, "present"), t, v, name="people home (model)", rgb=(255, 140, 120))
    ts, vs = truth_steps(ctx.tables.get("truth_count"))
    # the truth wide and translucent under the model's thin line: both stay readable where they agree
    log_step_series(
        rec, paths.join(ROOT, "truth"), ts, vs, name="people home (truth)", rgb=TRUTH_RGB, width=TRUTH_WIDTH
    )
    bins = made.get("occupancy_bins")
    if bins is not None and bins.height and bins["door"].any():
        d = bins.filter("door")
        entity = paths.join(ROOT, "doors")
        rec.log(entity, rr.SeriesPoints(colors=[(80, 160, 255)], names=["door event"], markers=["cross"]), static=True)
        rec.send_columns(
            entity,
            indexes=[paths.time_column(d["t"].to_numpy())],
            columns=rr.Scalars.columns(scalars=np.full(d.height, DOOR_Y)),
        )


def log_sensor_map(rec, site, motion: pl.DataFrame | None) -> None:
    """``occupancy/sensors``: the motion sensors on the site, labelled, coloured by their state.

    Positions and labels are static; the colours are one row per time at which some sensor
    changed (all sensors off before the first edge), so the map shows which sensors are on now.
    """
    sensors = list(site.motion_sensors)
    if not sensors or is_empty(motion):
        return
    index = {m.id: i for i, m in enumerate(sensors)}
    edges = motion.filter(pl.col("sensor").is_in(list(index))).sort("t", maintain_order=True)
    if edges.height == 0:
        return
    entity = paths.join(ROOT, "sensors")
    log_world_frame(rec, entity)
    rec.log(
        entity,
        rr.Points2D(
            [m.position for m in sensors],
            labels=[m.id for m in sensors],
            radii=rr.Radius.ui_points(5.0),
            show_labels=True,
            draw_order=12.0,
        ),
        static=True,
    )
    t = edges["t"].to_numpy().astype(np.float64)
    col = np.fromiter((index[s] for s in edges["sensor"].to_list()), dtype=np.int64, count=edges.height)
    state = np.zeros(len(sensors), dtype=bool)
    rows = np.empty((edges.height, len(sensors)), dtype=bool)
    for k, (c, on) in enumerate(zip(col, edges["on"].to_list(), strict=True)):
        state[c] = bool(on)
        rows[k] = state
    last = np.r_[t[1:] != t[:-1], True]  # one row per time: the state after its last edge
    t, rows = np.r_[t[0] - 1.0, t[last]], np.vstack([np.zeros((1, len(sensors)), dtype=bool), rows[last]])
    on_rgba, off_rgba = np.array([*colors.FIRING[:3], 255], np.uint8), np.array(SENSOR_OFF, np.uint8)
    rgba = np.where(rows.reshape(-1, 1), on_rgba, off_rgba)
    rec.send_columns(
        entity,
        indexes=[paths.time_column(t)],
        columns=rr.Points2D.columns(colors=rgba).partition(np.full(t.size, len(sensors), dtype=np.int64)),
    )
