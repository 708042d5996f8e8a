"""Sensor graphs from geometry: which positioned sensors are neighbours.

:func:`geometric_sensor_graph` links two sensors ``a``, ``b`` when

1. they are at most ``radius`` apart (``radius = None``: *the smallest distance that keeps the
   graph connected* -- the longest edge of a minimum spanning tree of the allowed pairs, the
   bottleneck distance), and
2. the segment between them crosses no wall (``walls``: any shapely geometry, e.g. obstacle
   polygons, wall lines or the boundary ring; touching a wall at an end point is allowed), and
3. with ``rooms`` (name -> polygon): both are in the same room, or in rooms that touch
   (share a boundary within ``touch_tol``: a doorway between them is assumed), or the segment
   passes through one of the ``openings`` (door geometries, e.g. points buffered by half a door
   width). A sensor in no room may link to any room (a doorway sensor).

With ``join_components``, components left apart at ``radius`` are then joined by the
shortest allowed pairs between them (Kruskal over the allowed pairs: a minimum spanning
forest of the components), listed in ``joins`` -- a sparse local graph that still reaches
an outlying sensor, instead of a radius so large that every sensor links to many.

The result says whether the graph is connected and lists its components: a caller must not
use a disconnected graph silently (:class:`GeometricGraph.require_connected`). Distances are
in the positions' units. Pairs are found with numpy (all pairs: homes have tens to a few
hundred sensors); the wall test is one vectorised ``shapely.intersects`` over the candidate
segments.

Examples
--------
>>> g = geometric_sensor_graph({"a": (0, 0), "b": (1, 0), "c": (2.5, 0)})
>>> g.edges, g.radius, g.connected
((('a', 'b'), ('b', 'c')), 1.5, True)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from onebit.core.errors import SiteError


@dataclass(frozen=True)
class GeometricGraph:
    """A sensor graph found from positions (module docstring).

    nodes : the sensor ids, in the order given.
    edges : ``(a, b)`` pairs, ``a`` before ``b`` in ``nodes`` order, sorted.
    radius : the distance used (the connecting distance when none was given).
    components : the connected components (each sorted by ``nodes`` order), largest first.
    rule : how the edges were found, in words (for import records).
    joins : the edges added to join components (``join_components``), a subset of ``edges``.
    """

    nodes: tuple[str, ...]
    edges: tuple[tuple[str, str], ...]
    radius: float
    components: tuple[tuple[str, ...], ...]
    rule: str
    joins: tuple[tuple[str, str], ...] = ()

    @property
    def connected(self) -> bool:
        return len(self.components) <= 1

    def require_connected(self, *, source: str = "<site>", field: str = "sensor_graph") -> GeometricGraph:
        """``self``, or a :class:`~onebit.core.errors.SiteError` naming the components."""
        if not self.connected:
            parts = "; ".join("{" + ", ".join(c[:6]) + (", ..." if len(c) > 6 else "") + "}" for c in self.components)
            raise SiteError(
                f"the sensor graph from geometry ({self.rule}) is not connected: {len(self.components)} components {parts}; "
                "give a larger radius, fewer walls, or the edges",
                file=source,
                field=field,
            )
        return self


def _allowed_pairs(
    xy: np.ndarray,
    walls: BaseGeometry | None,
    room_of: np.ndarray | None,
    touching: np.ndarray | None,
    openings: BaseGeometry | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(i, j, distance) of every pair i < j that rules 2 and 3 allow (any distance)."""
    n = xy.shape[0]
    i, j = np.triu_indices(n, k=1)
    d = np.hypot(*(xy[i] - xy[j]).T)
    ok = np.ones(i.size, dtype=bool)
    if i.size and (walls is not None or room_of is not None):
        segs = shapely.linestrings(np.stack([xy[i], xy[j]], axis=1))
        if walls is not None and not walls.is_empty:
            # a wall the segment passes through; touching at a sensor (end point) does not count
            inner = shapely.intersection(segs, walls)
            ends = shapely.multipoints(np.stack([xy[i], xy[j]], axis=1))
            crossing = ~shapely.is_empty(inner) & ~shapely.covers(shapely.buffer(ends, 1e-9), inner)
            ok &= ~crossing
        if room_of is not None:
            ri, rj = room_of[i], room_of[j]
            same = (ri == rj) | (ri < 0) | (rj < 0)
            near = (
                touching[np.maximum(ri, 0), np.maximum(rj, 0)] & (ri >= 0) & (rj >= 0)
                if touching is not None
                else np.zeros_like(same)
            )
            through = (
                shapely.intersects(segs, openings)
                if openings is not None and not openings.is_empty
                else np.zeros_like(same)
            )
            ok &= same | near | through
    return i[ok], j[ok], d[ok]


