"""Compiled (numba) kernels of the FindingHuMo decoders: the Viterbi recursions and the whole
explain-away coordinate ascent of the Adaptive-HMM (the ascent itself in
:mod:`onebit.models.graph_hmm.ascent`, which calls the Viterbi kernels of this module).

The Viterbi recursion is inherently sequential in time (slot ``d`` needs the scores of slot
``d - 1``) and so is the coordinate ascent (each user is re-decoded with the others fixed),
so they are compiled loops (``numba.njit(cache=True)``, :mod:`onebit.core.compiled`) rather than numpy broadcasting. Each
kernel keeps its plain numpy reference implementation as the test oracle:

=======================================  ====================================================
kernel                                   reference (``tests/models/graph_hmm/test_kernels.py``)
=======================================  ====================================================
:func:`viterbi_first_order`              :func:`onebit.models.graph_hmm.viterbi.viterbi_first_order`
:func:`viterbi_second_order`             :func:`onebit.models.graph_hmm.viterbi.viterbi_second_order`
:func:`viterbi_motion_second_order`      :func:`onebit.models.graph_hmm.viterbi.viterbi_motion_second_order`
:func:`~.ascent.coordinate_ascent`      :func:`onebit.models.graph_hmm.adaptive.coordinate_ascent_reference`
                                         (every user on every state) and brute force over
                                         every path (its users decoded on their reach)
=======================================  ====================================================

Equal outputs: the kernels do the same additions in the same order as the references and
break ties the same way (the first maximal index, numpy's ``argmax``), so paths are identical
and scores equal to the last bit; only the coordinate ascent's joint log-likelihood is summed
in a different order than numpy's pairwise sum (equal to ~1e-12). No transcendental function
is evaluated inside a kernel: the emission gains (logs of powers) are tabulated once per call
by the reference's own numpy function (:func:`~.ascent.emission_tables`), so the kernels never differ
from numpy's SIMD ``log`` by an ulp.

The equations are those of :mod:`onebit.models.graph_hmm.viterbi` (Algorithms 4 and 5,
and the distinct-node second-order context) and :mod:`onebit.models.graph_hmm.adaptive`
(section 4 of its docstring).
"""

from __future__ import annotations

import numpy as np

from onebit.core.compiled import kernel

NEG_INF = -np.inf


# --------------------------------------------------------------------------- first order


@kernel
def _viterbi1(log_pi, log_a, log_b):
    """First-order Viterbi (Algorithm 4); ``log_b (D, S)``. Returns ``(path (D,), log_prob)``.

    The inner loops run over (previous state i, state j) row by row of ``log_a`` so the
    access is contiguous; ``>`` with ``i`` ascending keeps the first maximal ``i``.
    """
    n_slots, n_states = log_b.shape
    path = np.zeros(n_slots, dtype=np.int64)
    if n_slots == 0:
        return path, 0.0
    psi = np.empty((n_slots, n_states), dtype=np.int32)  # every row written before it is read
    delta = np.empty(n_states)
    for j in range(n_states):
        delta[j] = log_pi[j] + log_b[0, j]
    best = np.empty(n_states)
    for d in range(1, n_slots):  # sequential in time by construction
        arg = psi[d]
        di = delta[0]
        for j in range(n_states):
            best[j] = di + log_a[0, j]
            arg[j] = 0
        for i in range(1, n_states):
            di = delta[i]
            row = log_a[i]
            for j in range(n_states):
                v = di + row[j]
                if v > best[j]:
                    best[j] = v
                    arg[j] = i
        for j in range(n_states):
            delta[j] = best[j] + log_b[d, j]
    last = 0
    for j in range(1, n_states):
        if delta[j] > delta[last]:
            last = j
    path[n_slots - 1] = last
    for d in range(n_slots - 1, 0, -1):
        path[d - 1] = psi[d, path[d]]
    return path, delta[last]


