"""Rerun logging of PIR motion sensors and the intruder particle filter.

Entities::

    sensors/<id>                         on/off state of each motion sensor over time (Scalars 0/1)
    site/sensors/<id>/coverage           each deployed sensor's detection grid as a heat map (static)
    <tracker>/sensors/<id>               field of view coloured by state: firing, refractory, idle
    <tracker>/particles                  particles every iteration, coloured by weight
    <tracker>/estimate                   the estimate and its bounding box
    <tracker>/camera                     the camera's view cone towards the estimate
    scores/<tracker>/<track>             error (see :mod:`onebit.viz.tracks`)

Bulk data (every iteration's particles) goes through ``send_columns`` with partitioned
component columns, never one ``log`` per iteration.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import polars as pl
import rerun as rr

from onebit.viz.tracks import log_point_tracks
from onebit.viz import colors, paths
from onebit.viz._series import is_empty

#: Colours of a sensor's state.
FIRING = (230, 40, 40, 140)
REFRACTORY = (240, 170, 30, 110)
IDLE = (120, 120, 120, 50)


def log_motion_states(rec: rr.RecordingStream, motion: pl.DataFrame | None, sensors: Sequence[str]) -> None:
    """Each sensor's state (1 on, 0 off) as a step series on ``sensors/<id>`` from its edges."""
    if is_empty(motion):
        return
    for sid in sensors:
        g = motion.filter(pl.col("sensor") == sid).sort("t")
        if g.height == 0:
            continue
        entity = paths.sensor(sid)
        rec.log(entity, rr.SeriesLines(colors=colors.color_of(sid), names=[sid]), static=True)
        t = g["t"].to_numpy()
        v = g["on"].cast(pl.Float64).to_numpy()
        # a step: the previous value just before each edge, then the new value
        tt = np.repeat(t, 2)
        vv = np.c_[1.0 - v, v].ravel()
        rec.send_columns(entity, indexes=[paths.time_column(tt)], columns=rr.Scalars.columns(scalars=vv))


def _exterior(poly) -> np.ndarray | None:
    if poly is None or poly.is_empty:
        return None
    if poly.geom_type == "Polygon":
        return np.asarray(poly.exterior.coords)[:, :2]
    return np.asarray(poly.coords)[:, :2] if hasattr(poly, "coords") else None


def weight_colors(w: np.ndarray, *, alpha: int = 200) -> np.ndarray:
    """``(..., 4)`` RGBA colours of weights: blue (lowest in its iteration) to red (highest).

    ``w`` is ``(T, L)``; each iteration is scaled by its own maximum.
    """
    w = np.asarray(w, float)
    top = np.max(w, axis=-1, keepdims=True)
    s = np.divide(w, top, out=np.zeros_like(w), where=top > 0)
    out = np.empty(w.shape + (4,), np.uint8)
    out[..., 0] = (40 + 215 * s).astype(np.uint8)
    out[..., 1] = (60 * (1 - s)).astype(np.uint8)
    out[..., 2] = (220 * (1 - s) + 20).astype(np.uint8)
    out[..., 3] = alpha
    return out


def log_coverage(rec: rr.RecordingStream, dep) -> None:
    """Each deployed sensor's q_ij grid as a heat map of cell boxes on ``site/sensors/<id>/coverage`` (static)."""
    g = dep.grid
    for i, sid in enumerate(dep.ids):
        iy, ix = np.nonzero(dep.q[i])
        if len(ix) == 0:
            continue
        q = dep.q[i][iy, ix]
        centers = np.c_[g.x0 + (ix + 0.5) * g.cell, g.y0 + (iy + 0.5) * g.cell]
        col = np.zeros((len(q), 4), np.uint8)
        col[:, 0], col[:, 1], col[:, 2] = 230, (160 * (1 - q)).astype(np.uint8), 30
        col[:, 3] = (30 + 120 * q).astype(np.uint8)
        rec.log(
            paths.join(paths.site_sensor(sid), "coverage"),
            rr.Boxes2D(centers=centers, half_sizes=np.full((len(q), 2), g.cell / 2), colors=col, draw_order=5.0),
            static=True,
        )


