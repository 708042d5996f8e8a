"""O'Kane's set-based information states: the unordered union-of-products filter.

An I-state is a set of target states ``eta subset W^n`` of ``n`` indistinguishable point
targets. By Lemma 3 every reachable I-state has the *unordered union-of-products* form (Eq. 3)

    eta = U_i U_{tau in S_n} R^(i)_tau(1) x ... x R^(i)_tau(n),

so it is stored as a set of **elements** ``i``, each an unordered collection of ``n`` planar
**regions** ``R^(i)_1..R^(i)_n`` (shapely geometry). :class:`IState` holds them as an
``(E, n)`` object array, so every geometric step is one call of shapely's vectorised
functions over all ``E * n`` regions (or all ``E * E * n * n`` region pairs).

Operations (each named after the paper's step):

* :func:`forward_project` -- motion update, ``R <- F(R) = (R (+) B(s_tgt)) cap W_free``;
* :func:`observation_update` -- Algorithm 1 / Eq. (4) for one sensing region with reading 1;
* :func:`negative_update` -- *beyond the paper*: a reading 0 of a sensor without false
  negatives, ``R <- R \\ S``;
* :func:`clean_up` -- canonical order, empty and duplicate elements removed, dominated
  elements removed (a perfect matching on the containment bipartite graph);
* :func:`cap_elements` -- while more than ``M`` elements, merge the two most similar into
  their region-wise union;
* :func:`constrain` -- the geometric over-approximation (section VI-A.1): the smallest
  axis-aligned rectangle or disk containing each exact result;
* :func:`contains` / :func:`contains_states` -- the query of section VI-A.2;
* :func:`communicate` -- the communication update of section VI-B (perfect matchings of the
  non-empty-intersection graph); :func:`communicate_bruteforce` is the direct
  ``O(M^2 n!)`` formula it replaces, kept as the reference.

Pairwise work done once. The cap and the clean-up compare regions pairwise across elements
(``E x E x n x n`` pairs), but an observation update copies every element ``n`` times with
one region replaced, so most of those pairs repeat (the same two regions in many element
pairs, and again at every detection of the stage). :class:`PairMemo` keeps the exact
result of every region-pair operation (intersection area, covering) keyed by the two
regions' WKB, so each distinct ordered pair is computed by shapely once and the results are
bit-for-bit those of computing every pair (the same GEOS call on the same coordinates); the
cap's first similarity matrix skips the element with itself. The stage keeps one memo for
the whole run: regions recur across stages too (the free space while a target is
unobserved, a sensing region clipped to it at each detection), so the memo also keeps each
distinct region's projection, intersection with a sensing region and merge union, and whole
observation steps by the I-state they start from (an I-state at a fixed point -- a target
staying within a sensor's reach -- comes back stage after stage).

Units. The filter is unit-free: the same site in cm gives the results in m times 100
(areas 10^4). Two things stood in the way, both decisions taken on round-off:

* GEOS decides exactly on floating-point coordinates. A region that exact arithmetic puts
  inside another, sharing part of its boundary (``R cap S`` and ``R``), is covered or not
  depending on the last bits of the coordinates; an exact collinearity inside GEOS's
  buffer keeps or drops a vertex; elements are ordered by their WKB bytes and the cap's
  ties fall by that order. Scaling every coordinate by 100 changes those bits, so the
  same site kept 8 elements in m and 6 in cm. The stage therefore runs the filter in the
  site's normalised frame (:class:`SiteFrame`): coordinates ``(x - origin) / L`` snapped
  to a ``2^-20`` grid, the same numbers in every unit, so the whole run is the same
  computation bit for bit (the inputs grown, shrunk or rounded up so every step stays a
  superset), mapped back to site units at the end.
* Dominance is decided to within ``delta = REL_TOL L`` (:func:`covers_pairs`), so a
  round-off sliver of ``R cap S`` poking out of ``R`` does not keep a dominated element
  alive: the decision exact arithmetic makes (the paper's), in the frame and in direct
  calls of these functions in any unit. Every tolerance and slack here is relative to
  ``L`` (:func:`site_scale`) or to the coordinates' magnitude, none absolute.

Soundness. Every operation returns a superset of the exact result (the containment
guarantee of the paper) -- up to ``delta = 1e-9 L``: an element removed as dominated lies
within ``delta`` of one kept. Shapely approximates round buffers by inscribed polygons, so every
buffer that must *contain* a disk is made with the circumscribing radius
``r / cos(pi / (4 q))`` (``q`` segments per quarter circle), see :func:`grow`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from onebit.core.lazy import lazy_module

nx = lazy_module("networkx")
_optimize = lazy_module("scipy.optimize")

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

#: Largest number of elements whose pairwise similarities the cap computes at once.
CAP_CHUNK = 128

#: Similarities computed per round of the cap's branch and bound (largest upper bounds first):
#: small, since the first exact values usually rule the rest out (measured: 2 is fastest).
SETTLE_BATCH = 2

#: Entries (region ids, region-pair results, region geometries, recalled steps) a
#: :class:`PairMemo` keeps across filter steps before it starts afresh (proximity-line 320
#: instants ends with ~33k).
MEMO_CAPACITY = 1 << 17

#: Largest ``n`` for which matchings are found by enumerating the ``n!`` permutations in numpy.
PERM_TABLE_MAX_N = 5


# --------------------------------------------------------------------------- representation


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


def _bounds(regions: np.ndarray) -> np.ndarray:
    """``(..., 4)`` bounds, NaN for empty geometries."""
    return shapely.bounds(regions)


def _encode_once(cache: dict, geoms: np.ndarray, encode, dtype) -> np.ndarray:
    """``encode`` of each geometry of ``geoms`` (1-d object array), computed once per geometry
    object: ``cache`` maps ``id(geometry)`` to ``(geometry, value)`` (the geometry kept alive so
    its id stays its own); ``encode(new)`` maps the array of uncached geometries to a list of values."""
    objs = geoms.tolist()
    hits = list(map(cache.get, map(id, objs)))
    new = [p for p, h in enumerate(hits) if h is None]
    if new:
        for p, v in zip(new, encode(geoms[new])):
            g = objs[p]
            cache[id(g)] = hits[p] = (g, v)
    return np.fromiter((h[1] for h in hits), dtype=dtype, count=len(hits))


class PairMemo:
    """Exact results of region-pair operations, keyed by the two regions' WKB (module
    docstring, "Pairwise work done once").

    Regions get an integer id per distinct WKB; ``area[code(a, b)] = area(a cap b)`` and
    ``covers[code(a, b)] = a covers b`` by ids (``code(a, b) = a * 2**31 + b``). Equal WKB means equal coordinates, so the same
    GEOS operation gives the same bits: looking a pair up instead of recomputing it never
    changes a result. A memo may live for a whole run (the stage passes one to every
    :func:`info_state_update`): regions recur across filter steps -- the free space ``W``
    while a target is unobserved, a sensing region clipped to it at each of its detections
    -- so most region pairs of a step were met in an earlier one (proximity-line: 60 % of
    the intersections, 66 % of the coverings). :meth:`new_step` bounds its memory.
    Functions given none use a fresh one.
    """

    #: Whether :meth:`recall` remembers whole observation steps (a reference that computes
    #: everything turns it off).
    remember_steps = True

    def __init__(self, capacity: int = MEMO_CAPACITY) -> None:
        self.capacity = capacity  # entries kept across steps before starting afresh (region ids stay < 2**31)
        self.area: dict[int, float] = {}  # code of (region id, region id) -> area of the intersection
        self.covers: dict[int, bool] = {}  # code of (region id, region id) -> the first covers the second
        self.covers_delta: float | None = None  # the tolerance ``self.covers`` was computed with
        self._tables: dict[
            object, dict
        ] = {}  # name -> code of a region pair -> geometry (geometries); input -> result (recall)
        self._rid: dict[bytes, int] = {}  # WKB -> region id (equal WKB, equal id)
        self._obj: dict[
            int, tuple[object, int]
        ] = {}  # id(geometry) -> (geometry, kept alive so its id stays its own; region id)
        self._norm: dict[int, tuple[object, bytes]] = {}  # id(geometry) -> (geometry, WKB of its normalised form)
        self.computed = 0  # pairs sent to shapely
        self.looked_up = 0  # pairs answered from the memo or by a duplicate in the same call

    def new_step(self) -> None:
        """Between filter steps: everything stays (region ids, pair results, the geometries of
        :meth:`geometries`, the per-object caches) until it holds more than ``capacity``
        entries; then all is dropped together (region ids restart)."""
        held = len(self.area) + len(self.covers) + len(self._rid) + len(self._obj) + len(self._norm)
        if held + sum(len(t) for t in self._tables.values()) > self.capacity:
            for d in (self.area, self.covers, self._rid, self._obj, self._norm):
                d.clear()
            self._tables.clear()

    def recall(self, istate: IState, region, name, op):
        """``op(istate, region)`` (an I-state, an area), computed once per distinct input --
        the regions' ids in order and the region's id -- in the table ``name`` (naming ``op``
        and its parameters); not remembered when ``remember_steps`` is false."""
        if not self.remember_steps:
            return op(istate, region)
        one = np.empty(1, dtype=object)
        one[0] = region
        key = (istate.regions.shape, int(self.keys(one)[0]), self.keys(istate.regions).tobytes())
        table = self._tables.setdefault(("recall", name), {})
        out = table.get(key)
        if out is None:
            out = table[key] = op(istate, region)
            if isinstance(out, IState):  # handed out again: nobody may change it in place
                out.regions.flags.writeable = False
            self.computed += 1
        else:
            self.looked_up += 1
        return out

    def geometries(self, left: np.ndarray, right, name, op) -> np.ndarray:
        """``op(left, right)`` elementwise for a geometry-valued elementwise ``op`` (``left`` an
        object array, ``right`` one like it or a single geometry), each distinct pair of regions
        computed once in the table ``name`` (a hashable naming ``op`` and any parameters it
        closes over) and the same geometry object returned for it every time."""
        shp = np.shape(left)
        left = np.asarray(left, dtype=object).ravel()
        kl = self.keys(left)
        if isinstance(right, np.ndarray):
            right = right.ravel()
            kr = self.keys(right)
        else:  # one geometry against every left one
            one = np.empty(1, dtype=object)
            one[0] = right
            kr = np.full(len(left), self.keys(one)[0])
            right = np.empty(len(left), dtype=object)
            right.fill(one[0])
        return self.pairs(left, right, kl, kr, self._tables.setdefault(name, {}), op, object).reshape(shp)

    def keys(self, geoms: np.ndarray) -> np.ndarray:
        """Region id of each geometry (int64, same shape): equal WKB <=> equal id. Each
        geometry object is encoded once."""
        flat = np.asarray(geoms, dtype=object).ravel()

        def encode(new: np.ndarray) -> list:
            return [self._rid.setdefault(w, len(self._rid)) for w in shapely.to_wkb(new).tolist()]

        return _encode_once(self._obj, flat, encode, np.int64).reshape(np.shape(geoms))

    def normalized(self, geoms: np.ndarray) -> np.ndarray:
        """``shapely.to_wkb(shapely.normalize(geoms))`` (1-d), each geometry object encoded once."""
        return _encode_once(self._norm, geoms, lambda new: shapely.to_wkb(shapely.normalize(new)).tolist(), object)

    def pairs(
        self, left: np.ndarray, right: np.ndarray, kl: np.ndarray, kr: np.ndarray, table: dict, op, dtype
    ) -> np.ndarray:
        """``op(left[p], right[p])`` for every pair ``p`` (1-d object arrays with their region
        ids ``kl``, ``kr``), each distinct ``(kl[p], kr[p])`` computed once (vectorised over the
        new ones) or looked up in ``table``."""
        m = len(left)
        if m == 0:
            return np.zeros(0, dtype=dtype)
        codes = (kl.astype(np.int64) * (1 << 31) + kr).tolist()  # one int per ordered pair of region ids
        vals = list(map(table.get, codes))
        todo: dict[int, int] = {}  # code of a pair not in the table -> its first position
        for p, v in enumerate(vals):
            if v is None and codes[p] not in todo:
                todo[codes[p]] = p
        if todo:
            first = np.fromiter(todo.values(), dtype=np.int64, count=len(todo))
            got = np.asarray(op(left[first], right[first]), dtype=dtype).tolist()
            table.update(zip(todo, got))
            vals = list(map(table.__getitem__, codes))
        self.computed += len(todo)
        self.looked_up += m - len(todo)
        return np.fromiter(vals, dtype=dtype, count=m)


def _intersection_area(a, b) -> np.ndarray:
    return shapely.area(shapely.intersection(a, b))


# --------------------------------------------------------------------------- perfect matchings


@lru_cache(maxsize=16)
def permutations(n: int) -> np.ndarray:
    """``(n!, n)`` table of all permutations of ``range(n)`` (the symmetric group S_n)."""
    return np.array(list(itertools.permutations(range(n))), dtype=np.int64).reshape(-1, n)


def has_perfect_matching(adj: np.ndarray) -> np.ndarray:
    """Whether each ``n x n`` bipartite graph ``adj[..., k, l]`` has a perfect matching.

    For ``n <= PERM_TABLE_MAX_N`` all ``n!`` permutations are tested at once in numpy
    (``any_tau all_k adj[k, tau(k)]``); above it each graph goes to networkx's
    Hopcroft-Karp maximum matching (a loop over graphs, documented as such).
    """
    adj = np.asarray(adj, dtype=bool)
    n = adj.shape[-1]
    lead = adj.shape[:-2]
    if n == 0:
        return np.ones(lead, dtype=bool)
    flat = adj.reshape(-1, n, n)
    if n <= PERM_TABLE_MAX_N:
        perms = permutations(n)
        rows = np.arange(n)
        ok = flat[:, rows[None, :], perms].all(axis=-1).any(axis=-1)
        return ok.reshape(lead)
    out = np.empty(len(flat), dtype=bool)
    for i, a in enumerate(flat):
        out[i] = _nx_perfect(a)
    return out.reshape(lead)


def _nx_perfect(a: np.ndarray) -> bool:
    n = a.shape[0]
    g = nx.Graph()
    g.add_nodes_from(range(2 * n))
    k, l = np.nonzero(a)
    g.add_edges_from(zip(k.tolist(), (l + n).tolist()))
    m = nx.bipartite.hopcroft_karp_matching(g, top_nodes=range(n))
    return len(m) == 2 * n


def enumerate_perfect_matchings(adj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All perfect matchings of a batch of bipartite graphs ``adj (G, n, n)``.

    Returns ``(graph, match)``: ``match[j]`` (``(n,)``) is a perfect matching of graph
    ``graph[j]``, row ``k`` matched to column ``match[j, k]``. The enumeration extends every
    partial matching row by row over all graphs at once (a breadth-first backtracking in
    numpy), so its cost grows with the number of partial matchings, not with ``n!`` -- the
    output-sensitive enumeration the paper cites [3], [19]. Partial matchings that leave
    a later row without a free neighbour are pruned at once.
    """
    adj = np.asarray(adj, dtype=bool)
    G, n, _ = adj.shape
    graph = np.arange(G)
    match = np.zeros((G, 0), dtype=np.int64)
    used = np.zeros((G, n), dtype=bool)
    for k in range(n):
        cand = adj[graph, k, :] & ~used  # (P, n)
        p, col = np.nonzero(cand)
        graph, match, used = graph[p], np.c_[match[p], col], used[p].copy()
        used[np.arange(len(p)), col] = True
        if k + 1 < n and len(graph):
            # prune: every later row needs at least one free neighbour
            alive = (adj[graph, k + 1 :, :] & ~used[:, None, :]).any(axis=-1).all(axis=-1)
            graph, match, used = graph[alive], match[alive], used[alive]
    return graph, match


