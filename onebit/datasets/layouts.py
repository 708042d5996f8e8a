"""Layout files of a CASAS home (``onebit import casas --layout``, :func:`onebit.datasets.importers.import_casas`):
sensor positions and optional edges from a TOML, JSON or CSV layout, or a floor plan of rooms
(the edges from geometry), and the matching of the file's sensor ids to the log's (``M017`` is ``M17``).
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError
from onebit.core.sensor_graph import geometric_sensor_graph
from onebit.readers.casas import (
    ALL_KINDS,
)

#: Floor-plan rooms closer than this (m, a wall's thickness) are neighbours (a doorway is assumed).
ROOM_TOUCH_M = 0.3

_LAYOUT_KEYS = {"units", "targets", "boundary", "range", "sensors", "graph", "name", "doors", "kinds"}


@dataclass(frozen=True)
class Layout:
    """A layout file: sensor positions (site units), optional edges, boundary, range, targets."""

    positions: dict[str, tuple[float, float]]
    edges: tuple[tuple[str, str], ...] | None = None
    boundary: list | None = None
    range: float | None = None
    units: str = "m"
    targets: int | None = None
    name: str | None = None
    source: str = "layout.toml"
    #: sensor id -> kind (:data:`onebit.readers.casas.ALL_KINDS`); doors are ``"door"``
    kinds: dict[str, str] = field(default_factory=dict)
    #: keep only the sensors the log has (a floor plan of a whole building), else every one placed
    only_logged: bool = False
    #: ``graph(positions) -> edges`` when the edges come from geometry (else None)
    graph: object = None
    #: how ``graph`` finds the edges (import.toml)
    graph_rule: str = ""


def _id_key(sid: str):
    """An id's match key: letters + the number without leading zeros (``M17`` = ``M017``)."""
    m = re.fullmatch(r"([A-Za-z]+)0*(\d+)(.*)", sid)
    return (m.group(1).upper(), int(m.group(2)), m.group(3)) if m else (sid,)


def match_ids(layout_ids, log_ids) -> dict[str, str]:
    """layout id -> log id, by exact id else by :func:`_id_key` (``M017`` in a floor plan is
    the log's ``M17``); ids the log does not have keep their own name."""
    log_ids = list(log_ids)
    exact = set(log_ids)
    by_key = {_id_key(i): i for i in log_ids}
    return {i: (i if i in exact else by_key.get(_id_key(i), i)) for i in layout_ids}


def _json_positions(data, path) -> tuple[dict[str, tuple[float, float]], dict[str, str], bool]:
    """Positions (as written), kinds and whether they are normalised, from a floor-plan JSON:
    ``{"M001": {"x": 483, "y": 264}, ...}`` (pixels), ``{"M001": [x, y]}``, or a pymrt /
    pyActLearn ``site.json`` (``{"sensors": [{"name": "M001", "locX": 0.4, "locY": 0.3,
    "types": [...]}]}``: ``locX``/``locY`` normalised to the plan)."""
    kinds: dict[str, str] = {}
    if isinstance(data, dict) and isinstance(data.get("sensors"), list):
        pos, norm = {}, True
        for k, sen in enumerate(data["sensors"]):
            if (
                not isinstance(sen, dict)
                or "name" not in sen
                or not all(isinstance(sen.get(c), (int, float)) for c in ("locX", "locY"))
            ):
                raise InputError("a sensor needs 'name', 'locX', 'locY' (numbers)", file=path, field=f"sensors[{k}]")
            pos[str(sen["name"])] = (float(sen["locX"]), float(sen["locY"]))
            types = " ".join(map(str, sen.get("types", []) or [sen.get("type", "")])).lower()
            if "door" in types:
                kinds[str(sen["name"])] = "contact"
            elif "motion" in types:
                kinds[str(sen["name"])] = "motion"
            norm = norm and 0.0 <= sen["locX"] <= 1.0 and 0.0 <= sen["locY"] <= 1.0
        return pos, kinds, norm
    if not isinstance(data, dict) or not data:
        raise InputError(
            "expected an object of sensor id -> {x, y} (or [x, y]), or a site.json with 'sensors'", file=path
        )
    pos = {}
    for sid, v in data.items():
        if isinstance(v, dict) and all(isinstance(v.get(c), (int, float)) for c in ("x", "y")):
            pos[str(sid)] = (float(v["x"]), float(v["y"]))
        elif isinstance(v, list) and len(v) == 2 and all(isinstance(c, (int, float)) for c in v):
            pos[str(sid)] = (float(v[0]), float(v[1]))
        else:
            raise InputError(f'must be {{"x": .., "y": ..}} or [x, y], got {v!r}', file=path, field=str(sid))
    xy = np.array(list(pos.values()))
    return pos, kinds, bool(((xy >= 0) & (xy <= 1)).all())


