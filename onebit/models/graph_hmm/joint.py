"""Joint re-decoding of two users through a meeting (beyond the paper; issue #15).

The window decoder (:mod:`onebit.models.graph_hmm.adaptive`) decodes users one at a time
(coordinate ascent); where two users meet, the first one decoded takes the activations that
suit it and the other gets what is left, so the pair can leave the meeting on each other's
path even where the model itself tells them apart (a head-on crossing). Here the two users'
states are decoded *together* over the meeting, with everyone else held fixed.

User state ``s = (x, c)``: node ``x`` and the node ``c`` it came from (``-1`` before its first
move), the context of the second-order transition ``a(c, x, y)``
(:func:`~onebit.models.graph_hmm.window.second_order_tensor`). Moves: stay
``(x, c) -> (x, c)`` with ``log a(c|x, x, x)``, or step to a neighbour ``y``:
``(x, c) -> (y, x)`` with ``log a(c|x, x, y)`` (``c|x``: ``c``, or ``x`` when unknown). The
pair's state is ``(s_1, s_2)`` (``S^2`` states, ``S = sum_x (deg x + 1)``); the Viterbi
recursion over the window ``t = w0 .. w1``::

    delta_t(s_1, s_2) = max_{p_1, p_2} delta_{t-1}(p_1, p_2) + log a(p_1 -> s_1) + log a(p_2 -> s_2)
                        + e_t(x(s_1), x(s_2)),
    e_t(j, k) = g_t(j) + [j = k] h_t(j) + [j != k] g_t(k),

with ``g_t(j) = log P(b_j(t) | c_j + 1) - log P(b_j(t) | c_j)`` and
``h_t(j) = log P(b_j(t) | c_j + 2) - log P(b_j(t) | c_j + 1)`` the noisy-OR gains over the
``c_j`` other users fixed at ``j`` (adaptive module docstring, item 4). It starts from the two
users' states at ``w0 - 1`` and ends by the move into each pairing of the two tails after
``w1``: ``(tail_a, tail_b)`` or exchanged. Each candidate (either pairing of the tails) is
then scored with the exact joint log-likelihood of all paths
(:func:`~onebit.models.graph_hmm.likelihood.model_log_likelihood`) and kept only when it
beats the current paths, so a re-decoding never lowers ``log L``.

Cost per meeting: ``O(W S^2 K)`` with ``K <= 1 + max deg + 1`` predecessors per user state and
``S`` the user states of the nodes the pair can reach in the window (:class:`JointSpaces`,
exact; optionally only the paper's 2-hop neighbourhood of their motion), not of the building;
the transitions are read entry by entry, with no ``N^3`` tensor. The recursion is sequential over the window's slots and
runs compiled (:func:`_pair_viterbi`, numba); :func:`pair_viterbi_reference`, vectorised in
numpy over the pair states, is its plain reference and test oracle.
"""

from __future__ import annotations

import functools

import numpy as np
import polars as pl

from onebit.core.compiled import kernel
from onebit.models.graph_hmm.adaptive import joint_emission
from onebit.models.graph_hmm.eatg import Eatg
from onebit.models.graph_hmm.likelihood import claims, path_log_prior
from onebit.models.graph_hmm.window import SecondOrderEntries


