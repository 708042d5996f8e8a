"""The sensor model of the base layer: where each sensor of a site detects, in world units.

Every sensor of ``site.toml`` has exactly one :class:`DetectionRegion`, built once per site by
:func:`detection_regions` (cached on the :class:`~onebit.core.site.Site`). Trackers, scorers
and simulators read sensor geometry from it and from nowhere else. All lengths are in the
site's ``units``.

Regions
-------
A region is the intersection of every extent the site declares for the sensor; a point
``p`` is in the region ``S_i`` when::

    p in fov_i                          (motion sensor ``fov``: a polygon, world coordinates)
    and p in E_i                        (the extent of the sensor's declared ``type``, below)
    and dist(p, a_i) <= r_i             (motion ``range``: a disk around the sensor;
                                         proximity ``R_o``: a disk around the sensor;
                                         beam: ``spacing / 2`` around its segment)

with each condition present only when the site declares it. The test is exact for disks
(:meth:`DetectionRegion.covers_xy`); :attr:`DetectionRegion.geometry` is a shapely polygon
(disks drawn with :data:`QUAD_SEGS` segments per quarter circle) for drawing and clipping.

* **motion sensor**: ``fov`` (polygon), ``range`` (disk of that radius around ``position``)
  and the extent ``E_i`` of its ``type``; at least one of the three is required;
* **proximity sensor**: the disk of radius ``R_o`` (``r_outer``); ``inner_radius`` is ``R_i``,
  the open disk an off reading clears;
* **binary sensor** (``[[binary_sensors]]``, declared once, listed as a motion and a proximity
  sensor too): one region of kind ``binary``, the disk ``R_o`` intersected with its ``fov`` and
  its type's extent; ``inner_radius`` is ``R_i``;
* **directional beam**: the segment grown by half its pair ``spacing`` (the two
  emitter-detector pairs run ``spacing`` apart; its end caps lie on walls). With spacing 0
  the region is the segment itself.

Extent of a declared sensor type
--------------------------------
A sensor type (a ``[sensor_types.<name>]`` table, or a built-in type of
:data:`BUILTIN_TYPES`) is given in the sensor's frame: apex at the sensor, looking along
``+u`` (rotated by ``heading`` degrees counter-clockwise from ``+x`` and translated to
``position``)::

    kind = "pir-triangle"   E = {(u, v): 0 <= u <= range, |v| <= u tan(fov / 2)}   (a triangle)
    kind = "beam"           E = [0, length] x [-width / 2, width / 2]   (the segment when width = 0)
    kind = "grid"           E = convex hull of the samples (u, v) with eta > 0
    kind = "polygon"        E = the polygon [[u, v], ...] itself (any footprint: a floor mat, a
                            door's contact strip, a ceiling sensor's disk drawn as a polygon)

A table declares a geometry when it has ``kind`` or one of the geometry keys; then every key
its kind needs is required (``range`` and ``fov``; ``length``; ``samples``; ``polygon``) -- there is no
default extent. ``resolution`` (the spacing of the characterisation's samples) defaults to
1 m in the site's units; a beam's ``width`` to its resolution (the paper's "10 x 1 x 1"
beam: each sample stands for a resolution-sized block on its axis). A table with only
debounce or rate keys declares no extent. Lengths of a site's table are in the site's
units; lengths of the built-in types are in metres and are converted to the site's units.

A motion sensor with no ``fov``, no ``range`` and no type extent has no usable region:
:func:`detection_regions` raises :class:`~onebit.core.errors.SiteError` naming its key.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Protocol

import numpy as np
import polars as pl
import shapely
from shapely.geometry import LineString, Point, Polygon
from shapely.geometry.base import BaseGeometry

from onebit.core.errors import SiteError
from onebit.core.units import units_per_metre


class SensorSite(Protocol):
    """What this module reads of a site; :class:`onebit.core.site.Site` is one.

    Typed by its shape, not by name: the site builds on this module (it caches its regions
    from :func:`build_detection_regions`), so this module does not import the site.
    """

    units: str
    source: str
    sensor_types: Mapping[str, Any]
    body_radius: float | None
    motion_sensors: Sequence[Any]
    binary_sensors: Sequence[Any]
    proximity_sensors: Sequence[Any]
    beams: Sequence[Any]

    @property
    def detection_regions(self) -> dict[str, DetectionRegion]: ...


#: Segments per quarter circle of a disk in :attr:`DetectionRegion.geometry`.
QUAD_SEGS = 32

#: Sensor-type kinds with a geometric extent.
KINDS = ("pir-triangle", "beam", "grid", "polygon")

#: Keys of a ``[sensor_types.<name>]`` table that describe its geometry.
GEOMETRY_KEYS = frozenset({"kind", "range", "fov", "length", "width", "resolution", "samples", "polygon"})

#: Keys whose value is a length (scaled with the units; ``samples`` scales its u and v).
LENGTH_KEYS = frozenset({"range", "length", "width", "resolution"})

#: Built-in sensor types, **lengths in metres** (converted to the site's units on use): the
#: paper's perfect PIR (8 m triangle, 60 degrees), its imperfect PIR and the 10 m optical beam
#: (Schiff & Goldberg section VIII; one cell = 1 m).
BUILTIN_TYPES: dict[str, dict] = {
    "pir": {"kind": "pir-triangle", "range": 8.0, "fov": 60.0, "resolution": 2.0},
    "pir-imperfect": {
        "kind": "pir-triangle",
        "range": 8.0,
        "fov": 60.0,
        "resolution": 2.0,
        "falloff": 0.6,
        "false_positive": 0.25,
    },
    "beam": {"kind": "beam", "length": 10.0, "resolution": 1.0},
}

#: Default sampling resolution of a characterisation, metres (converted to the site's units).
DEFAULT_RESOLUTION_M = 1.0

#: Radius of a person's body when ``site.toml`` gives no ``body_radius``, metres: a walker's
#: shoulders are ~0.45 m wide, and a beam crossing is logged with the centre ~0.2 m past it.
DEFAULT_BODY_RADIUS_M = 0.2


def body_radius(site: SensorSite) -> float:
    """The radius of a target's body in the site's units: ``site.toml``'s ``body_radius``, else
    :data:`DEFAULT_BODY_RADIUS_M` converted. The one value simulators (a beam is blocked while
    a body overlaps a pair), the beam reader's geometry (:func:`onebit.readers.beams.crossing_reach`)
    and trackers (istate's beam regions) use."""
    if getattr(site, "body_radius", None) is not None:
        return float(site.body_radius)
    return DEFAULT_BODY_RADIUS_M * units_per_metre(site.units)


# --------------------------------------------------------------------------- sensor types


def scale_type_table(table: Mapping, factor: float) -> dict:
    """A copy of a sensor-type table with every length (and the u, v of ``samples`` and ``polygon``) times ``factor``."""
    out = dict(table)
    for k in LENGTH_KEYS & set(out):
        out[k] = out[k] * factor
    if "samples" in out:
        s = np.asarray(out["samples"], dtype=float).reshape(-1, 3).copy()
        s[:, :2] *= factor
        out["samples"] = s.tolist()
    if "polygon" in out:
        out["polygon"] = (np.asarray(out["polygon"], dtype=float) * factor).tolist()
    return out


def type_table(
    name: str, site_types: Mapping | None, *, units: str = "m", source: str = "site.toml", field: str | None = None
) -> dict:
    """The raw table of sensor type ``name`` in site units: the site's ``[sensor_types.<name>]``,
    else the built-in type of that name converted from metres. Unknown names raise
    :class:`SiteError` (naming ``field``, default ``sensor_types.<name>``)."""
    if site_types is not None and name in site_types:
        return dict(site_types[name])
    if name in BUILTIN_TYPES:
        return scale_type_table(BUILTIN_TYPES[name], units_per_metre(units))
    raise SiteError(
        f"unknown sensor type {name!r}: not in [sensor_types] and not built in ({sorted(BUILTIN_TYPES)})",
        file=source,
        field=field or f"sensor_types.{name}",
    )


@dataclass(frozen=True, eq=False)
class TypeGeometry:
    """The validated geometry of a sensor type, in the sensor's frame (site units).

    ``range``/``fov`` (degrees) for ``pir-triangle``; ``length``/``width`` for ``beam``;
    ``samples`` ``(k, 3)`` (u, v, eta) for ``grid``; ``polygon`` ``(k, 2)`` (u, v) for
    ``polygon``; ``resolution`` is the sample spacing of
    the characterisation (:mod:`onebit.models.pir`).
    """

    name: str
    kind: str
    resolution: float
    range: float | None = None
    fov: float | None = None
    length: float | None = None
    width: float = 0.0
    samples: np.ndarray | None = None
    polygon: np.ndarray | None = None

    @cached_property
    def extent(self) -> BaseGeometry:
        """``E`` in the sensor frame (module docstring)."""
        if self.kind == "pir-triangle":
            half = math.tan(math.radians(self.fov) / 2) * self.range
            return Polygon([(0.0, 0.0), (self.range, -half), (self.range, half)])
        if self.kind == "beam":
            if self.width > 0:
                return shapely.box(0.0, -self.width / 2, self.length, self.width / 2)
            return LineString([(0.0, 0.0), (self.length, 0.0)])
        if self.kind == "polygon":
            return Polygon(self.polygon)
        pts = self.samples[self.samples[:, 2] > 0, :2]
        return shapely.convex_hull(shapely.multipoints(pts))

    def extent_at(self, position: tuple[float, float], heading: float) -> BaseGeometry:
        """``E`` in world coordinates: rotated by ``heading`` (degrees) and moved to ``position``."""
        return shapely.transform(self.extent, lambda uv: sensor_to_world(uv, position, heading))


def sensor_to_world(uv: np.ndarray, position: tuple[float, float], heading: float) -> np.ndarray:
    """``(k, 2)`` sensor-frame points (u, v) in world coordinates::

    x = x_s + u cos(h) - v sin(h),   y = y_s + u sin(h) + v cos(h)
    """
    th = math.radians(heading)
    c, s = math.cos(th), math.sin(th)
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    return np.c_[position[0] + c * uv[:, 0] - s * uv[:, 1], position[1] + s * uv[:, 0] + c * uv[:, 1]]


def type_geometry(name: str, table: Mapping, *, units: str = "m", source: str = "site.toml") -> TypeGeometry | None:
    """Validate the geometry of ``[sensor_types.<name>]`` (site units); ``None`` when the table
    declares none (module docstring). Errors name ``sensor_types.<name>.<key>``."""

    def err(k: str, reason: str) -> SiteError:
        return SiteError(reason, file=source, field=f"sensor_types.{name}.{k}")

    if not (GEOMETRY_KEYS & set(table)):
        return None

    def num(k: str, lo: float, hi: float | None = None, *, default: float | None = None) -> float:
        if k not in table:
            if default is not None:
                return default
            raise err(k, f"missing; a {kind!r} sensor type needs {k!r} (no default extent)")
        v = table[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise err(k, f"must be a finite number, got {v!r}")
        if v <= lo or (hi is not None and v > hi):
            raise err(k, f"{v!r} outside ({lo}, {hi if hi is not None else 'inf'}]")
        return float(v)

    kind = table.get("kind")
    if kind is None:  # implied by the keys present
        kind = (
            "grid"
            if "samples" in table
            else "polygon"
            if "polygon" in table
            else "beam"
            if "length" in table
            else "pir-triangle"
        )
    if kind not in KINDS:
        raise err("kind", f"{kind!r} is not one of {list(KINDS)}")
    res = num("resolution", 0.0, default=DEFAULT_RESOLUTION_M * units_per_metre(units))
    if kind == "pir-triangle":
        return TypeGeometry(name, kind, res, range=num("range", 0.0), fov=num("fov", 0.0, 179.0))
    if kind == "beam":
        width = res  # its samples stand for resolution-sized blocks along the axis
        if "width" in table:
            w = table["width"]
            if isinstance(w, bool) or not isinstance(w, (int, float)) or not math.isfinite(w) or w < 0:
                raise err("width", f"must be a non-negative number, got {w!r}")
            width = float(w)
        return TypeGeometry(name, kind, res, length=num("length", 0.0), width=width)
    if kind == "polygon":
        return TypeGeometry(name, kind, res, polygon=_footprint(table.get("polygon"), err))
    if "samples" not in table:
        raise err("samples", "missing; a 'grid' sensor type needs samples = [[u, v, eta], ...]")
    try:
        samples = np.asarray(table["samples"], dtype=float).reshape(-1, 3)
    except (TypeError, ValueError):
        raise err("samples", "must be a list of [u, v, eta] triples") from None
    if len(samples) == 0 or not np.all(np.isfinite(samples)) or np.any((samples[:, 2] < 0) | (samples[:, 2] > 1)):
        raise err("samples", "needs at least one [u, v, eta] with finite u, v and 0 <= eta <= 1")
    if not np.any(samples[:, 2] > 0):
        raise err("samples", "every eta is 0: the sensor can never detect")
    return TypeGeometry(name, kind, res, samples=samples)


def _footprint(value, err) -> np.ndarray:
    """The ``polygon`` of a ``kind = "polygon"`` type: at least 3 finite ``[u, v]`` points
    forming a simple polygon of positive area (sensor frame, site units)."""
    if value is None:
        raise err("polygon", "missing; a 'polygon' sensor type needs polygon = [[u, v], ...] (sensor frame)")
    try:
        pts = np.asarray(value, dtype=float).reshape(-1, 2)
    except (TypeError, ValueError):
        raise err("polygon", "must be a list of [u, v] pairs") from None
    if len(pts) < 3 or not np.all(np.isfinite(pts)):
        raise err("polygon", f"needs at least 3 finite [u, v] points, got {len(pts)}")
    poly = Polygon(pts)
    if not poly.is_valid or poly.area <= 0:
        raise err("polygon", "is not a simple polygon of positive area (edges cross, or the points are on a line)")
    return pts


# --------------------------------------------------------------------------- regions


@dataclass(frozen=True, eq=False)
class DetectionRegion:
    """Where one sensor detects (module docstring): the intersection of its declared extents.

    ``position`` is the sensor (a beam: the middle of its segment). ``radius`` is measured
    from ``axis`` (a beam's segment) or, without one, from ``position``. ``fov`` and
    ``extent`` (its type's, world coordinates) are polygons or, for a thin beam type, a
    segment. ``inner_radius`` is a proximity sensor's ``R_i``.
    """

    sensor: str
    kind: str  # "motion" | "proximity" | "binary" | "beam"
    position: tuple[float, float]
    fov: Polygon | None = None
    radius: float | None = None
    axis: LineString | None = None
    extent: BaseGeometry | None = None
    type: str | None = None
    inner_radius: float | None = None
    #: what a reading means (:data:`onebit.core.site.SIGNALS`): ``level`` = held on is presence
    signal: str = "edge"

    @property
    def core(self) -> BaseGeometry:
        """What ``radius`` is measured from: the beam's segment, else the sensor's position."""
        return self.axis if self.axis is not None else Point(self.position)

    @cached_property
    def window(self) -> BaseGeometry | None:
        """The world window the site declares for the sensor itself (``fov`` and ``range``,
        without its type's extent); ``None`` when it declares neither."""
        parts = [g for g in (self.fov, self._disk()) if g is not None]
        return _intersect(parts) if parts else None

    @cached_property
    def geometry(self) -> BaseGeometry:
        """The region as one shapely geometry (disks as polygons of :data:`QUAD_SEGS`)."""
        parts = [g for g in (self.fov, self.extent, self._disk()) if g is not None]
        return _intersect(parts)

    def _disk(self) -> BaseGeometry | None:
        if self.radius is None:
            return None
        return self.core if self.radius == 0 else shapely.buffer(self.core, self.radius, quad_segs=QUAD_SEGS)

    def covers_xy(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Exact membership of points (boundary included), vectorised: ``(N,)`` bool."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        ok = np.ones(x.shape, dtype=bool)
        for poly in (self.fov, self.extent):
            if poly is not None:
                ok &= shapely.intersects_xy(poly, x, y)
        if self.radius is not None:
            if self.axis is None:
                d = np.hypot(x - self.position[0], y - self.position[1])
            else:
                d = shapely.distance(self.axis, shapely.points(x, y))
            ok &= d <= self.radius
        return ok


def _intersect(parts: list[BaseGeometry]) -> BaseGeometry:
    out = parts[0]
    for g in parts[1:]:
        out = shapely.intersection(out, g)
    return out


def detection_regions(site: SensorSite) -> dict[str, DetectionRegion]:
    """Every sensor's :class:`DetectionRegion` by sensor id (motion, proximity, beams, in site
    order), built once per site and cached on it (:attr:`Site.detection_regions`).

    Raises :class:`SiteError` naming the sensor's key when a motion sensor has no usable
    region: no ``fov``, no ``range`` and no type extent, or extents that do not overlap.
    """
    return site.detection_regions


def build_detection_regions(site: SensorSite) -> dict[str, DetectionRegion]:
    """Build the regions of :func:`detection_regions` (uncached)."""
    out: dict[str, DetectionRegion] = {}
    tables = site.sensor_types if isinstance(site.sensor_types, dict) else {}
    binary = {b.id: b for b in getattr(site, "binary_sensors", ())}
    for i, m in enumerate(site.motion_sensors):
        key = f"motion_sensors[{i}] (id {m.id!r})"
        extent = None
        if m.type is not None:
            table = type_table(m.type, tables, units=site.units, source=site.source, field=key + ".type")
            tg = type_geometry(m.type, table, units=site.units, source=site.source)
            extent = tg.extent_at(m.position, m.heading) if tg is not None else None
        if m.fov is None and m.range is None and extent is None:
            typ = f"its type {m.type!r} declares no geometry" if m.type is not None else "it has no 'type'"
            raise SiteError(
                f"no detection region: no 'fov' polygon, no 'range' and {typ}; give 'fov', 'range' or a 'type' "
                "whose [sensor_types] table declares kind with range and fov, length or samples",
                file=site.source,
                field=key,
            )
        b = binary.get(m.id)
        reg = DetectionRegion(
            m.id,
            "motion" if b is None else "binary",
            m.position,
            fov=m.fov,
            radius=m.range,
            extent=extent,
            type=m.type,
            inner_radius=None if b is None else b.r_inner,
            signal=getattr(m, "signal", "edge"),
        )
        if reg.geometry.is_empty:
            declared = [
                k for k, v in (("fov", m.fov), ("range", m.range), (f"type {m.type!r}", extent)) if v is not None
            ]
            raise SiteError(
                f"empty detection region: {' and '.join(declared)} do not overlap", file=site.source, field=key
            )
        out[m.id] = reg
    for p in site.proximity_sensors:
        if p.id not in binary:  # a binary sensor's one region is made above
            out[p.id] = DetectionRegion(
                p.id, "proximity", p.position, radius=p.r_outer, inner_radius=p.r_inner, signal=p.signal
            )
    for b in site.beams:
        mid = b.line.interpolate(0.5, normalized=True)
        out[b.id] = DetectionRegion(b.id, "beam", (mid.x, mid.y), radius=b.spacing / 2.0, axis=b.line)
    return out


def covers(regions: Sequence[DetectionRegion], xy: np.ndarray) -> np.ndarray:
    """``(N, n)`` bool: sample ``k`` is in region ``i`` (a loop over the few sensors, each
    vectorised over the samples)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    out = np.zeros((len(xy), len(regions)), dtype=bool)
    for i, r in enumerate(regions):
        out[:, i] = r.covers_xy(xy[:, 0], xy[:, 1])
    return out


def current_node(xy: np.ndarray, targets: np.ndarray, regions: Sequence[DetectionRegion]) -> np.ndarray:
    """Index (into ``regions``) of the sensor whose detection region each sample is in.

    With ``inside_ki`` = sample ``k`` in region ``i`` (:func:`covers`) and ``d_ki`` its
    distance to sensor ``i``'s position::

        node_k = argmin_{i : inside_ki} d_ki                     when some region holds it,
               = node of the previous sample of the same target  otherwise (forward fill in
                                                                 sample order), -1 before the first.
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    pos = np.array([r.position for r in regions], dtype=float).reshape(-1, 2)
    inside = covers(regions, xy)
    d = np.hypot(xy[:, None, 0] - pos[None, :, 0], xy[:, None, 1] - pos[None, :, 1])
    near = np.argmin(np.where(inside, d, np.inf), axis=1) if len(regions) else np.zeros(len(xy), np.int64)
    cur = np.where(inside.any(axis=1), near, -1)
    s = pl.DataFrame({"target": targets, "cur": pl.Series(cur).replace(-1, None)})
    return s.select(pl.col("cur").forward_fill().over("target")).to_series().fill_null(-1).to_numpy()
