"""Rerun logging of the ``clustertrack`` stage (everything bulk goes through ``send_columns``).

Entities (``<tracker>`` = ``clustertrack``):

* ``<tracker>/sensors/outer`` and ``.../inner``: every proximity sensor as a disk of radius
  R_o (and R_i when it differs), coloured by its state at each instant (on: red, off: grey).
* ``<tracker>/feasible``: F at each instant -- segments on the line (1-D) or the F cells
  coloured by component (2-D).
* ``<tracker>/particles``: the surviving particles' current positions, coloured by cluster.
* ``<tracker>/tracks/<track>``: the final tracks (with their paths).
* ``<tracker>/space_time/...``: 1-D only, the paper's figures: a static time-by-position
  plane (x = position, y = instant index * ``row``) with F as segments, the truth and the
  tracks as polylines.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import rerun as rr

from onebit.viz import colors, paths
from onebit.viz.tracks import log_point_tracks

ON = (220, 40, 40, 110)
OFF = (150, 150, 150, 50)


def _instants(times: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.searchsorted(times, t)


def _colors_by_id(ids: pl.Series, *, alpha: int) -> np.ndarray:
    """``(n, 4)`` colours of integer ids (clusters, components): the palette is looked up once
    per distinct id and gathered, so there is no Python work per particle or cell."""
    u, inv = np.unique(ids.to_numpy(), return_inverse=True)
    return colors.colors_of(u.tolist(), alpha=alpha)[inv.ravel()]


def log_sensor_states(rec: rr.RecordingStream, tracker: str, site, frames_on: np.ndarray, times: np.ndarray) -> None:
    """Sensors as disks (R_o, and R_i when smaller) coloured by their state per instant."""
    ps = site.proximity_sensors
    if not ps or times.size == 0:
        return
    xy = np.array([p.position for p in ps], float)
    n, T = len(ps), times.size
    col = np.where(frames_on.reshape(T, n, 1), np.array(ON, np.uint8), np.array(OFF, np.uint8)).reshape(T * n, 4)
    for name, r in (("outer", [p.r_outer for p in ps]), ("inner", [p.r_inner for p in ps])):
        if name == "inner" and all(p.r_inner == p.r_outer for p in ps):
            continue
        ent = paths.join(paths.tracker_root(tracker), "sensors", name)
        rec.log(ent, rr.Points2D.from_fields(radii=np.asarray(r, np.float32), draw_order=1.0), static=True)
        rec.send_columns(
            ent,
            indexes=[paths.time_column(times)],
            columns=rr.Points2D.columns(positions=np.tile(xy, (T, 1)), colors=col).partition([n] * T),
        )


def log_feasible_1d(rec: rr.RecordingStream, tracker: str, feasible: pl.DataFrame, times: np.ndarray, *, row: float) -> None:
    """F per instant as segments on y = 0, and all instants on the time-by-position plane."""
    if feasible.height == 0:
        return
    f = feasible.sort("t")
    k = _instants(times, f["t"].to_numpy())
    lo, hi = f["lo"].to_numpy(), f["hi"].to_numpy()
    strips = np.stack([np.c_[lo, np.zeros_like(lo)], np.c_[hi, np.zeros_like(hi)]], axis=1)
    counts = np.bincount(k, minlength=times.size)
    ent = paths.join(paths.tracker_root(tracker), "feasible")
    rec.log(ent, rr.LineStrips2D.from_fields(radii=0.08, colors=(40, 120, 220, 200), draw_order=5.0), static=True)
    rec.send_columns(ent, indexes=[paths.time_column(times)], columns=rr.LineStrips2D.columns(strips=list(strips)).partition(counts.tolist()))
    st = strips.copy()
    st[:, :, 1] = (k * row)[:, None]
    rec.log(paths.join(paths.tracker_root(tracker), "space_time", "feasible"),
            rr.LineStrips2D(list(st), radii=0.05, colors=(40, 120, 220, 160)), static=True)


def log_feasible_2d(rec: rr.RecordingStream, tracker: str, cells: pl.DataFrame, times: np.ndarray, cell: float) -> None:
    """F cells per instant, coloured by component."""
    if cells.height == 0:
        return
    c = cells.sort("t")
    k = _instants(times, c["t"].to_numpy())
    counts = np.bincount(k, minlength=times.size)
    ent = paths.join(paths.tracker_root(tracker), "feasible")
    rec.log(ent, rr.Points2D.from_fields(radii=cell / 2, draw_order=4.0), static=True)
    rec.send_columns(
        ent,
        indexes=[paths.time_column(times)],
        columns=rr.Points2D.columns(positions=c.select("x", "y").to_numpy(), colors=_colors_by_id(c["component"], alpha=90)).partition(counts.tolist()),
    )


def log_particles(rec: rr.RecordingStream, tracker: str, particles: pl.DataFrame, times: np.ndarray) -> None:
    """Survivors per instant in their cluster's colour."""
    if particles.height == 0:
        return
    p = particles.sort("t", maintain_order=True)
    k = _instants(times, p["t"].to_numpy())
    counts = np.bincount(k, minlength=times.size)
    ent = paths.particles(tracker)
    rec.log(ent, rr.Points2D.from_fields(radii=0.06, draw_order=20.0), static=True)
    rec.send_columns(
        ent,
        indexes=[paths.time_column(times)],
        columns=rr.Points2D.columns(positions=p.select("x", "y").to_numpy(), colors=_colors_by_id(p["cluster"], alpha=160)).partition(counts.tolist()),
    )


