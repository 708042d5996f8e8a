"""Rerun logging of the ``binpf`` tracker (bulk data through ``send_columns``).

Entities (``<tracker>`` = ``binpf``)::

    <tracker>/sensors/on          every frame: the footprint (radius R_s) of each sensor that is on
    <tracker>/particles           every frame: a subsample of each live track's particles,
                                  coloured by track
    <tracker>/count/{expected,reported}   the filter's expected count sum r_i and the tracks reported
    <tracker>/tracks/<track>      the reported tracks (dot, trail, hidden path; onebit.viz.tracks)
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import colors, paths
from onebit.viz.families import GENERIC, Look
from onebit.viz.frame import log_world_frame
from onebit.viz.tracks import log_point_tracks

rr = lazy_module("rerun")

ON = (120, 35, 35, 255)


def _circle(c: np.ndarray, r: float, n: int = 24) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, n + 1)
    return np.c_[c[0] + r * np.cos(a), c[1] + r * np.sin(a)]


def log_footprints(rec, tracker: str, t: np.ndarray, on: np.ndarray, sensors: np.ndarray, radii: np.ndarray) -> None:
    """The footprints of the sensors that are on, every frame (one partitioned column)."""
    if len(t) == 0:
        return
    entity = paths.join(paths.tracker_root(tracker), "sensors", "on")
    log_world_frame(rec, entity)
    rec.log(
        entity, rr.LineStrips2D.from_fields(colors=ON, radii=rr.Radius.ui_points(1.0), draw_order=15.0), static=True
    )
    rings = np.stack([_circle(sensors[s], radii[s]) for s in range(len(sensors))])  # (S, 25, 2)
    _, ss = np.nonzero(on)
    rec.send_columns(  # one (strips, 25, 2) array: rerun's numpy path, not a list of arrays
        entity,
        indexes=[paths.time_column(t)],
        columns=rr.LineStrips2D.columns(strips=rings[ss]).partition(on.sum(axis=1).astype(np.int64)),
    )


def log_track_particles(
    rec, tracker: str, times: np.ndarray, pt: np.ndarray, xy: np.ndarray, track: np.ndarray
) -> None:
    """Particles (``xy`` rows at times ``pt``, of ``track``) partitioned by frame."""
    if len(times) == 0 or len(xy) == 0:
        return
    entity = paths.particles(tracker)
    log_world_frame(rec, entity)
    rec.log(entity, rr.Points2D.from_fields(radii=rr.Radius.ui_points(2.0), draw_order=20.0), static=True)
    k = np.searchsorted(times, pt)
    lengths = np.bincount(k, minlength=len(times)).astype(np.int64)
    rec.send_columns(
        entity,
        indexes=[paths.time_column(times)],
        columns=rr.Points2D.columns(positions=xy, colors=colors.colors_of(track, alpha=140)).partition(lengths),
    )


def log_counts(rec, tracker: str, frames: pl.DataFrame) -> None:
    """Expected and reported count over time (Scalars)."""
    if frames is None or frames.height == 0:
        return
    for name, col in (("expected", "count"), ("reported", "reported")):
        rec.send_columns(
            paths.join(paths.tracker_root(tracker), "count", name),
            indexes=[paths.time_column(frames["t"].to_numpy())],
            columns=rr.Scalars.columns(scalars=frames[col].cast(pl.Float64).to_numpy()),
        )


def log_run(rec, tracker: str, out: dict, *, site, region_graph, config, tables: dict, look: Look = GENERIC) -> None:
    """Everything ``binpf`` produced: footprints on, particles, counts, tracks."""
    art = out.get("artifacts")
    if art is not None:
        log_footprints(rec, tracker, art["times"], art["on"], art["sensors"], art["radii"])
        log_track_particles(rec, tracker, art["times"], art["particles_t"], art["particles_xy"], art["particles_track"])
    log_counts(rec, tracker, out.get("frames"))
    log_point_tracks(rec, tracker, out["tracks"], rgb=look.rgb)
