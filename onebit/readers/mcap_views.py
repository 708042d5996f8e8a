"""Typed view channels of an MCAP recording: the well-known Foxglove schemas, protobuf-encoded.

The raw-log channels of :mod:`onebit.readers.mcap_io` (``/beams``, ``/motion``, ...) are JSON
under onebit's own schema names: they round-trip exactly, but a viewer shows them as raw
messages. Beside them, :func:`view_messages` derives channels that Foxglove and Rerun's MCAP
importer (``rerun file.mcap``, ``rerun mcap convert``) decode and draw:

==================  ========================  =============================================
topic               schema                    what
==================  ========================  =============================================
/foxglove/site      ``foxglove.SceneUpdate``  boundary, obstacles, beams (line loops/lines),
                                              sensors (spheres + labels), once at the start
/foxglove/sensors   ``foxglove.SceneUpdate``  one sphere per toggle sensor, coloured on/off,
                                              at every toggle
/foxglove/truth     ``foxglove.SceneUpdate``  ground-truth positions, one update per instant
/foxglove/tracks    ``foxglove.SceneUpdate``  a run's estimated positions (when given)
/points/site        ``foxglove.PointCloud``   the outlines sampled as points (Rerun: Points3D)
/points/sensors     ``foxglove.PointCloud``   the sensors, coloured by state, at every toggle
/points/truth       ``foxglove.PointCloud``   ground truth per instant
/points/tracks      ``foxglove.PointCloud``   estimates per instant (when given)
/events             ``foxglove.Log``          every toggle, beam event and crossing as a line
                                              of text (Rerun: TextLog)
==================  ========================  =============================================

Why both SceneUpdate and PointCloud: Foxglove's 3D panel draws ``SceneUpdate`` (entities with
ids that later updates replace), while Rerun 0.41's MCAP importer decodes ``PointCloud``,
``Log``, ``PoseInFrame`` and a few others semantically and keeps ``SceneUpdate`` as a raw
protobuf message (checked with ``rerun mcap convert`` + ``rerun rrd print``). Coordinates are
the site's world units in a frame ``site`` (z = 0); times are the raw messages' log times, so
the views line up with the raw channels on one timeline.
Every sub-message (a pose's position and orientation, timestamps,
colours) is marked present even when all zero, so Rerun's importer finds no null where it needs
a value and ``rerun rrd verify`` accepts the converted recording.

The message classes and their ``FileDescriptorSet`` come from Foxglove's own
``foxglove-schemas-protobuf`` package (registered by ``mcap-protobuf-support``), so the
schemas are Foxglove's definitions, not copies. Building messages is a Python loop over
instants (protobuf objects are built one by one); the raw rows are grouped with polars first.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import polars as pl

#: frame_id of every view message
FRAME = "site"
#: Topic -> protobuf message type name of every view channel.
VIEW_TOPICS: dict[str, str] = {
    "/foxglove/site": "foxglove.SceneUpdate",
    "/foxglove/sensors": "foxglove.SceneUpdate",
    "/foxglove/truth": "foxglove.SceneUpdate",
    "/foxglove/tracks": "foxglove.SceneUpdate",
    "/points/site": "foxglove.PointCloud",
    "/points/sensors": "foxglove.PointCloud",
    "/points/truth": "foxglove.PointCloud",
    "/points/tracks": "foxglove.PointCloud",
    "/events": "foxglove.Log",
}

_ON = (1.0, 0.55, 0.0, 1.0)  # orange
_OFF = (0.55, 0.55, 0.55, 1.0)  # grey
_SITE = (0.85, 0.85, 0.85, 1.0)
_OBSTACLE = (0.6, 0.4, 0.3, 1.0)
_BEAM = (0.2, 0.6, 1.0, 1.0)
_TRUTH = (0.1, 0.8, 0.2, 1.0)
_TRACK = (0.9, 0.1, 0.5, 1.0)


@dataclass(frozen=True)
class ViewMessage:
    """One message of a view channel: topic, log time (ns) and the protobuf message."""

    topic: str
    log_time: int
    message: object


def message_classes() -> dict[str, type]:
    """Protobuf type name -> message class (Foxglove's ``foxglove-schemas-protobuf``)."""
    from foxglove_schemas_protobuf.Log_pb2 import Log
    from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    return {"foxglove.SceneUpdate": SceneUpdate, "foxglove.PointCloud": PointCloud, "foxglove.Log": Log}


# --------------------------------------------------------------------------- small builders


def _color(msg, rgba) -> None:
    msg.SetInParent()
    msg.r, msg.g, msg.b, msg.a = rgba


def _stamp(msg, ns: int) -> None:
    """A ``google.protobuf.Timestamp``, present even at 0 ns (the first message of a log in
    relative seconds): proto3 leaves an all-zero sub-message out unless it is marked set."""
    msg.SetInParent()
    msg.seconds, msg.nanos = divmod(int(ns), 1_000_000_000)


def _pose(pose, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> None:
    """A ``foxglove.Pose`` at ``(x, y, z)`` with the identity orientation, both parts present
    even when zero: Rerun's importer reads a missing position as null (``rerun rrd verify``
    then rejects the converted recording: "Expected non-nullable data")."""
    pose.position.SetInParent()
    pose.position.x, pose.position.y, pose.position.z = float(x), float(y), float(z)
    pose.orientation.SetInParent()
    pose.orientation.x = pose.orientation.y = pose.orientation.z = 0.0
    pose.orientation.w = 1.0


def _entity(update, entity_id: str, ns: int):
    e = update.entities.add()
    e.id = entity_id
    e.frame_id = FRAME
    _stamp(e.timestamp, ns)
    e.lifetime.SetInParent()  # 0: until replaced or deleted
    return e


def _line(entity, xy, rgba, *, closed: bool, thickness: float) -> None:
    from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive

    line = entity.lines.add()
    line.type = LinePrimitive.LINE_LOOP if closed else LinePrimitive.LINE_STRIP
    line.thickness = thickness
    line.scale_invariant = False
    _pose(line.pose)
    _color(line.color, rgba)
    for x, y in xy:
        p = line.points.add()
        p.x, p.y, p.z = float(x), float(y), 0.0


def _sphere(entity, x: float, y: float, size: float, rgba) -> None:
    s = entity.spheres.add()
    _pose(s.pose, x, y)
    s.size.x = s.size.y = s.size.z = size
    _color(s.color, rgba)


def _text(entity, x: float, y: float, text: str, size: float) -> None:
    t = entity.texts.add()
    _pose(t.pose, x, y, size)
    t.billboard = True
    t.font_size = 12.0
    t.scale_invariant = True
    _color(t.color, (1.0, 1.0, 1.0, 1.0))
    t.text = text


def point_cloud(ns: int, xy: np.ndarray, rgba: np.ndarray):
    """A ``foxglove.PointCloud`` of ``(n, 2)`` positions (z = 0) with ``(n, 4)`` colours in [0, 1]:
    fields x, y, z (float32) and red, green, blue, alpha (uint8), 16 bytes per point."""
    from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
    from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud

    n = len(xy)
    rec = np.zeros(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("c", "u1", (4,))])
    rec["x"], rec["y"] = xy[:, 0], xy[:, 1]
    rec["c"] = np.clip(np.round(np.asarray(rgba) * 255), 0, 255).astype(np.uint8)
    pc = PointCloud()
    _stamp(pc.timestamp, ns)
    pc.frame_id = FRAME
    _pose(pc.pose)
    pc.point_stride = 16
    for name, offset, kind in (
        ("x", 0, PackedElementField.FLOAT32),
        ("y", 4, PackedElementField.FLOAT32),
        ("z", 8, PackedElementField.FLOAT32),
        ("red", 12, PackedElementField.UINT8),
        ("green", 13, PackedElementField.UINT8),
        ("blue", 14, PackedElementField.UINT8),
        ("alpha", 15, PackedElementField.UINT8),
    ):
        f = pc.fields.add()
        f.name, f.offset, f.type = name, offset, kind
    pc.data = rec.tobytes()
    return pc


#: Points of a marker in the point clouds: a PointCloud has no point size (Rerun draws each point
#: a pixel or two wide), so a sensor is a ring and a position a disc of points, 1.5 % of the
#: site's diagonal across.
MARKER_POINTS = 16


def markers(xy: np.ndarray, rgba: np.ndarray, radius: float, *, filled: bool) -> tuple[np.ndarray, np.ndarray]:
    """Each of the ``(n, 2)`` positions as :data:`MARKER_POINTS` points on a circle of ``radius``
    (``filled``: plus a ring at half the radius and the centre); colours repeated per point."""
    a = np.linspace(0.0, 2 * np.pi, MARKER_POINTS, endpoint=False)
    ring = np.c_[np.cos(a), np.sin(a)] * radius
    shape = np.vstack([ring, ring * 0.5, [[0.0, 0.0]]]) if filled else ring
    pts = (np.asarray(xy, dtype=float)[:, None, :] + shape[None, :, :]).reshape(-1, 2)
    return pts, np.repeat(np.asarray(rgba, dtype=float), len(shape), axis=0)


def _log(ns: int, name: str, text: str):
    from foxglove_schemas_protobuf.Log_pb2 import Log

    m = Log()
    _stamp(m.timestamp, ns)
    m.level = Log.INFO
    m.name = name
    m.message = text
    return m


# --------------------------------------------------------------------------- the views


def _outline_points(geom, step: float) -> np.ndarray:
    """Points every ``step`` along the exterior of a shapely polygon or a line."""
    ring = getattr(geom, "exterior", geom)
    n = max(2, int(np.ceil(ring.length / step)) + 1)
    pts = [ring.interpolate(d) for d in np.linspace(0.0, ring.length, n)]
    return np.array([[p.x, p.y] for p in pts])


def site_views(site, ns: int) -> list[ViewMessage]:
    """The site once, at ``ns``: a SceneUpdate (outlines, beams, sensors, labels) and a
    PointCloud of the outlines sampled every 1/100 of the site's diagonal."""
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    size = max(site.diagonal * 0.02, 1e-6)
    up = SceneUpdate()
    e = _entity(up, "site/boundary", ns)
    _line(e, site.boundary.exterior.coords, _SITE, closed=True, thickness=size / 4)
    for i, (poly, name) in enumerate(zip(site.obstacles, site.obstacle_names, strict=True)):
        e = _entity(up, f"site/obstacles/{i}", ns)
        _line(e, poly.exterior.coords, _OBSTACLE, closed=True, thickness=size / 4)
        c = poly.centroid
        _text(e, c.x, c.y, name, size)
    for b in site.beams:
        e = _entity(up, f"site/beams/{b.id}", ns)
        _line(e, [b.p0, b.p1], _BEAM, closed=False, thickness=size / 3)
        _text(e, (b.p0[0] + b.p1[0]) / 2, (b.p0[1] + b.p1[1]) / 2, b.id, size)
    for s in (*site.motion_sensors, *site.proximity_sensors):
        e = _entity(up, f"site/sensors/{s.id}", ns)
        _sphere(e, s.position[0], s.position[1], size, _OFF)
        _text(e, s.position[0], s.position[1], s.id, size)
    step = max(site.diagonal / 100, 1e-6)
    parts = [_outline_points(site.boundary, step), *(_outline_points(p, step) for p in site.obstacles)]
    parts += [_outline_points(b.line, step) for b in site.beams]
    xy = np.concatenate(parts)
    rgba = np.tile(_SITE, (len(xy), 1))
    return [ViewMessage("/foxglove/site", ns, up), ViewMessage("/points/site", ns, point_cloud(ns, xy, rgba))]


def _positions(site) -> dict[str, tuple[float, float]]:
    return {s.id: tuple(s.position) for s in (*site.motion_sensors, *site.proximity_sensors)}


def toggle_views(events: pl.DataFrame, site) -> Iterator[ViewMessage]:
    """Every toggle (``log_time``, ``sensor``, ``on``; time order): the sensor's sphere and the
    point cloud of every sensor of the site coloured by its state after the toggle."""
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    pos = _positions(site) if site is not None else {}
    if not pos or events.height == 0:
        return
    ids = list(pos)
    index = {s: i for i, s in enumerate(ids)}
    xy = np.array([pos[s] for s in ids], dtype=float)
    state = np.zeros(len(ids), bool)
    size = max(site.diagonal * 0.025, 1e-6)
    for ns, sensor, on in events.select("log_time", "sensor", "on").iter_rows():
        i = index.get(sensor)
        if i is None or on is None:
            continue
        state[i] = on
        up = SceneUpdate()
        _sphere(_entity(up, f"sensors/{sensor}", ns), xy[i, 0], xy[i, 1], size, _ON if on else _OFF)
        yield ViewMessage("/foxglove/sensors", ns, up)
        rgba = np.where(state[:, None], np.array(_ON), np.array(_OFF))
        yield ViewMessage("/points/sensors", ns, point_cloud(ns, *markers(xy, rgba, size * 0.3, filled=False)))


def position_views(points: pl.DataFrame, *, kind: str, site) -> Iterator[ViewMessage]:
    """Positions per instant (``log_time``, ``id``, ``x``, ``y``): one SceneUpdate (a sphere per
    id, replacing the previous) and one PointCloud per distinct time. ``kind``: truth | tracks."""
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    rgba = _TRUTH if kind == "truth" else _TRACK
    size = max((site.diagonal if site is not None else 1.0) * 0.03, 1e-6)
    # float32 in the point cloud: positions beyond its range are not drawable
    points = points.filter(
        pl.col("x").is_finite() & pl.col("y").is_finite() & (pl.col("x").abs() < 1e30) & (pl.col("y").abs() < 1e30)
    )
    if points.height == 0:
        return
    for (ns,), group in points.sort("log_time", maintain_order=True).group_by("log_time", maintain_order=True):
        up = SceneUpdate()
        for ident, x, y in group.select("id", "x", "y").iter_rows():
            e = _entity(up, f"{kind}/{ident}", ns)
            _sphere(e, x, y, size, rgba)
            _text(e, x, y, str(ident), size)
        yield ViewMessage(f"/foxglove/{kind}", ns, up)
        xy = group.select("x", "y").to_numpy()
        yield ViewMessage(
            f"/points/{kind}", ns, point_cloud(ns, *markers(xy, np.tile(rgba, (len(xy), 1)), size * 0.25, filled=True))
        )


def event_views(lines: pl.DataFrame) -> Iterator[ViewMessage]:
    """``foxglove.Log`` lines (``log_time``, ``name``, ``text``)."""
    for ns, name, text in lines.select("log_time", "name", "text").iter_rows():
        yield ViewMessage("/events", ns, _log(ns, name, text))
