"""Active tracking with I-states (O'Kane, section VII): destinations, matching, shortest paths.

Each tracker, from its own I-state and what it knows of the other trackers' positions:

1. partitions the free space into **cells** -- maximal sets not crossed by any region
   boundary of its I-state (``shapely.polygonize`` of all boundaries) -- and bounds the
   number of targets in each cell, ``t(c) = max_i #{k : R^(i)_k covers c}`` (Fig. 5);
2. selects ``m`` destinations by a modified k-means over the cell centroids: greedy
   initialisation (a centre at the centroid of the largest contiguous set of cells with
   ``t(c) = t_max``, whose ``t`` is then decremented, ``m`` times) and weights
   ``w(c) = t(c) / a(c)^2`` (:func:`select_destinations`);
3. assigns trackers to destinations by a minimum-weight perfect matching on the complete
   bipartite graph whose weights are the *largest possible* tracker-destination distances
   (``scipy.optimize.linear_sum_assignment``);
4. moves along the shortest path among obstacles toward its own destination
   (:class:`ShortestPaths`, a visibility graph).

The paper says the weights are "included in the distance computation for moving the
cluster centers"; a per-observation factor on the distance does not change which centre is
nearest, so we read it as the weighted Lloyd update ``mu_j = sum_{c in C_j} w(c) x_c /
sum_{c in C_j} w(c)`` with assignment by Euclidean distance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from onebit.core.lazy import lazy_module
from onebit.models.walking import ShortestPaths, advance  # noqa: F401  (re-exported: the trackers move along them)
from onebit.trackers.istate.core import IState

nx = lazy_module("networkx")
_optimize = lazy_module("scipy.optimize")


# --------------------------------------------------------------------------- destination selection


@dataclass(frozen=True)
class Cells:
    """The partition of the free space by an I-state's region boundaries."""

    polygons: np.ndarray  # (C,) polygons
    centroids: np.ndarray  # (C, 2)
    area: np.ndarray  # (C,)
    bound: np.ndarray  # (C,) t(c)


def partition_cells(istate: IState, free_space: BaseGeometry) -> Cells:
    """Cells of ``free_space`` cut by every region boundary, and ``t(c)`` for each (Fig. 5).

    ``t(c) = max_i sum_k [R^(i)_k covers c]``, tested at a representative point of each
    cell (cells are not crossed by region boundaries), vectorised over elements, regions
    and cells.
    """
    lines = [shapely.boundary(free_space)]
    if istate.size:
        lines.extend(shapely.boundary(istate.regions.ravel()))
    noded = shapely.union_all(lines)
    polys = np.asarray(shapely.get_parts(shapely.polygonize(shapely.get_parts(noded))), dtype=object)
    rp = shapely.point_on_surface(polys)
    inside = shapely.covers(free_space, rp) & (shapely.area(polys) > 1e-12)
    polys, rp = polys[inside], rp[inside]
    xy = shapely.get_coordinates(rp)
    if istate.size:
        cov = shapely.intersects_xy(istate.regions[:, :, None], xy[None, None, :, 0], xy[None, None, :, 1])  # (E, n, C)
        bound = cov.sum(axis=1).max(axis=0)
    else:
        bound = np.zeros(len(polys), dtype=np.int64)
    return Cells(polys, shapely.get_coordinates(shapely.centroid(polys)), shapely.area(polys), bound.astype(np.int64))


def greedy_centres(cells: Cells, m: int) -> np.ndarray:
    """Greedy initialisation: ``m`` times, a centre at the (area-weighted) centroid of the
    largest contiguous collection of cells with ``t(c) = t_max`` (connected components of
    the cell adjacency graph, networkx), then those cells' ``t`` decremented."""
    C = len(cells.polygons)
    tree = shapely.STRtree(cells.polygons)
    a, b = tree.query(cells.polygons, predicate="intersects")
    keep = a < b
    shared = shapely.length(shapely.intersection(cells.polygons[a[keep]], cells.polygons[b[keep]])) > 0
    g = nx.Graph()
    g.add_nodes_from(range(C))
    g.add_edges_from(zip(a[keep][shared].tolist(), b[keep][shared].tolist()))
    t = cells.bound.copy()
    out = np.zeros((m, 2))
    for j in range(m):  # sequential: each centre changes the working t(c)
        tmax = t.max()
        top = np.flatnonzero(t == tmax)
        comps = [np.fromiter(c, dtype=np.int64) for c in nx.connected_components(g.subgraph(top.tolist()))]
        best = max(comps, key=lambda c: (cells.area[c].sum(), -c.min()))
        out[j] = (cells.centroids[best] * cells.area[best, None]).sum(axis=0) / cells.area[best].sum()
        t[best] -= 1
    return out


