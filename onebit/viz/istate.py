"""Rerun logging of O'Kane I-states and active tracking.

Entities (all through ``send_columns``, one call per entity):

* ``<tracker>/istate/<element>/<k>`` -- region ``k`` of element slot ``element`` at every
  stage as line strips (its boundary rings), one distinct colour per element slot; a stage
  where the slot is unused holds no strips;
* ``<tracker>/sensing/<sensor>`` -- static sensing regions; ``<tracker>/detections`` the
  regions with reading 1 at each stage;
* ``<tracker>/elements``, ``<tracker>/area`` (and ``<tracker>/P`` for active tracking) -- Scalars;
* active tracking: ``<tracker>/trackers/<j>`` points, ``.../sensing`` the 9 squares,
  ``.../destination``; ``<tracker>/links`` communication links; ``truth/<target>``.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import rerun as rr
import shapely

from onebit.viz.tracks import log_point_tracks
from onebit.viz import colors, paths
from onebit.viz._series import rings


def _strips_per_stage(geoms: np.ndarray) -> tuple[list[np.ndarray], list[int]]:
    strips, counts = [], []
    for g in geoms:  # one geometry per stage (None = absent)
        rs = [] if g is None or g.is_empty else rings(g)
        strips.extend(rs)
        counts.append(len(rs))
    return strips, counts


def _series(rec: rr.RecordingStream, entity: str, name: str, t: np.ndarray, values: np.ndarray) -> None:
    rec.log(entity, rr.SeriesLines(colors=colors.color_of(name), names=[name]), static=True)
    rec.send_columns(entity, indexes=[paths.time_column(t)], columns=rr.Scalars.columns(scalars=np.asarray(values, float)))


def log_istate_regions(rec: rr.RecordingStream, tracker: str, regions: pl.DataFrame, times: np.ndarray) -> None:
    """Every (element slot, k) of the ``regions`` table (t, stage, element, k, wkb) over ``times``."""
    if regions.height == 0:
        return
    n = int(regions["k"].max()) + 1
    E = int(regions["element"].max()) + 1
    K = len(times)
    grid = np.full((E, n, K), None, dtype=object)
    geoms = shapely.from_wkb(regions["wkb"].to_numpy())
    grid[regions["element"].to_numpy(), regions["k"].to_numpy(), regions["stage"].to_numpy()] = geoms
    tc = paths.time_column(times)
    for e in range(E):
        col = colors.color_of(f"element{e}", alpha=200)
        for k in range(n):
            strips, counts = _strips_per_stage(grid[e, k])
            ent = paths.istate(tracker, str(e), k)
            rec.log(ent, rr.LineStrips2D.from_fields(colors=[col]), static=True)
            rec.send_columns(ent, indexes=[tc], columns=rr.LineStrips2D.columns(strips=strips).partition(counts))


def log_istate_run(
    rec: rr.RecordingStream,
    tracker: str,
    regions: pl.DataFrame,
    summary: pl.DataFrame,
    *,
    site=None,
    sensing: dict | None = None,
    detections: pl.DataFrame | None = None,
) -> None:
    """The ``istate`` stage: I-state regions, sensing regions, detections, element count and area."""
    for sid, g in (sensing or {}).items():
        rec.log(
            paths.join(paths.tracker_root(tracker), "sensing", paths.part(sid)),
            rr.LineStrips2D(rings(g), colors=[(120, 120, 120, 160)]),
            static=True,
        )
    if summary.height == 0:
        return
    times = summary["t"].to_numpy()
    log_istate_regions(rec, tracker, regions, times)
    root = paths.tracker_root(tracker)
    _series(rec, paths.join(root, "elements"), "elements", times, summary["elements"].to_numpy())
    _series(rec, paths.join(root, "area"), "area", times, summary["area"].to_numpy())
    if detections is not None and detections.height and sensing:
        counts = detections.group_by("stage").agg(pl.len()).sort("stage")
        full = np.zeros(len(times), dtype=np.int64)
        full[counts["stage"].to_numpy()] = counts["len"].to_numpy()
        strips = [s for sid in detections.sort("stage", maintain_order=True)["sensor"] for s in rings(sensing[sid])]
        per = [len(rings(sensing[sid])) for sid in detections.sort("stage", maintain_order=True)["sensor"]]
        lens = np.zeros(len(times), dtype=np.int64)
        np.add.at(lens, detections.sort("stage", maintain_order=True)["stage"].to_numpy(), per)
        ent = paths.join(root, "detections")
        rec.log(ent, rr.LineStrips2D.from_fields(colors=[(255, 60, 60, 255)], radii=[0.04]), static=True)
        rec.send_columns(ent, indexes=[paths.time_column(times)], columns=rr.LineStrips2D.columns(strips=strips).partition(lens))


def log_active_tracking(
    rec: rr.RecordingStream,
    tracker: str,
    *,
    times: np.ndarray,
    targets: np.ndarray,
    trackers: np.ndarray,
    destinations: np.ndarray,
    sensing: np.ndarray,
    links: list[np.ndarray],
    elements: np.ndarray,
    performance: np.ndarray,
    regions: pl.DataFrame | None = None,
    free_space=None,
) -> None:
    """An active-tracking simulation (section VII).

    ``targets (K, n, 2)``, ``trackers (K, m, 2)``, ``destinations (K, m, 2)`` (each tracker's
    own destination), ``sensing (K, m)`` geometries (the tracker's sensing squares),
    ``links`` one ``(L, 2, 2)`` array of segments per stage, ``elements (K, m)``, ``P (K,)``,
    ``regions`` the I-state regions of tracker 0 (``istate`` schema).
    """
    tc = paths.time_column(times)
    root = paths.tracker_root(tracker)
    if free_space is not None:
        rec.log(paths.join(paths.SITE, "free_space"), rr.LineStrips2D(rings(free_space), colors=[colors.WALL]), static=True)
    for i in range(targets.shape[1]):
        ent = paths.truth(f"target{i + 1}")
        rec.log(ent, rr.Points2D.from_fields(colors=[colors.color_of(f"target{i + 1}")], radii=[0.8]), static=True)
        rec.send_columns(ent, indexes=[tc], columns=rr.Points2D.columns(positions=targets[:, i]))
    for j in range(trackers.shape[1]):
        base = paths.join(root, "trackers", paths.part(j))
        col = colors.color_of(f"tracker{j}")
        rec.log(base, rr.Points2D.from_fields(colors=[col], radii=[1.2]), static=True)
        rec.send_columns(base, indexes=[tc], columns=rr.Points2D.columns(positions=trackers[:, j]))
        rec.log(paths.join(base, "destination"), rr.Points2D.from_fields(colors=[col], radii=[0.6]), static=True)
        rec.send_columns(paths.join(base, "destination"), indexes=[tc], columns=rr.Points2D.columns(positions=destinations[:, j]))
        strips, counts = _strips_per_stage(sensing[:, j])
        rec.log(paths.join(base, "sensing"), rr.LineStrips2D.from_fields(colors=[col]), static=True)
        rec.send_columns(paths.join(base, "sensing"), indexes=[tc], columns=rr.LineStrips2D.columns(strips=strips).partition(counts))
        _series(rec, paths.join(root, "elements", paths.part(j)), f"tracker{j}", times, elements[:, j])
    lens = [len(seg) for seg in links]
    strips = [s for seg in links for s in seg]
    rec.log(paths.join(root, "links"), rr.LineStrips2D.from_fields(colors=[(0, 160, 255, 255)]), static=True)
    rec.send_columns(paths.join(root, "links"), indexes=[tc], columns=rr.LineStrips2D.columns(strips=strips).partition(lens))
    _series(rec, paths.join(root, "P"), "P", times, performance)
    if regions is not None:
        log_istate_regions(rec, tracker, regions, times)


def log_run(rec: rr.RecordingStream, tracker: str, out: dict, *, site, region_graph, config, tables: dict) -> None:
    """Everything the I-state filter produced: regions, sensing regions, detections, element
    count and area, and the point summary."""
    log_istate_run(
        rec, tracker, out["regions"], out["summary"], site=site,
        sensing=out["artifacts"]["sensing"], detections=out["detections"],
    )  # fmt: skip
    log_point_tracks(rec, tracker, out["tracks"])
