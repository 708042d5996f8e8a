"""Viterbi decoding of first- and second-order HMMs in log space (paper Algorithms 4 and 5).

Both decoders are max-product dynamic programmes vectorised over the states with numpy
broadcasting; the recursion over time slots is inherently sequential (slot ``d`` needs the
scores of slot ``d - 1``) and is the only Python loop. These numpy decoders are the plain
references (and test oracles) of the compiled kernels the trackers run,
:mod:`onebit.models.graph_hmm.kernels` (same inputs, same paths).

First order (Algorithm 4, Rabiner [20])::

    delta_0(j)  = log pi_j + log c_j(O_0)
    delta_d(j)  = max_i [delta_{d-1}(i) + log a(i, j)] + log c_j(O_d)
    psi_d(j)    = argmax_i [delta_{d-1}(i) + log a(i, j)]

Second order (Algorithm 5, Thede & Harper [25]); the score is kept over state *pairs*
``(q_{d-1}, q_d) = (j', j)``::

    delta_1(j', j) = log pi_j' + log c_j'(O_0) + log a1(j', j) + log c_j(O_1)
    delta_d(j', j) = max_j'' [delta_{d-1}(j'', j') + log a(j'', j', j)] + log c_j(O_d)
    psi_d(j', j)   = argmax_j'' [delta_{d-1}(j'', j') + log a(j'', j', j)]

``a1`` is the first-order transition used for the first step, where no ``q_{-1}`` exists.
Termination takes the best pair at the last slot and backtracks ``u_d = psi_{d+2}(u_{d+1}, u_{d+2})``.
"""

from __future__ import annotations

import numpy as np

NEG_INF = -np.inf


def viterbi_first_order(log_pi: np.ndarray, log_a: np.ndarray, log_b: np.ndarray) -> tuple[np.ndarray, float]:
    """Most probable state path of a first-order HMM (Algorithm 4).

    Parameters
    ----------
    log_pi : (S,) log initial distribution.
    log_a : (S, S) log transitions, ``log_a[i, j] = log P(q_d = j | q_{d-1} = i)``.
    log_b : (D, S) log emission of the observation at each slot under each state.

    Returns
    -------
    path : (D,) int state indices; ``log_prob`` : log probability of the path and observations.
    """
    log_b = np.asarray(log_b, float)
    n_slots, n_states = log_b.shape
    if n_slots == 0:
        return np.zeros(0, dtype=np.int64), 0.0
    psi = np.zeros((n_slots, n_states), dtype=np.int64)
    delta = np.asarray(log_pi, float) + log_b[0]
    for d in range(1, n_slots):  # sequential in time by construction
        scores = delta[:, None] + log_a  # (S_prev, S)
        psi[d] = np.argmax(scores, axis=0)
        delta = scores[psi[d], np.arange(n_states)] + log_b[d]
    return _backtrack_first(psi, delta)


def _backtrack_first(psi: np.ndarray, delta: np.ndarray) -> tuple[np.ndarray, float]:
    n_slots = psi.shape[0]
    path = np.zeros(n_slots, dtype=np.int64)
    path[-1] = int(np.argmax(delta))
    for d in range(n_slots - 1, 0, -1):
        path[d - 1] = psi[d, path[d]]
    return path, float(delta[path[-1]])


