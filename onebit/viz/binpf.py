"""Rerun logging of the ``binpf`` tracker (bulk data through ``send_columns``).

Entities (``<tracker>`` = ``binpf``)::

    <tracker>/sensors/on          every frame: the footprint (radius R_s) of each sensor that is on
    <tracker>/particles           every frame: a subsample of each live track's particles,
                                  coloured by track
    <tracker>/count/{expected,reported}   the filter's expected count sum r_i and the tracks reported
    <tracker>/tracks/<track>      the reported tracks (dot, trail, hidden path; onebit.viz.tracks)
    <tracker>/zones               on an array of more than LARGE_ARRAY sensors (a building floor):
                                  the site cut into ZONES x ZONES zones (boxes; ``/labels``: the
                                  number of people reported in each now, "A1: 3")
    <tracker>/zones/count/<zone>  that number over time (the blueprint shows these instead of
                                  one on/off row per sensor)
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
ZONE = (150, 150, 190, 255)
#: An array of more sensors than this is drawn by zone: counts per zone, no row per sensor.
LARGE_ARRAY = 64
#: Zones per side of the site's bounding box on a large array.
ZONES = 3


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


def zones_of(bounds: tuple[float, float, float, float], n: int = ZONES) -> tuple[list[str], np.ndarray, np.ndarray]:
    """``(names, lo (Z, 2), hi (Z, 2))``: the bounding box ``(minx, miny, maxx, maxy)`` cut into
    ``n x n`` zones, named ``A1`` (lowest x and y) .. by column letter and row number."""
    minx, miny, maxx, maxy = bounds
    xs, ys = np.linspace(minx, maxx, n + 1), np.linspace(miny, maxy, n + 1)
    names, lo, hi = [], [], []
    for j in range(n):
        for i in range(n):
            names.append(f"{chr(ord('A') + i)}{j + 1}")
            lo.append((xs[i], ys[j]))
            hi.append((xs[i + 1], ys[j + 1]))
    return names, np.array(lo), np.array(hi)


def zone_counts(times: np.ndarray, tracks: pl.DataFrame, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``(T, Z)``: the tracks reported at each frame time inside each zone (a point on a shared
    edge counts in the zone to its upper right; the site's outer edge belongs to its zone)."""
    counts = np.zeros((len(times), len(lo)), dtype=np.int64)
    if tracks is None or tracks.height == 0 or len(times) == 0:
        return counts
    rows = tracks.drop_nulls(["x", "y"])
    k = np.searchsorted(times, rows["t"].to_numpy())
    ok = (k < len(times)) & (times[np.minimum(k, len(times) - 1)] == rows["t"].to_numpy())
    xy = rows.select("x", "y").to_numpy()[ok]
    k = k[ok]
    top = hi.max(axis=0)
    inside = (xy[:, None, :] >= lo[None]) & ((xy[:, None, :] < hi[None]) | (hi[None] >= top))
    z = np.argmax(inside.all(axis=-1), axis=1)
    hit = inside.all(axis=-1).any(axis=1)
    np.add.at(counts, (k[hit], z[hit]), 1)
    return counts


def log_zones(rec, tracker: str, times: np.ndarray, tracks: pl.DataFrame, bounds) -> None:
    """The zones with their count of people now (boxes labelled ``A1: 3``) and each zone's
    count over time: what a floor of hundreds of sensors shows instead of a row per sensor."""
    if len(times) == 0:
        return
    names, lo, hi = zones_of(bounds)
    counts = zone_counts(times, tracks, lo, hi)
    entity = paths.join(paths.tracker_root(tracker), "zones")
    log_world_frame(rec, entity)
    rec.log(entity, rr.Boxes2D.from_fields(colors=ZONE, draw_order=5.0), static=True)
    Z = len(names)
    labels = [f"{names[z]}: {int(c)}" for row in counts for z, c in enumerate(row)]
    rec.send_columns(
        entity,
        indexes=[paths.time_column(times)],
        columns=rr.Boxes2D.columns(
            centers=np.tile((lo + hi) / 2, (len(times), 1)), half_sizes=np.tile((hi - lo) / 2, (len(times), 1))
        ).partition(np.full(len(times), Z, dtype=np.int64)),
    )
    # the count as text in each zone's upper left corner (a box's own label sits on its centre,
    # under the people)
    corner = np.c_[lo[:, 0] + 0.04 * (hi - lo)[:, 0], hi[:, 1] - 0.04 * (hi - lo)[:, 1]]
    label_entity = paths.join(entity, "labels")
    log_world_frame(rec, label_entity)
    rec.log(label_entity, rr.Points2D.from_fields(colors=ZONE, radii=rr.Radius.ui_points(1.0)), static=True)
    rec.send_columns(
        label_entity,
        indexes=[paths.time_column(times)],
        columns=rr.Points2D.columns(positions=np.tile(corner, (len(times), 1)), labels=labels).partition(
            np.full(len(times), Z, dtype=np.int64)
        ),
    )
    for z, name in enumerate(names):
        rec.send_columns(
            paths.join(entity, "count", name),
            indexes=[paths.time_column(times)],
            columns=rr.Scalars.columns(scalars=counts[:, z].astype(np.float64)),
        )


def log_run(rec, tracker: str, out: dict, *, site, region_graph, config, tables: dict, look: Look = GENERIC) -> None:
    """Everything ``binpf`` produced: footprints on, particles, counts, tracks (and, on a large
    array, the counts per zone)."""
    art = out.get("artifacts")
    if art is not None:
        log_footprints(rec, tracker, art["times"], art["on"], art["sensors"], art["radii"])
        log_track_particles(rec, tracker, art["times"], art["particles_t"], art["particles_xy"], art["particles_track"])
        if len(art["sensors"]) > LARGE_ARRAY:
            log_zones(rec, tracker, art["times"], out["tracks"], site.boundary.bounds)
    log_counts(rec, tracker, out.get("frames"))
    log_point_tracks(rec, tracker, out["tracks"], rgb=look.rgb)