class PairSpace:
    """The user states ``(x, c)`` on the nodes ``nodes`` (default: every node of the graph) and
    each state's predecessors with their log transition probabilities (module docstring).

    ``log_a`` gives ``log a(j3, j2, j1)`` by index arrays: the dense tensor of
    :func:`~onebit.models.graph_hmm.window.second_order_tensor` or its entries one by one
    (:class:`~onebit.models.graph_hmm.window.SecondOrderEntries`, no ``N^3`` array). On a
    subset of the nodes a state ``(x, c)`` keeps every context ``c`` of ``x``; a move from a
    node outside the subset has no predecessor state (paths stay inside it). States are
    ordered by node, then context, and so are the predecessors, as on the whole graph: a
    subset's recursion breaks ties as the whole graph's does among the paths both hold.
    ``local``: each state's node as a column of ``nodes`` (the emission gains are computed on
    those columns only)."""

    def __init__(self, hops: np.ndarray, log_a, nodes: np.ndarray | None = None):
        n = hops.shape[0]
        nodes = np.arange(n, dtype=np.int64) if nodes is None else np.unique(np.asarray(nodes, dtype=np.int64))
        self.nodes = nodes
        inside = np.zeros(n, dtype=bool)
        inside[nodes] = True
        xs, cs = [], []
        for x in nodes.tolist():  # the subset's (or the graph's, once per run) states
            for c in [-1, *np.flatnonzero(hops[x] == 1).tolist()]:
                xs.append(x)
                cs.append(c)
        self.x = np.array(xs, np.int64)
        self.c = np.array(cs, np.int64)
        self.local = np.searchsorted(nodes, self.x).astype(np.int64)
        index = {(x, c): i for i, (x, c) in enumerate(zip(xs, cs))}
        self.index = index
        at = {}  # node -> its states, in order
        for i, x in enumerate(xs):
            at.setdefault(x, []).append(i)
        rows, js = [], []  # (state, predecessor state) and the triple (j3, j2, j1) of the move
        for i, (x, c) in enumerate(zip(xs, cs)):
            rows.append((i, i))
            js.append((c if c >= 0 else x, x, x))  # stay
            if c >= 0 and inside[c]:  # arrived from c: any state at c moved here
                for p in at[c]:
                    cc = cs[p]
                    rows.append((i, p))
                    js.append((cc if cc >= 0 else c, c, x))
        j = np.array(js, dtype=np.int64).reshape(-1, 3)
        values = np.asarray(log_a[j[:, 0], j[:, 1], j[:, 2]], dtype=np.float64) if len(j) else np.zeros(0)
        owner = np.array([r[0] for r in rows], dtype=np.int64)
        counts = np.bincount(owner, minlength=len(xs))
        k = int(counts.max()) if len(xs) else 1
        col = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)
        self.pred = np.zeros((len(xs), k), np.int64)
        self.lp = np.full((len(xs), k), -np.inf)
        self.pred[owner, col] = [r[1] for r in rows]
        self.lp[owner, col] = values
        self.log_a = log_a

    def state(self, x: int, c: int) -> int:
        return self.index[(int(x), int(c) if c >= 0 and (int(x), int(c)) in self.index else -1)]


