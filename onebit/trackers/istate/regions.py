"""The I-state's representation and its regions' geometry (:mod:`onebit.trackers.istate.core`,
module docstring): :class:`IState`, the buffers that stay supersets (:func:`grow`,
:func:`shrink`, :func:`disk`), the over-approximating shapes (:func:`constrain`), the site's
scale and tolerance, and the normalised frame every run works in (:class:`SiteFrame`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

#: Region shapes: exact polygons, or the smallest axis-aligned rectangle / disk containing them.
SHAPES = ("exact", "rect", "disk")

#: Segments per quarter circle of every round buffer.
QUAD_SEGS = 4

#: Relative slack added to grown distances so round-off never excludes a reachable point.
_SLACK = 1e-9

#: Relative tolerance of the filter's geometric decisions (module docstring, "Units"): two
#: regions are compared to within ``delta = REL_TOL * L``, ``L`` the scale of the site
#: (:func:`site_scale`); areas to within ``REL_TOL * L^2``.
REL_TOL = 1e-9

#: Grid (world units) to which disk centres are snapped and radii rounded up.
DISK_GRID = 1e-6


@dataclass(frozen=True)
class IState:
    """An I-state in unordered union-of-products form (Eq. 3).

    ``regions`` is an ``(E, n)`` object array of shapely geometries: row ``i`` is element
    ``i``, representing ``U_tau R_tau(1) x ... x R_tau(n)``. ``E = 0`` is the empty set.
    """

    regions: np.ndarray

    def __post_init__(self) -> None:
        r = self.regions
        if not isinstance(r, np.ndarray) or r.ndim != 2 or r.dtype != object:
            raise ValueError(
                f"IState.regions must be an (E, n) object array, got {type(r).__name__} {getattr(r, 'shape', '')}"
            )

    @property
    def n(self) -> int:
        """Number of targets."""
        return self.regions.shape[1]

    @property
    def size(self) -> int:
        """Number of elements ``E``."""
        return self.regions.shape[0]

    @classmethod
    def initial(cls, space: BaseGeometry, n: int) -> IState:
        """The initial I-state ``eta_1 = W^n``: one element of ``n`` copies of ``W``."""
        if n < 1:
            raise ValueError(f"n = {n}; an I-state needs at least one target")
        return cls(_objects([[space] * n]))

    @classmethod
    def from_elements(cls, elements, n: int | None = None) -> IState:
        """From a list of elements, each a list of ``n`` geometries."""
        elements = list(elements)
        if not elements:
            return cls(np.empty((0, n or 0), dtype=object))
        return cls(_objects(elements))

    def total_area(self, within: BaseGeometry | None = None) -> float:
        """Area of the union of all regions (clipped to ``within``, e.g. the free space, since
        rectangles and disks may reach outside it): the footprint of the possible target positions."""
        if self.size == 0:
            return 0.0
        u = shapely.union_all(self.regions.ravel())
        return float(shapely.area(u if within is None else shapely.intersection(u, within)))


def _objects(rows) -> np.ndarray:
    rows = list(rows)
    out = np.empty((len(rows), len(rows[0]) if rows else 0), dtype=object)
    for i, row in enumerate(rows):
        out[i, :] = list(row)
    return out


# --------------------------------------------------------------------------- geometry helpers


def grow(geoms, distance, *, quad_segs: int = QUAD_SEGS):
    """``geoms (+) B(distance)``, a *superset* of the Minkowski sum with the closed disk.

    Shapely's round buffer is a polygon inscribed in the true offset curve; its chords are
    at least ``r cos(pi / (4 q))`` from the source, so buffering by ``r / cos(pi / (4 q))``
    contains every point within ``r``. ``distance`` may be an array (one per geometry).
    The slack against round-off, ``r (1 + 1e-9) + 1e-9 |x|_max`` (``|x|_max`` the largest
    coordinate magnitude of the geometry, :func:`_magnitude`), is relative: round-off of a
    coordinate is relative to its magnitude, and the result scales with the units.
    """
    d = np.asarray(distance, dtype=float)
    r = d / math.cos(math.pi / (4 * quad_segs)) * (1 + _SLACK) + _SLACK * _magnitude(geoms)
    return shapely.buffer(geoms, np.where(d > 0, r, 0.0), quad_segs=quad_segs)


def shrink(geoms, distance, *, quad_segs: int = QUAD_SEGS):
    """``geoms (-) B(distance)`` (erosion), a *subset* of the points at least ``distance``
    inside: the inward buffer by the circumscribing radius (see :func:`grow`)."""
    d = np.asarray(distance, dtype=float)
    r = d / math.cos(math.pi / (4 * quad_segs)) * (1 + _SLACK) + _SLACK * _magnitude(geoms)
    return shapely.buffer(geoms, -np.where(d > 0, r, 0.0), quad_segs=quad_segs)


def _magnitude(geoms) -> np.ndarray:
    """Largest absolute coordinate of each geometry (0 for an empty or missing one)."""
    b = np.abs(np.asarray(shapely.bounds(geoms), dtype=float))
    return np.nan_to_num(b.max(axis=-1, initial=0.0))


def site_scale(geoms) -> float:
    """The length scale ``L`` of a set of geometries (the free space, an I-state's regions):
    the largest of the width and height of their common bounding box and their largest
    absolute coordinate (round-off grows with it); 0 when all are empty.

    It scales with the units (``L`` in cm is 100 times ``L`` in m, to round-off), so every
    tolerance set relative to it (``REL_TOL * L``) decides the same way in any unit."""
    b = np.asarray(shapely.bounds(np.asarray(geoms, dtype=object).ravel()), dtype=float).reshape(-1, 4)
    b = b[~np.isnan(b).any(axis=1)]
    if len(b) == 0:
        return 0.0
    lo, hi = b[:, :2].min(axis=0), b[:, 2:].max(axis=0)
    return float(max(hi[0] - lo[0], hi[1] - lo[1], np.abs(lo).max(), np.abs(hi).max()))


def tolerance(geoms) -> float:
    """``delta = REL_TOL * L`` (:func:`site_scale`): the distance to within which the clean-up
    compares regions (:func:`covers_pairs`)."""
    return REL_TOL * site_scale(geoms)


def disk(center, radius: float, *, outer: bool = True, quad_segs: int = QUAD_SEGS):
    """A disk polygon: circumscribing the true disk (``outer``) or inscribed in it."""
    p = shapely.points(np.asarray(center, float))
    return grow(p, radius, quad_segs=quad_segs) if outer else shapely.buffer(p, radius, quad_segs=quad_segs)


def constrain(geoms, shape: str, *, quad_segs: int = QUAD_SEGS):
    """The smallest region of the range space ``shape`` containing each geometry (section VI-A.1).

    * ``exact``: unchanged;
    * ``rect``: the axis-aligned bounding box ``[min x, max x] x [min y, max y]``;
    * ``disk``: the minimum enclosing circle ``B(c, r)`` (shapely's
      ``minimum_bounding_circle``), its centre snapped to a ``DISK_GRID`` grid (absolute: in
      the stage's :class:`SiteFrame`, 1e-6 of the site's extent) and its radius
      rounded up by the snap distance (so equal disks get identical polygons and duplicates
      are found), drawn as a polygon circumscribing it.

    Empty geometries stay empty; a point or segment keeps a tiny positive extent so it is
    still contained.
    """
    if shape == "exact":
        return geoms
    g = np.asarray(geoms, dtype=object)
    empty = void(g)
    if shape == "rect":
        b = shapely.bounds(g)
        b = np.where(empty[..., None], 0.0, b)
        out = shapely.box(b[..., 0], b[..., 1], b[..., 2], b[..., 3])
    elif shape == "disk":
        xy = shapely.get_coordinates(shapely.centroid(shapely.minimum_bounding_circle(g[~empty])))
        r = shapely.minimum_bounding_radius(g[~empty])
        # snap centre to a grid and round the radius up (so equal disks compare equal)
        q = DISK_GRID
        cq = np.round(xy / q) * q
        rq = np.ceil((r + np.hypot(*(cq - xy).T)) / q) * q + q
        out = np.empty(g.shape, dtype=object)
        out[~empty] = grow(shapely.points(cq), rq, quad_segs=quad_segs)
        out[empty] = shapely.Polygon()
    else:
        raise ValueError(f"shape = {shape!r}; allowed: {list(SHAPES)}")
    return np.where(empty, shapely.Polygon(), out)


def void(geoms) -> np.ndarray:
    """Empty *or missing* (``None``, e.g. a box built from the NaN bounds of an empty
    geometry): a region representing the empty set. An element with such a region is empty
    and is dropped; a missing region must never reach a union (``R cup None = None``)."""
    return shapely.is_empty(geoms) | shapely.is_missing(geoms)


#: Grid of :class:`SiteFrame` coordinates and lengths, as a fraction of the site's extent
#: (about 1e-6: 30 micrometres in a 30 m room, far below any sensing region's accuracy).
FRAME_GRID = 2.0**-20


@dataclass(frozen=True)
class SiteFrame:
    """The site's normalised frame, ``x' = (x - origin) / scale``, inputs snapped to a grid of
    ``FRAME_GRID`` (module docstring, "Units").

    ``origin`` is the lower-left corner of the free space's bounding box and ``scale`` the
    larger of its width and height, so the site lies in ``[0, 1]^2`` whatever its units. The
    same site written in cm and in m has coordinates that differ only in their last bits
    (``100 x`` rounded, then divided by ``100 L`` rounded: a few units in the 53rd bit);
    rounded to a ``2^-20`` grid they are the same numbers -- unless one lies within those few
    bits of the middle between two grid points, probability ~2^-31 per coordinate -- and
    GEOS, given the same numbers, makes the same decisions. So the filter
    run on the snapped inputs is the same computation in every unit, bit for bit --
    including what no tolerance can fix: GEOS's buffer dropping an input vertex by an exact
    collinearity test, elements ordered by their WKB bytes, exact ties of the cap.

    Soundness: each snapped input *contains* the exact one (:meth:`outer`: snapped, then
    grown by one grid step ``q``, a mitre offset that holds every point within ``q`` of it, more
    than the ``q / sqrt(2)`` a vertex moves when snapped),
    each region a 0 clears is *inside* the exact one (:meth:`inner`), and each length is
    rounded up (:meth:`length`); the results are mapped back with :meth:`to_site`."""

    origin: tuple[float, float]
    scale: float

    @classmethod
    def of(cls, space: BaseGeometry) -> SiteFrame:
        """The frame of a free space (its bounding box)."""
        x0, y0, x1, y1 = shapely.bounds(space)
        scale = float(max(x1 - x0, y1 - y0))
        if not np.isfinite(scale) or scale <= 0:
            raise ValueError(f"SiteFrame: the free space has no extent (bounds {x0, y0, x1, y1})")
        return cls((float(x0), float(y0)), scale)

    def _snapped(self, geoms):
        o, L, q = np.asarray(self.origin), self.scale, FRAME_GRID
        return shapely.transform(geoms, lambda xy: np.round((xy - o) / L / q) * q)

    def outer(self, geoms):
        """Snapped geometries in the frame, each containing the exact one."""
        g = self._snapped(geoms)
        return shapely.buffer(g, np.where(void(g), 0.0, FRAME_GRID), join_style="mitre")

    def inner(self, geoms):
        """Snapped geometries in the frame, each inside the exact one (may be empty)."""
        g = self._snapped(geoms)
        return shapely.buffer(g, np.where(void(g), 0.0, -FRAME_GRID), join_style="mitre")

    def length(self, d):
        """Lengths in the frame, rounded to the grid and then up by one step (never shorter;
        0 stays 0)."""
        d = np.asarray(d, dtype=float)
        q = FRAME_GRID
        return np.where(d > 0, (np.round(d / self.scale / q) + 1) * q, 0.0)

    def to_site(self, geoms):
        """Geometries of the frame back in site units."""
        o, L = np.asarray(self.origin), self.scale
        return shapely.transform(geoms, lambda xy: xy * L + o)

    def xy_to_site(self, xy: np.ndarray) -> np.ndarray:
        """Points ``(..., 2)`` of the frame back in site units."""
        return np.asarray(xy, dtype=float) * self.scale + np.asarray(self.origin)
