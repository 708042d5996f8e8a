"""The site model: ``site.toml`` loaded and validated into shapely geometry.

A site describes one deployment: the boundary polygon of the workspace W, obstacle polygons
(holes and walls), directional beams, named regions, the overhead camera and the units.
Every problem is reported as a :class:`~onebit.core.errors.SiteError` naming the key.

Units: every length of ``site.toml`` (geometry, sensor ``range``/``fov``/radii, the lengths
of its ``[sensor_types]``) is in the site's ``units`` (one of
:data:`onebit.core.units.METRES_PER_UNIT`; ``m`` when the key is absent), and so are the
logs' and the truth's positions. Tracker configs are in metres and converted once
(:func:`onebit.core.units.config_in_site_units`). Each sensor's detection region is built
once per site by :mod:`onebit.core.sensing` (:attr:`Site.detection_regions`). Each field's
check (a number, a polygon, an id, ...) is in :mod:`onebit.core.site_fields`.

Beam convention
---------------
A beam is the segment ``p0 -> p1``. ``forward`` names the side ("left" or "right" of the
direction ``p0 -> p1``) on which an agent *ends* after a forward crossing (direction +1).
Its two emitter-detector pairs run parallel to the segment, ``spacing`` apart: pair ``a`` on
the backward side, pair ``b`` on the forward side, so a forward crossing blocks ``a`` first
and clears ``b`` last (paper Figs. 5-7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

from onebit.core.config import MAX_TARGETS, load_toml
from onebit.core.errors import SiteError
from onebit.core.sensing import build_detection_regions
from onebit.core.sensor_graph import geometric_sensor_graph
from onebit.core.site_fields import (
    _check_epoch,
    _geom_points,
    _integer,
    _is_matrix,
    _list_of_tables,
    _name,
    _natural_key,
    _number,
    _points,
    _polygon,
    _sensor_id,
    _shown,
    _unknown,
)
from onebit.core.units import METRES_PER_UNIT

#: Tolerance (world units) for "a beam end touches the boundary or an obstacle".
TOUCH_TOL = 1e-6

_TOP_KEYS = {
    "name",
    "units",
    "epoch",
    "boundary",
    "obstacles",
    "beams",
    "regions",
    "camera",
    "targets",
    "motion_sensors",
    "proximity_sensors",
    "binary_sensors",
    "sensor_graph",
    "sensor_types",
    "body_radius",
}
_MOTION_KEYS = {"id", "position", "heading", "type", "refractory", "fov", "range", "signal", "ignore"}
_BINARY_KEYS = {"id", "position", "radius", "r_inner", "r_outer", "fov", "type", "refractory", "signal", "ignore"}
#: What a binary reading means (``signal`` of a sensor or of its ``[sensor_types]`` table):
#: ``level`` -- on while a target is in the footprint (a sensor held on is presence: ceiling
#: IR, pressure mats, proximity sensors); ``edge`` -- an on is an event (motion began in the
#: footprint: a PIR's trigger), a sensor held on says nothing more after its rising edge.
SIGNALS = ("level", "edge")
_PROXIMITY_KEYS = {"id", "position", "radius", "r_inner", "r_outer", "ignore"}
_GRAPH_KEYS = {"edges", "entries", "exits", "signatures", "geometry"}
_BOUNDARY_KEYS = {"polygon"}
_OBSTACLE_KEYS = {"name", "polygon"}
_BEAM_KEYS = {"id", "segment", "forward", "spacing", "capacity", "ignore"}
_REGION_KEYS = {"name", "point", "capacity"}
_CAMERA_KEYS = {"width", "height", "fps", "homography", "points", "t0"}
_UNITS = set(METRES_PER_UNIT)


@dataclass(frozen=True)
class Beam:
    """A directional beam: segment, forward side and spacing of its two pairs."""

    id: str
    p0: tuple[float, float]
    p1: tuple[float, float]
    forward: str = "left"
    spacing: float = 0.0

    @property
    def line(self) -> LineString:
        return LineString([self.p0, self.p1])

    @property
    def forward_normal(self) -> np.ndarray:
        """Unit normal pointing to the forward side."""
        d = np.subtract(self.p1, self.p0, dtype=float)
        d /= np.hypot(*d)
        left = np.array([-d[1], d[0]])
        return left if self.forward == "left" else -left

    def pair_segments(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """End points of pair ``a`` (backward side) and pair ``b`` (forward side)."""
        off = self.forward_normal * self.spacing / 2.0
        p0, p1 = np.asarray(self.p0, float), np.asarray(self.p1, float)
        return {"a": (p0 - off, p1 - off), "b": (p0 + off, p1 + off)}


@dataclass(frozen=True)
class RegionSpec:
    """A named region, identified by a point inside it."""

    name: str
    point: tuple[float, float]
    capacity: int | None = None


@dataclass(frozen=True)
class Camera:
    """Overhead camera: image size, frame rate, pixel->world homography and time offset."""

    width: int
    height: int
    fps: float
    homography: np.ndarray = field(repr=False)  # 3x3, pixel (u, v, 1) -> world (x, y, w)
    t0: float = 0.0

    @property
    def world_to_pixel(self) -> np.ndarray:
        return np.linalg.inv(self.homography)

    def pixel_to_world(self, uv: np.ndarray) -> np.ndarray:
        """Map ``(N, 2)`` pixel coordinates to world coordinates."""
        return _apply_h(self.homography, uv)

    def world_to_pixel_xy(self, xy: np.ndarray) -> np.ndarray:
        """Map ``(N, 2)`` world coordinates to pixel coordinates."""
        return _apply_h(self.world_to_pixel, xy)


def _apply_h(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    pts = np.asarray(pts, float).reshape(-1, 2)
    hom = np.c_[pts, np.ones(len(pts))] @ h.T
    return hom[:, :2] / hom[:, 2:3]


@dataclass(frozen=True)
class MotionSensor:
    """A PIR / motion sensor: pose, type name, refractory period, field of view and range.

    ``heading`` is the direction (degrees, counter-clockwise from +x) of the sensor frame's
    x axis in the world. ``fov`` is a detection polygon in world coordinates, ``range`` the
    radius of a detection disk around ``position``, ``type`` names a table in
    ``[sensor_types]`` or a built-in type (``None``: not declared). The detection region is
    the intersection of the extents declared (:mod:`onebit.core.sensing`); a sensor needs at
    least one of them.
    """

    id: str
    position: tuple[float, float]
    heading: float = 0.0
    type: str | None = None
    refractory: float = 0.0
    fov: Polygon | None = None
    range: float | None = None
    signal: str = "edge"  #: what a reading means (:data:`SIGNALS`); a PIR's is ``edge``


@dataclass(frozen=True)
class ProximitySensor:
    """A binary proximity sensor at ``position``: on means a target within ``r_outer`` (R_o),
    off means no target within ``r_inner`` (R_i); ideal sensing has R_i = R_o = R."""

    id: str
    position: tuple[float, float]
    r_inner: float
    r_outer: float
    signal: str = "level"  #: what a reading means (:data:`SIGNALS`)


@dataclass(frozen=True)
class BinarySensor:
    """A binary sensor declared once (``[[binary_sensors]]``) with its footprint, serving every
    tracker that can use it: motion trackers see it as a :class:`MotionSensor` (detection disk
    of radius ``r_outer``, ``fov`` and ``type`` as given), proximity trackers as a
    :class:`ProximitySensor` (``R_i = r_inner``, ``R_o = r_outer``), the I-state filter as one
    sensing region. ``signal`` says what a reading means (:data:`SIGNALS`; default ``level``:
    on while someone is in the footprint), from the sensor, else its type's ``signal``.

    The footprint is the disk of radius ``r_outer`` around ``position`` (``radius`` sets
    ``r_inner = r_outer``), intersected with ``fov`` when given: a reading 1 means a target in
    it; a reading 0 means none within ``r_inner`` (for a ``level`` sensor).
    """

    id: str
    position: tuple[float, float]
    r_inner: float
    r_outer: float
    fov: Polygon | None = None
    type: str | None = None
    refractory: float = 0.0
    signal: str = "level"

    def as_motion(self) -> MotionSensor:
        return MotionSensor(
            self.id, self.position, 0.0, self.type, self.refractory, self.fov, self.r_outer, self.signal
        )

    def as_proximity(self) -> ProximitySensor:
        return ProximitySensor(self.id, self.position, self.r_inner, self.r_outer, self.signal)


@dataclass(frozen=True)
class SensorGraph:
    """Physical 1-hop adjacency of motion-sensor nodes, with entry/exit nodes.

    ``signatures`` are ordered node pairs ``(outer, inner)``: activity at ``outer`` followed by
    ``inner`` is an entry, the reverse an exit (paper: 104 -> 103 is an entry).
    """

    nodes: tuple[str, ...]
    edges: tuple[tuple[str, str], ...]
    entries: tuple[str, ...] = ()
    exits: tuple[str, ...] = ()
    signatures: tuple[tuple[str, str], ...] = ()

    def to_networkx(self, site: Site | None = None):
        """Undirected ``networkx.Graph``; node attribute ``pos`` when ``site`` is given."""
        import networkx as nx

        g = nx.Graph()
        pos = {m.id: m.position for m in site.motion_sensors} if site is not None else {}
        for n in self.nodes:
            g.add_node(n, pos=pos.get(n), entry=n in self.entries, exit=n in self.exits)
        g.add_edges_from(self.edges)
        return g


@dataclass(frozen=True)
class Site:
    """A validated deployment. ``free_space`` is the boundary minus the obstacles (E in the paper)."""

    name: str
    units: str
    boundary: Polygon
    obstacles: tuple[Polygon, ...]
    obstacle_names: tuple[str, ...]
    beams: tuple[Beam, ...]
    regions: tuple[RegionSpec, ...]
    camera: Camera | None
    epoch: str | None = None
    source: str = "<site>"
    targets: int | None = None
    motion_sensors: tuple[MotionSensor, ...] = ()
    proximity_sensors: tuple[ProximitySensor, ...] = ()
    #: sensors declared once in ``[[binary_sensors]]``; each is also in ``motion_sensors`` and
    #: ``proximity_sensors`` (same id), so every tracker that can use it sees it
    binary_sensors: tuple[BinarySensor, ...] = ()
    sensor_graph: SensorGraph | None = None
    sensor_types: dict = field(default_factory=dict, repr=False)  # raw tables, validated by their user
    #: radius of a target's body (site units; ``None`` = 0.2 m): a beam is blocked while the
    #: body overlaps a pair, so a crossing is logged with the centre up to ``spacing / 2 +
    #: body_radius`` past the beam (:func:`onebit.core.sensing.body_radius`)
    body_radius: float | None = None
    #: ids of the sensors (beams included) marked ``ignore = true``, on the sensor or on its
    #: ``[sensor_types.<name>]`` table: the readers know them (their rows are read, never
    #: rejected), no tracker sees them (:attr:`tracked`)
    ignored: frozenset[str] = frozenset()

    @cached_property
    def tracked(self) -> Site:
        """The site as the trackers see it: the ignored sensors left out of the motion,
        proximity and binary sensor lists (the sensor graph never has them). Beams stay (they
        bound the regions); an ignored beam's crossings are left out of the trackers' inputs
        (:func:`onebit.pipeline.stages.without_ignored`). ``self`` when nothing is ignored."""
        if not self.ignored:
            return self
        keep = self.ignored.isdisjoint
        return replace(
            self,
            motion_sensors=tuple(m for m in self.motion_sensors if keep((m.id,))),
            proximity_sensors=tuple(p for p in self.proximity_sensors if keep((p.id,))),
            binary_sensors=tuple(b for b in self.binary_sensors if keep((b.id,))),
        )

    @property
    def free_space(self):
        return (
            shapely.difference(self.boundary, shapely.union_all(list(self.obstacles)))
            if self.obstacles
            else self.boundary
        )

    @cached_property
    def signals(self) -> dict[str, str]:
        """What each binary sensor's reading means, by id (:data:`SIGNALS`): ``level`` (held on
        = presence) or ``edge`` (an on is an event). Beams are left out (their events are crossings)."""
        out = {m.id: m.signal for m in self.motion_sensors}
        out.update({p.id: p.signal for p in self.proximity_sensors})
        return out

    @property
    def level_sensors(self) -> frozenset[str]:
        """Ids of the sensors whose reading is a level (held on = presence)."""
        return frozenset(k for k, v in self.signals.items() if v == "level")

    @property
    def binary_ids(self) -> frozenset[str]:
        return frozenset(b.id for b in self.binary_sensors)

    @property
    def beam_ids(self) -> tuple[str, ...]:
        return tuple(b.id for b in self.beams)

    def beam(self, beam_id: str) -> Beam:
        for b in self.beams:
            if b.id == beam_id:
                return b
        raise KeyError(beam_id)

    @cached_property
    def detection_regions(self) -> dict:
        """Every sensor's detection region by id, built once (:func:`onebit.core.sensing.detection_regions`)."""
        return build_detection_regions(self)

    @property
    def diagonal(self) -> float:
        minx, miny, maxx, maxy = self.boundary.bounds
        return float(math.hypot(maxx - minx, maxy - miny))


