"""Compiled (numba) kernels of the FindingHuMo decoders: the Viterbi recursions and the whole
explain-away coordinate ascent of the Adaptive-HMM.

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
:func:`coordinate_ascent`                :func:`onebit.models.graph_hmm.adaptive.coordinate_ascent_reference`
                                         (every user on every state) and brute force over
                                         every path (its users decoded on their reach)
=======================================  ====================================================

Equal outputs: the kernels do the same additions in the same order as the references and
break ties the same way (the first maximal index, numpy's ``argmax``), so paths are identical
and scores equal to the last bit; only the coordinate ascent's joint log-likelihood is summed
in a different order than numpy's pairwise sum (equal to ~1e-12). No transcendental function
is evaluated inside a kernel: the emission gains (logs of powers) are tabulated once per call
by the reference's own numpy function (:func:`emission_tables`), so the kernels never differ
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
    runs on the nodes it can reach (:func:`_ascent_one_order`); the moves are read from
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
        nt = 0
        for i in range(nc):  # best[j, k] = max_p delta[p, j] + log_move[p, j, k]
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
    return path, score


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
    tensor is ``N^3``; :func:`onebit.models.graph_hmm.adaptive.second_order_support` builds it
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


# --------------------------------------------------------------------------- coordinate ascent


def emission_tables(k: int, p_hit: float, p_false: float, gain) -> np.ndarray:
    """``(4, k + 2)`` table over the claim count ``c = 0..k+1`` of the noisy-OR emission model:
    rows ``gain(on)``, ``gain(off)`` (``gain`` = the reference's
    :func:`~onebit.models.graph_hmm.adaptive.emission_gain`, evaluated by numpy) and
    ``log P(on | c)``, ``log P(off | c)`` (the terms of the joint emission)."""
    c = np.arange(k + 2, dtype=np.int64)[None, :]
    on = np.ones_like(c, dtype=bool)
    cf = c.astype(float)
    p_on = np.where(cf > 0, 1.0 - (1.0 - p_hit) ** cf, p_false)
    return np.vstack([gain(on, c, p_hit, p_false), gain(~on, c, p_hit, p_false), np.log(p_on), np.log1p(-p_on)]).astype(
        np.float64
    )


def transition_support(log_a1: np.ndarray, log_a2: np.ndarray | None) -> tuple:
    """The moves of a window's transitions, for the local decodes of :func:`coordinate_ascent`:
    ``(f_ptr, f_idx, b_ptr, b_idx, t_max, blocks, log_stay)`` -- the next states of each state as CSR
    (:func:`move_support` of ``log_a2`` for the second order, the finite entries of ``log_a1``
    for the first), the same graph transposed (the states each state is reached from), the
    largest log transition a path can take (stay or move, ``<= 0``) and the transitions stored
    sparse: for the second order the tensor (:func:`motion_blocks`), for the first the value of
    each move beside it (``blocks[4][q]`` is ``log_a1`` of move ``q``); and the stays
    (``diag log_a1``). Computed once per
    state set (the full-state baselines: once per run, without the dense tensor:
    :func:`onebit.models.graph_hmm.adaptive.second_order_support`)."""
    if log_a2 is not None:
        a2 = _f64(log_a2, 3)
        f_ptr, f_idx = move_support(a2)
        return support_from_blocks(motion_blocks(a2, f_ptr, f_idx), f_idx, np.diag(log_a1))
    a1 = _f64(log_a1, 2)
    rows, cols = np.nonzero(a1 > NEG_INF)
    f_ptr = np.zeros(a1.shape[0] + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=a1.shape[0]), out=f_ptr[1:])
    f_idx = cols.astype(np.int64)
    t_max = float(a1.max()) if a1.size else NEG_INF
    z = np.zeros(a1.shape[0] + 1, dtype=np.int64)
    first = (  # one row per node: each move's value beside it
        z,
        np.zeros(0, np.int64),
        f_ptr,
        f_ptr,
        np.ascontiguousarray(a1[rows, cols]),
        np.zeros(f_idx.size, np.int64),
        np.zeros(a1.shape[0], np.int64),
    )
    return (*_transpose(f_ptr, f_idx), min(t_max, 0.0), first, np.ascontiguousarray(np.diag(a1)))


def support_from_blocks(blocks: tuple, k_idx: np.ndarray, log_stay: np.ndarray) -> tuple:
    """:func:`transition_support` of a second-order tensor given as :func:`motion_blocks` (its
    next-node lists ``k_idx``; ``log_stay`` the stays)."""
    f_ptr = blocks[3]
    vals = blocks[4]
    stay = np.ascontiguousarray(log_stay, dtype=np.float64)
    t_max = max(float(vals.max()) if vals.size else NEG_INF, float(np.max(stay)) if len(stay) else NEG_INF)
    return (*_transpose(f_ptr, np.asarray(k_idx, np.int64)), min(t_max, 0.0), blocks, stay)


def _transpose(f_ptr: np.ndarray, f_idx: np.ndarray) -> tuple:
    """``(f_ptr, f_idx, b_ptr, b_idx)``: a CSR graph and its transpose (rows ascending)."""
    n = len(f_ptr) - 1
    src = np.repeat(np.arange(n, dtype=np.int64), np.diff(f_ptr))
    order = np.lexsort((src, f_idx))  # by destination, then source: ascending rows of the transpose
    b_ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(f_idx, minlength=n), out=b_ptr[1:])
    return f_ptr, f_idx, b_ptr, src[order]


@kernel
def _reach(seeds, n_seeds, radius, f_ptr, f_idx, b_ptr, b_idx, dist, out):
    """The states within ``radius`` moves of ``seeds[:n_seeds]`` on the transition graph taken
    both ways (breadth first), ascending in ``out``; returns their count. ``dist`` (``-1`` on
    entry) is left ``-1``. Cost: the states reached and their moves, not the state set."""
    n = 0
    for i in range(n_seeds):
        q = seeds[i]
        if dist[q] < 0:
            dist[q] = 0
            out[n] = q
            n += 1
    head = 0
    while head < n:
        j = out[head]
        head += 1
        dj = dist[j]
        if dj >= radius:
            continue
        for w in range(2):
            ptr = f_ptr if w == 0 else b_ptr
            idx = f_idx if w == 0 else b_idx
            for q in range(ptr[j], ptr[j + 1]):
                k = idx[q]
                if dist[k] < 0:
                    dist[k] = dj + 1
                    out[n] = k
                    n += 1
    for i in range(n):
        dist[out[i]] = -1
    out[:n] = np.sort(out[:n])
    return n


@kernel
def _claims(decoded, u, t, q):
    """Users other than ``u`` at state ``q`` in slot ``t``."""
    c = 0
    for v in range(decoded.shape[0]):
        if v != u and decoded[v, t] == q:
            c += 1
    return c


@kernel
def _decode_local(
    u, gs, n_loc, on, decoded, pre, npre, st, entry_u, order, log_a1, log_stay, blocks, f_ptr, f_idx, loc, table
):
    """One user's Viterbi (with the other users' claims fixed) on the states ``gs[:n_loc]``:
    emissions, initial distribution, transitions and moves restricted to them. Returns the
    path (rows: the clamped prefix, then slots ``st..L-1``) in state indices and its score."""
    n_slots = on.shape[0]
    gl = gs[:n_loc]
    for i in range(n_loc):
        loc[gl[i]] = i
    rows = npre + n_slots - st
    log_b = np.empty((rows, n_loc))
    for r in range(npre):
        for i in range(n_loc):
            log_b[r, i] = NEG_INF
        log_b[r, loc[pre[u, r]]] = 0.0
    for t in range(st, n_slots):
        r = npre + t - st
        for i in range(n_loc):  # no other user here, then the states other users hold
            log_b[r, i] = table[0, 0] if on[t, gl[i]] else table[1, 0]
        for v in range(decoded.shape[0]):
            q = decoded[v, t]
            if v != u and q >= 0 and loc[q] >= 0:
                c = _claims(decoded, u, t, q)
                log_b[r, loc[q]] = table[0, c] if on[t, q] else table[1, c]
    log_pi = np.zeros(n_loc)
    if npre == 0 and entry_u >= 0:
        for i in range(n_loc):
            log_pi[i] = NEG_INF
        log_pi[loc[entry_u]] = 0.0
    if order == 2:
        lk_ptr = np.zeros(n_loc + 1, dtype=np.int64)
        m = 0
        for i in range(n_loc):
            g = gl[i]
            for q in range(f_ptr[g], f_ptr[g + 1]):
                if loc[f_idx[q]] >= 0:
                    m += 1
            lk_ptr[i + 1] = m
        lk_idx = np.empty(m, dtype=np.int64)
        lk_col = np.empty(m, dtype=np.int64)  # the move's column in its node's block
        m = 0
        for i in range(n_loc):
            g = gl[i]
            for q in range(f_ptr[g], f_ptr[g + 1]):
                if loc[f_idx[q]] >= 0:
                    lk_idx[m] = loc[f_idx[q]]
                    lk_col[m] = q - f_ptr[g]
                    m += 1
        stay = np.empty(n_loc)
        for i in range(n_loc):
            stay[i] = log_stay[gl[i]]
        path, score = _viterbi_motion2_local(log_pi, stay, blocks, gl, log_b, lk_ptr, lk_idx, lk_col)
    else:
        if n_loc == log_a1.shape[0]:  # every state: the matrix as it is
            path, score = _viterbi1(log_pi, log_a1, log_b)
        else:
            a1 = np.full((n_loc, n_loc), NEG_INF)  # the finite entries only: the moves of the support
            for i in range(n_loc):
                g = gl[i]
                for q in range(f_ptr[g], f_ptr[g + 1]):
                    k = loc[f_idx[q]]
                    if k >= 0:
                        a1[i, k] = blocks[4][q]  # the move's value, stored beside it (first order)
            path, score = _viterbi1(log_pi, a1, log_b)
    emis_sum = 0.0
    for t in range(st, n_slots):
        emis_sum += log_b[npre + t - st, path[npre + t - st]]
    for i in range(n_loc):
        loc[gl[i]] = -1
    out = np.empty(rows, dtype=np.int64)
    for r in range(rows):
        out[r] = gl[path[r]]
    return out, score, emis_sum


@kernel
def _ascent_one_order(
    on,
    on_ptr,
    on_idx,
    pre,
    n_pre,
    starts,
    entry,
    order_u,
    order,
    log_a1,
    log_stay,
    blocks,
    support,
    table,
    sweeps,
    decoded,
    stats,
    scratch,
):
    """Explain-away sweeps over the users in ``order_u``; fills ``decoded (K, L)`` and returns the
    joint log-likelihood (see :func:`coordinate_ascent`; ``stats`` counts the decodes, those on
    all states and the certificate fallbacks; ``scratch`` (4, S) int: ``-1``, ``-1``, any, and
    ``0..S-1``, left as found)."""
    f_ptr, f_idx, b_ptr, b_idx, t_max = support
    n_slots, s = on.shape
    k = pre.shape[0]
    for u in range(k):
        for t in range(n_slots):
            decoded[u, t] = -1
    trans = np.zeros(k)
    dist, loc, gs, everything = scratch[0], scratch[1], scratch[2], scratch[3]
    seeds = np.empty(max(on_idx.shape[0], 1), dtype=np.int64)
    g0 = table[1, 0]  # the largest emission of a state that is off (no claim: off with claims is lower)
    for _ in range(max(sweeps, 1)):
        for oi in range(order_u.shape[0]):
            u = order_u[oi]
            st = starts[u]
            if st >= n_slots:
                continue
            for t in range(n_slots):
                decoded[u, t] = -1
            npre = n_pre[u]
            rows = npre + n_slots - st
            # the states the user can be at (module docstring of adaptive, "local decodes")
            uniform = False
            if npre > 0:
                seeds[0] = pre[u, npre - 1]
                n_loc = _reach(seeds, 1, rows - npre, f_ptr, f_idx, b_ptr, b_idx, dist, gs)
                if npre == 2:  # its context node, if farther
                    have = False
                    for i in range(n_loc):
                        have = have or gs[i] == pre[u, 0]
                    if not have:
                        gs[n_loc] = pre[u, 0]
                        n_loc += 1
                        gs[:n_loc] = np.sort(gs[:n_loc])
            elif entry[u] >= 0:
                seeds[0] = entry[u]
                n_loc = _reach(seeds, 1, rows - 1, f_ptr, f_idx, b_ptr, b_idx, dist, gs)
            else:
                uniform = True
                ns = 0
                for q in range(on_ptr[st], on_ptr[n_slots]):
                    seeds[ns] = on_idx[q]
                    ns += 1
                n_loc = _reach(seeds, ns, rows - 1, f_ptr, f_idx, b_ptr, b_idx, dist, gs) if ns else 0
            stats[0] += 1
            full = n_loc == 0 or 2 * n_loc > s  # reaching most states: every state (no certificate needed)
            path, score, emis_sum = _decode_local(
                u,
                everything if full else gs,
                s if full else n_loc,
                on,
                decoded,
                pre,
                npre,
                st,
                entry[u],
                order,
                log_a1,
                log_stay,
                blocks,
                f_ptr,
                f_idx,
                loc,
                table,
            )
            redo = False
            if not full:
                if score == NEG_INF:  # no path (a clamped jump): the all-state decode's choice among equals
                    redo = True
                elif uniform:
                    bound = g0  # the best score of a path that never meets an active state
                    for _r in range(1, rows):
                        bound = (bound + t_max) + g0
                    if not score > bound:  # not certified: decode on every state
                        redo = True
                        stats[2] += 1
                if redo:
                    path, score, emis_sum = _decode_local(
                        u,
                        everything,
                        s,
                        on,
                        decoded,
                        pre,
                        npre,
                        st,
                        entry[u],
                        order,
                        log_a1,
                        log_stay,
                        blocks,
                        f_ptr,
                        f_idx,
                        loc,
                        table,
                    )
            if full or redo:
                stats[1] += 1
            trans[u] = score - emis_sum
            for t in range(st, n_slots):
                decoded[u, t] = path[npre + t - st]
    total = 0.0
    for u in range(k):
        total += trans[u]
    joint = 0.0
    for t in range(n_slots):  # the states with an activation or a user; every other one is off and free
        special = 0
        for q in range(on_ptr[t], on_ptr[t + 1]):
            joint += table[2, _claims(decoded, -1, t, on_idx[q])]
            special += 1
        for u in range(k):
            q = decoded[u, t]
            if q < 0 or on[t, q]:
                continue
            first = True
            for v in range(u):
                if decoded[v, t] == q:
                    first = False
            if first:
                joint += table[3, _claims(decoded, -1, t, q)]
                special += 1
        joint += (s - special) * table[3, 0]
    return total + joint


@kernel
def _coordinate_ascent(
    on, on_ptr, on_idx, pre, n_pre, starts, entry, orders, order, log_a1, log_stay, blocks, support, table, sweeps
):
    k = pre.shape[0]
    n_slots = on.shape[0]
    best = np.full((k, n_slots), -1, dtype=np.int64)
    cur = np.empty((k, n_slots), dtype=np.int64)
    stats = np.zeros(3, dtype=np.int64)
    scratch = np.full((4, on.shape[1]), -1, dtype=np.int64)  # once per window, not per order
    for i in range(on.shape[1]):
        scratch[3, i] = i
    best_score = NEG_INF
    found = False
    for r in range(orders.shape[0]):
        score = _ascent_one_order(
            on,
            on_ptr,
            on_idx,
            pre,
            n_pre,
            starts,
            entry,
            orders[r],
            order,
            log_a1,
            log_stay,
            blocks,
            support,
            table,
            sweeps,
            cur,
            stats,
            scratch,
        )
        if not found or score > best_score + 1e-9:
            found = True
            best_score = score
            best[:, :] = cur
    return best, best_score, stats


#: user decodes of :func:`coordinate_ascent` in this process: ``[decodes, on every state,
#: uncertified local decodes redone on every state]`` (a diagnostic the benchmarks read)
DECODE_STATS = np.zeros(3, dtype=np.int64)


def coordinate_ascent(
    on: np.ndarray,
    prefixes: list[list[int]],
    starts: list[int],
    entries: list[int],
    orders: list[list[int]],
    *,
    order: int,
    log_a1: np.ndarray,
    log_a2: np.ndarray | None,
    table: np.ndarray,
    sweeps: int,
    support: tuple | None = None,
) -> tuple[np.ndarray, float]:
    """Every restart of the explain-away coordinate ascent in one compiled call.

    ``on (L, S)`` window activity on the state set; per user ``prefixes`` (0-2 state
    positions clamped before slot 0), ``starts`` (first window slot) and ``entries`` (entry
    state position or -1); ``orders`` the user orders to run; ``table`` from
    :func:`emission_tables`. Returns the ``(K, L)`` state positions of the order with the
    highest joint log-likelihood (first of equals within 1e-9) and that likelihood, as
    :func:`~onebit.models.graph_hmm.adaptive.coordinate_ascent_reference` run over the same
    orders. ``support``: :func:`transition_support` of the transitions when the caller has it
    (computed here otherwise from the dense ``log_a2``, ``O(S^3)``; with a second-order
    ``support`` ``log_a2`` may be ``None``).

    Each user is decoded on the states it can reach, not on all ``S`` (the per-slot cost
    follows the activity, not the building; paper III-B): a user with known last nodes on the
    states within the window's length of moves of its last node, one with an entry node on
    those of the entry node -- exact, no other state has a finite score -- and one that may
    start anywhere on the states within the window's length of an active state, with a
    certificate: the local best must beat the best score any path that never meets an active
    state can have (its every emission is at most the free-and-off gain, every transition at
    most ``t_max``); otherwise it is decoded again on every state. The paths are the
    all-state decode's (tests), the joint likelihood is summed over the active and claimed
    states plus the free-and-off ones counted (equal to ~1e-12).
    """
    k = len(prefixes)
    pre = np.zeros((k, 2), dtype=np.int64)
    n_pre = np.zeros(k, dtype=np.int64)
    for u, p in enumerate(prefixes):
        n_pre[u] = len(p)
        pre[u, : len(p)] = p
    a1 = _f64(log_a1, 2)
    second = order == 2 and (log_a2 is not None or support is not None)
    if support is None:
        support = transition_support(a1, _f64(log_a2, 3) if second else None)
    on = np.ascontiguousarray(on, dtype=np.bool_)
    t_on, j_on = np.nonzero(on)
    on_ptr = np.zeros(on.shape[0] + 1, dtype=np.int64)
    np.cumsum(np.bincount(t_on, minlength=on.shape[0]), out=on_ptr[1:])
    f_ptr, f_idx, b_ptr, b_idx, t_max, blocks, log_stay = support
    best, score, stats = _coordinate_ascent(
        on,
        on_ptr,
        j_on.astype(np.int64),
        pre,
        n_pre,
        np.asarray(starts, dtype=np.int64),
        np.asarray(entries, dtype=np.int64),
        np.asarray(orders, dtype=np.int64).reshape(-1, k),
        2 if second else 1,
        a1,
        log_stay,
        blocks,
        (f_ptr, f_idx, b_ptr, b_idx, float(t_max)),
        table,
        int(sweeps),
    )
    DECODE_STATS[:] += stats
    return best, float(score)


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
