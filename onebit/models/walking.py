"""Walking among obstacles: shortest paths in a polygonal free space and moving along them.

A motion model shared by the trackers (O'Kane's active trackers move along these paths,
section VII step 4) and the simulators (targets walk to random destinations), so neither
has to import the other.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from onebit.core.lazy import lazy_module

_csgraph = lazy_module("scipy.sparse.csgraph")


class ShortestPaths:
    """Shortest paths in a polygonal free space: a visibility graph on the obstacle vertices.

    The vertices of the free space's boundary rings, pushed ``margin`` away from the walls,
    are the graph nodes; two nodes are joined when the segment between them lies in the
    free space (``shapely.covers`` on all pairs at once). All-pairs distances and
    predecessors come from ``scipy.sparse.csgraph.shortest_path``. A query connects start
    and goal to the nodes they see (vectorised) and picks the best pair of entry and exit
    nodes in numpy.
    """

    def __init__(self, free_space: BaseGeometry, *, margin: float = 1e-3) -> None:
        self.free = free_space
        inner = free_space.buffer(-margin, join_style="mitre")
        pts = shapely.get_coordinates(shapely.boundary(inner))
        pts = np.unique(np.round(pts, 9), axis=0)
        pts = pts[shapely.covers(free_space, shapely.points(pts))]
        self.nodes = pts
        N = len(pts)
        i, j = np.triu_indices(N, 1)
        seg = shapely.linestrings(np.stack([pts[i], pts[j]], axis=1))
        vis = shapely.covers(free_space, seg)
        w = np.full((N, N), np.inf)
        d = np.hypot(*(pts[i] - pts[j]).T)
        w[i[vis], j[vis]] = d[vis]
        w[j[vis], i[vis]] = d[vis]
        from scipy.sparse import csr_matrix

        m = np.where(np.isfinite(w), w, 0.0)
        self.dist, self.pred = (
            _csgraph.shortest_path(csr_matrix(m), directed=False, return_predecessors=True)
            if N
            else (np.zeros((0, 0)), np.zeros((0, 0), int))
        )

    def _visible(self, p: np.ndarray) -> np.ndarray:
        if len(self.nodes) == 0:
            return np.zeros(0, dtype=bool)
        seg = shapely.linestrings(np.stack([np.broadcast_to(p, self.nodes.shape), self.nodes], axis=1))
        return shapely.covers(self.free, seg)

    def path(self, p, q) -> np.ndarray:
        """Waypoints ``(k, 2)`` from ``p`` to ``q`` (straight when visible); ``[p]`` if unreachable."""
        p, q = np.asarray(p, float), np.asarray(q, float)
        if shapely.covers(self.free, shapely.linestrings([p, q])):
            return np.array([p, q])
        vp, vq = self._visible(p), self._visible(q)
        if not vp.any() or not vq.any():
            return np.array([p])
        a, b = np.flatnonzero(vp), np.flatnonzero(vq)
        cost = (
            np.hypot(*(self.nodes[a] - p).T)[:, None]
            + self.dist[np.ix_(a, b)]
            + np.hypot(*(self.nodes[b] - q).T)[None, :]
        )
        ia, ib = np.unravel_index(np.argmin(cost), cost.shape)
        if not np.isfinite(cost[ia, ib]):
            return np.array([p])
        s, g = a[ia], b[ib]
        chain = [g]
        while chain[-1] != s:
            chain.append(self.pred[s, chain[-1]])
        return np.vstack([p, self.nodes[chain[::-1]], q])

    def length(self, p, q) -> float:
        w = self.path(p, q)
        return float(np.hypot(*np.diff(w, axis=0).T).sum()) if len(w) > 1 else (0.0 if np.allclose(p, q) else np.inf)


def advance(waypoints: np.ndarray, distance: float) -> np.ndarray:
    """The point ``distance`` along a polyline (its end when shorter)."""
    if len(waypoints) == 1:
        return waypoints[0]
    seg = np.diff(waypoints, axis=0)
    L = np.hypot(*seg.T)
    cum = np.r_[0.0, np.cumsum(L)]
    if distance >= cum[-1]:
        return waypoints[-1]
    k = int(np.searchsorted(cum, distance, side="right") - 1)
    u = (distance - cum[k]) / L[k] if L[k] > 0 else 0.0
    return waypoints[k] + u * seg[k]
