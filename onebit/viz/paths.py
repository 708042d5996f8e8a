"""Entity paths and the time line of every Rerun recording (docs/architecture.md, "Rerun recordings").

Every path a stage logs to is built here, so the layout lives in one place::

    site/boundary, site/obstacles/<i>, site/beams/<id>, site/regions/<name>
    site/sensors                        every sensor's dim mark; site/sensors/<id>/coverage heat maps
    truth/<target>                      position now (hollow ring); .../trail recent segments;
                                        .../path the whole path (static, hidden by default)
    sensors/<id>                        on/off state over time (StateChange), crossing events as
                                        text; sensors/<beam>/crossed the beam flashing when crossed
    <tracker>/particles                 Points2D, colour by weight
    <tracker>/istate/<element>/<k>      polygons of an I-state element; <tracker>/istate/fill the
                                        elements filled, as an image placed over the site
    <tracker>/tracks/<track>            estimate now (a dot in the tracker's colour, labelled
                                        "track k"); .../trail and .../path as for the truth
    <tracker>/occupancy/<region>        agents per region as Scalars
    <tracker>/decoded/<user>            decoded node sequence as a line strip over the graph
    scores/<tracker>/<track>            error as Scalars (hops or site units, one unit per plot)

A **trail** is one short segment per sample (from the previous position to this one), logged
at the sample's time; the blueprint shows each trail through a visible time range that ends at
the time cursor (:data:`onebit.viz.trails.TRAIL_S` seconds by default), so the trail moves
with the cursor and nothing re-logs a growing history. Spatial roots carry a static
``Transform3D`` flipping y (:mod:`onebit.viz.frame`): the world's y axis points up on screen.

Each id is one path part, escaped with :func:`rerun.escape_entity_path_part`, so an id holding
``/``, a space or ``^`` stays one part (``"a^-1"`` becomes ``a\\^-1``).

Time is the duration time line ``t`` in seconds since the dataset epoch.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from onebit.core.lazy import lazy_module

rr = lazy_module("rerun")

#: Name of the one time line: seconds since the dataset epoch, as a duration.
TIMELINE = "t"

SITE = "site"
TRUTH = "truth"
SENSORS = "sensors"
SCORES = "scores"


def part(value: object) -> str:
    """One escaped entity-path part for an id (beam, region, target, track, tracker...)."""
    return rr.escape_entity_path_part(str(value))


def join(*parts: object) -> str:
    """Join already-escaped ``parts`` into a path (no leading slash)."""
    return "/".join(str(p) for p in parts)


# --------------------------------------------------------------------------- site


def site_boundary() -> str:
    return join(SITE, "boundary")


def site_obstacle(i: int) -> str:
    return join(SITE, "obstacles", part(int(i)))


def site_beam(beam: str) -> str:
    return join(SITE, "beams", part(beam))


def site_sensor(sensor: str) -> str:
    return join(SITE, "sensors", part(sensor))


def site_region(region: str) -> str:
    return join(SITE, "regions", part(region))


# --------------------------------------------------------------------------- truth and sensors


def truth(target: str, *, prefix: str = TRUTH) -> str:
    return join(prefix, part(target))


def truth_path(target: str, *, prefix: str = TRUTH) -> str:
    """The whole path of ``target`` (static, hidden by default): a child of :func:`truth`."""
    return full_path(truth(target, prefix=prefix))


def trail(entity: str) -> str:
    """The recent-window trail of a moving ``entity``: ``<entity>/trail``."""
    return join(entity, "trail")


def full_path(entity: str) -> str:
    """The whole path of a moving ``entity`` (static): ``<entity>/path``."""
    return join(entity, "path")


def sensor(sensor_id: str, *, prefix: str = SENSORS) -> str:
    return join(prefix, part(sensor_id))


def sensor_crossed(beam: str, *, prefix: str = SENSORS) -> str:
    """A beam drawn on the map at the time of each crossing: ``sensors/<beam>/crossed``."""
    return join(sensor(beam, prefix=prefix), "crossed")


# --------------------------------------------------------------------------- trackers


def tracker_root(tracker: str) -> str:
    return part(tracker)


def track(tracker: str, track_id: str) -> str:
    return join(tracker_root(tracker), "tracks", part(track_id))


def track_path(tracker: str, track_id: str) -> str:
    """The whole path of one track (static, hidden by default): a child of :func:`track`."""
    return full_path(track(tracker, track_id))


def track_region(tracker: str, track_id: str) -> str:
    """The region a region-level track is in now, outlined in its colour."""
    return join(track(tracker, track_id), "region")


def track_region_path(tracker: str, track_id: str) -> str:
    """The whole region path of a region-level track (static, hidden by default)."""
    return join(track(tracker, track_id), "regions")


def occupancy(tracker: str, region: str) -> str:
    return join(tracker_root(tracker), "occupancy", part(region))


def particles(tracker: str) -> str:
    return join(tracker_root(tracker), "particles")


def istate(tracker: str, element: str, k: int) -> str:
    return join(tracker_root(tracker), "istate", part(element), part(int(k)))


def decoded(tracker: str, user: str) -> str:
    return join(tracker_root(tracker), "decoded", part(user))


def score(tracker: str, track_id: str) -> str:
    return join(SCORES, part(tracker), part(track_id))


# --------------------------------------------------------------------------- time


def time_column(seconds: Iterable[float] | np.ndarray) -> rr.TimeColumn:
    """The ``t`` index column for :meth:`rerun.RecordingStream.send_columns` (seconds)."""
    return rr.TimeColumn(TIMELINE, duration=np.asarray(seconds, dtype=np.float64))


def set_time(rec: rr.RecordingStream, seconds: float) -> None:
    """Set ``t`` on ``rec`` for the following ``rec.log`` calls."""
    rec.set_time(TIMELINE, duration=float(seconds))