# --------------------------------------------------------------------------- Algorithm 1


def forward_project(
    istate: IState,
    step: float,
    free_space: BaseGeometry,
    *,
    shape: str = "exact",
    substeps: int = 1,
    memo: PairMemo | None = None,
) -> IState:
    """Motion update (Algorithm 1, lines 1-5): every region ``R <- F(R)``.

    ``F(R) = (R (+) B(s_tgt)) cap W_free``, computed as ``substeps`` rounds of growing by
    ``s_tgt / substeps`` and clipping to the free space, then constrained to ``shape`` (for
    ``rect`` the grown rectangle is the box expanded by ``d`` on every side, which is the
    smallest rectangle containing ``R (+) B(d)``). Each
    round is a superset of the points reachable within that distance, so the result contains
    the exact forward projection (the geodesic ball among obstacles); more rounds follow the
    obstacles more tightly. By Lemma 1, ``F(U_i prod R) = U_i prod F(R)``. With a ``memo``
    each distinct region is projected once (:meth:`PairMemo.geometries`; not boxes, cheaper to redo).
    """
    if istate.size == 0 or step <= 0:
        return istate

    def project(r, free):
        for _ in range(max(1, substeps)):
            d = step / max(1, substeps)
            if shape == "rect":  # the smallest rectangle containing R (+) B(d) is R expanded by d
                b = shapely.bounds(r)
                grown = shapely.box(b[..., 0] - d, b[..., 1] - d, b[..., 2] + d, b[..., 3] + d)
            else:
                grown = grow(r, d)
            r = shapely.intersection(grown, free)
        return constrain(r, shape)

    if memo is None or shape == "rect":  # boxes: cheaper to grow and clip than to look up
        r = project(istate.regions, free_space)
    else:
        r = memo.geometries(istate.regions, free_space, ("forward", float(step), substeps, shape), project)
    r = np.asarray(r, dtype=object).reshape(istate.regions.shape)
    # a region that was only an over-approximation inside an obstacle can vanish: the element
    # is then empty and is dropped (before a later step could turn it into a missing region)
    return IState(r[~void(r).any(axis=1)])


