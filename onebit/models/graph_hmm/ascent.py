"""Compiled (numba) kernels of the Adaptive-HMM's explain-away coordinate ascent
(:mod:`onebit.models.graph_hmm.adaptive`, section 4 of its docstring): every restart of the
ascent in one call (:func:`coordinate_ascent`), each user decoded on the states it can reach
with the Viterbi kernels of :mod:`onebit.models.graph_hmm.kernels`.

:func:`coordinate_ascent`'s reference (its test oracle) is
:func:`onebit.models.graph_hmm.adaptive.coordinate_ascent_reference`, run on every state, and
brute force over every path (``tests/models/graph_hmm/test_kernels.py``); the rules of equal
outputs are those of :mod:`onebit.models.graph_hmm.kernels`. The emission gains are tabulated
once per call by numpy (:func:`emission_tables`), the transitions' support once per window
(:func:`transition_support`).
"""

from __future__ import annotations

import numpy as np

from onebit.core.compiled import kernel
from onebit.models.graph_hmm.kernels import (
    NEG_INF,
    _f64,
    _viterbi1,
    _viterbi_motion2_local,
    motion_blocks,
    move_support,
)

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
    :func:`onebit.models.graph_hmm.window.second_order_support`)."""
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
def _user_states(pre_u, npre, entry_u, st, rows, on_ptr, on_idx, seeds, f_ptr, f_idx, b_ptr, b_idx, dist, gs):
    """The states a user can be at (module docstring of adaptive, "local decodes"), written to
    ``gs``: ``(n_loc, uniform)``, ``uniform`` for a user that may start anywhere (its states
    those within reach of an active state, to be certified)."""
    n_slots = on_ptr.shape[0] - 1
    uniform = False
    if npre > 0:
        seeds[0] = pre_u[npre - 1]
        n_loc = _reach(seeds, 1, rows - npre, f_ptr, f_idx, b_ptr, b_idx, dist, gs)
        if npre == 2:  # its context node, if farther
            have = False
            for i in range(n_loc):
                have = have or gs[i] == pre_u[0]
            if not have:
                gs[n_loc] = pre_u[0]
                n_loc += 1
                gs[:n_loc] = np.sort(gs[:n_loc])
    elif entry_u >= 0:
        seeds[0] = entry_u
        n_loc = _reach(seeds, 1, rows - 1, f_ptr, f_idx, b_ptr, b_idx, dist, gs)
    else:
        uniform = True
        ns = 0
        for q in range(on_ptr[st], on_ptr[n_slots]):
            seeds[ns] = on_idx[q]
            ns += 1
        n_loc = _reach(seeds, ns, rows - 1, f_ptr, f_idx, b_ptr, b_idx, dist, gs) if ns else 0
    return n_loc, uniform


@kernel
def _joint_emission(on, on_ptr, on_idx, decoded, table):
    """The joint emission log-likelihood of the decoded users, summed over the states with an
    activation or a user; every other one is off and free (``table[3, 0]`` each)."""
    n_slots, s = on.shape
    k = decoded.shape[0]
    joint = 0.0
    for t in range(n_slots):
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
    return joint


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
            n_loc, uniform = _user_states(
                pre[u], npre, entry[u], st, rows, on_ptr, on_idx, seeds, f_ptr, f_idx, b_ptr, b_idx, dist, gs
            )
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
    return total + _joint_emission(on, on_ptr, on_idx, decoded, table)


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