# --------------------------------------------------------------------------- loading


def load_site(path: str | Path) -> Site:
    """Load and validate ``site.toml``; raise :class:`SiteError` naming the key on any problem."""
    path = Path(path)
    return site_from_dict(load_toml(path, error=SiteError), source=str(path))


def site_from_dict(data: dict, *, source: str = "<site>") -> Site:
    """Validate a parsed ``site.toml`` mapping into a :class:`Site`: the top keys, then the
    floor (boundary, obstacles), the beams, the regions, the camera and the sensors, each
    checked by its own step naming the key of anything wrong."""

    def err(key: str, reason: str) -> SiteError:
        return SiteError(reason, file=source, field=key)

    _unknown(data, _TOP_KEYS, "", err)
    name = _name(data.get("name", Path(source).parent.name or "site"), "name", err)
    units = data.get("units", "m")
    if not isinstance(units, str) or units not in _UNITS:
        raise err("units", f"unknown unit {units!r}; expected one of {sorted(_UNITS)}")
    epoch = _site_epoch(data.get("epoch"), err)
    boundary, obstacles, obstacle_names = _floor(data, err)
    free = shapely.difference(boundary, shapely.union_all(obstacles)) if obstacles else boundary
    beams = _beams(
        data.get("beams", []), free, shapely.union_all([boundary.exterior, *[o.boundary for o in obstacles]]), err
    )
    regions = _regions(data.get("regions", []), free, err)
    camera = _camera(data["camera"], err) if "camera" in data else None
    targets = data.get("targets")
    if targets is not None and (
        not isinstance(targets, int) or isinstance(targets, bool) or not 0 <= targets <= MAX_TARGETS
    ):
        raise err("targets", f"must be an integer in [0, {MAX_TARGETS}], got {targets!r}")
    body = _number(data["body_radius"], "body_radius", err, lo=0.0) if "body_radius" in data else None
    stypes = data.get("sensor_types", {})
    if not isinstance(stypes, dict) or not all(isinstance(v, dict) for v in stypes.values()):
        raise err("sensor_types", "must be a table of tables ([sensor_types.<name>])")
    motion, prox, binary = _sensors(data, boundary, {b.id for b in beams}, stypes, err)
    ignored = _ignored(data, stypes, err)
    graph = (
        _sensor_graph(
            data["sensor_graph"],
            {m.id for m in motion},
            err,
            motion=[m for m in motion if m.id not in ignored],
            ignored=ignored,
            walls=shapely.union_all([boundary.exterior, *obstacles]),
            source=source,
        )
        if "sensor_graph" in data
        else None
    )

    return Site(
        name=name,
        units=units,
        boundary=boundary,
        obstacles=tuple(obstacles),
        obstacle_names=tuple(obstacle_names),
        beams=tuple(beams),
        regions=tuple(regions),
        camera=camera,
        epoch=epoch,
        source=source,
        targets=targets,
        motion_sensors=tuple(motion),
        proximity_sensors=tuple(prox),
        binary_sensors=tuple(binary),
        sensor_graph=graph,
        sensor_types=stypes,
        body_radius=body,
        ignored=ignored,
    )


