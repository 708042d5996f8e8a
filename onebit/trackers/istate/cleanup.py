"""The clean-up of an I-state (:mod:`onebit.trackers.istate.core`): canonical order, empty and
duplicate elements removed, dominated elements removed (an element is dominated when a
perfect matching of its regions into another's covers it, to within ``delta``).
"""

from __future__ import annotations

import math

import numpy as np
import shapely

from onebit.trackers.istate.matching import (
    has_perfect_matching,
)
from onebit.trackers.istate.memo import PairMemo, _bounds
from onebit.trackers.istate.regions import (
    IState,
    tolerance,
    void,
)


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