class JointSpaces:
    """The pair states a meeting is re-decoded on (:func:`redecode_meetings`), built once per
    run and reused.

    **Exact** (always): the nodes the two users can be at. A window of ``W`` slots starts from
    the users' nodes ``s_u`` at the slot before it and ends by a move into a tail node ``y``
    (the first slot after it, either pairing); a path moves at most one hop a slot, so a node
    ``x`` at window slot ``t`` has ``hops(s_u, x) <= t + 1`` and ``hops(x, y) <= W - t``::

        X = {x : some t in [0, W) has hops(s_u, x) <= t + 1 and hops(x, y) <= W - t}
          = {x : hops(s_u, x) + hops(x, y) <= W + 1, hops(s_u, x) <= W, hops(x, y) <= W}
            for a user u and a tail y (hops(s_u, x) <= W where a pairing leaves u without one),

    plus the pair's current nodes. Every path of finite score lies in ``X``, and so does every
    predecessor a back-pointer of such a path can name; the states keep the whole graph's order
    (:class:`PairSpace`), so the decoded paths are the whole graph's, ties included (tests). A
    meeting costs ``O(W S_X^2 K)``: ``S_X`` grows with the window's length, not the building.

    ``reach = r > 0`` (the ``joint_hops`` option) further restricts ``X`` to the paper's state
    set for overlapping motion (Sec. III-B2 (a): "the activated nodes of the motion sequences
    and up to their 2-hop nodes"): the nodes within ``r`` hops of the pair's nodes and of the
    activations chained to them within ``r`` hops. Faster on long meetings but approximate: a
    joint optimum that leaves it is not found (on the simulated 24-hour home one hour-long
    meeting's gain in ``log L`` fell from 682 to 53). Transitions are read entry by entry
    (:class:`~onebit.models.graph_hmm.window.SecondOrderEntries`): no ``N^3`` tensor.
    Spaces are cached by their node set (at most ``MAX_CACHED``). ``whole=True``: every meeting
    on every node (the reference the exact sets are tested against)."""

    MAX_CACHED = 4096

    def __init__(self, eatg: Eatg, reach: int = 0, *, whole: bool = False):
        if reach < 0:
            raise ValueError(f"reach must be >= 0 hops, got {reach}")
        self.whole = bool(whole)
        self.hops = np.minimum(np.asarray(eatg.hops, dtype=np.int64), np.int64(2**40))  # no overflow in sums
        self.reach = int(reach)
        self.log_a = SecondOrderEntries(eatg.a1, eatg.a2)
        self._cache: dict[bytes, PairSpace] = {}

    def reachable(self, starts, tails, w: int) -> np.ndarray:
        """``(N,)`` mask of the exact set ``X`` (class docstring) for the users' start nodes,
        their tail nodes (``-1``: none) and a window of ``w`` slots."""
        ok = np.zeros(self.hops.shape[0], dtype=bool)
        ys = [int(y) for y in tails if y >= 0]
        for s in starts:
            if s < 0:
                continue
            h = self.hops[int(s)]
            if len(ys) < len(tails):  # a pairing leaves this user without a tail
                ok |= h <= w
            for y in ys:
                hy = self.hops[y]
                ok |= (h + hy <= w + 1) & (h <= w) & (hy <= w)
        return ok

    def neighbourhood(self, pair_nodes: np.ndarray, active: np.ndarray) -> np.ndarray:
        """``(N,)`` mask of the paper's state set (class docstring, ``reach > 0``) of the pair's
        nodes and the window's activity ``active (W, N)``."""
        on = active.any(axis=0)
        seeds = np.zeros(on.size, dtype=bool)
        seeds[np.unique(pair_nodes[pair_nodes >= 0])] = True
        new = seeds.copy()
        while new.any():  # the motion sequences the pair is part of: activations chained within reach
            near = (self.hops[np.flatnonzero(new)] <= self.reach).any(axis=0)
            new = near & on & ~seeds
            seeds |= new
        return (self.hops[np.flatnonzero(seeds)] <= self.reach).any(axis=0)

    def around(self, pair_nodes: np.ndarray, starts, tails, active: np.ndarray) -> PairSpace:
        """The :class:`PairSpace` a meeting is decoded on: ``pair_nodes`` the two users' nodes
        from the slot before the window to the first slot after it, ``starts`` / ``tails``
        their nodes there (``-1``: none), ``active (W, N)`` the window's activity."""
        ok = self.reachable(starts, tails, active.shape[0]) | self.whole
        if self.reach:
            ok &= self.neighbourhood(pair_nodes, active)
        ok[pair_nodes[pair_nodes >= 0]] = True
        nodes = np.flatnonzero(ok)
        key = nodes.tobytes()
        space = self._cache.get(key)
        if space is None:
            if len(self._cache) >= self.MAX_CACHED:
                self._cache.clear()
            space = self._cache[key] = PairSpace(self.hops, self.log_a, nodes)
        return space


def _gains(active: np.ndarray, others: np.ndarray, p_hit: float, p_false: float) -> tuple[np.ndarray, np.ndarray]:
    """(W, N) ``g`` and ``h`` of the module docstring."""

    def logp(c):
        p_on = np.where(c > 0, 1.0 - (1.0 - p_hit) ** c, p_false)
        return np.where(active, np.log(p_on), np.log1p(-p_on))

    c0 = others.astype(float)
    l0, l1, l2 = logp(c0), logp(c0 + 1), logp(c0 + 2)
    return l1 - l0, l2 - l1


def pair_viterbi_reference(delta, pred, lp, xs, g, h):
    """The pair recursion of the module docstring over ``W`` slots from ``delta (S, S)``:
    returns the last ``delta`` and the back-pointers ``psi (W, S, S)`` (``k_2 K + k_1``, the
    predecessors' columns in ``pred``; among equal predecessor pairs the first in that order),
    vectorised over the pair states."""
    s, k = pred.shape
    psi = np.zeros((g.shape[0], s, s), np.int64)
    same = xs[:, None] == xs[None, :]
    for t in range(g.shape[0]):  # sequential: the Viterbi recursion over the window's slots
        cand = (delta[pred[:, :, None, None], pred[None, None, :, :]] + lp[:, :, None, None]) + lp[None, None, :, :]
        cand = cand.transpose(0, 2, 3, 1).reshape(s, s, k * k)  # (a, b, k2 * K + k1)
        best = cand.argmax(axis=2)
        e = g[t][xs][:, None] + np.where(same, h[t][xs][:, None], g[t][xs][None, :])
        delta = np.take_along_axis(cand, best[:, :, None], axis=2)[:, :, 0] + e
        psi[t] = best
    return delta, psi