_SENSOR_LISTS = ("beams", "motion_sensors", "proximity_sensors", "binary_sensors")


def _ignored(data: dict, stypes: dict, err) -> frozenset[str]:
    """Ids of the sensors marked ``ignore = true``: on the sensor, else on its type's table
    (``[sensor_types.<name>] ignore = true``); a sensor's own ``ignore = false`` overrides its
    type's. The tables were validated already (ids, keys); ``ignore`` must be a boolean."""
    for name, table in stypes.items():
        if "ignore" in table and not isinstance(table["ignore"], bool):
            raise err(f"sensor_types.{name}.ignore", f"must be true or false, got {_shown(table['ignore'])}")
    out: set[str] = set()
    for kind in _SENSOR_LISTS:
        for i, table in enumerate(data.get(kind, [])):
            sid = str(table["id"])
            if "ignore" in table:
                if not isinstance(table["ignore"], bool):
                    raise err(
                        f"{kind}[{i}] (id {sid!r}).ignore", f"must be true or false, got {_shown(table['ignore'])}"
                    )
                flag = table["ignore"]
            else:
                typ = stypes.get(table.get("type")) if isinstance(table.get("type"), str) else None
                flag = bool(typ.get("ignore", False)) if typ is not None else False
            if flag:
                out.add(sid)
    return frozenset(out)


