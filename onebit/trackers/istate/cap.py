"""The cap ``M`` of section VI-A (:mod:`onebit.trackers.istate.core`): while more than ``M``
elements, merge the two most similar into their region-wise union. :func:`cap_elements`
computes only the similarities that can decide a merge (branch and bound on the regions'
bounding boxes); :func:`cap_elements_reference` computes every one (same result).
"""

from __future__ import annotations

import numpy as np
import shapely

from onebit.core.lazy import lazy_module
from onebit.trackers.istate.cleanup import (
    clean_up,
)
from onebit.trackers.istate.matching import (
    PERM_TABLE_MAX_N,
    permutations,
)
from onebit.trackers.istate.memo import PairMemo, _bounds, _intersection_area
from onebit.trackers.istate.regions import (
    IState,
    constrain,
)

_optimize = lazy_module("scipy.optimize")


#: Largest number of elements whose pairwise similarities the cap computes at once.
CAP_CHUNK = 128

#: Similarities computed per round of the cap's branch and bound (largest upper bounds first):
#: small, since the first exact values usually rule the rest out (measured: 2 is fastest).
SETTLE_BATCH = 2


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


def _capped_by_chunks(cap, istate: IState, max_elements: int, *, shape: str, memo: PairMemo, delta) -> IState:
    """``cap`` (:func:`cap_elements` or its reference) of each chunk of ``CAP_CHUNK`` elements,
    then of their cleaned-up union: the pairwise similarity matrix stays ``O(CAP_CHUNK^2 n^2)``."""
    parts = [
        cap(IState(istate.regions[i : i + CAP_CHUNK]), max_elements, shape=shape, memo=memo, delta=delta).regions
        for i in range(0, istate.regions.shape[0], CAP_CHUNK)
    ]
    return cap(
        clean_up(IState(np.vstack(parts)), shape=shape, memo=memo, delta=delta),
        max_elements,
        shape=shape,
        memo=memo,
        delta=delta,
    )


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
        return _capped_by_chunks(cap_elements, istate, max_elements, shape=shape, memo=memo, delta=delta)
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
