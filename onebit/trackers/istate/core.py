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
  non-empty-intersection graph); :func:`onebit._testing.oracles.communicate_bruteforce` is the direct
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

Modules. This one holds the filter's steps (Algorithm 1, the query, the communication
update, :func:`info_state_update`) and every name of the filter; the rest lives in its own
module, one per step: :mod:`~onebit.trackers.istate.regions` (the representation, buffers,
shapes, :class:`SiteFrame`), :mod:`~onebit.trackers.istate.memo` (:class:`PairMemo`),
:mod:`~onebit.trackers.istate.matching` (perfect matchings),
:mod:`~onebit.trackers.istate.cleanup` (:func:`clean_up`) and
:mod:`~onebit.trackers.istate.cap` (:func:`cap_elements`).
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from onebit.trackers.istate.cap import (
    CAP_CHUNK,
    SETTLE_BATCH,
    best_pairing,
    cap_elements,
    cap_elements_reference,
    merge_elements,
    overlap_areas,
)
from onebit.trackers.istate.cleanup import canonical, clean_up, covers_matrix, covers_pairs, remove_dominated
from onebit.trackers.istate.matching import (
    PERM_TABLE_MAX_N,
    enumerate_perfect_matchings,
    has_perfect_matching,
    permutations,
)
from onebit.trackers.istate.memo import MEMO_CAPACITY, PairMemo, _bounds
from onebit.trackers.istate.regions import (
    DISK_GRID,
    FRAME_GRID,
    QUAD_SEGS,
    REL_TOL,
    SHAPES,
    IState,
    SiteFrame,
    constrain,
    disk,
    grow,
    shrink,
    site_scale,
    tolerance,
    void,
)

#: The filter's names: its steps here, the rest from the modules it is split into.
__all__ = [
    "best_pairing",
    "canonical",
    "CAP_CHUNK",
    "cap_elements",
    "cap_elements_reference",
    "clean_up",
    "communicate",
    "constrain",
    "contains",
    "contains_states",
    "covers_matrix",
    "covers_pairs",
    "disk",
    "DISK_GRID",
    "enumerate_perfect_matchings",
    "forward_project",
    "FRAME_GRID",
    "grow",
    "has_perfect_matching",
    "info_state_update",
    "IState",
    "MEMO_CAPACITY",
    "merge_elements",
    "negative_update",
    "observation_update",
    "overlap_areas",
    "PairMemo",
    "PERM_TABLE_MAX_N",
    "permutations",
    "QUAD_SEGS",
    "REL_TOL",
    "remove_dominated",
    "same_elements",
    "SETTLE_BATCH",
    "SHAPES",
    "shrink",
    "site_scale",
    "SiteFrame",
    "tolerance",
    "void",
]


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