def _site_epoch(epoch, err) -> str | None:
    """``epoch`` as ISO text (a TOML date-time is written back as ISO), checked; ``None`` when unset."""
    if epoch is not None and not isinstance(epoch, str):
        epoch = epoch.isoformat() if hasattr(epoch, "isoformat") else str(epoch)
    if epoch is not None:
        _check_epoch(epoch, err)
    return epoch


def _floor(data: dict, err) -> tuple[Polygon, list[Polygon], list[str]]:
    """``[boundary]`` and ``[[obstacles]]``: the boundary polygon, the obstacles (each inside
    it) and their names."""
    if "boundary" not in data:
        raise err("boundary", "missing; the site needs a boundary polygon")
    bnd = data["boundary"]
    if not isinstance(bnd, dict):
        raise err("boundary", "must be a table with a 'polygon' key")
    _unknown(bnd, _BOUNDARY_KEYS, "boundary.", err)
    boundary = _polygon(bnd.get("polygon"), "boundary.polygon", err)
    obstacles, obstacle_names = [], []
    for i, ob in enumerate(_list_of_tables(data.get("obstacles", []), "obstacles", err)):
        key = f"obstacles[{i}]"
        _unknown(ob, _OBSTACLE_KEYS, key + ".", err)
        poly = _polygon(ob.get("polygon"), key + ".polygon", err)
        if not boundary.buffer(TOUCH_TOL).contains(poly):
            raise err(key + ".polygon", "obstacle is not inside the boundary")
        obstacles.append(poly)
        obstacle_names.append(_name(ob.get("name", i), key + ".name", err))
    return boundary, obstacles, obstacle_names


