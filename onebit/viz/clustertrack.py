"""Rerun logging of the ``clustertrack`` stage (Singh et al.): everything bulk goes through
``send_columns``.

Entities (``<tracker>`` = ``clustertrack``):

* ``<tracker>/space_time/...`` (1-D sites) -- the paper's picture: a static diagram with
  position along the line to the right and **time upwards**, with labelled axes
  (``axes``, ``axes/labels``: ``"position x (ft)"``, ``"time t (s)"``, ticks), the feasible
  space F of every instant as bands (``feasible``), the true paths (``truth/<target>``, neutral),
  the tracks (``tracks/<track>``, the tracker's colour, labelled ``"track k"``) and a line at the
  current instant (``now``) that moves with the time cursor;
* ``<tracker>/count/<series>`` -- the counting bound over time (Scalars, targets):
  ``lower_bound`` (Theorem 4), ``components`` (of F) and ``true`` (targets in the truth);
* ``<tracker>/sensors/outer`` and ``.../inner`` -- every proximity sensor at each instant: a red
  disk of radius R_o (and R_i when it differs) when on, a small grey dot when off;
* ``<tracker>/feasible`` -- F at each instant: segments on the line (1-D) or the F cells
  coloured by component (2-D);
* ``<tracker>/particles`` -- the surviving particles now, coloured by cluster;
* ``<tracker>/tracks/<track>`` -- the tracks now (dot, trail, hidden path; :mod:`onebit.viz.tracks`).
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import bulk, colors, paths
from onebit.viz._series import is_empty, strips_array
from onebit.viz.families import GENERIC, Look
from onebit.viz.frame import log_world_frame
from onebit.viz.tracks import log_point_tracks, track_colors, track_labels

rr = lazy_module("rerun")

#: A sensor that is on is a disk of its sensing radius (R_o; R_i darker inside when it differs),
#: one that is off a small dot: the union of the disks is where the targets can be.
ON = (120, 35, 35, 255)
ON_INNER = (160, 45, 45, 255)
OFF = (110, 110, 115, 255)
OFF_DOT = 0.08
FEASIBLE = (60, 130, 230, 150)
AXIS = (200, 200, 200, 255)


def _instants(times: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.searchsorted(times, t)


def _colors_by_id(ids: pl.Series, *, alpha: int) -> np.ndarray:
    """``(n, 4)`` colours of integer ids (clusters, components): the palette is looked up once
    per distinct id and gathered, so there is no Python work per particle or cell."""
    u, inv = np.unique(ids.to_numpy(), return_inverse=True)
    return colors.colors_of(u.tolist(), alpha=alpha)[inv.ravel()]


def nice_step(span: float, *, ticks: int = 6) -> float:
    """A round tick step (1, 2 or 5 times a power of ten) giving about ``ticks`` ticks over ``span``."""
    if not np.isfinite(span) or span <= 0:
        return 1.0
    raw = span / ticks
    p = 10.0 ** np.floor(np.log10(raw))
    return float(min((m * p for m in (1.0, 2.0, 5.0, 10.0)), key=lambda s: abs(s - raw)))


class SpaceTime:
    """The mapping of (position, time) to the diagram's plane: ``x`` as is, ``y = (t - t0) * scale``.

    ``scale`` makes the diagram about 0.6 times as tall as it is wide.
    """

    def __init__(self, x_lo: float, x_hi: float, times: np.ndarray) -> None:
        self.x_lo, self.x_hi = float(x_lo), float(x_hi)
        self.t0 = float(times[0]) if times.size else 0.0
        duration = float(times[-1] - times[0]) if times.size > 1 else 1.0
        self.duration = duration if duration > 0 else 1.0
        self.scale = 0.6 * (self.x_hi - self.x_lo) / self.duration
        self.row = self.scale * (float(np.median(np.diff(times))) if times.size > 1 else 1.0)

    def y(self, t: np.ndarray | float) -> np.ndarray:
        return (np.asarray(t, np.float64) - self.t0) * self.scale


def log_axes(rec: rr.RecordingStream, base: str, st: SpaceTime, units: str) -> None:
    """Static axes of the diagram with ticks and their labels, and the axis titles."""
    width = st.x_hi - st.x_lo
    pad = 0.03 * width
    top = st.y(st.t0 + st.duration)
    tick = 0.015 * width
    x_step, t_step = nice_step(width), nice_step(st.duration)
    xs = np.arange(np.ceil(st.x_lo / x_step) * x_step, st.x_hi + 1e-9, x_step)
    ts = np.arange(0.0, st.duration + 1e-9, t_step)
    y0, x0 = -pad, st.x_lo - pad
    strips = [np.array([[x0, y0], [st.x_hi, y0]]), np.array([[x0, y0], [x0, top + st.row]])]
    strips += [np.array([[x, y0], [x, y0 - tick]]) for x in xs]
    strips += [np.array([[x0, st.y(st.t0 + s)], [x0 - tick, st.y(st.t0 + s)]]) for s in ts]
    rec.log(paths.join(base, "axes"), rr.LineStrips2D(strips, colors=AXIS, radii=rr.Radius.ui_points(1.0)), static=True)
    pos = [[x, y0 - 3 * tick] for x in xs] + [[x0 - 5 * tick, st.y(st.t0 + s)] for s in ts]
    text = [f"{x + 0.0:g}" for x in np.round(xs, 9)] + [f"{st.t0 + s + 0.0:g} s" for s in np.round(ts, 9)]
    pos += [[(st.x_lo + st.x_hi) / 2, y0 - 8 * tick], [x0 - 5 * tick, top + st.row + 3 * tick]]
    text += [f"position x along the line ({units}) \u2192", "time t (s) \u2191"]
    rec.log(
        paths.join(base, "axes", "labels"),
        rr.Points2D(pos, labels=text, radii=0.0, colors=AXIS, show_labels=True),
        static=True,
    )


def log_space_time(
    rec: rr.RecordingStream,
    tracker: str,
    site,
    times: np.ndarray,
    *,
    feasible: pl.DataFrame | None,
    tracks: pl.DataFrame | None,
    truth: pl.DataFrame | None,
    rgb: tuple[int, int, int] | None = None,
) -> None:
    """The 1-D space-time diagram (module docstring); tracks in shades of ``rgb``."""
    if times.size == 0:
        return
    minx, _, maxx, _ = site.boundary.bounds
    st = SpaceTime(minx, maxx, times)
    base = paths.join(paths.tracker_root(tracker), "space_time")
    log_world_frame(rec, base)
    log_axes(rec, base, st, site.units)
    if not is_empty(feasible):
        f = feasible.sort("t")
        y = st.y(f["t"].to_numpy())
        strips = np.stack([np.c_[f["lo"].to_numpy(), y], np.c_[f["hi"].to_numpy(), y]], axis=1)
        rec.log(
            paths.join(base, "feasible"),
            rr.LineStrips2D(
                strips_array(strips, 2),
                radii=0.4 * st.row,
                colors=FEASIBLE,
                labels=["feasible space F"],
                show_labels=False,
            ),
            static=True,
        )
    if not is_empty(truth):
        _log_space_time_paths(
            rec, base, "truth", truth, "target", st, radius=1.0, shades=None, labels=None, show_labels=False
        )
    if not is_empty(tracks):
        labels = track_labels(tracker, tracks["track"].unique().to_list())
        shades = track_colors(tracker, labels, rgb=rgb)
        _log_space_time_paths(
            rec, base, "tracks", tracks, "track", st, radius=2.0, shades=shades, labels=labels, show_labels=True
        )
    now = paths.join(base, "now")
    y = st.y(times)
    rec.log(
        now,
        rr.LineStrips2D.from_fields(colors=(255, 255, 255, 200), radii=rr.Radius.ui_points(1.0), draw_order=30.0),
        static=True,
    )
    rec.send_columns(
        now,
        indexes=[paths.time_column(times)],
        columns=rr.LineStrips2D.columns(
            strips=strips_array(
                np.stack([np.c_[np.full_like(y, st.x_lo), y], np.c_[np.full_like(y, st.x_hi), y]], axis=1), 2
            )
        ),
    )


def _log_space_time_paths(
    rec: rr.RecordingStream,
    base: str,
    kind: str,
    frame: pl.DataFrame,
    key: str,
    st: SpaceTime,
    *,
    radius: float,
    shades: dict | None,
    labels: dict | None,
    show_labels: bool,
) -> None:
    """``<base>/<kind>/<id>``: each id's path in the space-time plane as one static strip, in
    its shade (``shades``; the truth's trail colour without) labelled ``labels[id]`` (``"true
    <id>"`` without); the strips of all ids are built in one go (:mod:`onebit.viz.bulk`)."""
    spans = bulk.track_spans(frame.select(key, "t", "x"), key)
    if not spans.keys:
        return
    f = spans.frame
    pts = np.c_[f["x"].to_numpy(), st.y(f["t"].to_numpy())]
    names = [labels[k] for k in spans.keys] if labels is not None else [f"true {k}" for k in spans.keys]
    tints = [shades[k] for k in spans.keys] if shades is not None else [colors.TRUTH_TRAIL] * len(spans.keys)
    template = rr.LineStrips2D(
        [pts[: spans.bounds[1]]],
        radii=rr.Radius.ui_points(radius),
        colors=tints[0],
        labels=[names[0]],
        show_labels=show_labels,
    )
    per_id = {
        "LineStrips2D:strips": strips_array(pts, spans.lengths),
        "LineStrips2D:colors": bulk.color_array(tints),
        "LineStrips2D:labels": bulk.text_batch(names),
    }
    bulk.log_styles(rec, [paths.join(base, kind, paths.part(k)) for k in spans.keys], template, per_id)


def log_counts(rec: rr.RecordingStream, tracker: str, counts: pl.DataFrame | None, truth: pl.DataFrame | None) -> None:
    """The counting bound over time (targets): Theorem 4's lower bound, F's components and,
    with the truth, the true number of targets at each instant."""
    if is_empty(counts):
        return
    c = counts.sort("t")
    t = c["t"].to_numpy()
    series = [
        ("lower_bound", "lower bound (Theorem 4)", (255, 160, 40), c["lower_bound"]),
        ("components", "components of F", (60, 130, 230), c["components"]),
    ]
    if not is_empty(truth):
        n_true = truth.group_by("t").agg(pl.col("target").n_unique().alias("n"))
        true = c.select("t").join(n_true, on="t", how="left")["n"].fill_null(0)
        series.append(("true", "true targets", colors.TRUTH[:3], true))
    for key, name, color, values in series:
        entity = paths.join(paths.tracker_root(tracker), "count", key)
        rec.log(
            entity,
            rr.SeriesLines(
                colors=color, names=[name], widths=[2.0], interpolation_mode=rr.components.InterpolationMode.StepAfter
            ),
            static=True,
        )
        rec.send_columns(
            entity,
            indexes=[paths.time_column(t)],
            columns=rr.Scalars.columns(scalars=values.cast(pl.Float64).to_numpy()),
        )


def log_sensor_states(rec: rr.RecordingStream, tracker: str, site, frames_on: np.ndarray, times: np.ndarray) -> None:
    """Sensors per instant: on = a disk of radius R_o (and R_i when smaller), off = a small dot."""
    ps = site.proximity_sensors
    if not ps or times.size == 0:
        return
    log_world_frame(rec, paths.tracker_root(tracker))
    xy = np.array([p.position for p in ps], float)
    n, T = len(ps), times.size
    on = frames_on.reshape(T, n)
    for name, r, color in (("outer", [p.r_outer for p in ps], ON), ("inner", [p.r_inner for p in ps], ON_INNER)):
        if name == "inner" and all(p.r_inner == p.r_outer for p in ps):
            continue
        ent = paths.join(paths.tracker_root(tracker), "sensors", name)
        r = np.asarray(r, np.float32)
        radii = np.where(on, r[None, :], OFF_DOT * r[None, :]).astype(np.float32).ravel()
        col = np.where(on[..., None], np.array(color, np.uint8), np.array(OFF, np.uint8)).reshape(T * n, 4)
        rec.log(ent, rr.Points2D.from_fields(draw_order=1.0 if name == "outer" else 1.5), static=True)
        rec.send_columns(
            ent,
            indexes=[paths.time_column(times)],
            columns=rr.Points2D.columns(positions=np.tile(xy, (T, 1)), colors=col, radii=radii).partition([n] * T),
        )


def log_feasible_1d(rec: rr.RecordingStream, tracker: str, feasible: pl.DataFrame, times: np.ndarray) -> None:
    """F per instant as segments on the line (y = 0)."""
    if feasible.height == 0:
        return
    f = feasible.sort("t")
    k = _instants(times, f["t"].to_numpy())
    lo, hi = f["lo"].to_numpy(), f["hi"].to_numpy()
    strips = np.stack([np.c_[lo, np.zeros_like(lo)], np.c_[hi, np.zeros_like(hi)]], axis=1)
    counts = np.bincount(k, minlength=times.size)
    ent = paths.join(paths.tracker_root(tracker), "feasible")
    log_world_frame(rec, ent)
    rec.log(
        ent, rr.LineStrips2D.from_fields(radii=rr.Radius.ui_points(5.0), colors=FEASIBLE, draw_order=5.0), static=True
    )
    rec.send_columns(
        ent,
        indexes=[paths.time_column(times)],
        columns=rr.LineStrips2D.columns(strips=strips_array(strips, 2)).partition(counts),
    )


def log_feasible_2d(rec: rr.RecordingStream, tracker: str, cells: pl.DataFrame, times: np.ndarray, cell: float) -> None:
    """F cells per instant, coloured by component."""
    if cells.height == 0:
        return
    c = cells.sort("t")
    k = _instants(times, c["t"].to_numpy())
    counts = np.bincount(k, minlength=times.size)
    ent = paths.join(paths.tracker_root(tracker), "feasible")
    log_world_frame(rec, ent)
    rec.log(ent, rr.Points2D.from_fields(radii=cell / 2, draw_order=4.0), static=True)
    rec.send_columns(
        ent,
        indexes=[paths.time_column(times)],
        columns=rr.Points2D.columns(
            positions=c.select("x", "y").to_numpy(), colors=_colors_by_id(c["component"], alpha=90)
        ).partition(counts.tolist()),
    )


def log_particles(rec: rr.RecordingStream, tracker: str, particles: pl.DataFrame, times: np.ndarray) -> None:
    """Survivors per instant in their cluster's colour."""
    if particles.height == 0:
        return
    p = particles.sort("t", maintain_order=True)
    k = _instants(times, p["t"].to_numpy())
    counts = np.bincount(k, minlength=times.size)
    ent = paths.particles(tracker)
    log_world_frame(rec, ent)
    rec.log(ent, rr.Points2D.from_fields(radii=rr.Radius.ui_points(2.5), draw_order=20.0), static=True)
    rec.send_columns(
        ent,
        indexes=[paths.time_column(times)],
        columns=rr.Points2D.columns(
            positions=p.select("x", "y").to_numpy(), colors=_colors_by_id(p["cluster"], alpha=160)
        ).partition(counts.tolist()),
    )


def log_clustertrack(
    rec: rr.RecordingStream,
    tracker: str,
    site,
    out: dict,
    times: np.ndarray,
    *,
    frames_on: np.ndarray | None = None,
    cells: pl.DataFrame | None = None,
    cell: float = 0.1,
    truth: pl.DataFrame | None = None,
    rgb: tuple[int, int, int] | None = None,
) -> None:
    """Everything the stage produced (see the module docstring); tracks in shades of ``rgb``."""
    if frames_on is not None:
        log_sensor_states(rec, tracker, site, frames_on, times)
    if "feasible" in out:
        log_feasible_1d(rec, tracker, out["feasible"], times)
        log_space_time(rec, tracker, site, times, feasible=out["feasible"], tracks=out["tracks"], truth=truth, rgb=rgb)
    elif cells is not None:
        log_feasible_2d(rec, tracker, cells, times, cell)
    log_counts(rec, tracker, out.get("counts"), truth)
    log_particles(rec, tracker, out["particles"], times)
    log_point_tracks(rec, tracker, out["tracks"], rgb=rgb)


def log_run(
    rec: rr.RecordingStream, tracker: str, out: dict, *, site, region_graph, config, tables: dict, look: Look = GENERIC
) -> None:
    """Everything CLUSTERTRACK produced (see the module docstring); the truth joins the
    space-time diagram and the count plot when the run has it."""
    art = out.get("artifacts")
    if art is None:
        return
    times = art["times"]
    truth = tables.get("truth")
    if truth is not None:
        truth = truth.filter(pl.col("t").is_in(times.tolist()))
    log_clustertrack(
        rec,
        tracker,
        site,
        out,
        times,
        frames_on=art["frames_on"],
        cells=art["cells"],
        cell=art["cell"],
        truth=truth,
        rgb=look.rgb,
    )