def weighted_kmeans(
    points: np.ndarray, weights: np.ndarray, centres: np.ndarray, *, iterations: int = 50
) -> np.ndarray:
    """Lloyd's algorithm with per-observation weights: assign each point to its nearest
    centre, move each centre to the weighted mean of its points (a centre whose points weigh
    nothing stays). Vectorised over points and centres; sequential over iterations."""
    c = centres.copy()
    for _ in range(iterations):
        d = np.hypot(*(points[:, None, :] - c[None, :, :]).transpose(2, 0, 1))
        lab = np.argmin(d, axis=1)
        W = np.zeros(len(c))
        np.add.at(W, lab, weights)
        S = np.zeros_like(c)
        np.add.at(S, lab, weights[:, None] * points)
        new = np.where(W[:, None] > 0, S / np.where(W > 0, W, 1.0)[:, None], c)
        if np.allclose(new, c):
            break
        c = new
    return c


def select_destinations(istate: IState, free_space: BaseGeometry, m: int) -> np.ndarray:
    """Destination selection (section VII-A): ``m`` points in the free space."""
    cells = partition_cells(istate, free_space)
    if len(cells.polygons) == 0:
        xy = np.asarray(free_space.representative_point().coords[0])
        return np.tile(xy, (m, 1))
    init = greedy_centres(cells, m)
    w = cells.bound / np.maximum(cells.area, 1e-12) ** 2
    c = weighted_kmeans(cells.centroids, w.astype(float), init)
    # a centre inside an obstacle moves to the nearest free point
    pts = shapely.points(c)
    outside = ~shapely.covers(free_space, pts)
    if outside.any():
        near = shapely.get_coordinates(shapely.shortest_line(free_space, pts[outside]))[1::2]
        c[outside] = near
    return c


def match_destinations(worst_distance: np.ndarray) -> np.ndarray:
    """Section VII-B: the minimum-weight perfect matching of trackers to destinations on the
    complete bipartite graph with weights = the largest possible distance
    (``worst_distance[j, d]``); returns the destination of each tracker."""
    r, c = _optimize.linear_sum_assignment(worst_distance)
    out = np.empty(worst_distance.shape[0], dtype=np.int64)
    out[r] = c
    return out


def worst_distances(possible: list[BaseGeometry], destinations: np.ndarray) -> np.ndarray:
    """Largest distance from each tracker's possible-position set to each destination:
    ``max_{p in P_j} |p - d|``, attained at a vertex of ``P_j`` (vectorised over vertices)."""
    out = np.zeros((len(possible), len(destinations)))
    for j, P in enumerate(possible):  # m is small
        v = shapely.get_coordinates(P)
        out[j] = np.hypot(*(v[:, None, :] - destinations[None, :, :]).transpose(2, 0, 1)).max(axis=0)
    return out


def performance(targets: np.ndarray, trackers: np.ndarray) -> np.ndarray:
    """Eq. (1): ``P_k = 1/(n k) sum_{i<=k} sum_l min_j |p_i(j) - q_i(l)|`` for every ``k``.

    ``targets (K, n, 2)``, ``trackers (K, m, 2)``; returns ``(K,)``."""
    d = np.hypot(*(targets[:, :, None, :] - trackers[:, None, :, :]).transpose(3, 0, 1, 2)).min(axis=2)  # (K, n)
    k = np.arange(1, len(d) + 1)
    return np.cumsum(d.sum(axis=1)) / (targets.shape[1] * k)