def _beams(tables, free, walls, err) -> list[Beam]:
    """``[[beams]]``: each a segment from wall to wall through the free space, ids unique,
    beams pairwise disjoint (they may meet at an end)."""
    beams: list[Beam] = []
    seen: set[str] = set()
    for i, bm in enumerate(_list_of_tables(tables, "beams", err)):
        key = f"beams[{i}]"
        _unknown(bm, _BEAM_KEYS, key + ".", err)
        if "id" not in bm:
            raise err(key + ".id", "missing")
        bid = _name(bm["id"], key + ".id", err)
        key = f"beams[{i}] (id {bid!r})"
        if bid in seen:
            raise err(key + ".id", "duplicate beam id")
        seen.add(bid)
        seg = bm.get("segment")
        pts = _points(seg, key + ".segment", err)
        if len(pts) != 2:
            raise err(key + ".segment", f"needs exactly 2 points, got {len(pts)}")
        line = LineString(pts)
        if line.length <= TOUCH_TOL:
            raise err(key + ".segment", "has zero length")
        for end, p in zip(("start", "end"), pts):
            if walls.distance(Point(p)) > TOUCH_TOL * max(1.0, line.length):
                raise err(key + ".segment", f"{end} point {tuple(p)} does not touch the boundary or an obstacle")
        mid = line.interpolate(0.5, normalized=True)
        if not free.buffer(TOUCH_TOL).contains(line) or not free.contains(mid):
            raise err(key + ".segment", "beam does not lie in the free space")
        forward = bm.get("forward", "left")
        if forward not in ("left", "right"):
            raise err(key + ".forward", f"must be 'left' or 'right', got {forward!r}")
        spacing = _number(bm.get("spacing", 0.0), key + ".spacing", err, lo=0.0)
        if "capacity" in bm:
            _integer(bm["capacity"], key + ".capacity", err, lo=0)
        beams.append(Beam(bid, tuple(pts[0]), tuple(pts[1]), forward, float(spacing)))
    for i in range(len(beams)):
        for j in range(i + 1, len(beams)):
            li, lj = beams[i].line, beams[j].line
            inter = li.intersection(lj)
            if not inter.is_empty and (
                inter.length > 0 or not _at_end(inter, beams[i]) or not _at_end(inter, beams[j])
            ):
                raise err(
                    f"beams[{j}] (id {beams[j].id!r}).segment",
                    f"crosses beam {beams[i].id!r}; beams must be pairwise disjoint",
                )
    return beams


