"""Sensor characterisation (section V) and deployment (section VI) of Schiff & Goldberg.

A **sensor type** is a characterisation: sample points ``(u, v)`` in the sensor's own frame
(apex at the origin, looking along +u) with detection probabilities ``eta_j``
(P(S=1 | a stimulus at only that sample, B=0)), plus the false-positive rate ``h``,
``P(S=1 | B=1)`` (``p_fire_refractory``) and the debounce rules of its toggle log. Types come
from ``site.toml`` ``[sensor_types.<name>]`` tables or are built in:

* ``kind = "pir-triangle"`` -- the paper's PIR: an isosceles triangle with its apex at the
  sensor, axis along +u, half-angle ``fov/2`` and height ``range``, sampled every
  ``resolution`` (the paper: every two cells); ``eta = peak * (1 - falloff * d / range)``
  inside (``d`` = distance from the apex; ``falloff = 0`` is the perfect sensor, the
  imperfect one loses detection with distance), 0 outside;
* ``kind = "beam"`` -- the 10 x 1 x 1 optical beam: samples every ``resolution`` along +u
  from 0 to ``length`` on the axis, ``eta = peak``;
* ``kind = "grid"`` -- measured samples ``samples = [[u, v, eta], ...]``.

**Deployment** (section VI) rotates the samples by the sensor's heading and translates them to
its position; each sample gives its value to the world cell that contains it (the largest
value when several land in one cell). Every other cell inside the convex hull of the cells
with a non-zero value is filled by Shepard's inverse-distance weighting (power 2) over all
mapped samples; cells outside the hull get 0. With ``xi`` the number of cells with a
non-zero value::

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
import shapely.affinity

from onebit.datasets.site import MotionSensor, Site
from onebit.errors import SiteError

#: Keys of a ``[sensor_types.<name>]`` table (the reader's debounce keys included).
TYPE_KEYS = {
    "kind", "range", "fov", "length", "resolution", "peak", "falloff", "samples",
    "false_positive", "p_fire_refractory", "chatter_window", "min_on",
}  # fmt: skip

#: Built-in sensor types (world units = cells of size 1): the paper's perfect PIR and beam.
BUILTIN_TYPES: dict[str, dict] = {
    "pir": {"kind": "pir-triangle", "range": 8.0, "fov": 60.0, "resolution": 2.0},
    "pir-imperfect": {"kind": "pir-triangle", "range": 8.0, "fov": 60.0, "resolution": 2.0, "falloff": 0.6, "false_positive": 0.25},
    "beam": {"kind": "beam", "length": 10.0, "resolution": 1.0},
}

IDW_POWER = 2.0


@dataclass(frozen=True)
class SensorType:
    """A validated characterisation: samples in the sensor frame and the scalar rates."""

    name: str
    samples: np.ndarray  # (k, 3): u, v, eta
    false_positive: float = 0.0  # h
    p_fire_refractory: float = 1e-6  # P(S=1 | B=1), the paper's 10^-6


def sensor_type(name: str, table: dict | None = None, *, source: str = "site.toml") -> SensorType:
    """Build a :class:`SensorType` from a ``[sensor_types.<name>]`` table (or a built-in)."""
    if table is None:
        if name not in BUILTIN_TYPES:
            raise SiteError(
                f"unknown sensor type {name!r}: not in [sensor_types] and not built in ({sorted(BUILTIN_TYPES)})",
                file=source,
                field=f"sensor_types.{name}",
            )
        table = BUILTIN_TYPES[name]
    key = f"sensor_types.{name}"

    def err(k: str, reason: str) -> SiteError:
        return SiteError(reason, file=source, field=f"{key}.{k}")

    for k in table:
        if k not in TYPE_KEYS:
            raise err(k, f"unknown key; known keys: {sorted(TYPE_KEYS)}")

    def num(k: str, default: float, lo: float, hi: float | None = None, *, open_lo: bool = False) -> float:
        v = table.get(k, default)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise err(k, f"must be a finite number, got {v!r}")
        if v < lo or (open_lo and v == lo) or (hi is not None and v > hi):
            raise err(k, f"{v!r} outside {'(' if open_lo else '['}{lo}, {hi if hi is not None else 'inf'}]")
        return float(v)

    kind = table.get("kind", "pir-triangle")
    peak = num("peak", 1.0, 0.0, 1.0)
    res = num("resolution", 1.0, 0.0, open_lo=True)
    if kind == "pir-triangle":
        rng = num("range", 8.0, 0.0, open_lo=True)
        fov = num("fov", 60.0, 0.0, 179.0, open_lo=True)
        falloff = num("falloff", 0.0, 0.0, 1.0)
        half = math.tan(math.radians(fov) / 2) * rng
        us = np.arange(0.0, rng + res, res)
        vs = np.arange(-math.ceil(half / res) * res, half + res, res)
        u, v = (a.ravel() for a in np.meshgrid(us, vs, indexing="ij"))
        inside = (u <= rng + 1e-9) & (np.abs(v) <= u * math.tan(math.radians(fov) / 2) + 1e-9)
        d = np.hypot(u, v)
        eta = np.where(inside, peak * np.clip(1.0 - falloff * d / rng, 0.0, 1.0), 0.0)
        samples = np.c_[u, v, eta]
    elif kind == "beam":
        length = num("length", 10.0, 0.0, open_lo=True)
        u = np.arange(res / 2, length, res)
        samples = np.c_[u, np.zeros_like(u), np.full_like(u, peak)]
    elif kind == "grid":
        raw = table.get("samples")
        try:
            samples = np.asarray(raw, dtype=float).reshape(-1, 3)
        except (TypeError, ValueError):
            raise err("samples", "must be a list of [u, v, eta] triples") from None
        if len(samples) == 0 or not np.all(np.isfinite(samples)) or np.any((samples[:, 2] < 0) | (samples[:, 2] > 1)):
            raise err("samples", "needs at least one [u, v, eta] with finite u, v and 0 <= eta <= 1")
    else:
        raise err("kind", f"{kind!r} is not one of ['pir-triangle', 'beam', 'grid']")
    if not np.any(samples[:, 2] > 0):
        raise err("samples", "every eta is 0: the sensor can never detect")
    h = num("false_positive", 0.0, 0.0, 1.0)
    rho = num("p_fire_refractory", 1e-6, 0.0, 1.0)
    return SensorType(name, samples, h, rho)


@dataclass(frozen=True)
class WorldGrid:
    """The uniform world grid over the site's bounding box: ``nx`` x ``ny`` cells of ``cell``."""

    x0: float
    y0: float
    cell: float
    nx: int
    ny: int

    @classmethod
    def of_site(cls, site: Site, cell: float) -> "WorldGrid":
        minx, miny, maxx, maxy = site.boundary.bounds
        nx = max(1, math.ceil((maxx - minx) / cell - 1e-9))
        ny = max(1, math.ceil((maxy - miny) / cell - 1e-9))
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
                out[i] = g.x0 + ix.min() * g.cell, g.y0 + iy.min() * g.cell, g.x0 + (ix.max() + 1) * g.cell, g.y0 + (iy.max() + 1) * g.cell
        return out