def pair_viterbi(delta, pred, lp, xs, g, h):
    """:func:`_pair_viterbi` with its back-pointers ``psi (W, S, S)`` in the smallest integer
    type that holds ``k_2 K + k_1 < K^2`` (``int8`` on a sensor graph: a 9 444-slot meeting of
    the 24-hour home log is 340 MB of back-pointers, not 2.7 GB in ``int64``)."""
    s, k = pred.shape
    kind = np.int8 if k * k <= np.iinfo(np.int8).max else np.int16 if k * k <= np.iinfo(np.int16).max else np.int64
    psi = np.zeros((g.shape[0], s, s), kind)
    return _pair_viterbi(delta, pred, lp, xs, g, h, psi), psi


@kernel
def _pair_viterbi(delta, pred, lp, xs, g, h, psi):
    """Compiled :func:`pair_viterbi_reference` (same outputs), separated: first the best first
    user's predecessor for every (state, predecessor state of the second user),
    ``m(a, q) = max_k1 delta(pred(a, k1), q) + lp(a, k1)``, then
    ``delta'(a, b) = max_k2 m(a, pred(b, k2)) + lp(b, k2)`` -- ``2 S^2 K`` operations per slot
    instead of ``S^2 K^2``; ties go to the first ``k2``, then the first ``k1``, as in the
    reference's ``argmax`` over ``k_2 K + k_1``. Fills ``psi (W, S, S)`` (any integer type
    holding ``K^2``), returns the last ``delta``."""
    s, k = pred.shape
    w = g.shape[0]
    cur = delta.copy()
    nxt = np.empty((s, s))
    m = np.empty((s, s))
    am = np.zeros((s, s), np.int64)
    for t in range(w):
        for a in range(s):
            for q in range(s):
                best = -np.inf
                arg = 0
                for k1 in range(k):
                    v = cur[pred[a, k1], q] + lp[a, k1]
                    if v > best:
                        best = v
                        arg = k1
                m[a, q] = best
                am[a, q] = arg
        for a in range(s):
            for b in range(s):
                best = -np.inf
                arg = 0
                for k2 in range(k):
                    q = pred[b, k2]
                    v = m[a, q] + lp[b, k2]
                    if v > best:
                        best = v
                        arg = k2 * k + am[a, q]
                if xs[a] == xs[b]:
                    e = g[t, xs[a]] + h[t, xs[a]]
                else:
                    e = g[t, xs[a]] + g[t, xs[b]]
                nxt[a, b] = best + e
                psi[t, a, b] = arg
        cur, nxt = nxt, cur
    return cur