def _regions(tables, free, err) -> list[RegionSpec]:
    """``[[regions]]``: named points in the free space (names unique), optional capacity."""
    regions: list[RegionSpec] = []
    for i, rg in enumerate(_list_of_tables(tables, "regions", err)):
        key = f"regions[{i}]"
        _unknown(rg, _REGION_KEYS, key + ".", err)
        if "name" not in rg:
            raise err(key + ".name", "missing")
        pts = _points([rg.get("point")] if rg.get("point") is not None else None, key + ".point", err)
        if not free.contains(Point(pts[0])):
            raise err(key + ".point", f"{tuple(pts[0])} is not in the free space")
        cap = rg.get("capacity")
        if cap is not None:
            cap = _integer(cap, key + ".capacity", err, lo=0)
        regions.append(RegionSpec(_name(rg["name"], key + ".name", err), tuple(pts[0]), cap))
    if len({r.name for r in regions}) != len(regions):
        raise err("regions", "duplicate region name")
    return regions


def _sensors(data: dict, boundary, beam_ids: set[str], stypes: dict, err):
    """``[[motion_sensors]]``, ``[[proximity_sensors]]`` and ``[[binary_sensors]]`` (a binary
    sensor is listed as a motion and a proximity sensor too); every id unique, beams' included."""
    ids = set(beam_ids)
    motion = [
        _motion_sensor(ms, i, boundary, ids, err, stypes)
        for i, ms in enumerate(_list_of_tables(data.get("motion_sensors", []), "motion_sensors", err))
    ]
    prox = [
        _proximity_sensor(ps, i, ids, err)
        for i, ps in enumerate(_list_of_tables(data.get("proximity_sensors", []), "proximity_sensors", err))
    ]
    binary = [
        _binary_sensor(bs, i, ids, err, stypes)
        for i, bs in enumerate(_list_of_tables(data.get("binary_sensors", []), "binary_sensors", err))
    ]
    return motion + [b.as_motion() for b in binary], prox + [b.as_proximity() for b in binary], binary


def _signal(table: dict, typ: str | None, stypes: dict, key: str, default: str, err) -> str:
    """The sensor's ``signal``, else its type table's, else ``default`` (:data:`SIGNALS`)."""
    if "signal" in table:
        value, where = table["signal"], key + ".signal"
    elif typ is not None and isinstance(stypes.get(typ), dict) and "signal" in stypes[typ]:
        value, where = stypes[typ]["signal"], f"sensor_types.{typ}.signal"
    else:
        return default
    if value not in SIGNALS:
        raise err(
            where,
            f"must be one of {list(SIGNALS)} (level: held on = presence; edge: an on is an event), got {_shown(value)}",
        )
    return value


def _binary_sensor(bs: dict, i: int, seen: set[str], err, stypes: dict) -> BinarySensor:
    key = f"binary_sensors[{i}]"
    _unknown(bs, _BINARY_KEYS, key + ".", err)
    sid = _sensor_id(bs, key, seen, err)
    key = f"binary_sensors[{i}] (id {sid!r})"
    pos = _points([bs.get("position")] if bs.get("position") is not None else None, key + ".position", err)[0]
    if "radius" in bs:
        if "r_inner" in bs or "r_outer" in bs:
            raise err(key + ".radius", "give either 'radius' or 'r_inner'/'r_outer', not both")
        r_in = r_out = _number(bs["radius"], key + ".radius", err, positive=True)
    elif "r_outer" in bs:
        r_out = _number(bs["r_outer"], key + ".r_outer", err, positive=True)
        r_in = _number(bs.get("r_inner", r_out), key + ".r_inner", err, lo=0.0)
        if r_in > r_out:
            raise err(key + ".r_inner", f"r_inner {r_in} exceeds r_outer {r_out}")
    else:
        raise err(key + ".radius", "missing; the footprint needs 'radius' (or 'r_outer' and optionally 'r_inner')")
    typ = bs.get("type")
    if typ is not None and not isinstance(typ, str):
        raise err(key + ".type", f"must be a string, got {_shown(typ)}")
    fov = _polygon(bs["fov"], key + ".fov", err) if "fov" in bs else None
    refr = _number(bs.get("refractory", 0.0), key + ".refractory", err, lo=0.0)
    signal = _signal(bs, typ, stypes, key, "level", err)
    return BinarySensor(sid, (float(pos[0]), float(pos[1])), r_in, r_out, fov, typ, refr, signal)