def observation_update(
    istate: IState, sensing: BaseGeometry, *, shape: str = "exact", memo: PairMemo | None = None
) -> IState:
    """Observation update for one sensing region ``S`` with reading 1 (Algorithm 1, lines 9-15).

    Eq. (4): ``eta' = U_i U_j R^(i)_1 x .. x (R^(i)_j cap S) x .. x R^(i)_n`` -- every
    element is replaced by ``n`` elements, the ``j``-th intersecting its ``j``-th region
    with ``S``. Elements with an empty region are dropped at once (the paper's on-the-fly
    optimisation of line 12). Vectorised over the ``E * n`` new elements; with a ``memo``
    each distinct region is intersected with ``S`` once (:meth:`PairMemo.geometries`).
    """
    E, n = istate.regions.shape
    if E == 0:
        return istate
    rep = np.repeat(istate.regions, n, axis=0)  # (E n, n): element i repeated n times
    rows = np.arange(E * n)
    cols = np.tile(np.arange(n), E)
    if shape == "rect" and shapely.equals(sensing, shapely.envelope(sensing)):  # box cap box, in numpy
        b = _bounds(rep[rows, cols])
        sb = np.asarray(sensing.bounds)
        lo, hi = np.maximum(b[:, :2], sb[:2]), np.minimum(b[:, 2:], sb[2:])
        ok = (lo <= hi).all(axis=1)
        new = np.full(len(rows), shapely.Polygon(), dtype=object)
        new[ok] = shapely.box(lo[ok, 0], lo[ok, 1], hi[ok, 0], hi[ok, 1])
        rep[rows, cols] = new
    elif memo is None:
        rep[rows, cols] = constrain(shapely.intersection(rep[rows, cols], sensing), shape)
    else:  # rep[rows, cols] is istate.regions.ravel()
        cut = lambda a, b: constrain(shapely.intersection(a, b), shape)  # noqa: E731
        rep[rows, cols] = memo.geometries(istate.regions.ravel(), sensing, ("observe", shape), cut)
    keep = ~void(rep[rows, cols])
    return IState(rep[keep])