def decode_pair(
    space: PairSpace,
    start: tuple[int, int],
    active: np.ndarray,
    others: np.ndarray,
    ends,
    *,
    p_hit: float,
    p_false: float,
    compiled: bool = True,
):
    """Joint Viterbi of two users over a window (module docstring).

    ``start``: the two users' states at the slot before the window; ``active`` ``(W, N)`` and
    ``others`` ``(W, N)`` (users at each node other than the pair), or both on the space's
    nodes only (``(W, len(space.nodes))``); ``ends``: a list of
    ``(y_1, y_2)`` first nodes after the window (``-1``: none) to finish into. Returns one
    ``(2, W)`` node array per end, or ``None`` where no path reaches it. ``compiled=False``
    runs the numpy reference recursion."""
    s = space.x.size
    if active.shape[1] != space.nodes.size:  # the graph's columns: keep the space's
        active, others = active[:, space.nodes], others[:, space.nodes]
    g, h = _gains(active, others, p_hit, p_false)
    delta0 = np.full((s, s), -np.inf)
    delta0[start[0], start[1]] = 0.0
    pred, k, xs = space.pred, space.pred.shape[1], space.x
    run = pair_viterbi if compiled else pair_viterbi_reference
    delta, psi = run(delta0, pred, space.lp, space.local, np.ascontiguousarray(g), np.ascontiguousarray(h))
    out = []
    for y1, y2 in ends:
        term = delta.copy()
        for u, y in ((0, y1), (1, y2)):
            if y < 0:
                continue
            ctx = np.where(space.c >= 0, space.c, xs)
            step = space.log_a[ctx, xs, y]  # the move from the window's last state into the tail
            term = term + (step[:, None] if u == 0 else step[None, :])
        if not np.isfinite(term.max()):
            out.append(None)
            continue
        a, b = np.unravel_index(int(term.argmax()), term.shape)
        path = np.zeros((2, active.shape[0]), np.int64)
        for t in range(active.shape[0] - 1, -1, -1):  # backtrack
            path[0, t], path[1, t] = xs[a], xs[b]
            kk = int(psi[t, a, b])  # k2 * K + k1
            a, b = pred[a, kk % k], pred[b, kk // k]
        out.append(path)
    return out


def meetings(paths: np.ndarray, hops: np.ndarray, *, pad: int) -> list[tuple[int, int, int, int]]:
    """``(u, v, w0, w1)``: every maximal run of slots where users ``u < v`` are within one hop of
    each other, padded by ``pad`` slots each side (clipped to the run and to where both are
    present)."""
    u_n, d = paths.shape
    out = []
    for u in range(u_n):  # a handful of users: pairs
        for v in range(u + 1, u_n):
            a, b = paths[u], paths[v]
            both = (a >= 0) & (b >= 0)
            near = both & (hops[np.maximum(a, 0), np.maximum(b, 0)] <= 1)
            if not near.any():
                continue
            edges = np.diff(np.concatenate([[0], near.astype(np.int8), [0]]))
            for s0, s1 in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1):
                w0, w1 = max(1, s0 - pad), min(d - 1, s1 + pad)
                while w0 < s0 and not both[w0 - 1]:
                    w0 += 1
                while w1 > s1 and not both[w1]:
                    w1 -= 1
                if both[w0 - 1 : w1 + 1].all():
                    out.append((u, v, int(w0), int(w1)))
    return sorted(out, key=lambda m: m[2])


def pair_space(eatg: Eatg) -> PairSpace:
    """The :class:`PairSpace` of every node of an EATG (its transitions read entry by entry)."""
    return PairSpace(eatg.hops, SecondOrderEntries(eatg.a1, eatg.a2))


def _window_columns(nodes: np.ndarray, n: int, rest: np.ndarray, active: np.ndarray) -> tuple:
    """``(col, others, act)`` of a meeting's window on its space's nodes: each node's column
    (-1 outside), the other users' claims (``rest``, their paths in the window) and the
    activity, on those columns."""
    col = np.full(n, -1, dtype=np.int64)
    col[nodes] = np.arange(nodes.size)
    others = claims(np.where(rest >= 0, col[np.maximum(rest, 0)], -1), nodes.size)
    return col, others, active[:, nodes]


def _best_candidate(seg: np.ndarray, window: tuple[int, int], candidates, score, cur: float):
    """``(best log L, pick)``: the candidate pair path (``candidates``: one per pairing of the
    tails, None when none) of highest exact ``log L`` over ``seg`` when it beats the current
    ``cur`` by more than 1e-9 -- ``pick = (path, tails exchanged)`` -- else ``(cur, None)``."""
    k0, k1 = window
    best, pick = cur, None
    for swap, path in enumerate(candidates):
        if path is None:
            continue
        y = seg.copy()
        y[:, k0:k1] = path
        if swap:
            y[:, k1:] = seg[::-1, k1:]
        ll = score(y)
        if ll > best + 1e-9:
            best, pick = ll, (path, bool(swap))
    return best, pick