def deploy_one(ms: MotionSensor, st: SensorType, grid: WorldGrid) -> tuple[np.ndarray, object]:
    """Section VI for one sensor: ``(ny, nx)`` grid of q_ij and the hull polygon (world)."""
    th = math.radians(ms.heading)
    c, s = math.cos(th), math.sin(th)
    u, v, eta = st.samples.T
    wx = ms.position[0] + c * u - s * v
    wy = ms.position[1] + s * u + c * v
    # round away the 1e-16 residue of cos/sin so a sample on a cell edge lands consistently
    ix, iy = grid.cell_of(np.round(wx, 9), np.round(wy, 9))
    ok = (ix >= 0) & (ix < grid.nx) & (iy >= 0) & (iy < grid.ny)
    q = np.zeros((grid.ny, grid.nx))
    has = np.zeros((grid.ny, grid.nx), dtype=bool)
    np.maximum.at(q, (iy[ok], ix[ok]), eta[ok])
    has[iy[ok], ix[ok]] = True
    cxs, cys = grid.centres()
    nz = q > 0
    if not nz.any():
        return q, shapely.Polygon()
    pts = shapely.multipoints(np.c_[cxs[nz], cys[nz]])
    hull = shapely.convex_hull(pts)
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
    cell_poly = shapely.box(-grid.cell / 2, -grid.cell / 2, grid.cell / 2, grid.cell / 2)
    footprint = shapely.union_all(
        [shapely.affinity.translate(cell_poly, x, y) for x, y in zip(cxs[q > 0], cys[q > 0])]
    )
    return q, shapely.convex_hull(footprint)


def deploy(site: Site, cell: float, types: dict[str, SensorType] | None = None) -> Deployment:
    """Deploy every motion sensor of ``site`` on the world grid of ``cell`` (section VI)."""
    grid = WorldGrid.of_site(site, cell)
    types = dict(types or {})
    qs, p0, rho, f, xi, hulls = [], [], [], [], [], []
    for ms in site.motion_sensors:
        if ms.type not in types:
            table = site.sensor_types.get(ms.type) if isinstance(site.sensor_types, dict) else None
            types[ms.type] = sensor_type(ms.type, table, source=site.source)
        st = types[ms.type]
        q, hull = deploy_one(ms, st, grid)
        n_nz = int((q > 0).sum())
        qs.append(q)
        xi.append(n_nz)
        p0.append(1.0 - (1.0 - st.false_positive) ** (1.0 / max(n_nz, 1)))
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
