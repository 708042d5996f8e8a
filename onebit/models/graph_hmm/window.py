"""The model pieces of one Adaptive-HMM window (:mod:`onebit.models.graph_hmm.adaptive`,
paper section III-B2..4): the transitions restricted to the window's state set (first order,
the distinct-node second-order tensor and its sparse support), and the user count's pieces
(the maximum independent set of the nodes on, the motion components).
"""

from __future__ import annotations

import numpy as np

from onebit.core.lazy import lazy_module
from onebit.models.graph_hmm.ascent import support_from_blocks, transition_support
from onebit.models.graph_hmm.eatg import Eatg
from onebit.models.graph_hmm.kernels import with_bases
from onebit.models.graph_hmm.viterbi import log_safe

nx = lazy_module("networkx")
_csgraph = lazy_module("scipy.sparse.csgraph")
_sparse = lazy_module("scipy.sparse")


def restricted_first(a1: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(S, S) log a' restricted to the states ``idx`` and renormalised."""
    sub = a1[np.ix_(idx, idx)]
    s = sub.sum(axis=1, keepdims=True)
    sub = np.where(s > 0, sub / np.where(s > 0, s, 1.0), np.eye(len(idx)))
    return log_safe(sub)


def _restricted(a1: np.ndarray, a2: np.ndarray, idx: np.ndarray) -> tuple:
    """``a1`` row-normalised on the states ``idx`` (a row without moves: stay), ``a2`` on them,
    their number and the identity mask: what the second-order model is built from."""
    p1 = a1[np.ix_(idx, idx)]
    s = p1.sum(axis=1, keepdims=True)
    p1 = np.where(s > 0, p1 / np.where(s > 0, s, 1.0), np.eye(len(idx)))
    n = len(idx)
    return p1, a2[np.ix_(idx, idx)], n, np.eye(n, dtype=bool)


def second_order_tensor(a1: np.ndarray, a2: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(S, S, S) log a(j3, j2, j1) on the states ``idx`` (module docstring, item 3)."""
    p1, p2, n, eye = _restricted(a1, a2, idx)
    stay = np.diag(p1)  # (j2,)
    move = np.where(eye, 0.0, p1)  # (j2, j1), j1 != j2
    w = move[None, :, :] * p2[:, None, :]  # (j3, j2, j1)
    z = w.sum(axis=2, keepdims=True)
    directed = np.where(z > 0, (1.0 - stay)[None, :, None] * w / np.where(z > 0, z, 1.0), move[None, :, :])
    t = np.where(eye[:, :, None], move[None, :, :], directed)  # j3 == j2: first order
    t = np.where(eye[None, :, :], stay[None, :, None] * np.ones((n, 1, 1)), t)  # j1 == j2: stay
    return log_safe(t)


class SecondOrderEntries:
    """The entries of :func:`second_order_tensor` on every node (``idx = arange(N)``), one by
    one, without its ``N^3`` array: ``T[j3, j2, j1]`` with index arrays (broadcast together)
    gives ``log a(j3, j2, j1)`` of the module docstring (item 3)::

        a(j3, j2, j2) = p1(j2, j2)                                   (stay)
        a(j2, j2, j1) = p1(j2, j1)                                   (no direction yet: first order)
        a(j3, j2, j1) = (1 - p1(j2, j2)) w(j3, j2, j1) / z(j3, j2)   (z > 0; else p1(j2, j1))
        w(j3, j2, j1) = p1(j2, j1) p2(j3, j1),   z(j3, j2) = sum_{k != j2} w(j3, j2, k)

    (``p1``/``p2`` the row-normalised ``a1`` and ``a2``). ``z`` is summed once per distinct
    ``(j3, j2)`` of a call over the same row of ``N`` products as the dense tensor's, so each
    entry equals the dense one bit for bit (tests); memory ``O(N^2)``, a call
    ``O(m + pairs N)``. Used where only the entries along paths or of a few states are read:
    the joint re-decoding of meetings (:mod:`onebit.models.graph_hmm.joint`) and the
    likelihood of paths (:mod:`onebit.models.graph_hmm.likelihood`)."""

    #: distinct ``(j3, j2)`` rows whose ``z`` is summed at once (bounds a call's memory)
    CHUNK = 4096

    def __init__(self, a1: np.ndarray, a2: np.ndarray):
        p1, p2, n, eye = _restricted(a1, a2, np.arange(a1.shape[0]))
        self.n = n
        self.shape = (n, n, n)
        self.stay = np.diag(p1).copy()
        self.move = np.where(eye, 0.0, p1)
        self.p2 = np.ascontiguousarray(p2)
        # z of the contexts a path can have (j3 a neighbour of j2 either way), summed once per
        # run: a call then sums only the rows of other contexts
        j3, j2 = np.nonzero((self.move > 0) | (self.move.T > 0))
        self._keys = j3.astype(np.int64) * n + j2
        self._z = self._sums(j3, j2)

    def _sums(self, j3: np.ndarray, j2: np.ndarray) -> np.ndarray:
        z = np.empty(j3.size)
        for lo in range(0, j3.size, self.CHUNK):  # bounded memory: CHUNK rows of N products at a time
            hi = lo + self.CHUNK
            z[lo:hi] = (self.move[j2[lo:hi]] * self.p2[j3[lo:hi]]).sum(axis=1)
        return z

    def __getitem__(self, key) -> np.ndarray:
        j3, j2, j1 = np.broadcast_arrays(*(np.asarray(k, dtype=np.int64) for k in key))
        shape = j3.shape
        j3, j2, j1 = j3.ravel(), j2.ravel(), j1.ravel()
        n = self.n
        uniq, inv = np.unique(j3 * n + j2, return_inverse=True)
        z = np.empty(uniq.size)
        at = np.minimum(np.searchsorted(self._keys, uniq), max(self._keys.size - 1, 0))
        known = self._keys[at] == uniq if self._keys.size else np.zeros(uniq.size, bool)
        z[known] = self._z[at[known]]
        other = uniq[~known]
        z[~known] = self._sums(other // n, other % n)
        z = z[inv.reshape(-1)]
        move = self.move[j2, j1]
        w = move * self.p2[j3, j1]
        directed = np.where(z > 0, (1.0 - self.stay[j2]) * w / np.where(z > 0, z, 1.0), move)
        t = np.where(j3 == j2, move, directed)
        t = np.where(j1 == j2, self.stay[j2], t)
        return log_safe(t).reshape(shape)


def second_order_support(a1: np.ndarray, a2: np.ndarray, idx: np.ndarray) -> tuple:
    """:func:`~onebit.models.graph_hmm.ascent.transition_support` of
    :func:`second_order_tensor` on the states ``idx``, built without the ``S^3`` tensor: per
    node ``j2`` only the contexts ``j3`` a path can have there (``j2`` itself and the nodes that
    move to it) and the nodes it moves to -- ``O(S deg^2)`` values, ``O(S^2 deg)`` time. Each
    value is computed as :func:`second_order_tensor` computes it (the same products, the same
    row sums over all ``S`` nodes), so it equals the dense entry bit for bit (tests)."""
    p1, p2, n, eye = _restricted(a1, a2, idx)
    stay = np.diag(p1).copy()
    move = np.where(eye, 0.0, p1)
    nxt = (move > 0) | (eye & (stay > 0)[:, None])  # the finite entries of the tensor's rows: moves and the stay
    k_ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(nxt.sum(axis=1), out=k_ptr[1:])
    k_idx = np.nonzero(nxt)[1].astype(np.int64)
    came = (move > 0).T | eye  # came[j, p]: a path at j can have come from p (or no direction yet: p = j)
    p_ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(came.sum(axis=1), out=p_ptr[1:])
    p_idx = np.nonzero(came)[1].astype(np.int64)
    blk_ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.diff(p_ptr) * np.diff(k_ptr), out=blk_ptr[1:])
    vals = np.empty(int(blk_ptr[-1]))
    for j2 in range(n):  # per node: its contexts x its next nodes (the tensor's formula, module item 3)
        ctx = p_idx[p_ptr[j2] : p_ptr[j2 + 1]]
        ks = k_idx[k_ptr[j2] : k_ptr[j2 + 1]]
        w = move[j2][None, :] * p2[ctx, :]  # (contexts, S): the same products as the dense tensor's
        z = w.sum(axis=1, keepdims=True)  # the same row sums over all S nodes
        directed = np.where(z > 0, (1.0 - stay[j2]) * w / np.where(z > 0, z, 1.0), move[j2][None, :])
        t = np.where((ctx == j2)[:, None], move[j2][None, :], directed)[:, ks]
        t = np.where((ks == j2)[None, :], stay[j2] * np.ones((len(ctx), 1)), t)
        vals[blk_ptr[j2] : blk_ptr[j2 + 1]] = log_safe(t).ravel()
    return support_from_blocks(with_bases(p_ptr, p_idx, blk_ptr, k_ptr, vals, k_idx), k_idx, log_safe(stay))


def window_transitions(
    eatg: Eatg, states: np.ndarray, order: int, *, dense: bool = True
) -> tuple[np.ndarray, np.ndarray | None, tuple]:
    """``(log a1, log a2, support)`` restricted to ``states``: ``log a2`` only for ``order == 2``
    and ``dense`` (else ``None``: the decoders read the sparse tensor of ``support``,
    :func:`second_order_support`, built without the ``S^3`` array); ``support`` the moves the
    decodes follow (:func:`onebit.models.graph_hmm.ascent.transition_support`)."""
    log_a1 = restricted_first(eatg.a1, states)
    if order != 2:
        return log_a1, None, transition_support(log_a1, None)
    if not dense:
        return log_a1, None, second_order_support(eatg.a1, eatg.a2, states)
    log_a2 = second_order_tensor(eatg.a1, eatg.a2, states)
    return log_a1, log_a2, transition_support(log_a1, log_a2)


def max_independent(nodes_on: np.ndarray, adj: np.ndarray, cache: dict) -> int:
    """Size of a maximum set of active nodes pairwise >= 2 hops apart (exact)."""
    key = tuple(nodes_on.tolist())
    if len(key) <= 1:
        return len(key)
    if key not in cache:
        sub = adj[np.ix_(nodes_on, nodes_on)]
        comp = nx.from_numpy_array((~sub & ~np.eye(len(key), dtype=bool)).astype(int))
        cache[key] = len(nx.max_weight_clique(comp, weight=None)[0])
    return cache[key]


def motion_components(obs: np.ndarray, hops: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Space-time components of the activations of a window: (slot, node, label) arrays."""
    t, j = np.nonzero(obs)
    if t.size == 0:
        return t, j, t
    near = (np.abs(t[:, None] - t[None, :]) <= 1) & (hops[j[:, None], j[None, :]] <= 1)
    r, c = np.nonzero(near)
    _, lab = _csgraph.connected_components(
        _sparse.coo_matrix((np.ones(r.size), (r, c)), shape=(t.size, t.size)), directed=False
    )
    return t, j, lab