def log_sensor_states(
    rec: rr.RecordingStream, tracker: str, dep, t: np.ndarray, fired: np.ndarray, blind: np.ndarray
) -> None:
    """Each sensor's field of view (hull of its coverage) on ``<tracker>/sensors/<id>``, its colour
    per iteration: firing (red), refractory (orange) or idle (grey)."""
    if len(t) == 0:
        return
    for i, sid in enumerate(dep.ids):
        ring = _exterior(dep.hulls[i])
        if ring is None:
            continue
        entity = paths.join(paths.tracker_root(tracker), "sensors", paths.part(sid))
        rec.log(entity, rr.LineStrips2D([ring], radii=rr.Radius.ui_points(2.0), labels=[sid], draw_order=12.0), static=True)
        col = np.where(fired[:, i, None], np.array(FIRING, np.uint8), np.where(blind[:, i, None], np.array(REFRACTORY, np.uint8), np.array(IDLE, np.uint8)))
        col[:, 3] = 255
        rec.send_columns(entity, indexes=[paths.time_column(t)], columns=rr.LineStrips2D.columns(colors=col.astype(np.uint8)))


def log_particles(rec: rr.RecordingStream, tracker: str, t: np.ndarray, xy: np.ndarray, w: np.ndarray) -> None:
    """Particles of every iteration (``xy`` (T, L, 2), weights ``w`` (T, L)) on ``<tracker>/particles``."""
    if len(t) == 0 or xy.shape[1] == 0:
        return
    T, L = w.shape
    entity = paths.particles(tracker)
    rec.log(entity, rr.Points2D.from_fields(radii=rr.Radius.ui_points(2.5), draw_order=20.0), static=True)
    rec.send_columns(
        entity,
        indexes=[paths.time_column(t)],
        columns=rr.Points2D.columns(positions=xy.reshape(-1, 2), colors=weight_colors(w).reshape(-1, 4)).partition([L] * T),
    )


def log_estimate(
    rec: rr.RecordingStream, tracker: str, t: np.ndarray, est: np.ndarray, width: float, depth: float
) -> None:
    """The estimate and its bounding box on ``<tracker>/estimate``."""
    if len(t) == 0:
        return
    entity = paths.join(paths.tracker_root(tracker), "estimate")
    rec.log(entity, rr.Boxes2D.from_fields(colors=colors.color_of(tracker), radii=rr.Radius.ui_points(2.0), draw_order=28.0), static=True)
    rec.send_columns(
        entity,
        indexes=[paths.time_column(t)],
        columns=rr.Boxes2D.columns(centers=est, half_sizes=np.tile([width / 2, depth / 2], (len(t), 1))),
    )


def log_camera_cone(
    rec: rr.RecordingStream,
    tracker: str,
    camera: tuple[float, float, float],
    t: np.ndarray,
    est: np.ndarray,
    ptz: pl.DataFrame,
    fov_deg: float,
) -> None:
    """The camera's horizontal view cone towards each estimate on ``<tracker>/camera`` (floor plan).

    The cone's half-angle is ``atan(tan(fov/2) / zoom)``; its sides reach just past the estimate.
    """
    if len(t) == 0:
        return
    entity = paths.join(paths.tracker_root(tracker), "camera")
    cam = np.asarray(camera[:2], float)
    pan = np.radians(ptz["pan"].to_numpy())
    half = np.arctan(np.tan(np.radians(fov_deg) / 2) / ptz["zoom"].to_numpy())
    reach = np.linalg.norm(est - cam, axis=1) * 1.15
    a = cam + reach[:, None] * np.c_[np.cos(pan - half), np.sin(pan - half)]
    b = cam + reach[:, None] * np.c_[np.cos(pan + half), np.sin(pan + half)]
    strips = [np.vstack([a[k], cam, b[k]]) for k in range(len(t))]  # one 3-vertex strip per iteration
    rec.log(entity, rr.LineStrips2D.from_fields(colors=(40, 170, 90, 255), radii=rr.Radius.ui_points(1.5), draw_order=26.0), static=True)
    rec.send_columns(entity, indexes=[paths.time_column(t)], columns=rr.LineStrips2D.columns(strips=strips))


def log_run(rec: rr.RecordingStream, tracker: str, out: dict, *, site, region_graph, config, tables: dict) -> None:
    """Everything the ``intruder`` (or ``intruder-naive``) tracker produced: coverage, sensor
    states, particles, the estimate with its box, the camera cone and the track."""
    art = out.get("artifacts")
    if art is not None:
        t_end = art["t_end"]
        log_coverage(rec, art["deployment"])
        log_sensor_states(rec, tracker, art["deployment"], t_end, art["fired"], art["blind"])
        log_particles(rec, tracker, t_end, art["particles_xy"], art["particles_w"])
        log_estimate(rec, tracker, t_end, art["estimates"], *art["box"])
        if "camera" in out:
            log_camera_cone(rec, tracker, tuple(config.camera_position), t_end, art["estimates"], out["camera"], config.camera_fov)
    log_point_tracks(rec, tracker, out["tracks"])