def viterbi_first_order(log_pi: np.ndarray, log_a: np.ndarray, log_b: np.ndarray) -> tuple[np.ndarray, float]:
    """Compiled :func:`onebit.models.graph_hmm.viterbi.viterbi_first_order` (same inputs,
    same outputs): ``log_pi (S,)``, ``log_a (S, S)``, ``log_b (D, S)`` -> ``(path (D,), log_prob)``."""
    path, lp = _viterbi1(_f64(log_pi), _f64(log_a, 2), _f64(log_b, 2))
    return path, float(lp)


# --------------------------------------------------------------------------- second order


@kernel
def _viterbi2(log_pi, log_a1, log_a2, log_b):
    """Second-order Viterbi over state pairs (Algorithm 5)."""
    n_slots, n_states = log_b.shape
    path = np.zeros(n_slots, dtype=np.int64)
    if n_slots == 0:
        return path, 0.0
    if n_slots == 1:
        j = 0
        for k in range(1, n_states):
            if log_pi[k] + log_b[0, k] > log_pi[j] + log_b[0, j]:
                j = k
        path[0] = j
        return path, log_pi[j] + log_b[0, j]
    delta = np.empty((n_states, n_states))
    for a in range(n_states):
        d0 = log_pi[a] + log_b[0, a]
        for b in range(n_states):
            delta[a, b] = d0 + log_a1[a, b] + log_b[1, b]
    psi = np.zeros((n_slots, n_states, n_states), dtype=np.int64)
    best = np.empty((n_states, n_states))
    for d in range(2, n_slots):  # sequential in time by construction
        arg = psi[d]
        for jp in range(n_states):
            for j in range(n_states):
                best[jp, j] = delta[0, jp] + log_a2[0, jp, j]
                arg[jp, j] = 0
        for jpp in range(1, n_states):
            for jp in range(n_states):
                dv = delta[jpp, jp]
                row = log_a2[jpp, jp]
                for j in range(n_states):
                    v = dv + row[j]
                    if v > best[jp, j]:
                        best[jp, j] = v
                        arg[jp, j] = jpp
        for jp in range(n_states):
            for j in range(n_states):
                delta[jp, j] = best[jp, j] + log_b[d, j]
    prev, last = 0, 0
    for a in range(n_states):
        for b in range(n_states):
            if delta[a, b] > delta[prev, last]:
                prev, last = a, b
    path[n_slots - 1], path[n_slots - 2] = last, prev
    for d in range(n_slots - 1, 1, -1):
        path[d - 2] = psi[d, path[d - 1], path[d]]
    return path, delta[prev, last]


def viterbi_second_order(
    log_pi: np.ndarray, log_a1: np.ndarray, log_a2: np.ndarray, log_b: np.ndarray
) -> tuple[np.ndarray, float]:
    """Compiled :func:`onebit.models.graph_hmm.viterbi.viterbi_second_order` (same I/O)."""
    path, lp = _viterbi2(_f64(log_pi), _f64(log_a1, 2), _f64(log_a2, 3), _f64(log_b, 2))
    return path, float(lp)


