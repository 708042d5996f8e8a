"""Sensor characterisation (section V) and deployment (section VI) of Schiff & Goldberg.

A **sensor type** is a characterisation: sample points ``(u, v)`` in the sensor's own frame
(apex at the origin, looking along +u) with detection probabilities ``eta_j``
(P(S=1 | a stimulus at only that sample, B=0)), plus the false-positive rate ``h``,
``P(S=1 | B=1)`` (``p_fire_refractory``) and the debounce rules of its toggle log. Types come
from ``site.toml`` ``[sensor_types.<name>]`` tables (lengths in the site's units) or are
built in (:data:`onebit.core.sensing.BUILTIN_TYPES`, metres converted to the site's units).
Their geometry (and its validation) is the base layer's, :func:`onebit.core.sensing.type_geometry`;
this module adds the probabilities:

* ``kind = "pir-triangle"`` -- the paper's PIR: an isosceles triangle with its apex at the
  sensor, axis along +u, half-angle ``fov/2`` and height ``range``, sampled every
  ``resolution`` (the paper: every two cells); ``eta = peak * (1 - falloff * d / range)``
  inside (``d`` = distance from the apex; ``falloff = 0`` is the perfect sensor, the
  imperfect one loses detection with distance), 0 outside;
* ``kind = "beam"`` -- the 10 x 1 x 1 optical beam: samples every ``resolution`` along +u
  from 0 to ``length`` (``round(width / resolution)`` rows across its ``width``, one on the
  axis by default), ``eta = peak``;
* ``kind = "grid"`` -- measured samples ``samples = [[u, v, eta], ...]``;
* a type that declares no geometry (only rates or debounce keys), or no type at all: the
  sensor detects with ``eta = peak`` everywhere in its detection region (below).

**Deployment** (section VI) rotates the samples by the sensor's heading and translates them to
its position; each sample gives its value to the world cell that contains it (the largest
value when several land in one cell). Every other cell inside the convex hull of the cells
with a non-zero value is filled by Shepard's inverse-distance weighting (power 2) over all
mapped samples; cells outside the hull get 0. This gives ``q^type_ij``.

**Restriction to the site's detection region.** The site may declare, for the sensor
itself, a world window ``W_i``: its ``fov`` polygon and/or the disk of its ``range``
(:attr:`onebit.core.sensing.DetectionRegion.window`). The intruder is uniform over the
cell it occupies, and a stimulus outside ``W_i`` is never seen, so the deployed value is
the characterisation averaged over the part of the cell inside the window::

    a_ij = |c_j cap W_i| / |c_j|                         (area fraction of cell j in W_i)
    q_ij = q^type_ij * a_ij                              (a_ij = 1 when no window is declared)
    q_ij = peak_i * a_ij                                 (no characterisation: uniform over W_i)

so a cell wholly inside the window keeps the characterisation, a cell outside it gets 0,
and the type's own extent (its triangle, beam or sample hull) is the support of
``q^type`` -- the detection region of :mod:`onebit.core.sensing` is ``W_i cap E_i``.
A sensor with neither window nor characterisation has no region: the base layer raises
:class:`~onebit.core.errors.SiteError` naming it, never a default.

With ``xi`` the number of cells with a non-zero value::

    q_ij = P(S_i = 1 | O_j = 1, B_i = 0)                 (the deployed grid)
    p0_i = P(S_i = 1 | O_j = 0, B_i = 0) = 1 - (1 - h)^(1 / xi)

so that the ``xi`` independent cells of the detection region give the paper's definition of
the false-positive rate, ``P(S_i = 1 | O_1 = ... = O_m = 0, B_i = 0) = 1 - (1 - p0_i)^xi = h``
(per sensor and iteration; cells outside the region do not influence the sensor, see
:func:`onebit.trackers.intruder.filter.log_p_silent`).

The world grid is 2-D (the floor layer): the intruder stays on the floor (section VII-B.1)
and its bounding prism is one layer high, so only the floor layer of a characterisation is
used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from onebit.core.config import MAX_GRID_CELLS, check_size
from onebit.core.errors import SiteError
from onebit.core.sensing import (
    BUILTIN_TYPES,
    GEOMETRY_KEYS,
    DetectionRegion,
    detection_regions,
    sensor_to_world,
    type_geometry,
    type_table,
)
from onebit.core.site import MotionSensor, Site

__all__ = [
    "BUILTIN_TYPES",
    "TYPE_KEYS",
    "SensorType",
    "NO_TYPE",
    "sensor_type",
    "WorldGrid",
    "Deployment",
    "characterisation_grid",
    "window_fraction",
    "deploy_one",
    "deploy",
    "box_cells",
    "log_p_silent",
    "sensor_likelihood",
    "log_weights",
    "PROB_FLOOR",
    "CHUNK",
    "ToggleEdges",
    "hold_samples",
    "pir_on",
    "hold_on",
    "toggle_edges",
    "keep_bursts",
]

#: Keys of a ``[sensor_types.<name>]`` table: geometry, rates and the reader's debounce keys.
TYPE_KEYS = GEOMETRY_KEYS | {
    "peak",
    "falloff",
    "false_positive",
    "p_fire_refractory",
    "chatter_window",
    "min_on",
    "signal",
    "ignore",
}

IDW_POWER = 2.0


@dataclass(frozen=True, eq=False)
class SensorType:
    """A validated characterisation: samples in the sensor frame and the scalar rates.

    ``samples`` is ``(k, 3)`` (u, v, eta), or ``None`` for a type without geometry: the
    sensor then detects with ``peak`` everywhere in its detection region.
    """

    name: str | None
    samples: np.ndarray | None  # (k, 3): u, v, eta
    false_positive: float = 0.0  # h
    p_fire_refractory: float = 1e-6  # P(S=1 | B=1), the paper's 10^-6
    peak: float = 1.0


#: The characterisation of a sensor that declares no type: perfect detection in its region.
NO_TYPE = SensorType(None, None)


def sensor_type(name: str, table: dict | None = None, *, source: str = "site.toml", units: str = "m") -> SensorType:
    """Build a :class:`SensorType` from a ``[sensor_types.<name>]`` table (site units) or,
    without a table, the built-in type ``name`` (converted to ``units``)."""
    if table is None:
        table = type_table(name, None, units=units, source=source)
    key = f"sensor_types.{name}"

    def err(k: str, reason: str) -> SiteError:
        return SiteError(reason, file=source, field=f"{key}.{k}")

    for k in table:
        if k not in TYPE_KEYS:
            raise err(k, f"unknown key; known keys: {sorted(TYPE_KEYS)}")

    def num(k: str, default: float, lo: float, hi: float | None = None) -> float:
        v = table.get(k, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise err(k, f"must be a finite number, got {v!r}")
        if v < lo or (hi is not None and v > hi):
            raise err(k, f"{v!r} outside [{lo}, {hi if hi is not None else 'inf'}]")
        return float(v)

    peak = num("peak", 1.0, 0.0, 1.0)
    falloff = num("falloff", 0.0, 0.0, 1.0)
    h = num("false_positive", 0.0, 0.0, 1.0)
    rho = num("p_fire_refractory", 1e-6, 0.0, 1.0)
    geo = type_geometry(name, table, units=units, source=source)
    if geo is None:
        if peak <= 0:
            raise err("peak", "is 0: the sensor can never detect")
        return SensorType(name, None, h, rho, peak)
    res = geo.resolution
    if geo.kind == "pir-triangle":
        rng, tan_half = geo.range, math.tan(math.radians(geo.fov) / 2)
        half = tan_half * rng
        us = np.arange(0.0, rng + res, res)
        vs = np.arange(-math.ceil(half / res) * res, half + res, res)
        u, v = (a.ravel() for a in np.meshgrid(us, vs, indexing="ij"))
        inside = (u <= rng + 1e-9 * rng) & (np.abs(v) <= u * tan_half + 1e-9 * rng)
        d = np.hypot(u, v)
        eta = np.where(inside, peak * np.clip(1.0 - falloff * d / rng, 0.0, 1.0), 0.0)
        samples = np.c_[u, v, eta]
    elif geo.kind == "beam":
        u = np.arange(res / 2, geo.length, res)
        n_v = max(1, round(geo.width / res))
        v = (np.arange(n_v) - (n_v - 1) / 2) * (geo.width / n_v)
        uu, vv = (a.ravel() for a in np.meshgrid(u, v, indexing="ij"))
        samples = np.c_[uu, vv, np.full_like(uu, peak)]
    elif geo.kind == "polygon":  # every grid point of the footprint, at the peak (one at its centroid if it is tiny)
        samples = _footprint_samples(geo.extent, res, peak)
    else:
        samples = geo.samples
    if not np.any(samples[:, 2] > 0):
        raise err("samples", "every eta is 0: the sensor can never detect")
    return SensorType(name, samples, h, rho, peak)


def _footprint_samples(extent, res: float, peak: float) -> np.ndarray:
    """``(k, 3)`` samples (u, v, ``peak``) at the points of a ``res`` grid inside ``extent``
    (sensor frame); the centroid alone when no grid point falls inside."""
    minx, miny, maxx, maxy = extent.bounds
    us = np.arange(math.floor(minx / res) * res, maxx + res / 2, res)
    vs = np.arange(math.floor(miny / res) * res, maxy + res / 2, res)
    u, v = (a.ravel() for a in np.meshgrid(us, vs, indexing="ij"))
    inside = shapely.contains_xy(extent, u, v)
    if not inside.any():
        c = extent.centroid
        return np.array([[c.x, c.y, peak]])
    return np.c_[u[inside], v[inside], np.full(int(inside.sum()), peak)]


@dataclass(frozen=True)
class WorldGrid:
    """The uniform world grid over the site's bounding box: ``nx`` x ``ny`` cells of ``cell``."""

    x0: float
    y0: float
    cell: float
    nx: int
    ny: int

    @classmethod
    def of_site(cls, site: Site, cell: float, *, maps: int = 1) -> WorldGrid:
        """The grid of ``cell`` over ``site``; ``maps`` arrays of its size will be made (one per
        sensor): more than :data:`~onebit.core.config.MAX_GRID_CELLS` cells in all is a
        :class:`~onebit.core.errors.ConfigError` naming the cell size."""
        minx, miny, maxx, maxy = site.boundary.bounds
        wide, high = (maxx - minx) / cell - 1e-9, (maxy - miny) / cell - 1e-9
        check_size(
            max(1.0, math.ceil(wide)) * max(1.0, math.ceil(high)) * max(maps, 1),
            MAX_GRID_CELLS,
            what=f"grid cells ({wide:,.0f} x {high:,.0f} cells of {cell:g} site units x {max(maps, 1)} sensor maps)",
            field=f"cell = {cell:g}",
            hint="a larger cell",
        )
        nx = max(1, math.ceil(wide))
        ny = max(1, math.ceil(high))
        return cls(float(minx), float(miny), float(cell), nx, ny)

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """``(ny, nx)`` arrays of cell-centre x and y."""
        cx = self.x0 + (np.arange(self.nx) + 0.5) * self.cell
        cy = self.y0 + (np.arange(self.ny) + 0.5) * self.cell
        return np.meshgrid(cx, cy)

    def cell_of(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (
            np.floor((np.asarray(x) - self.x0) / self.cell).astype(np.int64),
            np.floor((np.asarray(y) - self.y0) / self.cell).astype(np.int64),
        )


@dataclass(frozen=True)
class Deployment:
    """Every sensor of a site deployed on one world grid (arrays over sensors i and cells)."""

    ids: tuple[str, ...]
    grid: WorldGrid
    q: np.ndarray  # (n, ny, nx) P(S_i=1 | O_j=1, B_i=0)
    p0: np.ndarray  # (n,) P(S_i=1 | O_j=0, B_i=0)
    rho: np.ndarray  # (n,) P(S_i=1 | B_i=1)
    refractory: np.ndarray  # (n,) f_i seconds
    xi: np.ndarray  # (n,) cells with q > 0
    hulls: tuple  # shapely polygons: convex hull of each sensor's non-zero cells (world)

    def cell_bounds(self) -> np.ndarray:
        """``(n, 4)`` world bounds (x0, y0, x1, y1) of each sensor's non-zero cells (empty: inverted)."""
        g = self.grid
        out = np.tile([np.inf, np.inf, -np.inf, -np.inf], (len(self.ids), 1))
        for i in range(len(self.ids)):  # one entry per sensor
            iy, ix = np.nonzero(self.q[i])
            if len(ix):
                out[i] = (
                    g.x0 + ix.min() * g.cell,
                    g.y0 + iy.min() * g.cell,
                    g.x0 + (ix.max() + 1) * g.cell,
                    g.y0 + (iy.max() + 1) * g.cell,
                )
        return out


def characterisation_grid(ms: MotionSensor, st: SensorType, grid: WorldGrid) -> np.ndarray:
    """Section VI for one sensor: the ``(ny, nx)`` grid ``q^type_ij`` of its characterisation
    (samples mapped to cells, IDW fill inside the hull of the non-zero cells, 0 outside)."""
    u, v, eta = st.samples.T
    wxy = sensor_to_world(np.c_[u, v], ms.position, ms.heading)
    # round away the 1e-16 residue of cos/sin so a sample on a cell edge lands consistently
    ix, iy = grid.cell_of(np.round(wxy[:, 0], 9), np.round(wxy[:, 1], 9))
    ok = (ix >= 0) & (ix < grid.nx) & (iy >= 0) & (iy < grid.ny)
    q = np.zeros((grid.ny, grid.nx))
    has = np.zeros((grid.ny, grid.nx), dtype=bool)
    np.maximum.at(q, (iy[ok], ix[ok]), eta[ok])
    has[iy[ok], ix[ok]] = True
    cxs, cys = grid.centres()
    nz = q > 0
    if not nz.any():
        return q
    hull = shapely.convex_hull(shapely.multipoints(np.c_[cxs[nz], cys[nz]]))
    # cells whose centre is in the hull (a buffer keeps the degenerate hull of a line of cells)
    in_hull = shapely.intersects_xy(hull.buffer(1e-6 * grid.cell), cxs, cys)
    fill = in_hull & ~has
    if fill.any():
        # Shepard's IDW over the mapped samples (their cell centres): w = 1 / d^p
        sx, sy = cxs[has], cys[has]
        sv = q[has]
        d2 = (cxs[fill][:, None] - sx[None, :]) ** 2 + (cys[fill][:, None] - sy[None, :]) ** 2
        w = 1.0 / np.power(d2, IDW_POWER / 2)
        q[fill] = (w * sv[None, :]).sum(axis=1) / w.sum(axis=1)
    q[~in_hull] = 0.0
    return q


def window_fraction(grid: WorldGrid, window) -> np.ndarray:
    """``(ny, nx)`` ``a_ij = |c_j cap W| / |c_j|``: the fraction of each cell inside the window
    polygon ``W`` (vectorised over the cells under ``W``'s bounding box; 0 elsewhere)."""
    a = np.zeros((grid.ny, grid.nx))
    if window is None or window.is_empty:
        return a
    c = grid.cell
    minx, miny, maxx, maxy = window.bounds
    ix0, ix1 = (
        int(np.clip(k, 0, grid.nx)) for k in (math.floor((minx - grid.x0) / c), math.ceil((maxx - grid.x0) / c))
    )
    iy0, iy1 = (
        int(np.clip(k, 0, grid.ny)) for k in (math.floor((miny - grid.y0) / c), math.ceil((maxy - grid.y0) / c))
    )
    if ix1 <= ix0 or iy1 <= iy0:
        return a
    ix, iy = np.meshgrid(np.arange(ix0, ix1), np.arange(iy0, iy1))
    x0, y0 = grid.x0 + ix * c, grid.y0 + iy * c
    boxes = shapely.box(x0, y0, x0 + c, y0 + c)
    a[iy0:iy1, ix0:ix1] = np.clip(shapely.area(shapely.intersection(boxes, window)) / (c * c), 0.0, 1.0)
    return a


def deploy_one(
    ms: MotionSensor, st: SensorType, grid: WorldGrid, region: DetectionRegion | None = None
) -> tuple[np.ndarray, object]:
    """One sensor: ``(ny, nx)`` grid of ``q_ij`` and the convex hull (world) of its non-zero
    cells. ``q_ij = q^type_ij a_ij`` with the window of ``region`` (module docstring)."""
    window = region.window if region is not None else None
    if st.samples is None:
        if window is None:
            raise SiteError(
                f"sensor {ms.id!r} has neither a characterisation nor a detection window",
                field=f"motion_sensors ({ms.id!r})",
            )
        q = st.peak * window_fraction(grid, window)
    else:
        q = characterisation_grid(ms, st, grid)
        if window is not None:
            q = q * window_fraction(grid, window)
    nz = q > 0
    if not nz.any():
        return q, shapely.Polygon()
    cxs, cys = grid.centres()
    h = grid.cell / 2
    footprint = shapely.union_all(shapely.box(cxs[nz] - h, cys[nz] - h, cxs[nz] + h, cys[nz] + h))
    return q, shapely.convex_hull(footprint)


def deploy(
    site: Site, cell: float, types: dict[str, SensorType] | None = None, *, false_alarm: float = 0.0
) -> Deployment:
    """Deploy every motion sensor of ``site`` on the world grid of ``cell`` (section VI),
    each restricted to its detection region (:func:`onebit.core.sensing.detection_regions`;
    a sensor without a usable region raises :class:`SiteError` naming it).

    ``false_alarm`` is the h of a sensor whose characterisation does not state one: no type,
    or a ``[sensor_types]`` table of the site without ``false_positive``. The built-in types
    keep their own (the paper's simulated sensors)."""
    grid = WorldGrid.of_site(site, cell, maps=len(site.motion_sensors))
    regions = detection_regions(site)
    types = dict(types or {})
    tables = site.sensor_types if isinstance(site.sensor_types, dict) else {}
    qs, p0, rho, f, xi, hulls = [], [], [], [], [], []
    for i, ms in enumerate(site.motion_sensors):  # one grid per sensor
        if ms.type is None:
            st = NO_TYPE
        else:
            if ms.type not in types:
                table = type_table(
                    ms.type,
                    tables,
                    units=site.units,
                    source=site.source,
                    field=f"motion_sensors[{i}] (id {ms.id!r}).type",
                )
                types[ms.type] = sensor_type(ms.type, table, source=site.source, units=site.units)
            st = types[ms.type]
        q, hull = deploy_one(ms, st, grid, regions[ms.id])
        n_nz = int((q > 0).sum())
        qs.append(q)
        xi.append(n_nz)
        h = st.false_positive
        if ms.type is None or (ms.type in tables and "false_positive" not in tables[ms.type]):
            h = false_alarm  # the sensor's characterisation says nothing: the caller's default
        p0.append(1.0 - (1.0 - h) ** (1.0 / max(n_nz, 1)))
        rho.append(st.p_fire_refractory)
        f.append(ms.refractory)
        hulls.append(hull)
    n = len(qs)
    return Deployment(
        ids=tuple(m.id for m in site.motion_sensors),
        grid=grid,
        q=np.stack(qs) if n else np.zeros((0, grid.ny, grid.nx)),
        p0=np.asarray(p0, float),
        rho=np.asarray(rho, float),
        refractory=np.asarray(f, float),
        xi=np.asarray(xi, np.int64),
        hulls=tuple(hulls),
    )


# --------------------------------------------------------------------------- observation model (VII-B.2)

PROB_FLOOR = 1e-12
#: Particles per chunk of the likelihood (bounds the (n, chunk, K) temporaries).
CHUNK = 1 << 15


def box_cells(x: np.ndarray, y: np.ndarray, grid: WorldGrid, half_w: float, half_d: float):
    """Cells touched by the bounding box centred on each particle and the covered fractions.

    Returns ``(iy, ix, V)``, each ``(N, K)``: cell indices (clipped into the grid) and
    ``V_k(x)`` = covered area / cell area (0 for cells outside the grid).
    """
    c = grid.cell
    kx = int(math.ceil(2 * half_w / c)) + 1
    ky = int(math.ceil(2 * half_d / c)) + 1
    ix0 = np.floor((x - half_w - grid.x0) / c).astype(np.int64)
    iy0 = np.floor((y - half_d - grid.y0) / c).astype(np.int64)
    ix = ix0[:, None] + np.arange(kx)[None, :]  # (N, kx)
    iy = iy0[:, None] + np.arange(ky)[None, :]  # (N, ky)
    left = grid.x0 + ix * c
    bottom = grid.y0 + iy * c
    ox = np.clip(np.minimum(x[:, None] + half_w, left + c) - np.maximum(x[:, None] - half_w, left), 0.0, c) / c
    oy = np.clip(np.minimum(y[:, None] + half_d, bottom + c) - np.maximum(y[:, None] - half_d, bottom), 0.0, c) / c
    ox = np.where((ix >= 0) & (ix < grid.nx), ox, 0.0)
    oy = np.where((iy >= 0) & (iy < grid.ny), oy, 0.0)
    V = (oy[:, :, None] * ox[:, None, :]).reshape(len(x), -1)
    IY = np.broadcast_to(np.clip(iy, 0, grid.ny - 1)[:, :, None], (len(x), ky, kx)).reshape(len(x), -1)
    IX = np.broadcast_to(np.clip(ix, 0, grid.nx - 1)[:, None, :], (len(x), ky, kx)).reshape(len(x), -1)
    return IY, IX, V


def log_p_silent(x: np.ndarray, y: np.ndarray, dep: Deployment, half_w: float, half_d: float) -> np.ndarray:
    """``(n, N)`` log P(S_i = 0 | x, B_i = 0) = log prod_{k in R_i} L(1 - p0_i, 1 - q_ik, V_k(x)).

    ``R_i`` = the ``xi_i`` cells with ``q_ik > 0``. Sensor by sensor (a loop over sensors,
    vectorised over particles): only particles whose box reaches the bounding box of the
    sensor's non-zero cells are computed; for the others no touched cell is in ``R_i`` and
    the value is exactly ``xi_i log(1 - p0_i) = log(1 - h_i)``.
    """
    n = len(dep.ids)
    out = np.empty((n, len(x)))
    if n == 0:
        return out
    g = dep.grid
    log_a = np.log1p(-np.minimum(dep.p0, 1 - PROB_FLOOR))  # (n,)
    out[:] = (dep.xi * log_a)[:, None]
    qf = dep.q.reshape(n, -1)
    bbox = dep.cell_bounds()  # (n, 4): x0, y0, x1, y1 of the non-zero cells
    for s in range(0, len(x), CHUNK):
        xs, ys = x[s : s + CHUNK], y[s : s + CHUNK]
        iy, ix, V = box_cells(xs, ys, g, half_w, half_d)
        flat = iy * g.nx + ix
        for i in range(n):
            bx0, by0, bx1, by1 = bbox[i]
            sel = np.flatnonzero((xs + half_w > bx0) & (xs - half_w < bx1) & (ys + half_d > by0) & (ys - half_d < by1))
            if sel.size == 0:
                continue
            p0 = dep.p0[i]
            qk = qf[i][flat[sel]]  # (c, K)
            q = np.maximum(qk, p0)
            L = (1.0 - p0) - V[sel] * (q - p0)  # L(1 - p0, 1 - q, V)
            np.maximum(L, PROB_FLOOR, out=L)
            # touched cells of R_i replace their (1 - p0) factor by L; cells outside R_i give 1.
            # (A touched cell clipped in from outside the grid has V = 0, so L = 1 - p0 and the
            # replacement changes nothing.)
            ratio = np.where(qk > 0, L / math.exp(log_a[i]), 1.0)
            out[i, s + sel] = dep.xi[i] * log_a[i] + np.log(ratio).sum(axis=1)
    return out


def sensor_likelihood(
    x: np.ndarray,
    y: np.ndarray,
    fired: np.ndarray,
    blind: np.ndarray,
    dep: Deployment,
    half_w: float,
    half_d: float,
) -> np.ndarray:
    """``(n, N)`` P(S_i = s_i | X = x) for every sensor and particle (section VII-B.2).

    ``fired`` and ``blind`` are ``(n,)`` booleans (S_i and B_i of this iteration). A blind
    sensor's row is ``rho_i`` (fired) or ``1 - rho_i`` (silent) for every particle.
    """
    p_silent = np.exp(log_p_silent(x, y, dep, half_w, half_d))
    live = np.where(fired[:, None], 1.0 - p_silent, p_silent)
    refr = np.where(fired, dep.rho, 1.0 - dep.rho)[:, None]
    return np.clip(np.where(blind[:, None], refr, live), PROB_FLOOR, 1.0)


def log_weights(x, y, fired, blind, dep, half_w, half_d) -> np.ndarray:
    """``(N,)`` log P(E | x) = sum_i log P(S_i = s_i | x); blind sensors add a constant and are left out."""
    live = ~blind
    if not live.any():
        return np.zeros(len(x))
    sub = Deployment(
        tuple(np.asarray(dep.ids)[live]),
        dep.grid,
        dep.q[live],
        dep.p0[live],
        dep.rho[live],
        dep.refractory[live],
        dep.xi[live],
        (),
    )
    ls = log_p_silent(x, y, sub, half_w, half_d)
    f = fired[live][:, None]
    p_fire = -np.expm1(ls)
    logp = np.where(f, np.log(np.clip(p_fire, PROB_FLOOR, 1.0)), np.maximum(ls, math.log(PROB_FLOOR)))
    return logp.sum(axis=0)


# --------------------------------------------------------------------------- the toggle log
# What a PIR writes, sampled on a regular clock: a detection holds it on for ``hold`` samples,
# its log holds the on and off edges, and a lost packet loses a whole on-burst. The simulators
# (:mod:`onebit.datasets.hallway_sim`, :mod:`onebit.datasets.home_sim`) sense with it.


@dataclass(frozen=True)
class ToggleEdges:
    """The toggles of ``s`` PIRs over ``n`` samples, one entry per edge, ordered by
    ``(sample, sensor)``.

    ``sample`` is the index of the first sample in the new state (``n`` for an off edge after
    the last sample), ``sensor`` the PIR's column, ``value`` ``True`` for an on edge; ``burst``
    is one id per on-burst, shared by its on edge and the off edge that ends it.
    """

    sample: np.ndarray  # (e,) int
    sensor: np.ndarray  # (e,) int
    value: np.ndarray  # (e,) bool
    burst: np.ndarray  # (e,) int


def hold_samples(hold_s: float, rate_hz: float) -> int:
    """Samples a detection holds the PIR on: ``hold_s`` at ``rate_hz``, at least one."""
    return max(1, int(round(hold_s * rate_hz)))


def pir_on(sample: np.ndarray, detected: np.ndarray, n: int, hold: int) -> np.ndarray:
    """``(n, s)`` on-states of ``s`` PIRs over ``n`` samples, from detections of bodies.

    ``detected`` is ``(m, s)``: row ``r`` (a body at sample ``sample[r]``) detected by sensor
    ``j``; a sample with any detection is a trigger (:func:`hold_on`).
    """
    hit = np.zeros((n, detected.shape[1]), bool)
    rows, cols = np.nonzero(detected)
    hit[sample[rows], cols] = True
    return hold_on(hit, hold)


def hold_on(hit: np.ndarray, hold: int) -> np.ndarray:
    """``(n, s)`` on-states of PIRs triggered at ``hit`` (``(n, s)`` bool) that stay on ``hold``
    samples (:func:`hold_samples`): sensor ``j`` is on at sample ``k`` when it was triggered in
    samples ``k - hold + 1 .. k``::

        on[k, j] = OR_{k - hold < k' <= k} hit[k', j]
    """
    n, s = hit.shape
    csum = np.cumsum(np.vstack([np.zeros((1, s), np.int64), hit.astype(np.int64)]), axis=0)
    lo = np.maximum(np.arange(n) - hold + 1, 0)
    return (csum[np.arange(n) + 1] - csum[lo]) > 0


def toggle_edges(on: np.ndarray) -> ToggleEdges:
    """The on and off edges of ``(n, s)`` on-states (every PIR off before and after them)."""
    n, s = on.shape
    padded = np.vstack([np.zeros((1, s), bool), on, np.zeros((1, s), bool)])
    sample, sensor = np.nonzero(padded[1:] != padded[:-1])
    value = padded[1:][sample, sensor]
    # bursts: number the on edges of each sensor in time; an off edge keeps its on edge's number
    burst = np.zeros(len(sample), np.int64)
    order = np.lexsort((sample, sensor))
    burst[order] = np.cumsum(value[order]) + sensor[order] * n
    return ToggleEdges(sample, sensor, value, burst)


def keep_bursts(burst: np.ndarray, drop: float, rng: np.random.Generator) -> np.ndarray:
    """``(e,)`` booleans: the edges kept when each whole on-burst (its on and its off edge) is
    lost with probability ``drop``. One draw per burst, in burst-id order, even when
    ``drop`` is 0 (the generator's stream does not depend on ``drop``)."""
    ids, inverse = np.unique(burst, return_inverse=True)
    return (rng.random(len(ids)) >= drop)[inverse]