def negative_update(
    istate: IState, sensing: BaseGeometry, *, shape: str = "exact", memo: PairMemo | None = None
) -> IState:
    """*Beyond the paper*: a reading 0 from a sensor without false negatives, ``R <- R \\ S``
    for every region (no target is in ``S``). Elements with an emptied region are dropped.
    Under ``rect``/``disk`` the difference is over-approximated like every other result."""
    if istate.size == 0:
        return istate
    cut = lambda a, b: constrain(shapely.difference(a, b), shape)  # noqa: E731
    r = (
        cut(istate.regions, sensing)
        if memo is None
        else memo.geometries(istate.regions, sensing, ("negative", shape), cut)
    )
    r = np.asarray(r, dtype=object).reshape(istate.regions.shape)
    keep = ~void(r).any(axis=1)
    return IState(r[keep])


# --------------------------------------------------------------------------- clean-up


def canonical(istate: IState, *, shape: str = "exact", memo: PairMemo | None = None) -> IState:
    """Canonical form: empty elements dropped, regions of each element in lexicographic order
    of their normalised WKB (of their bounds, for ``rect``), elements in lexicographic order,
    duplicates removed.

    Lemma 2 (reordering regions) and the commutativity and idempotence of the union
    (reordering and de-duplicating elements) leave the represented set unchanged.
    """
    r = istate.regions
    if r.shape[0] == 0:
        return istate
    r = r[~void(r).any(axis=1)]
    if r.shape[0] == 0:
        return IState(r)
    if shape == "rect":  # a box is identified by its bounds
        _, inv = np.unique(_bounds(r.ravel()), axis=0, return_inverse=True)
    else:
        flat = r.ravel()
        wkb = shapely.to_wkb(shapely.normalize(flat)) if memo is None else memo.normalized(flat)
        _, inv = np.unique(wkb, return_inverse=True)
    ids = inv.reshape(r.shape)
    order = np.argsort(ids, axis=1, kind="stable")
    ids = np.take_along_axis(ids, order, axis=1)
    r = np.take_along_axis(r, order, axis=1)
    codes = _row_codes(ids)
    _, first = np.unique(
        codes, axis=0 if codes.ndim > 1 else None, return_index=True
    )  # sorted unique rows: canonical order
    return IState(r[first])


def _row_codes(ids: np.ndarray) -> np.ndarray:
    """Rows of non-negative ints ``(E, n)`` as one int64 each, in the same lexicographic order
    (base ``max + 1`` digits) when that fits in 62 bits; else the rows themselves."""
    base = int(ids.max(initial=0)) + 1
    n = ids.shape[1]
    if n * math.log2(base) >= 62:
        return ids
    return ids.astype(np.int64) @ (base ** np.arange(n - 1, -1, -1, dtype=np.int64))


def covers_pairs(
    regions: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    *,
    shape: str = "exact",
    memo: PairMemo | None = None,
    delta: float | None = None,
) -> np.ndarray:
    """``cov[p, k, l]``: region ``l`` of element ``b[p]`` covers region ``k`` of element ``a[p]``
    to within ``delta`` (default :func:`tolerance` of ``regions``): ``R_k subset R_l (+) B(delta)``.

    Why a tolerance (module docstring, "Units"). The regions are results of overlays in
    floating point: a region that exact arithmetic puts inside another, sharing part of its
    boundary, pokes out of it by a sliver of round-off width (~1e-16 L) or not, depending on
    the last bits of the coordinates -- and so on the units (the same site in cm and in m
    kept 6 and 8 elements). Covering to within ``delta = 1e-9 L`` decides those the way
    exact arithmetic does, in every unit: the decision changes only where a region pokes
    out by about ``delta``, 10^7 times the round-off, a coincidence the units do not move.
    The grown region is shapely's buffer by ``delta`` with one segment per quarter circle,
    which holds every point within ``delta cos(pi/4)`` of ``R_l`` (and none farther than
    ``delta``); exact covering is tried first (the same answer, cheaper). ``delta = 0``
    is GEOS's exact ``covers``.

    Only region pairs whose bounding boxes nest (to within ``delta``) are tested (for
    ``rect`` regions bounding-box nesting *is* covering), each distinct pair once
    (:class:`PairMemo`)."""
    delta = tolerance(regions) if delta is None else float(delta)
    nest = _nested_boxes(_bounds(regions), a, b, delta)
    if shape == "rect":
        return nest
    cov = np.zeros_like(nest)
    p, k, l = np.nonzero(nest)
    memo = PairMemo() if memo is None else memo
    if memo.covers_delta != delta:  # the memo's coverings hold for one tolerance
        memo.covers.clear()
        memo.covers_delta = delta
    key = memo.keys(regions)

    def covers_within(big, small):
        out = shapely.covers(big, small)
        if delta > 0 and not out.all():
            rest = ~out
            out[rest] = shapely.covers(shapely.buffer(big[rest], delta, quad_segs=1), small[rest])
        return out

    cov[p, k, l] = memo.pairs(
        regions[b[p], l], regions[a[p], k], key[b[p], l], key[a[p], k], memo.covers, covers_within, bool
    )
    return cov


def _nested_boxes(bnd: np.ndarray, a: np.ndarray, b: np.ndarray, delta: float = 0.0) -> np.ndarray:
    """``nest[p, k, l]``: the bounding box of region ``l`` of element ``b[p]``, grown by
    ``delta`` on every side, contains that of region ``k`` of element ``a[p]`` (``bnd (E, n, 4)``
    the regions' bounds)."""
    ba = bnd[a][:, :, None, :]
    bb = bnd[b][:, None, :, :]
    return (
        (bb[..., 0] - delta <= ba[..., 0])
        & (bb[..., 1] - delta <= ba[..., 1])
        & (bb[..., 2] + delta >= ba[..., 2])
        & (bb[..., 3] + delta >= ba[..., 3])
    )


def covers_matrix(regions: np.ndarray, *, shape: str = "exact", delta: float | None = None) -> np.ndarray:
    """``cov[a, b, k, l]`` for every pair of elements (see :func:`covers_pairs`)."""
    E = regions.shape[0]
    a, b = np.divmod(np.arange(E * E), E)
    return covers_pairs(regions, a, b, shape=shape, delta=delta).reshape(E, E, regions.shape[1], regions.shape[1])