def log_space_time(rec: rr.RecordingStream, tracker: str, tracks: pl.DataFrame, truth: pl.DataFrame | None, times: np.ndarray, *, row: float) -> None:
    """Tracks (and the truth when given) as polylines on the time-by-position plane."""
    base = paths.join(paths.tracker_root(tracker), "space_time")
    for name, df, key, width in (("tracks", tracks, "track", 0.06), ("truth", truth, "target", 0.04)):
        if df is None or df.height == 0:
            continue
        for ident, g in df.sort("t").partition_by(key, as_dict=True, maintain_order=True).items():  # one strip per track
            k = _instants(times, g["t"].to_numpy())
            strip = np.c_[g["x"].to_numpy(), k * row]
            rec.log(paths.join(base, name, paths.part(ident[0])), rr.LineStrips2D([strip], radii=width, colors=colors.color_of(ident[0])), static=True)


def log_clustertrack(rec: rr.RecordingStream, tracker: str, site, out: dict, times: np.ndarray, *, frames_on: np.ndarray | None = None,
                     cells: pl.DataFrame | None = None, cell: float = 0.1, truth: pl.DataFrame | None = None) -> None:
    """Everything the stage produced (see the module docstring)."""
    minx, _, maxx, _ = site.boundary.bounds
    row = max((maxx - minx) / max(times.size, 1) / 2.0, 0.2)
    if frames_on is not None:
        log_sensor_states(rec, tracker, site, frames_on, times)
    if "feasible" in out:
        log_feasible_1d(rec, tracker, out["feasible"], times, row=row)
        log_space_time(rec, tracker, out["tracks"], truth, times, row=row)
    elif cells is not None:
        log_feasible_2d(rec, tracker, cells, times, cell)
    log_particles(rec, tracker, out["particles"], times)
    log_point_tracks(rec, tracker, out["tracks"])


def log_run(rec: rr.RecordingStream, tracker: str, out: dict, *, site, region_graph, config, tables: dict) -> None:
    """Everything CLUSTERTRACK produced (see the module docstring); the truth joins the
    space-time view when the run has it."""
    art = out.get("artifacts")
    if art is None:
        return
    times = art["times"]
    truth = tables.get("truth")
    if truth is not None:
        truth = truth.filter(pl.col("t").is_in(times.tolist()))
    log_clustertrack(rec, tracker, site, out, times, frames_on=art["frames_on"], cells=art["cells"], cell=art["cell"], truth=truth)