def redecode_meetings(
    paths: np.ndarray,
    active: np.ndarray,
    eatg: Eatg,
    *,
    p_hit: float,
    p_false: float,
    pad: int = 4,
    compiled: bool = True,
    decide: tuple[int, int] | None = None,
    reach: int = 0,
    spaces: JointSpaces | None = None,
) -> tuple[np.ndarray, list[dict]]:
    """Every meeting of two users (:func:`meetings`, in slot order) jointly re-decoded
    (:func:`decode_pair`), either pairing of the tails, the candidate of highest exact
    ``log L`` kept when it beats the current paths. After an accepted change the meetings
    still ahead are listed again on the changed paths (issue #22: a list made once on the
    initial paths named users absent after an exchange of tails). ``decide = (lo, hi)``: only the
    meetings whose window ends at ``w1`` in ``[lo, hi)`` (lagged decoding: a meeting is
    re-decoded with the block in which it ends, seen whole with its tails after it). Each meeting
    is decoded on the pair states its users can reach (:class:`JointSpaces`; ``reach > 0``:
    within the paper's neighbourhood of ``reach`` hops too, approximate); ``spaces``: those of an earlier call (a caller decoding block by block
    builds them once; its ``reach`` is used). Returns the paths and one record per meeting
    (slots, users, gain in ``log L``, whether the tails were exchanged)."""
    n = len(eatg.nodes)
    if spaces is None:
        spaces = JointSpaces(eatg, reach)
    log_a = spaces.log_a
    x = np.array(paths, dtype=np.int64, copy=True)
    d = x.shape[1]
    log = []

    def listed(m) -> bool:
        return decide is None or decide[0] <= m[3] < decide[1]

    queue, done = [m for m in meetings(x, eatg.hops, pad=pad) if listed(m)], set()
    while queue:  # sequential: each re-decoding changes the paths the next one sees
        u, v, w0, w1 = queue.pop(0)
        done.add((u, v, w0))
        a = w0 - 1
        nxt = (int(x[u, w1 + 1]), int(x[v, w1 + 1])) if w1 + 1 < d else (-1, -1)
        ends = [nxt, (nxt[1], nxt[0])]
        space = spaces.around(x[[u, v], a : min(w1 + 2, d)], (x[u, a], x[v, a]), nxt, active[w0 : w1 + 1])
        ctx = np.array([_context(x[u], a), _context(x[v], a)], dtype=np.int64)
        start = (space.state(x[u, a], ctx[0]), space.state(x[v, a], ctx[1]))
        # the window's emissions on the space's columns only: the pair's current and candidate
        # nodes are all in it, so the columns outside add the same to every candidate's log L
        col, others, act = _window_columns(
            space.nodes, n, np.delete(x[:, w0 : w1 + 1], [u, v], axis=0), active[w0 : w1 + 1]
        )
        b = min(max(w1 + 1, _first_change(x[u], w1 + 1), _first_change(x[v], w1 + 1)), d - 1)
        seg = x[[u, v], a : b + 1]  # the pair from the slot before the window to where their tails settle
        k0, k1 = w0 - a, w1 + 1 - a  # the window inside ``seg``
        score = functools.partial(
            _segment_log_likelihood,
            ctx0=ctx,
            window=(k0, k1),
            others=others,
            active=act,
            log_a=log_a,
            p_hit=p_hit,
            p_false=p_false,
            col=col,
        )
        cur = score(seg)
        candidates = decode_pair(space, start, act, others, ends, p_hit=p_hit, p_false=p_false, compiled=compiled)
        best, pick = _best_candidate(seg, (k0, k1), candidates, score, cur)
        if pick is not None:
            x[[u, v], w0 : w1 + 1] = pick[0]
            if pick[1]:  # the tails change hands: from here on each follows the other's path
                x[u, w1 + 1 :], x[v, w1 + 1 :] = x[v, w1 + 1 :].copy(), x[u, w1 + 1 :].copy()
            # the paths changed from w0 on: the later meetings are those of the new paths (a user
            # whose tail went to the other may no longer be present at a meeting listed before)
            queue = [
                m
                for m in meetings(x, eatg.hops, pad=pad)
                if m[2] >= w0 and (m[0], m[1], m[2]) not in done and listed(m)
            ]
        mid = (w0 + w1) // 2
        log.append(
            {
                "slot": w0,
                "end": w1,
                "users": (u, v),
                "gain": best - cur,
                "exchanged": bool(pick and pick[1]),
                "node": int(x[u, mid]),
            }
        )
    return x, log


def _context(row: np.ndarray, t: int) -> int:
    """The node ``row`` came from before its dwell at slot ``t`` (``-1``: unknown or absent;
    :func:`~onebit.models.graph_hmm.likelihood.came_from` at ``t``), looking back in growing
    steps so a meeting costs its dwell, not the run."""
    here = row[t]
    if here < 0:
        return -1
    step, hi = 64, t
    while hi > 0:
        lo = max(0, hi - step)
        diff = np.flatnonzero(row[lo:hi] != here)
        if diff.size:
            return int(row[lo + diff[-1]])  # -1 when the user was absent there
        hi, step = lo, step * 4
    return -1