def remove_dominated(
    istate: IState, *, shape: str = "exact", memo: PairMemo | None = None, delta: float | None = None
) -> IState:
    """Remove every element dominated by another (section VI-A, fourth clean-up step).

    ``E_b`` dominates ``E_a`` iff the containment bipartite graph (region ``k`` of ``E_a`` --
    region ``l`` of ``E_b`` when ``R^(a)_k subset R^(b)_l``) has a perfect matching. ``E_a``
    is removed when some ``E_b`` dominates it strictly, or equally with ``b < a``: that
    relation is a strict partial order, so every removed element is dominated by a kept
    one and the union is unchanged.

    Containment is decided to within ``delta`` (``R^(a)_k subset R^(b)_l (+) B(delta)``,
    :func:`covers_pairs`; default :func:`tolerance` of the regions), so that the same site
    keeps the same elements in any unit; a removed element then lies within ``delta`` of a
    kept one (every target position of it is at most ``delta = 1e-9 L`` from the I-state).

    Two necessary conditions prune the ``E^2`` pairs in numpy before any geometry: the
    bounding box of ``E_b``'s regions grown by ``delta`` contains that of ``E_a``'s, and
    ``E_b``'s region areas grown by what the ``delta``-neighbourhood can add
    (``|R (+) B(delta)| <= |R| + delta perimeter(R) + 4 delta^2``), sorted, are elementwise at
    least ``E_a``'s (a matching into supersets implies both).
    """
    E = istate.size
    if E <= 1:
        return istate
    r = istate.regions
    delta = tolerance(r) if delta is None else float(delta)
    bnd = _bounds(r)
    box_e = np.stack([bnd[..., 0].min(1), bnd[..., 1].min(1), bnd[..., 2].max(1), bnd[..., 3].max(1)], axis=1)
    area = shapely.area(r)
    sa = -np.sort(-area, axis=1)
    sb = -np.sort(-(area + delta * shapely.length(r) + 4 * delta * delta), axis=1)
    tol = 1e-12 * sa.max()  # round-off of the areas, relative
    dom = np.zeros((E, E), dtype=bool)  # dom[a, b]: b dominates a
    for lo in range(0, E, 512):  # rows in blocks: memory O(512 E n)
        hi = min(E, lo + 512)
        ba, bb = box_e[lo:hi, None, :], box_e[None, :, :]
        cand = (
            (bb[..., 0] - delta <= ba[..., 0])
            & (bb[..., 1] - delta <= ba[..., 1])
            & (bb[..., 2] + delta >= ba[..., 2])
            & (bb[..., 3] + delta >= ba[..., 3])
        )
        cand &= (sb[None, :, :] >= sa[lo:hi, None, :] - tol).all(axis=-1)
        a, b = np.nonzero(cand)
        a = a + lo
        keep = a != b
        a, b = a[keep], b[keep]
        for c in range(0, len(a), 65536):  # candidate pairs in chunks: memory O(65536 n^2)
            aa, bb_ = a[c : c + 65536], b[c : c + 65536]
            if shape != "rect":  # a covering nests the boxes: no perfect matching of nested boxes, none of coverings
                ok = has_perfect_matching(_nested_boxes(bnd, aa, bb_, delta))
                aa, bb_ = aa[ok], bb_[ok]
            dom[aa, bb_] = has_perfect_matching(covers_pairs(r, aa, bb_, shape=shape, memo=memo, delta=delta))
    idx = np.arange(E)
    beaten = dom & (~dom.T | (idx[None, :] < idx[:, None]))
    return IState(r[~beaten.any(axis=1)])


def clean_up(
    istate: IState, *, shape: str = "exact", memo: PairMemo | None = None, delta: float | None = None
) -> IState:
    """The four clean-up steps of section VI-A: canonical order, duplicates and empty elements
    removed, dominated elements removed (to within ``delta``, see :func:`remove_dominated`)."""
    return remove_dominated(canonical(istate, shape=shape, memo=memo), shape=shape, memo=memo, delta=delta)


# --------------------------------------------------------------------------- the cap M


def overlap_areas(
    a: np.ndarray, b: np.ndarray, *, shape: str = "exact", memo: PairMemo | None = None, skip_same: bool = False
) -> np.ndarray:
    """``ov[i, j, k, l] = area(R^(a_i)_k cap R^(b_j)_l)`` for elements ``a (Ea, n)`` and ``b (Eb, n)``;
    only pairs with intersecting bounding boxes are intersected (numpy for ``rect``), each
    distinct ordered region pair once (:class:`PairMemo`). ``skip_same`` (``a`` is ``b``):
    the element with itself (``i == j``) is left 0, the cap never merges an element with itself."""
    ba = _bounds(a)[:, None, :, None, :]
    bb = _bounds(b)[None, :, None, :, :]
    w = np.minimum(ba[..., 2], bb[..., 2]) - np.maximum(ba[..., 0], bb[..., 0])
    h = np.minimum(ba[..., 3], bb[..., 3]) - np.maximum(ba[..., 1], bb[..., 1])
    box = np.where((w > 0) & (h > 0), w * h, 0.0)
    box = np.nan_to_num(box)
    if shape == "rect":
        return box
    ov = np.zeros_like(box)
    i, j, k, l = np.nonzero(box > 0)
    if skip_same:
        keep = i != j
        i, j, k, l = i[keep], j[keep], k[keep], l[keep]
    memo = PairMemo() if memo is None else memo
    ka = memo.keys(a)
    kb = ka if b is a else memo.keys(b)
    ov[i, j, k, l] = memo.pairs(a[i, k], b[j, l], ka[i, k], kb[j, l], memo.area, _intersection_area, np.float64)
    return ov