def _csv_positions(path) -> tuple[dict[str, tuple[float, float]], dict[str, str], bool]:
    """A CSV floor plan: a header with ``id`` (or ``sensor``/``name``), ``x``, ``y`` (or
    ``locX``/``locY``) and optionally ``kind``."""
    df = pl.read_csv(path, infer_schema=False)
    low = {c.lower(): c for c in df.columns}
    idc = next((low[c] for c in ("id", "sensor", "name") if c in low), None)
    xc = next((low[c] for c in ("x", "locx") if c in low), None)
    yc = next((low[c] for c in ("y", "locy") if c in low), None)
    if idc is None or xc is None or yc is None:
        raise InputError(f"needs columns id (or sensor/name), x, y (or locX, locY); has {df.columns}", file=path)
    x = df[xc].str.strip_chars().cast(pl.Float64, strict=False)
    y = df[yc].str.strip_chars().cast(pl.Float64, strict=False)
    bad = (x.is_null() | y.is_null()).arg_true().to_list()
    if bad:
        raise InputError(f"x/y not a number: {df.row(bad[0])}", file=path, line=bad[0] + 2)
    pos = {str(i): (float(a), float(b)) for i, a, b in zip(df[idc].to_list(), x.to_list(), y.to_list())}
    kinds = {str(i): str(k) for i, k in zip(df[idc].to_list(), df[low["kind"]].to_list())} if "kind" in low else {}
    xy = np.array(list(pos.values()))
    return pos, kinds, bool(((xy >= 0) & (xy <= 1)).all())


def load_rooms(path: str | Path) -> dict[str, object]:
    """Rooms of a floor plan (JSON): name -> a list of rectangles ``{"top_left": {"x", "y"},
    "width", "height"}`` (their union: the CASAS Kyoto labelling tool's ``partitions.json``), or
    name -> a polygon ``[[x, y], ...]``, in the sensors' coordinates (before scaling)."""
    import json

    from shapely.geometry import Polygon, box

    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read rooms JSON: {exc}", file=path) from None
    if not isinstance(data, dict):
        raise InputError("expected an object: room name -> rectangles or polygon", file=path)
    rooms = {}
    for name, v in data.items():
        try:
            if isinstance(v, list) and v and isinstance(v[0], dict):
                parts = [
                    box(
                        r["top_left"]["x"],
                        r["top_left"]["y"],
                        r["top_left"]["x"] + r["width"],
                        r["top_left"]["y"] + r["height"],
                    )
                    for r in v
                ]
                import shapely

                rooms[str(name)] = shapely.union_all(parts)
            else:
                rooms[str(name)] = Polygon([(float(a), float(b)) for a, b in v])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"not a list of rectangles or a polygon: {exc}", file=path, field=str(name)) from None
        if rooms[str(name)].is_empty or not rooms[str(name)].is_valid:
            raise InputError("empty or invalid room geometry", file=path, field=str(name))
    return rooms


def load_floor_plan(
    path: str | Path,
    *,
    scale: float | None = None,
    rooms: str | Path | None = None,
    radius: float | None = None,
    range_m: float | None = None,
) -> Layout:
    """A floor-plan layout (``--layout sensors.json|sensors.csv [--rooms R] [--scale S]``):
    sensor positions in pixels or normalised units (:func:`_json_positions`,
    :func:`_csv_positions`) times ``scale`` (site units per pixel / per plan width; required
    unless the coordinates are already metres -- pass ``--scale 1`` then), the image's y axis
    (down) flipped to the world's (up); rooms (:func:`load_rooms`) in the same coordinates.
    The edges come from geometry (:func:`onebit.core.sensor_graph.geometric_sensor_graph`:
    neighbours within ``radius``, or the smallest distance that keeps the graph connected, and
    the rooms respected) over the sensors the log has (``only_logged``)."""
    import json

    import shapely

    path = Path(path)
    if path.suffix.lower() == ".csv":
        pos, kinds, norm = _csv_positions(path)
    else:
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot read floor-plan JSON: {exc}", file=path) from None
        pos, kinds, norm = _json_positions(data, path)
    if scale is None:
        raise InputError(
            "--scale is needed with a floor plan: metres per pixel (or per plan width for normalised "
            f"coordinates{', as these are' if norm else ''}); --scale 1 if the numbers are metres",
            file=path,
        )
    if not (math.isfinite(scale) and scale > 0):
        raise InputError(f"--scale = {scale!r}: must be a positive number")

    def world(x: float, y: float) -> tuple[float, float]:
        return (round(x * scale, 6), round(-y * scale, 6))

    positions = {k: world(*v) for k, v in pos.items()}
    room_polys = {}
    if rooms is not None:
        room_polys = {
            k: shapely.affinity.scale(p, xfact=scale, yfact=-scale, origin=(0, 0)) for k, p in load_rooms(rooms).items()
        }

    def graph(placed: dict[str, tuple[float, float]]):
        gg = geometric_sensor_graph(
            placed, radius=radius, rooms=room_polys or None, touch_tol=ROOM_TOUCH_M, join_components=radius is not None
        )
        gg.require_connected(source=str(path), field="sensors (graph from geometry)")
        return list(gg.edges)

    rule = (
        "geometry: "
        + (
            f"neighbours within {radius} m, components joined by their shortest allowed pairs"
            if radius
            else "the smallest distance that keeps the graph connected"
        )
        + (
            f", rooms of {Path(rooms).name} respected (same room, or rooms within {ROOM_TOUCH_M} m: a wall with a doorway)"
            if rooms
            else ""
        )
    )
    xy = np.array(list(positions.values())) if positions else np.zeros((0, 2))
    boundary = None
    if room_polys:
        x0, y0, x1, y1 = shapely.union_all(list(room_polys.values())).bounds
        lo, hi = np.minimum([x0, y0], xy.min(axis=0)), np.maximum([x1, y1], xy.max(axis=0))
        boundary = [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]
    return Layout(positions, None, boundary, range_m, "m", None, path.stem, str(path), kinds, True, graph, rule)