def _motion_sensor(
    ms: dict, i: int, boundary: Polygon, seen: set[str], err, stypes: dict | None = None
) -> MotionSensor:
    key = f"motion_sensors[{i}]"
    _unknown(ms, _MOTION_KEYS, key + ".", err)
    sid = _sensor_id(ms, key, seen, err)
    key = f"motion_sensors[{i}] (id {sid!r})"
    pos = _points([ms.get("position")] if ms.get("position") is not None else None, key + ".position", err)[0]
    heading = _number(ms.get("heading", 0.0), key + ".heading", err)
    typ = ms.get("type")
    if typ is not None and not isinstance(typ, str):
        raise err(key + ".type", f"must be a string, got {_shown(typ)}")
    refr = _number(ms.get("refractory", 0.0), key + ".refractory", err, lo=0.0)
    fov = _polygon(ms["fov"], key + ".fov", err) if "fov" in ms else None
    rng = _number(ms["range"], key + ".range", err, positive=True) if "range" in ms else None
    signal = _signal(ms, typ, stypes or {}, key, "edge", err)
    return MotionSensor(sid, (float(pos[0]), float(pos[1])), heading, typ, refr, fov, rng, signal)


def _proximity_sensor(ps: dict, i: int, seen: set[str], err) -> ProximitySensor:
    key = f"proximity_sensors[{i}]"
    _unknown(ps, _PROXIMITY_KEYS, key + ".", err)
    sid = _sensor_id(ps, key, seen, err)
    key = f"proximity_sensors[{i}] (id {sid!r})"
    pos = _points([ps.get("position")] if ps.get("position") is not None else None, key + ".position", err)[0]
    if "radius" in ps:
        if "r_inner" in ps or "r_outer" in ps:
            raise err(key + ".radius", "give either 'radius' or 'r_inner'/'r_outer', not both")
        r_in = r_out = _number(ps["radius"], key + ".radius", err, positive=True)
    else:
        if "r_inner" not in ps or "r_outer" not in ps:
            raise err(key + ".radius", "missing; give 'radius' (ideal) or both 'r_inner' and 'r_outer'")
        r_in = _number(ps["r_inner"], key + ".r_inner", err, lo=0.0)
        r_out = _number(ps["r_outer"], key + ".r_outer", err, positive=True)
        if r_in > r_out:
            raise err(key + ".r_inner", f"r_inner {r_in} exceeds r_outer {r_out}")
    return ProximitySensor(sid, (float(pos[0]), float(pos[1])), r_in, r_out)