@kernel
def _viterbi_motion2(log_pi, log_stay, log_move, log_b):
    """Second-order Viterbi over (previous distinct node, current node) pairs."""
    n_slots, n_states = log_b.shape
    path = np.zeros(n_slots, dtype=np.int64)
    if n_slots == 0:
        return path, 0.0
    delta = np.full((n_states, n_states), NEG_INF)
    for j in range(n_states):
        delta[j, j] = log_pi[j] + log_b[0, j]
    back = np.full((n_slots, n_states, n_states), -1, dtype=np.int64)
    best = np.empty((n_states, n_states))
    arg = np.empty((n_states, n_states), dtype=np.int64)
    new = np.empty((n_states, n_states))
    for d in range(1, n_slots):  # sequential in time by construction
        for j in range(n_states):
            dv = delta[0, j]
            row = log_move[0, j]
            for k in range(n_states):
                best[j, k] = dv + row[k]
                arg[j, k] = 0
        for p in range(1, n_states):
            for j in range(n_states):
                dv = delta[p, j]
                row = log_move[p, j]
                for k in range(n_states):
                    v = dv + row[k]
                    if v > best[j, k]:
                        best[j, k] = v
                        arg[j, k] = p
        bd = back[d]
        for j in range(n_states):
            for k in range(n_states):
                stay = delta[j, k] + log_stay[k]
                move = NEG_INF if j == k else best[j, k]
                if move > stay:
                    bd[j, k] = arg[j, k]
                    new[j, k] = move + log_b[d, k]
                else:
                    new[j, k] = stay + log_b[d, k]
        for j in range(n_states):
            for k in range(n_states):
                delta[j, k] = new[j, k]
    x, y = 0, 0
    for a in range(n_states):
        for b in range(n_states):
            if delta[a, b] > delta[x, y]:
                x, y = a, b
    score = delta[x, y]
    path[n_slots - 1] = y
    for d in range(n_slots - 1, 0, -1):
        b = back[d, x, y]
        if b >= 0:
            x, y = b, x
        path[d - 1] = y
    return path, score


@kernel
def move_support(log_move):
    """The moves a second-order tensor allows, as CSR over the current node ``j``: the next
    nodes ``k`` with ``log_move[p, j, k] > -inf`` for some previous node ``p``
    (``k_idx[k_ptr[j]:k_ptr[j+1]]``, ascending). On a sensor graph these are ``j``'s
    neighbours: a handful, not the graph."""
    n = log_move.shape[0]
    mask = np.zeros((n, n), dtype=np.bool_)
    for p in range(n):
        for j in range(n):
            for k in range(n):
                if log_move[p, j, k] > NEG_INF:
                    mask[j, k] = True
    k_ptr = np.zeros(n + 1, dtype=np.int64)
    for j in range(n):
        k_ptr[j + 1] = k_ptr[j] + mask[j].sum()
    k_idx = np.empty(k_ptr[n], dtype=np.int64)
    q = 0
    for j in range(n):
        for k in range(n):
            if mask[j, k]:
                k_idx[q] = k
                q += 1
    return k_ptr, k_idx


@kernel
def _grow(arr, need):
    """``arr`` if it holds ``need`` items, else a copy twice as large (or ``need``)."""
    if need <= arr.shape[0]:
        return arr
    out = np.empty(max(need, 2 * arr.shape[0]), dtype=arr.dtype)
    out[: arr.shape[0]] = arr
    return out


@kernel
def _best_moves(delta, ca, cb, nc, blocks, gs, k_ptr, k_idx, k_col, base_of, best, arg, touched, ta, tb):
    """One slot's moves of :func:`_viterbi_motion2_local`: ``best[j, k] = max_p delta[p, j] +
    log_move[p, j, k]`` over the finite pairs ``(ca, cb)`` and the moves of the support, ``arg``
    the smallest maximising ``p``; the pairs a move reaches are marked in ``touched`` and listed
    in ``(ta, tb)`` (grown as needed). Returns ``(ta, tb, count)``."""
    nt = 0
    for i in range(nc):
        p = ca[i]
        j = cb[i]
        dv = delta[p, j]
        base = base_of[p, j]
        for q in range(k_ptr[j], k_ptr[j + 1]):
            k = k_idx[q]
            if k == j:
                continue
            v = dv + blocks[4][base + k_col[q]]
            if v == NEG_INF:
                continue
            if not touched[j, k]:
                touched[j, k] = True
                base_of[j, k] = blocks[5][blocks[3][gs[j]] + k_col[q]]
                ta = _grow(ta, nt + 1)
                tb = _grow(tb, nt + 1)
                ta[nt] = j
                tb[nt] = k
                nt += 1
                best[j, k] = v
                arg[j, k] = p
            elif v > best[j, k] or (v == best[j, k] and p < arg[j, k]):
                best[j, k] = v
                arg[j, k] = p
    return ta, tb, nt