def load_layout(path: str | Path) -> Layout:
    """Read a layout file (``--layout``)::

        units = "m"                       # optional (default m)
        targets = 1                       # optional: people in the home at most
        range = 1.5                       # optional: each sensor's detection radius
        boundary = [[0, 0], [25, 0], [25, 10], [0, 10]]   # optional, else the positions' box
        [sensors]                         # required: a position for every sensor of the log
        M001 = [1.5, 2.0]
        D001 = [0.0, 2.0]
        [graph]                           # optional: the edges (else learned from the log)
        edges = [["D001", "M001"], ["M001", "M002"]]
        doors = ["D001"]                  # optional: contacts that are doors to the outside (entry/exit)
        [kinds]                           # optional: a sensor's kind (named sensors, overrides)
        Bedroom = "motion"

    Errors name the file and the key."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read layout file: {exc.strerror}", file=path) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"not valid TOML: {exc}", file=path) from None
    for k in data:
        if k not in _LAYOUT_KEYS:
            raise InputError(f"unknown key; allowed keys are {sorted(_LAYOUT_KEYS)}", file=path, field=k)
    sensors = data.get("sensors")
    if not isinstance(sensors, dict) or not sensors:
        raise InputError("missing; a [sensors] table with a position [x, y] per sensor id", file=path, field="sensors")
    positions = {}
    for sid, p in sensors.items():
        if not (
            isinstance(p, list)
            and len(p) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in p)
        ):
            raise InputError(f"must be [x, y] (two numbers), got {p!r}", file=path, field=f"sensors.{sid}")
        positions[str(sid)] = (float(p[0]), float(p[1]))
    edges = None
    graph = data.get("graph", {})
    if not isinstance(graph, dict):
        raise InputError("must be a table with 'edges'", file=path, field="graph")
    if "edges" in graph:
        e = graph["edges"]
        if not isinstance(e, list) or not all(isinstance(x, list) and len(x) == 2 for x in e):
            raise InputError("must be a list of [sensor, sensor] pairs", file=path, field="graph.edges")
        for k, (a, b) in enumerate(e):
            for n in (a, b):
                if str(n) not in positions:
                    raise InputError(f"sensor {n!r} has no position in [sensors]", file=path, field=f"graph.edges[{k}]")
        edges = tuple((str(a), str(b)) for a, b in e)
    rng = data.get("range")
    if rng is not None and (isinstance(rng, bool) or not isinstance(rng, (int, float)) or not rng > 0):
        raise InputError(f"must be a positive number, got {rng!r}", file=path, field="range")
    targets = data.get("targets")
    if targets is not None and (isinstance(targets, bool) or not isinstance(targets, int) or targets < 0):
        raise InputError(f"must be a non-negative integer, got {targets!r}", file=path, field="targets")
    kinds = _layout_kinds(data, path)
    return Layout(
        positions,
        edges,
        data.get("boundary"),
        None if rng is None else float(rng),
        str(data.get("units", "m")),
        targets,
        data.get("name"),
        str(path),
        kinds,
    )


def _layout_kinds(data: dict, path) -> dict[str, str]:
    """``[kinds]`` and ``doors`` of a layout as sensor id -> kind (errors name the key)."""
    kinds = data.get("kinds", {})
    if not isinstance(kinds, dict):
        raise InputError("must be a table: sensor id = kind", file=path, field="kinds")
    out = {}
    for sid, k in kinds.items():
        if k not in ALL_KINDS:
            raise InputError(f"unknown kind {k!r}; one of {list(ALL_KINDS)}", file=path, field=f"kinds.{sid}")
        out[str(sid)] = str(k)
    doors = data.get("doors", [])
    if not isinstance(doors, list) or not all(isinstance(d, str) for d in doors):
        raise InputError("must be a list of sensor ids", file=path, field="doors")
    out.update({d: "door" for d in doors})
    return out
