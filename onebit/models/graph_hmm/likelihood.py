"""The joint log-likelihood of a set of user paths under the decoders' model.

The model every HMM tracker maximises (:mod:`onebit.models.graph_hmm.adaptive`, module
docstring items 3 and 4): each user's path ``x_u(t)`` is a second-order motion chain on the
sensor graph whose context ``j3`` is the node the user came from (the last node different
from the current one, however long it dwelt), and each node is an independent noisy OR of the
users at it::

    log L(X) = sum_u sum_t log a(c_u(t-1), x_u(t-1), x_u(t))
             + sum_{t,j} log P(b_j(t) | c_j(t)),
    P(b_j = 1 | c) = 1 - (1 - p_hit)^c  (c >= 1),   p_false  (c = 0),

with ``a(j3, j2, j1)`` the tensor of :func:`~onebit.models.graph_hmm.window.second_order_tensor`
(``j3 = j2`` where no direction is known yet: first order). A slot where a user is absent
(``-1``) ends its chain; the first slot after it is not scored (the same for every labelling).

Used to ask of a labelling of the *true* paths whether the model can tell it from another:
exchanging two users' tails at a slot where they share a node leaves the emission term and
every first-order factor unchanged, so only ``a''`` across the meeting -- the direction each
user came from against the one it leaves by -- can tell who is who
(:func:`exchange_margin`; the identity-swap diagnosis of ``docs/findinghumo.md``).
"""

from __future__ import annotations

import numpy as np

from onebit.models.graph_hmm.adaptive import joint_emission
from onebit.models.graph_hmm.eatg import Eatg
from onebit.models.graph_hmm.window import SecondOrderEntries


def came_from(paths: np.ndarray, ctx0: np.ndarray | None = None) -> np.ndarray:
    """(U, D) the node each user came from before its current dwell (``-1`` when unknown):
    at a node change ``x(t) != x(t-1)`` it is ``x(t-1)``, carried forward while the user
    dwells; an absent slot (``-1``) forgets it. ``ctx0`` (U,): the context at slot 0 when
    ``paths`` is a slice of longer paths (default: unknown)."""
    paths = np.asarray(paths, dtype=np.int64)
    u, d = paths.shape
    prev = np.concatenate([np.full((u, 1), -1, np.int64), paths[:, :-1]], axis=1)
    change = (paths != prev) & (paths >= 0) & (prev >= 0)
    reset = (paths < 0) | ((paths != prev) & ~change)  # absent, or the first slot after an absence
    mark = change | reset
    val = np.where(change, prev, -1)
    if ctx0 is not None:
        val[:, 0] = np.where(paths[:, 0] >= 0, ctx0, -1)
    # forward fill ``val`` from the last marked slot of each row (slot 0 is always marked)
    pos = np.where(mark, np.arange(d)[None, :], 0)
    np.maximum.accumulate(pos, axis=1, out=pos)
    return np.take_along_axis(val, pos, axis=1)


def path_log_prior(paths: np.ndarray, log_a: np.ndarray, ctx0: np.ndarray | None = None) -> float:
    """``sum_u sum_t log a(c_u(t-1), x_u(t-1), x_u(t))`` over slots where the user is present
    at ``t - 1`` and ``t`` (``log_a`` indexed ``log_a[j3, j2, j1]``: the ``(N, N, N)`` tensor or
    :class:`~onebit.models.graph_hmm.window.SecondOrderEntries`; ``ctx0``
    as in :func:`came_from`)."""
    paths = np.asarray(paths, dtype=np.int64)
    ctx = came_from(paths, ctx0)
    j2, j1 = paths[:, :-1], paths[:, 1:]
    ok = (j2 >= 0) & (j1 >= 0)
    j3 = np.where(ctx[:, :-1] >= 0, ctx[:, :-1], j2)
    return float(log_a[j3[ok], j2[ok], j1[ok]].sum())


def claims(paths: np.ndarray, n: int) -> np.ndarray:
    """(D, N) number of users at each node per slot."""
    paths = np.asarray(paths, dtype=np.int64)
    d = paths.shape[1]
    c = np.zeros((d, n), np.int64)
    s, j = np.nonzero(paths.T >= 0)
    np.add.at(c, (s, paths.T[s, j]), 1)
    return c


