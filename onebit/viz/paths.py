"""Entity paths and the time line of every Rerun recording (DESIGN.md, "Rerun recordings").

Every path a stage logs to is built here, so the layout lives in one place::

    site/boundary, site/obstacles/<i>, site/beams/<id>, site/sensors/<id>, site/regions/<name>
    truth/<target>                      points over time; truth/<target>/path the path so far
    sensors/<id>                        on/off state over time, crossing events as text
    <tracker>/particles                 Points2D, radius or colour by weight
    <tracker>/istate/<element>/<k>      polygons of an I-state element
    <tracker>/tracks/<track>            estimated position; <tracker>/tracks/<track>/path its path
    <tracker>/occupancy/<region>        agents per region as Scalars
    <tracker>/decoded/<user>            decoded node sequence as a line strip over the graph
    scores/<tracker>/<track>            error as Scalars

Each id is one path part, escaped with :func:`rerun.escape_entity_path_part`, so an id holding
``/``, a space or ``^`` stays one part (``"a^-1"`` becomes ``a\\^-1``).

Time is the duration time line ``t`` in seconds since the dataset epoch.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import rerun as rr

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
    """The path so far of ``target``: a child of :func:`truth`."""
    return join(truth(target, prefix=prefix), "path")


def sensor(sensor_id: str, *, prefix: str = SENSORS) -> str:
    return join(prefix, part(sensor_id))


# --------------------------------------------------------------------------- trackers


def tracker_root(tracker: str) -> str:
    return part(tracker)


def track(tracker: str, track_id: str) -> str:
    return join(tracker_root(tracker), "tracks", part(track_id))


def track_path(tracker: str, track_id: str) -> str:
    """The path so far of one track: a child of :func:`track`."""
    return join(track(tracker, track_id), "path")


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