def best_pairing(ov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For overlap matrices ``ov (..., n, n)``: the largest total overlap over pairings
    ``max_tau sum_k ov[k, tau(k)]`` and the maximising ``tau (..., n)``.

    ``n <= PERM_TABLE_MAX_N``: all permutations in numpy; above: ``linear_sum_assignment``
    per matrix (a loop over pairs)."""
    n = ov.shape[-1]
    lead = ov.shape[:-2]
    flat = ov.reshape(-1, n, n)
    if n <= PERM_TABLE_MAX_N:
        perms = permutations(n)
        tot = flat[:, np.arange(n)[None, :], perms].sum(axis=-1)  # (P, n!)
        best = tot.argmax(axis=1)
        return tot[np.arange(len(flat)), best].reshape(lead), perms[best].reshape(*lead, n)
    vals = np.empty(len(flat))
    taus = np.empty((len(flat), n), dtype=np.int64)
    for p, m in enumerate(flat):
        r, c = _optimize.linear_sum_assignment(m, maximize=True)
        vals[p], taus[p, r] = m[r, c].sum(), c
    return vals.reshape(lead), taus.reshape(*lead, n)


def merge_elements(
    a: np.ndarray, b: np.ndarray, tau: np.ndarray, *, shape: str = "exact", memo: PairMemo | None = None
) -> np.ndarray:
    """Region-wise union ``(R^(a)_k cup R^(b)_tau(k))_k`` of two elements.

    For any pairing ``tau`` the result contains both elements' products (``prod_k R^(a)_k``
    and ``prod_k R^(b)_tau(k)`` are sub-products of it), so the merge never shrinks the set.
    With a ``memo`` each distinct region pair is united once (:meth:`PairMemo.geometries`)."""
    join = lambda x, y: constrain(shapely.union(x, y), shape)  # noqa: E731
    fresh = memo is None or shape == "rect"  # boxes: cheaper to unite than to look up
    return np.asarray(join(a, b[tau]) if fresh else memo.geometries(a, b[tau], ("merge", shape), join), dtype=object)


def cap_elements(
    istate: IState,
    max_elements: int,
    *,
    shape: str = "exact",
    memo: PairMemo | None = None,
    delta: float | None = None,
) -> IState:
    """Merge until at most ``M`` elements remain (section VI-A).

    Similarity of two elements = their total pairwise region overlap under the pairing of
    regions that maximises it, ``sim(a, b) = max_tau sum_k area(R^(a)_k cap R^(b)_tau(k))``
    (the paper's "total pairwise overlap" needs a pairing of the unordered regions; we use
    the best one). The most similar pair is replaced by :func:`merge_elements` along that
    pairing; the new element's similarities are recomputed against the others. Inherently
    sequential over merges; each merge is vectorised. Above ``CAP_CHUNK`` elements (after a
    communication update) chunks of ``CAP_CHUNK`` are capped first, then their union: the
    pairwise similarity matrix stays ``O(CAP_CHUNK^2 n^2)``.

    Only the similarities that can decide a merge are computed (branch and bound). The
    bounding boxes give, in numpy, an upper bound of every similarity,
    ``ub(a, b) = max_tau sum_k |box(R^(a)_k) cap box(R^(b)_tau(k))| >= sim(a, b)``; a merge
    picks the first largest similarity (row-major, as ``argmax``), so exact values are needed
    only for pairs whose bound reaches the largest exact value known -- computed in
    descending order of their bound until no unknown bound reaches it. The others cannot
    be the largest (nor tie with it). Region pairs already intersected (in this call or,
    through ``memo``, earlier in the filter step) are looked up. The result is the one of
    :func:`cap_elements_reference`, which computes every similarity (the test oracle): each
    exact value is computed the same way, in the same orientation.
    """
    E, n = istate.regions.shape
    if E <= max_elements:
        return istate
    memo = PairMemo() if memo is None else memo
    if E > CAP_CHUNK:  # hierarchical: cap chunks of CAP_CHUNK first (each merge is a superset)
        parts = [
            cap_elements(
                IState(istate.regions[i : i + CAP_CHUNK]), max_elements, shape=shape, memo=memo, delta=delta
            ).regions
            for i in range(0, E, CAP_CHUNK)
        ]
        return cap_elements(
            clean_up(IState(np.vstack(parts)), shape=shape, memo=memo, delta=delta),
            max_elements,
            shape=shape,
            memo=memo,
            delta=delta,
        )
    if shape == "rect":  # box overlaps are the exact similarities: nothing to bound
        return cap_elements_reference(istate, max_elements, shape=shape, memo=memo, delta=delta)
    regs = [row for row in istate.regions]
    sim = np.full((E, E), -np.inf)
    tau = np.zeros((E, E, n), dtype=np.int64)
    known = np.eye(E, dtype=bool)  # the diagonal is -inf: never merged with itself
    ub, _ = best_pairing(_box_overlaps(istate.regions, istate.regions))
    ub = _slack(ub)
    last = np.zeros(E, dtype=np.int64)  # merge step that last replaced each element (0: an input element)
    alive = np.ones(E, dtype=bool)
    step = 0
    while alive.sum() > max_elements:
        live = alive[:, None] & alive[None, :]
        while True:  # settle: every pair that could be the argmax gets its exact similarity
            todo = live & ~known
            if not todo.any():
                break
            best = sim[live & known].max(initial=-np.inf)
            ci, cj = np.nonzero(todo & (ub >= best))
            if ci.size == 0:
                break
            if ci.size > SETTLE_BATCH:  # largest bounds first, a few at a time
                top = np.argsort(-ub[ci, cj], kind="stable")[:SETTLE_BATCH]
                ci, cj = ci[top], cj[top]
            _exact_similarities(regs, ci, cj, last, sim, tau, known, shape=shape, memo=memo)
        masked = np.where(live & known, sim, -np.inf)
        i, j = np.unravel_index(np.argmax(masked), masked.shape)
        merged = merge_elements(regs[i], regs[j], tau[i, j], shape=shape, memo=memo)
        alive[j] = False
        regs[i] = merged
        step += 1
        last[i] = step
        others = np.flatnonzero(alive)
        others = others[others != i]
        if len(others):  # the merged element's similarities are unknown again
            b, _ = best_pairing(_box_overlaps(merged[None, :], np.stack([regs[o] for o in others])))
            ub[i, others] = ub[others, i] = _slack(b[0])
            known[i, others] = known[others, i] = False
    out = IState(np.stack([regs[k] for k in np.flatnonzero(alive)]))
    return clean_up(out, shape=shape, memo=memo, delta=delta)


def _box_overlaps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(Ea, Eb, n, n)`` areas of the intersections of the regions' bounding boxes (0 for
    boxes that do not overlap or empty regions), capped by the smaller of the two regions'
    areas: each bounds the region overlap from above."""
    ba = _bounds(a)[:, None, :, None, :]
    bb = _bounds(b)[None, :, None, :, :]
    w = np.minimum(ba[..., 2], bb[..., 2]) - np.maximum(ba[..., 0], bb[..., 0])
    h = np.minimum(ba[..., 3], bb[..., 3]) - np.maximum(ba[..., 1], bb[..., 1])
    small = np.minimum(shapely.area(a)[:, None, :, None], shapely.area(b)[None, :, None, :])
    return np.nan_to_num(np.where((w > 0) & (h > 0), np.minimum(w * h, small), 0.0))


def _slack(ub: np.ndarray) -> np.ndarray:
    """An upper bound made safe against round-off of the exact areas it bounds."""
    return ub * (1 + 1e-7) + 1e-12