def _components(n: int, i: np.ndarray, j: np.ndarray) -> list[list[int]]:
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    adj = csr_matrix((np.ones(i.size), (i, j)), shape=(n, n))
    k, lab = connected_components(adj, directed=False)
    comps = [np.flatnonzero(lab == c).tolist() for c in range(k)]
    return sorted(comps, key=lambda c: (-len(c), c[0]))


def connecting_radius(n: int, i: np.ndarray, j: np.ndarray, d: np.ndarray) -> float:
    """The smallest distance at which the allowed pairs ``(i, j, d)`` connect as much as they
    can: the longest edge of their minimum spanning forest (0 for fewer than 2 nodes)."""
    if n < 2 or i.size == 0:
        return 0.0
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import minimum_spanning_tree

    w = np.maximum(d, 1e-12)  # a zero weight would be dropped as "no edge"
    mst = minimum_spanning_tree(csr_matrix((w, (i, j)), shape=(n, n)))
    return float(mst.data.max()) if mst.nnz else 0.0


def geometric_sensor_graph(
    positions: Mapping[str, tuple[float, float]],
    *,
    radius: float | None = None,
    walls: BaseGeometry | None = None,
    rooms: Mapping[str, BaseGeometry] | None = None,
    openings: Sequence[BaseGeometry] | BaseGeometry | None = None,
    touch_tol: float = 1e-6,
    join_components: bool = False,
) -> GeometricGraph:
    """The sensor graph of ``positions`` from geometry (module docstring).

    Parameters
    ----------
    positions : sensor id -> (x, y).
    radius : link sensors at most this far apart; ``None`` = the connecting distance.
    walls : geometry no edge may cross (polygons: their area; lines: the lines).
    rooms : room name -> polygon; sensors are placed in the first room containing them.
    openings : door geometries an edge between non-touching rooms may pass through.
    touch_tol : rooms closer than this share a boundary (a doorway is assumed).
    join_components : join what ``radius`` leaves apart by the shortest allowed pairs.
    """
    if radius is not None and not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"radius must be a positive number or None, got {radius!r}")
    nodes = tuple(positions)
    xy = np.array([positions[k] for k in nodes], dtype=float).reshape(-1, 2)
    n = len(nodes)
    room_of = touching = None
    if rooms:
        polys = list(rooms.values())
        room_of = np.full(n, -1, dtype=np.int64)
        for r, poly in enumerate(polys):
            inside = shapely.covers(poly, shapely.points(xy)) & (room_of < 0)
            room_of[inside] = r
        touching = np.array([[shapely.distance(a, b) <= touch_tol for b in polys] for a in polys], dtype=bool).reshape(
            len(polys), len(polys)
        )
    if openings is not None and not isinstance(openings, BaseGeometry):
        openings = shapely.union_all(list(openings)) if len(openings) else None
    i, j, d = _allowed_pairs(xy, walls, room_of, touching, openings)
    r = connecting_radius(n, i, j, d) if radius is None else float(radius)
    keep = d <= r * (1 + 1e-9) + 1e-12
    joins: list[tuple[str, str]] = []
    if join_components and n:
        lab = np.arange(n)
        for c, comp in enumerate(_components(n, i[keep], j[keep])):
            lab[comp] = c
        parent = list(range(int(lab.max()) + 1))

        def root(x: int) -> int:
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        for k in np.argsort(d, kind="stable"):  # Kruskal over the components (inherently sequential)
            a, b = root(int(lab[i[k]])), root(int(lab[j[k]]))
            if a != b and not keep[k]:
                parent[a] = b
                keep[k] = True
                joins.append((nodes[i[k]], nodes[j[k]]))
    i, j = i[keep], j[keep]
    comps = _components(n, i, j) if n else []
    edges = tuple(sorted((nodes[a], nodes[b]) for a, b in zip(i.tolist(), j.tolist())))
    how = (
        f"neighbours within {r:.3g}"
        + (" (the smallest distance that keeps the graph connected)" if radius is None else "")
        + (", no edge through a wall" if walls is not None else "")
        + (", rooms: same or touching room, or through an opening" if rooms else "")
        + (f", components joined by their {len(joins)} shortest allowed pairs" if join_components else "")
    )
    return GeometricGraph(nodes, edges, r, tuple(tuple(nodes[k] for k in c) for c in comps), how, tuple(sorted(joins)))