def viterbi_first_order_batch(
    log_pi: np.ndarray, log_a: np.ndarray, log_b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`viterbi_first_order` for ``U`` independent sequences at once (same model).

    ``log_pi``: (U, S); ``log_b``: (U, D, S). Returns paths (U, D) and log probs (U,).
    Vectorised over sequences and states.
    """
    log_b = np.asarray(log_b, float)
    n_seq, n_slots, n_states = log_b.shape
    if n_slots == 0:
        return np.zeros((n_seq, 0), dtype=np.int64), np.zeros(n_seq)
    psi = np.zeros((n_slots, n_seq, n_states), dtype=np.int64)
    delta = np.asarray(log_pi, float) + log_b[:, 0]
    rows = np.arange(n_seq)[:, None]
    cols = np.arange(n_states)[None, :]
    for d in range(1, n_slots):
        scores = delta[:, :, None] + log_a[None]  # (U, S_prev, S)
        psi[d] = np.argmax(scores, axis=1)
        delta = scores[rows, psi[d], cols] + log_b[:, d]
    path = np.zeros((n_seq, n_slots), dtype=np.int64)
    path[:, -1] = np.argmax(delta, axis=1)
    for d in range(n_slots - 1, 0, -1):
        path[:, d - 1] = psi[d, np.arange(n_seq), path[:, d]]
    return path, delta[np.arange(n_seq), path[:, -1]]


def viterbi_second_order(
    log_pi: np.ndarray, log_a1: np.ndarray, log_a2: np.ndarray, log_b: np.ndarray
) -> tuple[np.ndarray, float]:
    """Most probable state path of a second-order HMM (Algorithm 5).

    Parameters
    ----------
    log_pi : (S,) log initial distribution of ``q_0``.
    log_a1 : (S, S) log first-step transitions ``q_0 -> q_1``.
    log_a2 : (S, S, S) log transitions ``log_a2[j'', j', j] = log P(q_d = j | q_{d-1} = j', q_{d-2} = j'')``.
    log_b : (D, S) log emissions.

    Returns
    -------
    path : (D,) int state indices; ``log_prob``.

    Memory: the back-pointers are (D, S, S) ints, each step broadcasts an (S, S, S) array.
    """
    log_b = np.asarray(log_b, float)
    n_slots, n_states = log_b.shape
    if n_slots == 0:
        return np.zeros(0, dtype=np.int64), 0.0
    if n_slots == 1:
        d0 = np.asarray(log_pi, float) + log_b[0]
        j = int(np.argmax(d0))
        return np.array([j]), float(d0[j])
    delta = (np.asarray(log_pi, float) + log_b[0])[:, None] + log_a1 + log_b[1][None, :]  # (j', j)
    psi = np.zeros((n_slots, n_states, n_states), dtype=np.int64)
    jp = np.arange(n_states)[:, None]
    jj = np.arange(n_states)[None, :]
    for d in range(2, n_slots):  # sequential in time by construction
        scores = delta[:, :, None] + log_a2  # (j'', j', j)
        best = np.argmax(scores, axis=0)  # (j', j)
        psi[d] = best
        delta = scores[best, jp, jj] + log_b[d][None, :]
    flat = int(np.argmax(delta))
    prev, last = divmod(flat, n_states)
    path = np.zeros(n_slots, dtype=np.int64)
    path[-1], path[-2] = last, prev
    for d in range(n_slots - 1, 1, -1):
        path[d - 2] = psi[d, path[d - 1], path[d]]
    return path, float(delta[prev, last])


def viterbi_motion_second_order(
    log_pi: np.ndarray, log_stay: np.ndarray, log_move: np.ndarray, log_b: np.ndarray
) -> tuple[np.ndarray, float]:
    """Most probable path of a second-order HMM whose context is the previous *distinct* node.

    With slots of 1 s a user dwells several slots at a node, so the literal context
    ``q(t-2)`` is the same node most of the time and the 2-hop factor ``a''`` would only act
    on a move right after another move. Here the second-order context is the node the user
    came from -- the EATG's node sequence, on which ``a''`` is trained (triggers) -- so every
    move is weighted by where the user came from, however long it stayed::

        P(q_d = q_{d-1})                  = stay(q_{d-1})
        P(q_d = k != q_{d-1} = j | p)     = move(p, j, k)     p = last node != j before d-1
                                                              (p = j: none yet, first order)

    The Viterbi runs over pairs ``(x, y)`` = (previous distinct node, current node), the
    pair states of Algorithm 5; ``(j, j)`` means "no previous node yet"::

        delta_0(j, j)  = log pi_j + log b_0(j)
        delta_d(x, y)  = max( delta_{d-1}(x, y) + log stay(y),                 (stay)
                              max_p delta_{d-1}(p, x) + log move(p, x, y) )     (move x -> y)
                         + log b_d(y)

    Parameters
    ----------
    log_pi : (S,); log_stay : (S,); log_move : (S, S, S) indexed ``[p, j, k]`` (entries with
    ``k == j`` are ignored); log_b : (D, S).

    Returns
    -------
    path : (D,) state indices; ``log_prob``. Vectorised over states; the recursion over
    slots is sequential by construction. Memory: (D, S, S) back-pointers.
    """
    log_b = np.asarray(log_b, float)
    n_slots, n_states = log_b.shape
    if n_slots == 0:
        return np.zeros(0, dtype=np.int64), 0.0
    log_stay = np.asarray(log_stay, float)
    no_move = np.eye(n_states, dtype=bool)
    delta = np.full((n_states, n_states), NEG_INF)
    delta[np.diag_indices(n_states)] = np.asarray(log_pi, float) + log_b[0]
    back = np.full((n_slots, n_states, n_states), -1, dtype=np.int64)
    jj = np.arange(n_states)[:, None]
    kk = np.arange(n_states)[None, :]
    for d in range(1, n_slots):  # sequential in time by construction
        stay = delta + log_stay[None, :]
        scores = delta[:, :, None] + log_move  # (p, j, k)
        best = np.argmax(scores, axis=0)  # (j, k)
        move = np.where(no_move, NEG_INF, scores[best, jj, kk])
        moved = move > stay
        back[d] = np.where(moved, best, -1)
        delta = np.where(moved, move, stay) + log_b[d][None, :]
    flat = int(np.argmax(delta))
    x, y = divmod(flat, n_states)
    score = float(delta[x, y])
    path = np.zeros(n_slots, dtype=np.int64)
    path[-1] = y
    for d in range(n_slots - 1, 0, -1):
        b = back[d, x, y]
        if b >= 0:
            x, y = int(b), x
        path[d - 1] = y
    return path, score


def log_safe(p: np.ndarray) -> np.ndarray:
    """``log(p)`` with ``log(0) = -inf`` and no warning."""
    with np.errstate(divide="ignore"):
        return np.log(np.asarray(p, float))