def _exact_similarities(regs, ci, cj, last, sim, tau, known, *, shape, memo) -> None:
    """Exact ``sim``/``tau`` of the element pairs ``(ci, cj)``, in the orientation
    :func:`cap_elements_reference` computes them: input elements ``a -> b``; a pair with a
    merged element from the merged element (the one merged last) to the other, the reverse
    entry the same similarity with the inverse pairing."""
    flip = last[cj] > last[ci]  # the merged side (merged last) goes first
    src = np.where(flip, cj, ci)
    dst = np.where(flip, ci, cj)
    merged = np.maximum(last[ci], last[cj]) > 0
    key = np.where(merged, np.minimum(src, dst) * len(regs) + np.maximum(src, dst), ci * len(regs) + cj)
    _, first = np.unique(np.where(merged, key, -1 - key), return_index=True)  # one computation per merged pair
    src, dst, merged = src[first], dst[first], merged[first]
    left = np.stack([regs[a] for a in src])
    right = np.stack([regs[b] for b in dst])
    s, t = best_pairing(_aligned_overlaps(left, right, shape=shape, memo=memo))
    sim[src, dst], tau[src, dst], known[src, dst] = s, t, True
    m = merged
    sim[dst[m], src[m]], tau[dst[m], src[m]], known[dst[m], src[m]] = s[m], np.argsort(t[m], axis=1), True


def _aligned_overlaps(a: np.ndarray, b: np.ndarray, *, shape: str, memo: PairMemo) -> np.ndarray:
    """``ov[p, k, l] = area(a[p, k] cap b[p, l])`` for aligned element pairs ``a, b (P, n)``
    (:func:`overlap_areas` of each pair, through the memo)."""
    ba = _bounds(a)[:, :, None, :]
    bb = _bounds(b)[:, None, :, :]
    w = np.minimum(ba[..., 2], bb[..., 2]) - np.maximum(ba[..., 0], bb[..., 0])
    h = np.minimum(ba[..., 3], bb[..., 3]) - np.maximum(ba[..., 1], bb[..., 1])
    box = np.nan_to_num(np.where((w > 0) & (h > 0), w * h, 0.0))
    ov = np.zeros_like(box)
    p, k, l = np.nonzero(box > 0)
    ka, kb = memo.keys(a), memo.keys(b)
    ov[p, k, l] = memo.pairs(a[p, k], b[p, l], ka[p, k], kb[p, l], memo.area, _intersection_area, np.float64)
    return ov


def cap_elements_reference(
    istate: IState,
    max_elements: int,
    *,
    shape: str = "exact",
    memo: PairMemo | None = None,
    delta: float | None = None,
) -> IState:
    """Merge until at most ``M`` elements remain (section VI-A), every similarity computed:
    the plain reference of :func:`cap_elements` (and the test oracle; same result).

    Similarity of two elements = their total pairwise region overlap under the pairing of
    regions that maximises it, ``sim(a, b) = max_tau sum_k area(R^(a)_k cap R^(b)_tau(k))``
    (the paper's "total pairwise overlap" needs a pairing of the unordered regions; we use
    the best one). The most similar pair is replaced by :func:`merge_elements` along that
    pairing; the new element's similarities are computed incrementally. Inherently
    sequential over merges; each merge is vectorised. Above ``CAP_CHUNK`` elements (after a
    communication update) chunks of ``CAP_CHUNK`` are capped first, then their union: the
    pairwise similarity matrix stays ``O(CAP_CHUNK^2 n^2)``. Region pairs already intersected
    (in this call or, through ``memo``, earlier in the filter step) are looked up.
    """
    E, n = istate.regions.shape
    if E <= max_elements:
        return istate
    if E > CAP_CHUNK:  # hierarchical: cap chunks of CAP_CHUNK first (each merge is a superset)
        memo = PairMemo() if memo is None else memo
        parts = [
            cap_elements_reference(
                IState(istate.regions[i : i + CAP_CHUNK]), max_elements, shape=shape, memo=memo, delta=delta
            ).regions
            for i in range(0, E, CAP_CHUNK)
        ]
        return cap_elements_reference(
            clean_up(IState(np.vstack(parts)), shape=shape, memo=memo, delta=delta),
            max_elements,
            shape=shape,
            memo=memo,
            delta=delta,
        )
    regs = [row for row in istate.regions]
    memo = PairMemo() if memo is None else memo
    ov = overlap_areas(istate.regions, istate.regions, shape=shape, memo=memo, skip_same=True)
    sim, tau = best_pairing(ov)
    sim = sim.astype(float)
    np.fill_diagonal(sim, -np.inf)
    alive = np.ones(E, dtype=bool)
    while alive.sum() > max_elements:
        masked = np.where(alive[:, None] & alive[None, :], sim, -np.inf)
        i, j = np.unravel_index(np.argmax(masked), masked.shape)
        merged = merge_elements(regs[i], regs[j], tau[i, j], shape=shape, memo=memo)
        alive[j] = False
        regs[i] = merged
        others = np.flatnonzero(alive)
        others = others[others != i]
        if len(others):
            stack = np.stack([regs[o] for o in others])
            ov_new = overlap_areas(merged[None, :], stack, shape=shape, memo=memo)[0]  # (len(others), n, n)
            s_new, t_new = best_pairing(ov_new)
            sim[i, others] = s_new
            tau[i, others] = t_new
            sim[others, i] = s_new
            tau[others, i] = np.argsort(t_new, axis=1)  # inverse pairing
    out = IState(np.stack([regs[k] for k in np.flatnonzero(alive)]))
    return clean_up(out, shape=shape, memo=memo, delta=delta)


# --------------------------------------------------------------------------- query


def contains_states(istate: IState, states: np.ndarray) -> np.ndarray:
    """Query (section VI-A.2): does the I-state contain each target state?

    ``states (Q, n, 2)``. For every element a bipartite graph joins target ``l`` to region
    ``k`` when the point lies in (or on) the region; the state is in the element iff that
    graph has a perfect matching, and in the I-state iff it is in some element. Vectorised
    over states, elements, regions and targets.
    """
    states = np.asarray(states, dtype=float)
    if states.ndim == 2:
        states = states[None]
    Q = states.shape[0]
    if istate.size == 0:
        return np.zeros(Q, dtype=bool)
    r = istate.regions[None, :, :, None]  # (1, E, n_regions, 1)
    x = states[:, None, None, :, 0]
    y = states[:, None, None, :, 1]
    adj = shapely.intersects_xy(r, x, y)  # (Q, E, k, l)
    return has_perfect_matching(adj).any(axis=1)


def contains(istate: IState, state) -> bool:
    """Whether the I-state contains one target state ``(n, 2)``."""
    return bool(contains_states(istate, np.asarray(state, float)[None])[0])


# --------------------------------------------------------------------------- communication


