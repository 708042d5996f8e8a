"""The feasible target space F (Singh et al., section 3.2 and section 5.2).

Sensing model (two radii, Fig. 8): an on-sensor i says a target is within ``R_o`` of it, an
off-sensor j says no target is within ``R_i`` of it. Ideal sensing is ``R_i = R_o = R``::

    C_i^o = {x : |x - s_i| <= R_o,i}            (on-range)
    C_j^i = {x : |x - s_j| <  R_i,j}            (off-range, open)
    F     = (U_{i in I} C_i^o  -  U_{j in Z} C_j^i)  intersected with the site
            (when that is empty -- no on-sensor, e.g. a missed detection -- F is taken as the
            site minus the off-ranges: the instant then carries no positive information)
    g_i   = C_i^o - U_{j in Z} C_j^i             (sensor i's contribution; F = U_i g_i)

1-D (every proximity sensor has ``y == 0``): F and every ``g_i`` are exact unions of closed
intervals, computed with a sweep over the sorted break points (numpy, vectorised over
sensors). 2-D: F is rasterised on a grid of square cells (a cell is in F when its centre
is), the disk masks of all sensors are computed once and F for every instant is a matrix
product ``on @ outer_masks > 0`` and ``off @ inner_masks == 0``; its connected components
come from OpenCV (8-connectivity).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from onebit.core.config import MAX_GRID_CELLS, check_size
from onebit.core.lazy import lazy_module
from onebit.core.sensing import detection_regions
from onebit.trackers.clustertrack import kernels

cv2 = lazy_module("cv2")

#: Lengths below this (world units) are treated as empty.
EPS = 1e-9


@dataclass(frozen=True)
class SensorArray:
    """Positions ``(n, 2)``, inner radii ``(n,)`` and outer radii ``(n,)`` of the sensors."""

    ids: tuple[str, ...]
    xy: np.ndarray
    r_inner: np.ndarray
    r_outer: np.ndarray

    @property
    def is_1d(self) -> bool:
        """True when every sensor lies on the line ``y = 0`` (the site is a 1-D strip)."""
        return bool(len(self.ids)) and bool(np.all(self.xy[:, 1] == 0.0))

    @property
    def radius(self) -> float:
        """The nominal R: mean of ``(R_i + R_o) / 2`` (the paper's R for the PIR experiment)."""
        return float(np.mean((self.r_inner + self.r_outer) / 2.0)) if len(self.ids) else 1.0


def sensor_array(site) -> SensorArray:
    """The site's proximity sensors from their detection regions
    (:func:`onebit.core.sensing.detection_regions`): centre, ``R_i`` and ``R_o``."""
    regions = detection_regions(site)
    rs = [regions[p.id] for p in site.proximity_sensors]
    return SensorArray(
        tuple(r.sensor for r in rs),
        np.array([r.position for r in rs], dtype=float).reshape(-1, 2),
        np.array([r.inner_radius for r in rs], dtype=float),
        np.array([r.radius for r in rs], dtype=float),
    )


# --------------------------------------------------------------------------- 1-D intervals


def union_intervals(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Union of closed intervals ``[lo_k, hi_k]`` as sorted disjoint ``(m, 2)`` intervals.

    Sort by ``lo``; a new component starts where ``lo`` exceeds the running maximum of the
    ``hi`` before it (``np.maximum.accumulate``), so the union is one sort and one scan.
    """
    keep = hi - lo > -EPS
    lo, hi = lo[keep], hi[keep]
    if lo.size == 0:
        return np.zeros((0, 2))
    o = np.argsort(lo, kind="stable")
    lo, hi = lo[o], hi[o]
    run = np.maximum.accumulate(hi)
    start = np.r_[True, lo[1:] > run[:-1]]
    gid = np.cumsum(start) - 1
    out_lo = lo[start]
    out_hi = np.full(out_lo.size, -np.inf)
    np.maximum.at(out_hi, gid, hi)
    return np.c_[out_lo, out_hi]


def complement_intervals(iv: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """``[lo, hi]`` minus the union of the (open) disjoint sorted intervals ``iv``."""
    if iv.size == 0:
        return np.array([[lo, hi]])
    a = np.r_[lo, iv[:, 1]]
    b = np.r_[iv[:, 0], hi]
    a = np.clip(a, lo, hi)
    b = np.clip(b, lo, hi)
    keep = b - a >= 0.0
    return np.c_[a[keep], b[keep]]


def intersect_intervals(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairwise intersections of interval sets ``a (p, 2)`` and ``b (q, 2)``.

    Returns the non-empty pieces ``(r, 2)`` and, for each, the row of ``a`` it came from.
    """
    lo = np.maximum(a[:, None, 0], b[None, :, 0])
    hi = np.minimum(a[:, None, 1], b[None, :, 1])
    ok = hi - lo >= 0.0
    ia, _ = np.nonzero(ok)
    return np.c_[lo[ok], hi[ok]], ia


@dataclass(frozen=True)
class Feasible1D:
    """F at one instant in 1-D.

    components : ``(c, 2)`` sorted disjoint closed intervals whose union is F.
    pieces : ``(r, 2)`` the pieces of every g_i (sensor i's contribution, possibly several
        intervals under non-ideal sensing), ``piece_sensor`` the on-sensor (index into the
        sensor array) of each piece and ``piece_component`` the component holding it.
    """

    components: np.ndarray
    pieces: np.ndarray
    piece_sensor: np.ndarray
    piece_component: np.ndarray

    @property
    def size(self) -> float:
        """S_F: total length of F."""
        return float(np.sum(self.components[:, 1] - self.components[:, 0])) if self.components.size else 0.0

    def hulls(self) -> tuple[np.ndarray, np.ndarray]:
        """Per on-sensor with a non-empty g_i: its convex hull ``[min, max]`` and sensor index."""
        if self.pieces.size == 0:
            return np.zeros((0, 2)), np.zeros(0, dtype=np.int64)
        s, inv = np.unique(self.piece_sensor, return_inverse=True)
        lo = np.full(s.size, np.inf)
        hi = np.full(s.size, -np.inf)
        np.minimum.at(lo, inv, self.pieces[:, 0])
        np.maximum.at(hi, inv, self.pieces[:, 1])
        return np.c_[lo, hi], s

    def component_of(self, x: np.ndarray) -> np.ndarray:
        """Component index of each position, ``-1`` outside F (tolerance ``1e-6``)."""
        x = np.asarray(x, dtype=float)
        if self.components.size == 0:
            return np.full(x.shape, -1, dtype=np.int64)
        k = np.searchsorted(self.components[:, 0], x + 1e-6, side="right") - 1
        kk = np.clip(k, 0, len(self.components) - 1)
        inside = (k >= 0) & (x <= self.components[kk, 1] + 1e-6)
        return np.where(inside, kk, -1)


def feasible_1d(
    x: np.ndarray, on: np.ndarray, r_inner: np.ndarray, r_outer: np.ndarray, lo: float, hi: float
) -> Feasible1D:
    """F and the g_i at one instant from sensor positions ``x (n,)`` and readings ``on (n,)``.

    ``[lo, hi]`` is the site's extent along the line; F is clipped to it.
    """
    on = np.asarray(on, dtype=bool)
    off_iv = union_intervals(x[~on] - r_inner[~on], x[~on] + r_inner[~on])
    # R_i = 0 removes nothing (an open interval of length 0 is empty)
    off_iv = off_iv[off_iv[:, 1] - off_iv[:, 0] > EPS] if off_iv.size else off_iv
    free = complement_intervals(off_iv, lo, hi)
    idx = np.flatnonzero(on)
    c_on = np.c_[np.maximum(x[idx] - r_outer[idx], lo), np.minimum(x[idx] + r_outer[idx], hi)]
    c_on = c_on[c_on[:, 1] >= c_on[:, 0]] if c_on.size else c_on.reshape(0, 2)
    idx = idx[np.maximum(x[idx] - r_outer[idx], lo) <= np.minimum(x[idx] + r_outer[idx], hi)]
    pieces, ia = (
        intersect_intervals(c_on.reshape(-1, 2), free) if idx.size else (np.zeros((0, 2)), np.zeros(0, np.int64))
    )
    sensor = idx[ia] if idx.size else np.zeros(0, dtype=np.int64)
    # single points (a target exactly at distance R_o) have measure zero: dropped
    keep = pieces[:, 1] - pieces[:, 0] > EPS if pieces.size else np.zeros(0, dtype=bool)
    pieces, sensor = pieces[keep], sensor[keep]
    comps = union_intervals(pieces[:, 0], pieces[:, 1]) if pieces.size else np.zeros((0, 2))
    if comps.size == 0:
        # no on-sensor with a non-empty contribution: no positive information at this instant;
        # the targets are somewhere the off-sensors leave free (count bound 0)
        comps = free[free[:, 1] - free[:, 0] > EPS] if free.size else free.reshape(0, 2)
    f = Feasible1D(comps, pieces.reshape(-1, 2), sensor.astype(np.int64), np.zeros(len(pieces), dtype=np.int64))
    comp = f.component_of((pieces[:, 0] + pieces[:, 1]) / 2.0) if pieces.size else np.zeros(0, dtype=np.int64)
    return Feasible1D(comps, f.pieces, f.piece_sensor, comp)


def sample_intervals(iv: np.ndarray, n: int, rng: np.random.Generator, *, compiled: bool = False) -> np.ndarray:
    """``n`` points uniform on the union of disjoint intervals ``iv (c, 2)``.

    A uniform draw on ``[0, S_F)`` is mapped through the cumulative lengths (``compiled``: by
    :func:`onebit.trackers.clustertrack.kernels.map_intervals`, the same draws and points).
    """
    length = iv[:, 1] - iv[:, 0]
    total = float(length.sum())
    if n <= 0 or iv.size == 0:
        return np.zeros(0)
    if total <= EPS:  # degenerate F (single points): pick among them
        return iv[rng.integers(0, len(iv), size=n), 0]
    if compiled:
        return kernels.map_intervals(rng.random(n), np.ascontiguousarray(iv, dtype=np.float64), total)
    u = rng.random(n) * total
    cum = np.cumsum(length)
    k = np.minimum(np.searchsorted(cum, u, side="right"), len(iv) - 1)
    return iv[k, 0] + u - (cum[k] - length[k])


# --------------------------------------------------------------------------- 2-D raster


@dataclass(frozen=True)
class Raster:
    """A grid of square cells over the site's bounding box: centres ``(h*w, 2)``."""

    x0: float
    y0: float
    cell: float
    width: int
    height: int
    inside: np.ndarray  # (h*w,) bool, the cell centre is inside the site boundary

    def centres_of(self, k: np.ndarray) -> np.ndarray:
        """``(len(k), 2)`` centres of the cells with flat indices ``k``."""
        return _centres_of(self, np.asarray(k, dtype=np.int64))

    @property
    def centres(self) -> np.ndarray:
        j, i = np.meshgrid(np.arange(self.width), np.arange(self.height))
        return np.c_[self.x0 + (j.ravel() + 0.5) * self.cell, self.y0 + (i.ravel() + 0.5) * self.cell]


def make_raster(boundary, cell: float) -> Raster:
    import shapely

    minx, miny, maxx, maxy = boundary.bounds
    wide, high = max(1.0, np.ceil((maxx - minx) / cell)), max(1.0, np.ceil((maxy - miny) / cell))
    check_size(
        wide * high,
        MAX_GRID_CELLS,
        what=f"raster cells ({wide:,.0f} x {high:,.0f} of {cell:g})",
        field="[clustertrack] raster_per_r",
        hint="fewer cells per R",
    )
    w, h = int(wide), int(high)
    r = Raster(minx, miny, cell, w, h, np.ones(w * h, dtype=bool))
    c = r.centres
    return Raster(minx, miny, cell, w, h, shapely.contains_xy(boundary, c[:, 0], c[:, 1]))


def disk_masks(raster: Raster, xy: np.ndarray, radius: np.ndarray, *, closed: bool) -> np.ndarray:
    """``(n_sensors, cells)`` bool: cell centre within ``radius`` of each sensor."""
    check_size(
        float(len(xy)) * raster.width * raster.height,
        MAX_GRID_CELLS,
        what=f"sensor-cell pairs ({len(xy)} sensors x {raster.width * raster.height:,} raster cells)",
        field="[clustertrack] raster_per_r",
        hint="fewer cells per R",
    )
    c = raster.centres
    d2 = (c[None, :, 0] - xy[:, None, 0]) ** 2 + (c[None, :, 1] - xy[:, None, 1]) ** 2
    r2 = (radius**2)[:, None]
    return d2 <= r2 if closed else d2 < r2


def feasible_raster(on: np.ndarray, outer: np.ndarray, inner: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """F for every instant at once: ``on (T, n)`` readings -> ``(T, cells)`` bool.

    ``F = (on @ outer > 0) & (off @ inner == 0) & inside`` (counts via matrix products).
    """
    on = np.asarray(on, dtype=np.float32)
    hit = on @ outer.astype(np.float32) > 0.5
    cleared = (1.0 - on) @ inner.astype(np.float32) < 0.5
    f = hit & cleared & inside[None, :]
    # an instant with an empty F carries no positive information: the free space stands in
    empty = ~f.any(axis=1)
    f[empty] = (cleared & inside[None, :])[empty]
    return f


def raster_components(mask: np.ndarray, raster: Raster) -> tuple[int, np.ndarray]:
    """Connected components (OpenCV, 8-connectivity) of one F mask: ``(count, labels)``.

    ``labels`` is ``(cells,)`` int with 0 outside F and 1..count for the components.
    """
    img = mask.reshape(raster.height, raster.width).astype(np.uint8)
    n, lab = cv2.connectedComponents(img, connectivity=8)
    return int(n - 1), lab.ravel().astype(np.int64)


def sample_raster(mask: np.ndarray, raster: Raster, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniform on the F cells: a cell uniformly, then uniform inside it."""
    return sample_cells(np.flatnonzero(mask), raster, n, rng)


def sample_cells(cells: np.ndarray, raster: Raster, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniform on the raster cells ``cells`` (flat indices; same draws as
    :func:`sample_raster` on their mask): the cost grows with n and |F|, not the grid."""
    if n <= 0 or cells.size == 0:
        return np.zeros((0, 2))
    k = cells[rng.integers(0, cells.size, size=n)]
    c = _centres_of(raster, k)
    return c + (rng.random((n, 2)) - 0.5) * raster.cell


def sample_cell_centres(
    xy: np.ndarray, cell: float, n: int, rng: np.random.Generator, *, compiled: bool = False
) -> np.ndarray:
    """``n`` points uniform on the cells of centres ``xy (m, 2)``: the same draws as
    :func:`sample_cells` on those cells (a cell uniformly, then uniform inside it), with the
    centres looked up once per instant instead of recomputed per draw (``compiled``: the
    lookup and offsets in one pass, :func:`onebit.trackers.clustertrack.kernels.jitter_cells`;
    the same draws and points)."""
    if n <= 0 or len(xy) == 0:
        return np.zeros((0, 2))
    if compiled:
        k = rng.integers(0, len(xy), size=n)
        return kernels.jitter_cells(np.ascontiguousarray(xy, dtype=np.float64), k, rng.random((n, 2)), float(cell))
    c = xy[rng.integers(0, len(xy), size=n)]
    return c + (rng.random((n, 2)) - 0.5) * cell


def _centres_of(raster: Raster, k: np.ndarray) -> np.ndarray:
    i, j = np.divmod(k, raster.width)
    out = np.empty((k.size, 2))
    out[:, 0] = raster.x0 + (j + 0.5) * raster.cell
    out[:, 1] = raster.y0 + (i + 0.5) * raster.cell
    return out