@kernel
def _backtrack_pairs(delta, ca, cb, nc, rec_ptr, ra, rb, rp, path):
    """The end of :func:`_viterbi_motion2_local`: the row-major first maximal pair of the last
    ``delta``, then back through the slots' sparse back-pointers (a pair without one stayed).
    Fills ``path``; returns the score."""
    n_slots = path.shape[0]
    x, y = 0, 0
    for i in range(nc):  # the row-major first maximum
        a, b = ca[i], cb[i]
        if delta[a, b] > delta[x, y] or (delta[a, b] == delta[x, y] and (a < x or (a == x and b < y))):
            x, y = a, b
    score = delta[x, y]
    path[n_slots - 1] = y
    for d in range(n_slots - 1, 0, -1):
        b = -1
        for r in range(rec_ptr[d], rec_ptr[d + 1]):
            if ra[r] == x and rb[r] == y:
                b = rp[r]
                break
        if b >= 0:
            x, y = b, x
        path[d - 1] = y
    return score


@kernel
def _viterbi_motion2_local(log_pi, log_stay, blocks, gs, log_b, k_ptr, k_idx, k_col):
    """:func:`_viterbi_motion2` over the reachable pairs only: it keeps the list of the
    (previous, current) pairs whose ``delta`` is finite and, per slot, extends each by the moves
    :func:`move_support` allows and by staying. A user whose last nodes are known (the clamped
    prefix) reaches a few pairs per slot, so the cost follows the neighbourhood it can reach, not
    the graph; one that may start anywhere reaches every node. Back-pointers are kept only where
    a move wins (per slot, sparse). Every maximum keeps the dense kernel's choice (the smallest
    previous node among equals; the row-major first pair at the end), so the path and the score
    are the dense kernel's (tests).

    Local states: state ``i`` of ``log_pi``, ``log_stay``, ``log_b`` and of the support
    ``k_ptr``/``k_idx`` is the tensor's node ``gs[i]`` (``gs`` ascending), so a user's decode
    runs on the nodes it can reach (:func:`onebit.models.graph_hmm.ascent._ascent_one_order`); the moves are read from
    ``blocks`` (:func:`motion_blocks`: per node, its contexts x its next nodes, the tensor of the
    whole state set stored sparse), move ``q`` of the local support being column ``k_col[q]`` of
    its node's block (each pair's row offset kept from its creation: ``blocks[5]``, ``blocks[6]``). A
    finite pair ``(p, j)`` always has ``p`` among ``j``'s contexts (it was
    reached by a move ``p -> j`` of the support, or is a start ``(j, j)``).
    :func:`_viterbi_motion2_sparse` is the identity map."""
    n_slots, n = log_b.shape
    path = np.zeros(n_slots, dtype=np.int64)
    if n_slots == 0:
        return path, 0.0
    delta = np.full((n, n), NEG_INF)
    nd = np.full((n, n), NEG_INF)
    best = np.full((n, n), NEG_INF)
    arg = np.zeros((n, n), dtype=np.int64)
    touched = np.zeros((n, n), dtype=np.bool_)
    base_of = np.empty((n, n), dtype=np.int64)  # a finite pair's row in its node's block (offset in vals)
    ca = np.empty(max(n, 16), dtype=np.int64)  # the finite pairs of delta: (ca[i], cb[i])
    cb = np.empty(max(n, 16), dtype=np.int64)
    nc = 0
    for j in range(n):
        v = log_pi[j] + log_b[0, j]
        if v > NEG_INF:
            delta[j, j] = v
            base_of[j, j] = blocks[6][gs[j]]
            ca[nc] = j
            cb[nc] = j
            nc += 1
    ta = np.empty(16, dtype=np.int64)  # pairs a move reaches this slot
    tb = np.empty(16, dtype=np.int64)
    na = np.empty(16, dtype=np.int64)  # the finite pairs of the next delta
    nb = np.empty(16, dtype=np.int64)
    rec_ptr = np.zeros(n_slots + 1, dtype=np.int64)  # back-pointers where a move won: per slot
    ra = np.empty(16, dtype=np.int64)
    rb = np.empty(16, dtype=np.int64)
    rp = np.empty(16, dtype=np.int64)
    nr = 0
    for d in range(1, n_slots):  # sequential in time by construction
        ta, tb, nt = _best_moves(
            delta, ca, cb, nc, blocks, gs, k_ptr, k_idx, k_col, base_of, best, arg, touched, ta, tb
        )
        nn = 0
        for pass_ in range(2):  # the pairs a move reaches, then the others that stay
            m = nt if pass_ == 0 else nc
            for i in range(m):
                j = ta[i] if pass_ == 0 else ca[i]
                k = tb[i] if pass_ == 0 else cb[i]
                if pass_ == 1 and touched[j, k]:
                    continue
                stay = delta[j, k] + log_stay[k]
                move = best[j, k] if pass_ == 0 else NEG_INF
                if move > stay:
                    ra = _grow(ra, nr + 1)
                    rb = _grow(rb, nr + 1)
                    rp = _grow(rp, nr + 1)
                    ra[nr] = j
                    rb[nr] = k
                    rp[nr] = arg[j, k]
                    nr += 1
                    v = move + log_b[d, k]
                else:
                    v = stay + log_b[d, k]
                if v > NEG_INF:
                    nd[j, k] = v
                    na = _grow(na, nn + 1)
                    nb = _grow(nb, nn + 1)
                    na[nn] = j
                    nb[nn] = k
                    nn += 1
        rec_ptr[d + 1] = nr
        for i in range(nt):
            touched[ta[i], tb[i]] = False
            best[ta[i], tb[i]] = NEG_INF
            arg[ta[i], tb[i]] = 0
        for i in range(nc):
            delta[ca[i], cb[i]] = NEG_INF
        delta, nd = nd, delta
        ca, na = na, ca
        cb, nb = nb, cb
        nc = nn
    return path, _backtrack_pairs(delta, ca, cb, nc, rec_ptr, ra, rb, rp, path)