def model_log_likelihood(
    paths: np.ndarray, active: np.ndarray, eatg: Eatg, *, p_hit: float, p_false: float, log_a=None
) -> float:
    """``log L(X)`` of the module docstring for paths ``(U, D)`` and slot activity ``(D, N)``."""
    n = len(eatg.nodes)
    if log_a is None:
        log_a = SecondOrderEntries(eatg.a1, eatg.a2)
    return path_log_prior(paths, log_a) + joint_emission(active, claims(paths, n), p_hit, p_false)


def exchange_margin(
    paths: np.ndarray, u: int, v: int, slots, active: np.ndarray, eatg: Eatg, *, p_hit: float, p_false: float
) -> tuple[float, int]:
    """``(log L(X) - max_e log L(X_e), e*)``: how much more probable the labelling ``X`` is than
    the best one that exchanges the tails of users ``u`` and ``v`` at a slot ``e`` of ``slots``
    (``X_e``: ``u`` follows ``x_v(t)`` and ``v`` follows ``x_u(t)`` for ``t >= e``). ``> 0``: the
    model prefers ``X``; ``0``: it cannot tell them apart; ``-inf`` is impossible (``X``
    itself has probability 0); ``+inf`` when every exchange is impossible (a jump)."""
    log_a = SecondOrderEntries(eatg.a1, eatg.a2)
    base = model_log_likelihood(paths, active, eatg, p_hit=p_hit, p_false=p_false, log_a=log_a)
    best, at = -np.inf, -1
    for e in slots:  # a handful of candidate slots
        x = np.array(paths, copy=True)
        x[u, e:], x[v, e:] = paths[v, e:], paths[u, e:]
        ll = model_log_likelihood(x, active, eatg, p_hit=p_hit, p_false=p_false, log_a=log_a)
        if ll > best:
            best, at = ll, int(e)
    if not np.isfinite(base):
        return -np.inf, at
    return (base - best if np.isfinite(best) else np.inf), at


def colocations(paths: np.ndarray) -> list[tuple[int, tuple[int, ...]]]:
    """``(slot, users)``: each start of two or more users sharing a node -- a slot ``e`` where
    the users at some node differ from those at it at ``e - 1`` -- in slot order."""
    paths = np.asarray(paths, dtype=np.int64)
    out = []
    prev: set = set()
    for e in range(paths.shape[1]):  # sequential over slots; a handful of users per slot
        col = paths[:, e]
        here = set()
        for j in np.unique(col[col >= 0]):
            grp = tuple(int(u) for u in np.flatnonzero(col == j))
            if len(grp) >= 2:
                here.add(grp)
                if grp not in prev:
                    out.append((e, grp))
        prev = here
    return out


def tie_relabelling(
    paths: np.ndarray,
    active: np.ndarray,
    eatg: Eatg,
    *,
    p_hit: float,
    p_false: float,
    rng: np.random.Generator,
    tol: float = 1e-6,
) -> tuple[np.ndarray, int]:
    """The true paths as the best *model-following* association would label them: at every
    co-location (:func:`colocations`, in slot order) the users' tails are permuted by a
    pairing of maximal ``log L`` (:func:`model_log_likelihood`), drawn uniformly among those
    within ``tol`` of the maximum. Positions are exact, so the hop error of the result is the
    identity error that even a perfect decoder of positions followed by an exact maximiser of
    the paper's model (CPDA, a flow, a joint decoder) makes on these observations when it
    breaks ties by chance. Returns the relabelled paths and the number of co-locations where
    the draw changed the labels."""
    import itertools

    log_a = SecondOrderEntries(eatg.a1, eatg.a2)
    x = np.array(paths, dtype=np.int64, copy=True)
    changed = 0
    for e in sorted({e for e, _ in colocations(paths)}):
        col = x[:, e]
        for j in np.unique(col[col >= 0]):
            grp = np.flatnonzero(col == j)
            if grp.size < 2 or grp.size > 5:
                continue
            perms = list(itertools.permutations(range(grp.size)))
            cands = []
            for p in perms:
                y = x.copy()
                y[grp, e:] = x[grp[list(p)], e:]
                cands.append((model_log_likelihood(y, active, eatg, p_hit=p_hit, p_false=p_false, log_a=log_a), y))
            best = max(c for c, _ in cands)
            near = [k for k, (c, _) in enumerate(cands) if c >= best - tol]
            k = int(near[rng.integers(len(near))])
            if k != 0:
                changed += 1
            x = cands[k][1]
    return x, changed