def communicate(a: IState, b: IState, *, shape: str = "exact") -> IState:
    """Communication update (section VI-B): ``eta' = eta^(1) cap eta^(2)``.

    ``eta' = U_i U_j U_tau prod_k (R^(i)_tau(k) cap T^(j)_k)``. Instead of all
    ``Ea Eb n!`` terms, for each element pair ``(i, j)`` the bipartite graph joining
    ``R^(i)_k`` and ``T^(j)_l`` when they intersect is built (``shapely.intersects`` on all
    ``Ea Eb n^2`` pairs at once) and only its perfect matchings are enumerated
    (:func:`enumerate_perfect_matchings`); each gives one element of intersected regions.
    The result is cleaned up (not capped).
    """
    if a.n != b.n:
        raise ValueError(f"cannot intersect I-states of {a.n} and {b.n} targets")
    Ea, Eb, n = a.size, b.size, a.n
    if Ea == 0 or Eb == 0:
        return IState(np.empty((0, n), dtype=object))
    if shape == "rect":  # boxes: intersection tests and intersections in numpy
        ba, bb = _bounds(a.regions), _bounds(b.regions)
        x = ba[:, None, :, None, :], bb[None, :, None, :, :]
        adj = (np.maximum(x[0][..., 0], x[1][..., 0]) <= np.minimum(x[0][..., 2], x[1][..., 2])) & (
            np.maximum(x[0][..., 1], x[1][..., 1]) <= np.minimum(x[0][..., 3], x[1][..., 3])
        )
    else:
        adj = shapely.intersects(a.regions[:, None, :, None], b.regions[None, :, None, :])  # (Ea, Eb, n, n)
    graph, match = enumerate_perfect_matchings(adj.reshape(Ea * Eb, n, n))
    if len(graph) == 0:
        return IState(np.empty((0, n), dtype=object))
    i, j = np.divmod(graph, Eb)
    if shape == "rect":
        la = ba[i]
        rb_ = np.take_along_axis(bb[j], match[..., None], axis=1)
        lo = np.maximum(la[..., :2], rb_[..., :2])
        hi = np.minimum(la[..., 2:], rb_[..., 2:])
        inter = np.asarray(shapely.box(lo[..., 0], lo[..., 1], hi[..., 0], hi[..., 1]), dtype=object)
    else:
        left = a.regions[i]  # (P, n)
        right = np.take_along_axis(b.regions[j], match, axis=1)
        inter = np.asarray(constrain(shapely.intersection(left, right), shape), dtype=object).reshape(left.shape)
    return clean_up(IState(inter), shape=shape)


def communicate_bruteforce(a: IState, b: IState, *, shape: str = "exact") -> IState:
    """The direct formula of section VI-B, ``O(Ea Eb n!)`` intersections: every element pair
    and every permutation, empty products dropped, then clean-up (reference for tests and
    the benchmark)."""
    Ea, Eb, n = a.size, b.size, a.n
    if Ea == 0 or Eb == 0:
        return IState(np.empty((0, n), dtype=object))
    perms = permutations(n)
    i, j, p = np.meshgrid(np.arange(Ea), np.arange(Eb), np.arange(len(perms)), indexing="ij")
    i, j, p = i.ravel(), j.ravel(), p.ravel()
    left = a.regions[i]
    right = np.take_along_axis(b.regions[j], perms[p], axis=1)
    inter = np.asarray(constrain(shapely.intersection(left, right), shape), dtype=object).reshape(left.shape)
    return clean_up(IState(inter), shape=shape)


def same_elements(a: IState, b: IState) -> bool:
    """Whether two canonical I-states hold the same elements (exact geometric equality)."""
    if a.regions.shape != b.regions.shape:
        return False
    if a.size == 0:
        return True
    ka = shapely.to_wkb(shapely.normalize(canonical(a).regions.ravel()))
    kb = shapely.to_wkb(shapely.normalize(canonical(b).regions.ravel()))
    return bool(np.all(ka == kb))


# --------------------------------------------------------------------------- one filter step


def info_state_update(
    istate: IState,
    detections,
    *,
    step: float,
    free_space: BaseGeometry,
    shape: str = "exact",
    max_elements: int | None = 10,
    negatives=(),
    substeps: int = 1,
    memo: PairMemo | None = None,
    rejected: list | None = None,
) -> IState:
    """INFOSTATEUPDATE (Algorithm 1) followed by the clean-up and the cap.

    Outlier-tolerant observations (beyond the paper). When ``rejected`` is a list, a reading
    that would leave the I-state *empty* -- no joint state of n targets explains it together
    with every earlier reading: a spurious firing, a footprint larger than declared, a
    reading that arrived late -- is rejected instead: the I-state is kept as it was before
    that reading and the reading's index (in ``detections``, then ``len(detections) + j``
    for the ``j``-th negative) is appended to ``rejected``. Without it (``None``, the paper's
    filter) such a reading empties the I-state, and an empty I-state stays empty for good.

    Motion update with ``step = s_tgt``; then, for each sensing region in ``detections``
    (readings 1), :func:`observation_update` followed by :func:`clean_up` and -- when
    ``max_elements`` is set -- :func:`cap_elements` (the clean-up is applied after every
    region, the paper's "on-the-fly" variant, so the element count stays below ``M n``);
    finally each region of ``negatives`` (sensors without false negatives reading 0, beyond
    the paper) is subtracted. Sequential over sensing regions (each depends on the last).
    ``memo``: region-pair results shared by every clean-up and cap of the step and, when the
    caller passes the same memo to every step, across steps (:class:`PairMemo`). Each
    observation (update, clean-up, cap) and each negative is a function of the I-state it
    starts from and its sensing region, so it is looked up when both recur
    (:meth:`PairMemo.recall`): an I-state at a fixed point of the motion and observation
    updates -- a target staying within a sensor's reach -- comes back stage after stage
    (proximity-line: half of the observations). The result is the same bits with or without
    the memo.
    """
    if memo is None:  # a memo for this step only: no earlier observation to recall
        memo = PairMemo()
        recall = lambda eta, s, name, op: op(eta, s)  # noqa: E731
    else:
        memo.new_step()
        recall = memo.recall
    eta = forward_project(istate, step, free_space, shape=shape, substeps=substeps, memo=memo)
    delta = tolerance(free_space)  # one tolerance for the whole run: the site's scale

    def observe(eta, s):
        eta = clean_up(observation_update(eta, s, shape=shape, memo=memo), shape=shape, memo=memo, delta=delta)
        return eta if max_elements is None else cap_elements(eta, max_elements, shape=shape, memo=memo, delta=delta)

    def subtract(eta, s):
        return clean_up(negative_update(eta, s, shape=shape, memo=memo), shape=shape, memo=memo, delta=delta)

    for i, s in enumerate(detections):
        new = recall(eta, s, ("observe", shape, max_elements), observe)
        if rejected is not None and new.size == 0 and eta.size > 0:
            rejected.append(i)
            continue
        eta = new
    for j, s in enumerate(negatives):
        new = recall(eta, s, ("negative", shape), subtract)
        if rejected is not None and new.size == 0 and eta.size > 0:
            rejected.append(len(detections) + j)
            continue
        eta = new
    return eta