@kernel
def _context_bases(p_ptr, p_idx, blk_ptr, k_ptr, k_idx):
    """Where each move's pair starts in ``vals``: ``arr[q]`` for move ``q`` (``j -> k``) the
    row of context ``j`` in ``k``'s block, ``own[j]`` the row of ``j`` (no direction yet) in its
    own block -- looked up once per model, so the decoders never search a context list."""
    n = p_ptr.shape[0] - 1
    arr = np.zeros(k_idx.shape[0], dtype=np.int64)
    own = np.zeros(n, dtype=np.int64)
    for j in range(n):
        for z in range(p_ptr[j], p_ptr[j + 1]):
            if p_idx[z] == j:
                own[j] = blk_ptr[j] + (z - p_ptr[j]) * (k_ptr[j + 1] - k_ptr[j])
        for q in range(k_ptr[j], k_ptr[j + 1]):
            k = k_idx[q]
            for z in range(p_ptr[k], p_ptr[k + 1]):
                if p_idx[z] == j:
                    arr[q] = blk_ptr[k] + (z - p_ptr[k]) * (k_ptr[k + 1] - k_ptr[k])
    return arr, own


@kernel
def _blocks_from_dense(log_move, k_ptr, k_idx):
    """:func:`motion_blocks` of a dense tensor."""
    n = log_move.shape[0]
    p_cnt = np.ones(n, dtype=np.int64)  # the node itself (no direction known yet)
    for p in range(n):
        for q in range(k_ptr[p], k_ptr[p + 1]):
            if k_idx[q] != p:
                p_cnt[k_idx[q]] += 1
    p_ptr = np.zeros(n + 1, dtype=np.int64)
    for j in range(n):
        p_ptr[j + 1] = p_ptr[j] + p_cnt[j]
    p_idx = np.empty(p_ptr[n], dtype=np.int64)
    fill = p_ptr[:-1].copy()
    for p in range(n):  # ascending p: each node's contexts come out sorted
        for q in range(k_ptr[p], k_ptr[p + 1]):
            j = k_idx[q]
            if j != p:
                p_idx[fill[j]] = p
                fill[j] += 1
        p_idx[fill[p]] = p  # placed in p's own list at its turn: ascending overall
        fill[p] += 1
    blk_ptr = np.zeros(n + 1, dtype=np.int64)
    for j in range(n):
        blk_ptr[j + 1] = blk_ptr[j] + (p_ptr[j + 1] - p_ptr[j]) * (k_ptr[j + 1] - k_ptr[j])
    vals = np.empty(blk_ptr[n])
    for j in range(n):
        nk = k_ptr[j + 1] - k_ptr[j]
        for r in range(p_ptr[j + 1] - p_ptr[j]):
            p = p_idx[p_ptr[j] + r]
            for c in range(nk):
                vals[blk_ptr[j] + r * nk + c] = log_move[p, j, k_idx[k_ptr[j] + c]]
    return p_ptr, p_idx, blk_ptr, vals


