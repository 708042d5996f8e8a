"""Decomposition of the free space into regions and the directed, beam-labelled region graph.

Bobadilla et al., section II: the obstacles and the beams split the free space E into
connected regions R = {r_1..r_p}; the region graph G has an edge r_i -> r_j labelled beta
when a forward crossing of beam beta takes an agent from r_i to r_j, and the reverse edge
r_j -> r_i labelled beta^-1 (Fig. 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl
import shapely
from shapely.geometry import Point, Polygon

from onebit.core.errors import SiteError
from onebit.core.lazy import lazy_module
from onebit.core.site import Site

nx = lazy_module("networkx")

#: Half-width of the cut made along each beam, relative to the site's diagonal.
_CUT_REL = 1e-7


@dataclass(frozen=True)
class RegionGraph:
    """Regions of a site and the labelled region graph.

    Attributes
    ----------
    names : region names, index ``i`` is region ``i``.
    polygons : shapely polygon of each region.
    graph : ``networkx.MultiDiGraph`` on region names; each edge has ``beam`` and
        ``direction`` (+1 forward, -1 backward) and the key ``"beta"`` / ``"beta^-1"``.
    beam_source / beam_target : for each beam id, the region a *forward* crossing leaves and enters.
    """

    names: tuple[str, ...]
    polygons: tuple[Polygon, ...]
    graph: nx.MultiDiGraph
    beam_source: dict[str, str]
    beam_target: dict[str, str]

    @property
    def index(self) -> dict[str, int]:
        return {n: i for i, n in enumerate(self.names)}

    def endpoints(self, beam: str, direction: int) -> tuple[str, str]:
        """(source, target) region of one crossing."""
        s, t = self.beam_source[beam], self.beam_target[beam]
        return (s, t) if direction > 0 else (t, s)

    def endpoint_arrays(self, beams: np.ndarray | pl.Series, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :meth:`endpoints`: region indices of source and target of every crossing."""
        idx = self.index
        ids = sorted(self.beam_source)
        fwd_s = np.array([idx[self.beam_source[b]] for b in ids], dtype=np.int64)
        fwd_t = np.array([idx[self.beam_target[b]] for b in ids], dtype=np.int64)
        k = (
            (beams if isinstance(beams, pl.Series) else pl.Series(beams, dtype=pl.String))
            .replace_strict(ids, list(range(len(ids))), return_dtype=pl.Int64)
            .to_numpy()
            if len(beams)
            else np.zeros(0, np.int64)
        )
        fwd = np.asarray(directions) > 0
        src = np.where(fwd, fwd_s[k], fwd_t[k])
        tgt = np.where(fwd, fwd_t[k], fwd_s[k])
        return src, tgt

    def region_of(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Name of the region containing each point (``None`` where none does), vectorised."""
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        out = np.full(x.shape, None, dtype=object)
        for name, poly in zip(self.names, self.polygons):
            inside = shapely.contains_xy(poly, x, y)
            out[inside & (out == None)] = name  # noqa: E711 -- elementwise on object array
        return out

    def region_index_of(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Index of the region containing each point, -1 where none does (the first region
        containing it). Only the points not yet placed and within a region's bounding box are
        tested against its polygon."""
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        shape = x.shape
        x, y = x.ravel(), y.ravel()
        out = np.full(x.shape, -1, dtype=np.int64)
        for i, poly in enumerate(self.polygons):
            x0, y0, x1, y1 = shapely.bounds(poly)
            cand = np.flatnonzero((out < 0) & (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1))
            if cand.size:
                out[cand[shapely.contains_xy(poly, x[cand], y[cand])]] = i
        return out.reshape(shape)

    def hop_distance(self) -> np.ndarray:
        """All-pairs hop distance between regions in the undirected region graph (p x p)."""
        und = nx.Graph(self.graph)
        n = len(self.names)
        d = np.full((n, n), -1, dtype=np.int64)
        for s, lengths in nx.all_pairs_shortest_path_length(und):
            for t, L in lengths.items():
                d[self.index[s], self.index[t]] = L
        return d

    def label(self, beam: str, direction: int) -> str:
        return beam if direction > 0 else f"{beam}^-1"


def build_region_graph(site: Site) -> RegionGraph:
    """Decompose ``site.free_space`` by its beams and build the labelled region graph.

    The beams are cut out of the free space as thin slits; the connected pieces left are the
    regions. Each region is named after the site's region whose ``point`` it contains, or
    ``r<k>`` (k from 1, ordered by centroid x then y) when the site names none.
    """
    free = site.free_space
    eps = _CUT_REL * site.diagonal
    cuts = shapely.union_all([b.line.buffer(eps, cap_style="flat") for b in site.beams]) if site.beams else None
    pieces = shapely.difference(free, cuts) if cuts is not None else free
    polys = [g for g in getattr(pieces, "geoms", [pieces]) if g.geom_type == "Polygon" and g.area > eps * site.diagonal]
    if not polys:
        raise SiteError("beams leave no free space", file=site.source, field="beams")

    names: list[str | None] = [None] * len(polys)
    for spec in site.regions:
        hits = [i for i, p in enumerate(polys) if p.contains(Point(spec.point))]
        if not hits:
            raise SiteError(
                f"point {spec.point} lies on a beam", file=site.source, field=f"regions ({spec.name}).point"
            )
        i = hits[0]
        if names[i] is not None:
            raise SiteError(
                f"regions {names[i]!r} and {spec.name!r} name the same region", file=site.source, field="regions"
            )
        names[i] = spec.name
    order = sorted(range(len(polys)), key=lambda i: (round(polys[i].centroid.x, 9), round(polys[i].centroid.y, 9)))
    taken = {n for n in names if n is not None}
    k = 1
    for i in order:
        if names[i] is None:
            while f"r{k}" in taken:
                k += 1
            names[i] = f"r{k}"
            taken.add(names[i])
    final = sorted(range(len(polys)), key=lambda i: _natural(names[i]))
    names_t = tuple(names[i] for i in final)
    polys_t = tuple(polys[i] for i in final)

    g = nx.MultiDiGraph()
    g.add_nodes_from(names_t)
    src: dict[str, str] = {}
    tgt: dict[str, str] = {}
    probe = max(10 * eps, 1e-9)
    for b in site.beams:
        mid = np.asarray(b.line.interpolate(0.5, normalized=True).coords[0])
        n = b.forward_normal
        back = front = None
        for scale in (1.0, 10.0, 100.0, 1000.0):  # nearest piece first: a neighbouring beam may be close
            back = back if back is not None else _containing(polys_t, mid - n * probe * scale)
            front = front if front is not None else _containing(polys_t, mid + n * probe * scale)
        if back is None or front is None:
            raise SiteError(
                "cannot find the regions on both sides of the beam", file=site.source, field=f"beams ({b.id})"
            )
        if back == front:
            raise SiteError(
                "both sides of the beam lie in one region; a beam must separate two regions",
                file=site.source,
                field=f"beams ({b.id})",
            )
        s, t = names_t[back], names_t[front]
        src[b.id], tgt[b.id] = s, t
        g.add_edge(s, t, key=b.id, beam=b.id, direction=1)
        g.add_edge(t, s, key=f"{b.id}^-1", beam=b.id, direction=-1)
    return RegionGraph(names_t, polys_t, g, src, tgt)


def _containing(polys, pt) -> int | None:
    for i, p in enumerate(polys):
        if shapely.contains_xy(p, pt[0], pt[1]):
            return i
    return None


def _natural(name: str):
    import re

    return [int(tok) if tok.isdigit() else tok for tok in re.split(r"(\d+)", name)]
