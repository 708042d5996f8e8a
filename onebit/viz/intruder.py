"""Rerun logging of PIR motion sensors and the intruder particle filter.

Entities::

    sensors/<id>                         on/off state of each motion sensor over time (StateChange)
    site/sensors/<id>/coverage           each deployed sensor's detection grid as a heat map
                                         (static; hidden by default in the blueprint)
    <tracker>/sensors/<id>               field of view of each sensor that fired in the iteration
                                         (red); nothing when it did not (site/sensors marks
                                         every sensor, dimmed)
    <tracker>/particles                  particles every iteration, coloured by weight (dim
                                         purple = low, bright yellow = high)
    <tracker>/estimate                   the estimate's bounding box, in the tracker's colour
    <tracker>/tracks/<track>             the estimate (dot, trail, hidden path; onebit.viz.tracks)
    <tracker>/camera                     the camera's view cone towards the estimate
    scores/<tracker>/<track>             distance from the truth (site units; onebit.viz.tracks)

Bulk data (every iteration's particles) goes through ``send_columns`` with partitioned
component columns, never one ``log`` per iteration.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import colors, paths
from onebit.viz._series import groups, is_empty, strips_array, text_array
from onebit.viz.families import GENERIC, Look
from onebit.viz.frame import log_world_frame
from onebit.viz.radii import ui_points
from onebit.viz.tracks import log_point_tracks

rr = lazy_module("rerun")

#: Colour and width of the field of view of a sensor that fired (the others are not drawn).
FIRING = (235, 70, 60, 255)
FOV_WIDTH = ui_points(1.25)

#: The two states of a binary sensor in the state timeline, and their colours.
ON, OFF = "on", "off"


@functools.cache
def _states():
    """The on / off state configuration of the sensor timelines (built on first use: rerun is imported lazily)."""
    return rr.StateConfiguration(values=[ON, OFF], colors=[colors.FIRING[:3], (60, 60, 60)])


def log_motion_states(rec: rr.RecordingStream, motion: pl.DataFrame | None, sensors: Sequence[str]) -> None:
    """Each sensor's on/off state over time on ``sensors/<id>`` (:class:`rerun.StateChange` at
    each accepted edge, shown as bands in a state timeline)."""
    if is_empty(motion):
        return
    known = set(map(str, sensors))
    for sid, g in groups(motion, "sensor"):  # one partition of the log per sensor, not a filter each
        if sid not in known:
            continue
        entity = paths.sensor(sid)
        rec.log(entity, _states(), static=True)
        state = text_array(pl.select(pl.when(g["on"]).then(pl.lit(ON)).otherwise(pl.lit(OFF))).to_series())
        rec.send_columns(
            entity, indexes=[paths.time_column(g["t"].to_numpy())], columns=rr.StateChange.columns(state=state)
        )


def _exterior(poly) -> np.ndarray | None:
    if poly is None or poly.is_empty:
        return None
    if poly.geom_type == "Polygon":
        return np.asarray(poly.exterior.coords)[:, :2]
    return np.asarray(poly.coords)[:, :2] if hasattr(poly, "coords") else None


#: Particle colour ramp by weight: dim purple (lowest) -> bright yellow (highest), alpha rising.
_LOW = np.array([110, 80, 190, 110], float)
_HIGH = np.array([255, 235, 90, 230], float)


def weight_colors(w: np.ndarray) -> np.ndarray:
    """``(..., 4)`` RGBA colours of weights: dim translucent purple (lowest in its iteration)
    to bright opaque yellow (highest), so the weighty particles stand out.

    ``w`` is ``(T, L)``; each iteration is scaled by its own maximum.
    """
    w = np.asarray(w, float)
    top = np.max(w, axis=-1, keepdims=True)
    s = np.divide(w, top, out=np.zeros_like(w), where=top > 0)[..., None]
    return np.round(_LOW + (_HIGH - _LOW) * np.sqrt(s)).astype(np.uint8)


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
        log_world_frame(rec, paths.SITE)
        rec.log(
            paths.join(paths.site_sensor(sid), "coverage"),
            rr.Boxes2D(centers=centers, half_sizes=np.full((len(q), 2), g.cell / 2), colors=col, draw_order=5.0),
            static=True,
        )


def log_sensor_states(
    rec: rr.RecordingStream, tracker: str, dep, t: np.ndarray, fired: np.ndarray, blind: np.ndarray
) -> None:
    """The field of view (hull of its coverage, simplified) of each sensor that fired in an
    iteration, bright red, on ``<tracker>/sensors/<id>``; nothing in iterations it did not fire.

    Every sensor keeps its dim mark on ``site/sensors`` and its on/off state in the state
    timeline, so the room stays readable and the wedges drawn are the ones the filter is using
    now (``fired``, S_i; ``blind`` is not drawn). Rerun draws a transparent line dark, not
    invisible, so an idle sensor gets no strip at all.
    """
    if len(t) == 0:
        return
    log_world_frame(rec, paths.tracker_root(tracker))
    tolerance = 0.005 * max(dep.grid.cell * max(dep.q.shape[1:]), 1e-9)
    for i, sid in enumerate(dep.ids):
        hull = dep.hulls[i]
        ring = _exterior(hull.simplify(tolerance) if hull is not None and not hull.is_empty else hull)
        if ring is None:
            continue
        entity = paths.join(paths.tracker_root(tracker), "sensors", paths.part(sid))
        rec.log(
            entity,
            rr.LineStrips2D.from_fields(
                colors=FIRING, radii=FOV_WIDTH, labels=[f"{sid} fired"], show_labels=False, draw_order=12.0
            ),
            static=True,
        )
        on = fired[:, i].astype(bool)
        k = int(on.sum())
        rec.send_columns(
            entity,
            indexes=[paths.time_column(t)],
            columns=rr.LineStrips2D.columns(
                strips=strips_array(np.tile(ring, (k, 1)), np.full(k, len(ring)))
            ).partition(on.astype(np.int64)),
        )


def log_particles(rec: rr.RecordingStream, tracker: str, t: np.ndarray, xy: np.ndarray, w: np.ndarray) -> None:
    """Particles of every iteration (``xy`` (T, L, 2), weights ``w`` (T, L)) on ``<tracker>/particles``."""
    if len(t) == 0 or xy.shape[1] == 0:
        return
    T, L = w.shape
    entity = paths.particles(tracker)
    log_world_frame(rec, entity)
    rec.log(entity, rr.Points2D.from_fields(radii=rr.Radius.ui_points(2.5), draw_order=20.0), static=True)
    rec.send_columns(
        entity,
        indexes=[paths.time_column(t)],
        columns=rr.Points2D.columns(positions=xy.reshape(-1, 2), colors=weight_colors(w).reshape(-1, 4)).partition(
            [L] * T
        ),
    )


def log_estimate(
    rec: rr.RecordingStream,
    tracker: str,
    t: np.ndarray,
    est: np.ndarray,
    width: float,
    depth: float,
    *,
    rgb: tuple[int, int, int] | None = None,
) -> None:
    """The estimate's bounding box (the body the likelihood uses) on ``<tracker>/estimate``."""
    if len(t) == 0:
        return
    entity = paths.join(paths.tracker_root(tracker), "estimate")
    log_world_frame(rec, entity)
    rec.log(
        entity,
        rr.Boxes2D.from_fields(
            colors=colors.tracker_color(tracker, rgb=rgb), radii=rr.Radius.ui_points(1.5), draw_order=29.0
        ),
        static=True,
    )
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
    strips = np.stack([a, np.broadcast_to(cam, a.shape), b], axis=1)  # one 3-vertex strip per iteration
    log_world_frame(rec, entity)
    rec.log(
        entity,
        rr.LineStrips2D.from_fields(colors=(70, 110, 130, 255), radii=rr.Radius.ui_points(1.0), draw_order=26.0),
        static=True,
    )
    rec.send_columns(
        entity, indexes=[paths.time_column(t)], columns=rr.LineStrips2D.columns(strips=strips_array(strips, 3))
    )


def log_run(
    rec: rr.RecordingStream, tracker: str, out: dict, *, site, region_graph, config, tables: dict, look: Look = GENERIC
) -> None:
    """Everything the ``intruder`` (or ``intruder-naive``) tracker produced: coverage, sensor
    states, particles, the estimate with its box, the camera cone and the track."""
    art = out.get("artifacts")
    if art is not None:
        t_end = art["t_end"]
        log_coverage(rec, art["deployment"])
        log_sensor_states(rec, tracker, art["deployment"], t_end, art["fired"], art["blind"])
        log_particles(rec, tracker, t_end, art["particles_xy"], art["particles_w"])
        log_estimate(rec, tracker, t_end, art["estimates"], *art["box"], rgb=look.rgb)
        if "camera" in out:
            log_camera_cone(
                rec, tracker, tuple(config.camera_position), t_end, art["estimates"], out["camera"], config.camera_fov
            )
    log_point_tracks(rec, tracker, out["tracks"], rgb=look.rgb)