def motion_blocks(log_move: np.ndarray, k_ptr: np.ndarray, k_idx: np.ndarray) -> tuple:
    """A second-order tensor ``log_move[p, j, k]`` stored sparse, as the decoders read it:
    ``(p_ptr, p_idx, blk_ptr, k_ptr, vals, arr, own)`` -- per node ``j`` its contexts ``p`` (``j`` itself and
    the nodes that move to ``j``: ``p_idx[p_ptr[j]:p_ptr[j+1]]``, ascending), its next nodes
    (``k_idx[k_ptr[j]:k_ptr[j+1]]``, :func:`move_support`) and the block ``contexts x next
    nodes`` of values at ``vals[blk_ptr[j]:blk_ptr[j+1]]`` (row-major), and where each pair's row
    starts (:func:`_context_bases`). ``O(N deg^2)``, where the
    tensor is ``N^3``; :func:`onebit.models.graph_hmm.window.second_order_support` builds it
    without the dense tensor."""
    p_ptr, p_idx, blk_ptr, vals = _blocks_from_dense(_f64(log_move, 3), k_ptr, k_idx)
    return with_bases(p_ptr, p_idx, blk_ptr, np.asarray(k_ptr, np.int64), vals, np.asarray(k_idx, np.int64))


def with_bases(p_ptr, p_idx, blk_ptr, k_ptr, vals, k_idx) -> tuple:
    """The :func:`motion_blocks` tuple ``(p_ptr, p_idx, blk_ptr, k_ptr, vals, arr, own)`` with
    the offsets of :func:`_context_bases`."""
    arr, own = _context_bases(p_ptr, p_idx, blk_ptr, k_ptr, k_idx)
    return p_ptr, p_idx, blk_ptr, k_ptr, vals, arr, own


@kernel
def _viterbi_motion2_sparse(log_pi, log_stay, log_move, log_b, k_ptr, k_idx):
    """:func:`_viterbi_motion2_local` on every state of ``log_move`` (the identity map)."""
    p_ptr, p_idx, blk_ptr, vals = _blocks_from_dense(log_move, k_ptr, k_idx)
    arr, own = _context_bases(p_ptr, p_idx, blk_ptr, k_ptr, k_idx)
    col = np.empty(k_idx.shape[0], dtype=np.int64)
    for j in range(k_ptr.shape[0] - 1):
        for q in range(k_ptr[j], k_ptr[j + 1]):
            col[q] = q - k_ptr[j]
    return _viterbi_motion2_local(
        log_pi,
        log_stay,
        (p_ptr, p_idx, blk_ptr, k_ptr, vals, arr, own),
        np.arange(log_b.shape[1], dtype=np.int64),
        log_b,
        k_ptr,
        k_idx,
        col,
    )