def _first_change(row: np.ndarray, t: int) -> int:
    """The first slot after ``t`` at which ``row`` changes node (``len(row) - 1`` if never),
    looking ahead in growing steps."""
    d = row.size
    if t >= d - 1:
        return d - 1
    step, lo = 64, t
    while lo < d - 1:
        hi = min(d, lo + step + 1)
        diff = np.flatnonzero(row[lo + 1 : hi] != row[lo : hi - 1])
        if diff.size:
            return lo + 1 + int(diff[0])
        lo, step = hi - 1, step * 4
    return d - 1


def _settled(rows: np.ndarray, w1: int) -> int:
    """The last slot whose transition can depend on the window ending at ``w1``: for each of
    the two users the slot of its first node change after ``w1`` (from there its came-from
    context is its tail's own), the later of the two; the run's end if one never changes."""
    d = rows.shape[1]
    return min(max(w1 + 1, *(_first_change(r, w1 + 1) for r in rows)), d - 1)


def _segment_log_likelihood(seg, *, ctx0, window, others, active, log_a, p_hit, p_false, col=None) -> float:
    """:func:`_local_log_likelihood` on the pair's segment ``seg`` (2, b - a + 1) from slot ``a``
    (contexts ``ctx0``), the window at columns ``window`` and the other users' ``claims`` there;
    ``col``: each node's column in ``others``/``active`` when they hold only some nodes (the
    emissions of those columns; the pair's nodes in the window must be among them)."""
    k0, k1 = window
    inside = others.copy()
    for r in seg[:, k0:k1]:  # the two users
        ok = r >= 0
        inside[np.flatnonzero(ok), r[ok] if col is None else col[r[ok]]] += 1
    return path_log_prior(seg, log_a, ctx0) + joint_emission(active, inside, p_hit, p_false)


def _local_log_likelihood(x, *, rows, a, b, w, ctx0, active, n, log_a, p_hit, p_false) -> float:
    """The part of :func:`~onebit.models.graph_hmm.likelihood.model_log_likelihood` that a
    re-decoding of ``rows`` inside the window ``w`` (tails possibly exchanged after it) can
    change: the two users' transitions from slot ``a`` (context ``ctx0``) to ``b``
    (:func:`_settled`) and the emissions of the window's slots. Two labellings that agree
    outside differ in the full ``log L`` by exactly the difference of this."""
    w0, w1 = w
    others = claims(np.delete(x[:, w0 : w1 + 1], list(rows), axis=0), n)
    return _segment_log_likelihood(
        x[list(rows), a : b + 1],
        ctx0=ctx0,
        window=(w0 - a, w1 + 1 - a),
        others=others,
        active=active[w0 : w1 + 1],
        log_a=log_a,
        p_hit=p_hit,
        p_false=p_false,
    )


#: one row per meeting re-decoded jointly: its window, the two decoded users, the gain in
#: ``log L`` of the kept candidate (0 when the paths were kept), whether the tails were exchanged,
#: and the node of ``track_a`` at the window's middle slot (where the viewer shows it)
JOINT = pl.Schema(
    {
        "slot": pl.Int64,
        "end": pl.Int64,
        "t": pl.Float64,
        "track_a": pl.String,
        "track_b": pl.String,
        "gain": pl.Float64,
        "exchanged": pl.Boolean,
        "node": pl.String,
    }
)


def joint_table(log: list[dict], nodes, t0: float, period: float) -> pl.DataFrame:
    """The records of :func:`redecode_meetings` as a :data:`JOINT` table (the decoder's users
    named ``user<k+1>`` as in the tracks table; where the user cap (``max_users`` / the site's
    ``targets``) drops users, the tracks table renumbers what it keeps)."""
    rows = [
        (
            r["slot"],
            r["end"],
            t0 + (r["slot"] + 0.5) * period,
            f"user{r['users'][0] + 1}",
            f"user{r['users'][1] + 1}",
            float(r["gain"]),
            r["exchanged"],
            nodes[r["node"]],
        )
        for r in log
    ]
    return pl.DataFrame(rows, schema=JOINT, orient="row")
