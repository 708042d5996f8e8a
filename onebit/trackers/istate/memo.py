"""Pairwise work done once (:mod:`onebit.trackers.istate.core`, module docstring):
:class:`PairMemo` keeps the exact result of every region-pair operation keyed by the two
regions' WKB, and whole observation steps by the I-state they start from.
"""

from __future__ import annotations

import numpy as np
import shapely

from onebit.trackers.istate.regions import (
    IState,
)

#: Entries (region ids, region-pair results, region geometries, recalled steps) a
#: :class:`PairMemo` keeps across filter steps before it starts afresh (proximity-line 320
#: instants ends with ~33k).
MEMO_CAPACITY = 1 << 17


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