def _sensor_graph(
    g,
    motion_ids: set[str],
    err,
    *,
    motion=(),
    walls=None,
    source: str = "<site>",
    ignored: frozenset[str] = frozenset(),
) -> SensorGraph:
    """``[sensor_graph]``: edges given or from the sensors' geometry (``motion``: the sensors
    not ignored). An ignored sensor may be named in the table (it is a motion sensor) but is
    no node of the graph: its edges, entries, exits and signatures are dropped."""
    if not isinstance(g, dict):
        raise err("sensor_graph", "must be a table")
    _unknown(g, _GRAPH_KEYS, "sensor_graph.", err)
    edges = g.get("edges", [])
    if (
        "geometry" in g
    ):  # the edges from the sensors' positions (onebit.core.sensor_graph), walls = boundary + obstacles
        geo = g["geometry"]
        if "edges" in g:
            raise err("sensor_graph.geometry", "give either 'edges' or 'geometry', not both")
        if geo == "connected":
            radius = None
        elif isinstance(geo, (int, float)) and not isinstance(geo, bool) and math.isfinite(geo) and geo > 0:
            radius = float(geo)
        else:
            raise err(
                "sensor_graph.geometry",
                f'must be "connected" (the smallest distance that keeps the graph connected) or a positive distance, got {_shown(geo)}',
            )
        gg = geometric_sensor_graph({m.id: m.position for m in motion}, radius=radius, walls=walls)
        gg.require_connected(source=source, field="sensor_graph.geometry")
        edges = [list(e) for e in gg.edges]
    if not isinstance(edges, list) or not all(isinstance(e, list) and len(e) == 2 for e in edges):
        raise err("sensor_graph.edges", "must be a list of [node, node] pairs")
    edges_t = tuple((str(a), str(b)) for a, b in edges)
    for k, (a, b) in enumerate(edges_t):
        for n in (a, b):
            if n not in motion_ids:
                raise err(f"sensor_graph.edges[{k}]", f"node {n!r} is not a motion sensor id")
        if a == b:
            raise err(f"sensor_graph.edges[{k}]", f"self loop at {a!r}")
    out = {}
    for name in ("entries", "exits"):
        v = g.get(name, [])
        if not isinstance(v, list):
            raise err(f"sensor_graph.{name}", "must be a list of node ids")
        for n in v:
            if str(n) not in motion_ids:
                raise err(f"sensor_graph.{name}", f"node {n!r} is not a motion sensor id")
        out[name] = tuple(str(n) for n in v)
    sig = g.get("signatures", [])
    if not isinstance(sig, list) or not all(isinstance(e, list) and len(e) == 2 for e in sig):
        raise err("sensor_graph.signatures", "must be a list of [outer, inner] node pairs")
    sig_t = tuple((str(a), str(b)) for a, b in sig)
    if ignored:
        edges_t = tuple(e for e in edges_t if ignored.isdisjoint(e))
        sig_t = tuple(e for e in sig_t if ignored.isdisjoint(e))
        out = {k: tuple(n for n in v if n not in ignored) for k, v in out.items()}
    nodes = tuple(sorted(motion_ids - ignored, key=_natural_key))
    return SensorGraph(nodes, edges_t, out["entries"], out["exits"], sig_t)


def _at_end(inter, beam: Beam) -> bool:
    pts = [Point(beam.p0), Point(beam.p1)]
    return all(min(p.distance(q) for q in pts) <= TOUCH_TOL for p in _geom_points(inter))


def _camera(cam, err) -> Camera:
    if not isinstance(cam, dict):
        raise err("camera", "must be a table")
    _unknown(cam, _CAMERA_KEYS, "camera.", err)
    for k in ("width", "height"):
        if k not in cam:
            raise err(f"camera.{k}", "missing")
        _integer(cam[k], f"camera.{k}", err, lo=1)
    fps = _number(cam.get("fps", 10.0), "camera.fps", err, positive=True)
    if "homography" in cam and "points" in cam:
        raise err("camera", "give either 'homography' or 'points', not both")
    if "homography" in cam:
        h = np.asarray(cam["homography"], dtype=float) if _is_matrix(cam["homography"]) else None
        if h is None or h.shape != (3, 3) or not np.all(np.isfinite(h)):
            raise err("camera.homography", "must be a 3x3 matrix of numbers (pixel -> world)")
        if abs(np.linalg.det(h)) < 1e-12:
            raise err("camera.homography", "is singular")
    elif "points" in cam:
        pts = cam["points"]
        if not isinstance(pts, dict) or set(pts) != {"pixel", "world"}:
            raise err("camera.points", "must be a table with 'pixel' and 'world' lists of 4 points")
        px = _points(pts["pixel"], "camera.points.pixel", err)
        wd = _points(pts["world"], "camera.points.world", err)
        if len(px) != 4 or len(wd) != 4:
            raise err("camera.points", "needs exactly 4 pixel and 4 world points")
        import cv2

        h = cv2.getPerspectiveTransform(px.astype(np.float32), wd.astype(np.float32)).astype(float)
    else:
        raise err("camera.homography", "missing; give 'homography' (3x3) or 'points' (4 correspondences)")
    t0 = _number(cam.get("t0", 0.0), "camera.t0", err)
    return Camera(int(cam["width"]), int(cam["height"]), float(fps), h, float(t0))