def viterbi_motion_second_order(
    log_pi: np.ndarray, log_stay: np.ndarray, log_move: np.ndarray, log_b: np.ndarray
) -> tuple[np.ndarray, float]:
    """Compiled :func:`onebit.models.graph_hmm.viterbi.viterbi_motion_second_order` (same I/O)."""
    path, lp = _viterbi_motion2(_f64(log_pi), _f64(log_stay), _f64(log_move, 3), _f64(log_b, 2))
    return path, float(lp)


def _f64(a, ndim: int = 1) -> np.ndarray:
    """A C-contiguous float64 array of ``ndim`` dimensions (one compiled signature per kernel)."""
    out = np.ascontiguousarray(a, dtype=np.float64)
    if out.ndim != ndim:
        raise ValueError(f"expected a {ndim}-d array, got shape {out.shape}")
    return out


# --------------------------------------------------------------------------- capping the users


@kernel
def cap_users_pass(paths, active, hops, cap):
    """Compiled :func:`onebit.models.graph_hmm.decoding.cap_users_reference` (same output): per
    slot the present users ranked by (node active now, last slot it was active, held by an
    identity, user index), the first ``cap`` kept, each newly kept user given the free identity
    whose last node is nearest in hops (first of equals). Sequential over slots; ``O(cap U)``
    per slot."""
    n_users, n_slots = paths.shape
    out = np.full((cap, n_slots), -1, dtype=np.int64)
    holder = np.full(cap, -1, dtype=np.int64)
    last_node = np.full(cap, -1, dtype=np.int64)
    seen = np.full(n_users, -1, dtype=np.int64)
    lit = np.zeros(n_users, dtype=np.bool_)
    held = np.zeros(n_users, dtype=np.bool_)
    taken = np.zeros(n_users, dtype=np.bool_)
    keep = np.empty(cap, dtype=np.int64)
    in_keep = np.zeros(n_users, dtype=np.bool_)
    for s in range(n_slots):
        for u in range(n_users):
            q = paths[u, s]
            lit[u] = q >= 0 and active[s, q]
            if lit[u]:
                seen[u] = s
            held[u] = False
            taken[u] = False
            in_keep[u] = False
        for i in range(cap):
            if holder[i] >= 0:
                held[holder[i]] = True
        n_keep = 0
        while n_keep < cap:  # the next present user in (lit, seen, held, index) order
            b = -1
            for u in range(n_users):
                if paths[u, s] < 0 or taken[u]:
                    continue
                if b < 0:
                    b = u
                    continue
                if lit[u] != lit[b]:
                    better = lit[u]
                elif seen[u] != seen[b]:
                    better = seen[u] > seen[b]
                else:
                    better = held[u] and not held[b]
                if better:
                    b = u
            if b < 0:
                break
            taken[b] = True
            keep[n_keep] = b
            in_keep[b] = True
            n_keep += 1
        for i in range(cap):
            if holder[i] >= 0 and not in_keep[holder[i]]:
                holder[i] = -1
        for r in range(n_keep):
            u = keep[r]
            have = False
            for i in range(cap):
                if holder[i] == u:
                    have = True
            if have:
                continue
            best_i = -1
            best_d = 0
            for i in range(cap):
                if holder[i] >= 0:
                    continue
                d = hops[last_node[i], paths[u, s]] if last_node[i] >= 0 else 0
                if best_i < 0 or d < best_d:
                    best_i, best_d = i, d
            holder[best_i] = u
        for i in range(cap):
            if holder[i] >= 0:
                out[i, s] = paths[holder[i], s]
                last_node[i] = out[i, s]
    return out
