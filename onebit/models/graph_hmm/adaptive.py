"""Adaptive-HMM (paper section III-B2..4) and the full-state baselines, window by window.

The run's slot activity ``B`` (D, N) bool is decoded in windows of ``d_max`` slots that
slide by ``tau`` (the decoded states of the first ``tau`` slots of a window are accepted,
the rest is look-ahead). Per window:

1. **User count** (III-B3): ``K = max(K_pre + Sig_in - Sig_out, K_now)``, at most
   ``max_users`` when it is given (the site's ``targets``: a bound inside the decoder, so
   that no more users than that are ever decoded). ``K_now`` is the largest number of nodes
   triggered in one slot that are pairwise at least 2 hops apart (a maximum independent set
   in the 1-hop graph; exact, by ``networkx.max_weight_clique`` on the complement -- active
   sets are small). *Triggered* (``count = "fresh"``, the default) is a node that turned on
   in this slot or the ``fresh_slots - 1`` before it: a motion sensor stays on for seconds
   after the person left it (and a real log loses OFFs), so counting every node *on*
   (``count = "on"``, the paper's literal reading) makes one walker several users that never
   leave -- a one-resident CASAS log decoded 5 users that way, 1 with fresh onsets. ``Sig_in``
   counts entry signatures ``outer -> inner`` (an onset at ``outer`` followed by activity at
   ``inner`` in the window) with no known user within 1 hop of ``outer``; ``Sig_out`` counts
   users whose decoded path ends ``inner -> outer`` with ``outer`` silent afterwards in the
   window: they leave. A door node can lie on a corridor (104 between 97 and 103): walking
   through it is an exit signature followed by an entry one (``-1 + 1``, K unchanged). So
   that the walker keeps its identity, a user that left is kept *dormant* for ``resume``
   slots; a new user (from an entry signature at that door, or from ``K_now`` with the
   door within 1 hop of the window's activity) in that time is the dormant user coming back
   (its slots in between are filled with the door node).
2. **Overlap detection and model choice** (III-B2(a), Algorithm 3). The activations of the
   window form a space-time graph (``(t, j)`` ~ ``(t', j')`` when ``|t - t'| <= 1`` and
   ``hops(j, j') <= 1``); its connected components (``scipy.sparse.csgraph``) are the motion
   sequences. The window is *non-overlapping* when every component has at most one
   independent active node per slot and at most one known user near it (last node within
   ``NEAR_HOPS`` = 1 hop of the component: the paper's "activated nodes at each slot are 1-hop
   away"), and no user is near two components; then one first-order HMM is forked per component over its
   nodes and their 1-hop neighbours. Otherwise one second-order HMM over the active nodes and
   their 1- and 2-hop neighbours decodes all ``K`` users.
3. **Transitions** (III-B2(b)): first order ``a(j2, j1) = a'(j2, j1)``; second order
   ``a(j3, j2, j1) = a'(j2, j1) a''(j3, j1)``, applied where it carries information -- a
   2-hop move ``j3 != j2 != j1`` -- and normalised so that the 2-hop factor re-weights
   *where* a user moves, not *whether* it moves. ``j3`` is the node the user came from --
   the last node different from ``j2``, however many slots it dwelt at ``j2`` -- not the
   node at slot ``t - 2``: with 1-s slots a user dwells ~4 slots per node, and the slot-literal
   context would forget the direction after one slot of dwelling
   (:func:`~onebit.models.graph_hmm.viterbi.viterbi_motion_second_order`; ``a''`` is
   trained on trigger sequences, i.e. on exactly these distinct-node sequences)::

       a(j3, j2, j2) = a'(j2, j2)                                       (stay)
       a(j2, j2, j1) = a'(j2, j1)                                       (no direction known)
       a(j3, j2, j1) = (1 - a'(j2, j2)) a'(j2, j1) a''(j3, j1) / sum_{m != j2} a'(j2, m) a''(j3, m)

   Rows restricted to a reduced state set are renormalised.
4. **Emissions** (III-B2(c)) and **multi-user decoding**. The paper does not say how ``K``
   paths are decoded jointly; a joint HMM over K-tuples is exponential in ``K``. We decode the
   users one after another, each *explaining away* the activations the earlier ones claimed,
   and repeat the sweep (each user re-decoded with the others fixed) ``sweeps`` times -- a
   coordinate ascent on the joint log-likelihood::

   Each node is an independent noisy OR of the users at it: with ``c`` users at ``j``,
   ``P(b_j = 1 | c) = 1 - (1 - p_hit)^c`` for ``c >= 1`` and ``p_false`` for ``c = 0``. The
   joint log-likelihood of all users then changes, when user ``u`` is put at ``j`` while
   ``c`` others are there, by the emission term used in ``u``'s Viterbi::

       log c_j(O_t) = log(p_hit / p_false)                          b_j(t) = 1, c = 0
                    = log(P(on | c + 1) / P(on | c))                b_j(t) = 1, c >= 1
                    = log((1 - p_hit) / (1 - p_false))              b_j(t) = 0, c = 0
                    = log(1 - p_hit)                                b_j(t) = 0, c >= 1

   so an activation nobody explains pulls a user towards it, and an activation already
   explained adds little (the paper's ``c_{j2 j1}`` is taken independent of ``j2``). Each
   re-decoding of one user with the others fixed cannot lower the joint likelihood. The initial distribution is
   the previous window's result: each known user's last accepted node, preceded by the node it
   came from, is prepended as clamped slots (emission 0 at that node, ``-inf`` elsewhere), so
   the decoder continues the user's path with its second-order context. A new user starts at
   its entry node (Sig_in) or uniformly over the window's states. Coordinate ascent finds a
   local optimum that depends on the order the users are decoded in (i.e. on their arbitrary
   labels), so it is run over every order when ``K! <= restarts`` (else ``restarts``
   rotations), and the run with the highest joint
   log-likelihood ``sum_u log P(path_u) + sum_{t,j} log P(b_j(t) | c_j(t))`` is kept.

The baselines ``hmm1`` / ``hmm2`` run the same loop with the full state set and a fixed order
(``mode = "full1"`` / ``"full2"``); ``offline`` uses one window spanning the whole run.

5. **Local decodes** (the cost follows the activity, III-B): inside the coordinate ascent each
   user's Viterbi runs on the states it can reach in the window, not on the whole state set
   -- the nodes within the window's length of moves of its last node (known users) or entry
   node (exact: no other state has a finite score); for a user that may start anywhere, those
   within the window's length of a node active in its slots, certified: a path that never
   meets an activation scores at most ``g0 + (L - 1)(t_max + g0)`` (``g0`` the free-and-off
   emission gain, the largest of an inactive state; ``t_max`` the largest log transition), and
   the local best must beat that strictly, else the user is decoded on every state. The paths
   are the all-state decoder's (:func:`onebit.models.graph_hmm.ascent.coordinate_ascent`);
   so the full-state baselines cost per slot what the activity around the users costs, not
   what the building does (``benchmarks/bench_hmm_growth.py``).
The window loop is inherently sequential (each window starts from the previous one's users),
and so is the coordinate ascent inside a window: every restart of it (all user orders, sweeps
and users, the Viterbi recursions included) runs as one compiled call
(:func:`onebit.models.graph_hmm.ascent.coordinate_ascent`, ``DecoderParams.compiled``);
:func:`coordinate_ascent_reference` with the numpy decoders of
:mod:`onebit.models.graph_hmm.viterbi` is its plain reference and test oracle.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from onebit.core.lazy import lazy_module
from onebit.core.params import derived, param
from onebit.models.graph_hmm.ascent import (
    coordinate_ascent,
    emission_tables,
)
from onebit.models.graph_hmm.config import RESUME_SLOTS, HmmConfig
from onebit.models.graph_hmm.eatg import Eatg, onsets
from onebit.models.graph_hmm.viterbi import viterbi_first_order, viterbi_motion_second_order
from onebit.models.graph_hmm.window import max_independent, motion_components, second_order_tensor, window_transitions

_optimize = lazy_module("scipy.optimize")

MODES = ("adaptive", "full1", "full2")

#: slots searched back for the node a user came from (its second-order context)
LOOKBACK = 120

#: a known user is "near" a motion component when its last node is within this many hops of it
NEAR_HOPS = 1


#: The window decoder's parameters: the declarations of :class:`HmmConfig` it shares (type,
#: default, doc, bounds: not copied), then its own -- the mode, the resume span, compiled or not.
#: ``max_users`` here is the bound in force (:func:`onebit.models.graph_hmm.decoding.user_bound`).
DecoderParams = derived(
    "DecoderParams",
    HmmConfig,
    ("d_max", "tau", "p_hit", "p_false", "sweeps", "restarts", "offline", "max_users", "count", "fresh_slots"),
    extra={
        "mode": param("adaptive", "decoder: the paper's Adaptive-HMM, or a full-state baseline", choices=MODES),
        "resume": param(
            RESUME_SLOTS, "slots after an exit in which an entry at the same door continues that user", lo=0
        ),
        "compiled": param(
            True, "the coordinate ascent as one numba kernel (ascent.coordinate_ascent); False = the numpy reference"
        ),
    },
    doc="Parameters of the window decoder (see the module docstring).",
    module=__name__,
)
#: the paper's decoder (every default)
DEFAULT_DECODER = DecoderParams()


@dataclass
class DecodeResult:
    paths: np.ndarray  # (U, D) node index per user and slot, -1 when absent
    windows: list[dict] = field(default_factory=list)  # per window: slot, K, order, states, overlap


# --------------------------------------------------------------------------- decoding users


def emission_gain(on: np.ndarray, claims: np.ndarray, p_hit: float, p_false: float) -> np.ndarray:
    """(L, S) log-likelihood change of putting one more user at each state (module docstring, 4)."""
    c = claims.astype(float)
    p_on_c = np.where(c > 0, 1.0 - (1.0 - p_hit) ** c, p_false)
    p_on_c1 = 1.0 - (1.0 - p_hit) ** (c + 1.0)
    gain_on = np.log(p_on_c1 / p_on_c)
    gain_off = np.where(c > 0, np.log1p(-p_hit), np.log((1.0 - p_hit) / (1.0 - p_false)))
    return np.where(on, gain_on, gain_off)


@dataclass
class _User:
    uid: int
    start: int  # first slot (absolute) of the user
    entry_node: int = -1  # node to start at (entry signature), -1 = uniform


def decode_users(
    obs: np.ndarray,
    states: np.ndarray,
    prefixes: list[list[int]],
    starts: list[int],
    entry_nodes: list[int],
    *,
    order: int,
    eatg: Eatg,
    params: DecoderParams,
    transitions: tuple | None = None,
) -> np.ndarray:
    """Decode ``K`` users on one window by explain-away coordinate ascent (module docstring).

    obs : (L, N) bool activity of the window; states : (S,) node indices of the state set.
    prefixes : per user, the last accepted nodes (0-2 of them) clamped before slot 0.
    starts : per user, the window slot it appears at (0 for known users).
    transitions : :func:`window_transitions` of ``states`` when the caller has them already (the
        full-state baselines decode every window on the same states: computed once per run).
    Returns (K, L) node indices, -1 before a user's start.
    """
    k = len(prefixes)
    n_slots = obs.shape[0]
    out = np.full((k, n_slots), -1, dtype=np.int64)
    if k == 0 or n_slots == 0:
        return out
    states = np.asarray(states, dtype=np.int64)
    if len(states) != obs.shape[1] and states.size > 1 and not (np.diff(states) > 0).all():
        raise ValueError("decode_users: states must be ascending and distinct")
    on = obs if len(states) == obs.shape[1] else obs[:, states]  # (L, S): every node, or the listed ones
    if transitions is None:
        transitions = window_transitions(eatg, states, order)
    log_a1, log_a2, support = transitions
    if math.factorial(k) <= params.restarts:  # every order: the result does not depend on the labels
        orders = [list(o) for o in itertools.permutations(range(k))]
    else:  # the users' decoding order rotated
        orders = [[(u + r) % k for u in range(k)] for r in range(min(k, params.restarts))]
    if params.compiled:
        pre = [[_position(states, q) for q in p] for p in prefixes]
        entries = [_position(states, e) if not p and e >= 0 else -1 for p, e in zip(prefixes, entry_nodes)]
        table = emission_tables(k, params.p_hit, params.p_false, emission_gain)
        best, _ = coordinate_ascent(
            on,
            pre,
            starts,
            entries,
            orders,
            order=order,
            log_a1=log_a1,
            log_a2=log_a2,
            table=table,
            sweeps=params.sweeps,
            support=support,
        )
    else:
        if order == 2 and log_a2 is None:  # the reference reads the dense tensor
            log_a2 = second_order_tensor(eatg.a1, eatg.a2, states)
        pos = {int(v): i for i, v in enumerate(states)}
        best, best_score = None, -np.inf
        for order_u in orders:
            decoded, score = coordinate_ascent_reference(
                on,
                pos,
                prefixes,
                starts,
                entry_nodes,
                order_u,
                order=order,
                log_a1=log_a1,
                log_a2=log_a2,
                params=params,
            )
            if best is None or score > best_score + 1e-9:
                best, best_score = decoded, score
    decoded = best
    have = decoded >= 0
    out[have] = states[decoded[have]]
    return out


def _position(states: np.ndarray, node: int) -> int:
    """The index of ``node`` in the ascending ``states`` (a ``KeyError`` if absent)."""
    i = int(np.searchsorted(states, node))
    if i >= len(states) or states[i] != node:
        raise KeyError(node)
    return i


def joint_emission(on: np.ndarray, claims: np.ndarray, p_hit: float, p_false: float) -> float:
    """``sum_{t,j} log P(b_j(t) | c_j(t))`` of the noisy-OR emission model (module docstring, 4)."""
    c = claims.astype(float)
    p_on = np.where(c > 0, 1.0 - (1.0 - p_hit) ** c, p_false)
    return float(np.where(on, np.log(p_on), np.log1p(-p_on)).sum())


def coordinate_ascent_reference(on, pos, prefixes, starts, entry_nodes, order_u, *, order, log_a1, log_a2, params):
    """Explain-away sweeps over the users in the order ``order_u``; returns the (K, L) state
    positions and the joint log-likelihood ``sum_u log P(path_u) + joint_emission``.

    The plain numpy reference (one numpy Viterbi per user and sweep) of the compiled
    :func:`onebit.models.graph_hmm.ascent.coordinate_ascent`, which runs every order of a
    window in one call; the tests check both give the same paths on random windows."""
    k = len(prefixes)
    n_slots, s = on.shape
    claims = np.zeros((n_slots, s), dtype=np.int64)
    decoded = np.full((k, n_slots), -1, dtype=np.int64)
    trans = np.zeros(k)
    for _ in range(max(params.sweeps, 1)):
        for u in order_u:
            st = starts[u]
            if st >= n_slots:
                continue
            mine = decoded[u]
            have = mine >= 0
            claims[np.flatnonzero(have), mine[have]] -= 1
            emis = emission_gain(on[st:], claims[st:], params.p_hit, params.p_false)
            pre = [pos[q] for q in prefixes[u]]
            clamp = np.full((len(pre), s), -np.inf)
            clamp[np.arange(len(pre)), pre] = 0.0
            log_b = np.vstack([clamp, emis])
            log_pi = np.zeros(s)
            if not pre and entry_nodes[u] >= 0:
                log_pi = np.full(s, -np.inf)
                log_pi[pos[entry_nodes[u]]] = 0.0
            if order == 2:
                path, score = viterbi_motion_second_order(log_pi, np.diag(log_a1), log_a2, log_b)
            else:
                path, score = viterbi_first_order(log_pi, log_a1, log_b)
            path = path[len(pre) :]
            trans[u] = score - float(emis[np.arange(n_slots - st), path].sum())
            decoded[u] = -1
            decoded[u, st:] = path
            claims[np.arange(st, n_slots), path] += 1
    return decoded, float(trans.sum()) + joint_emission(on, claims, params.p_hit, params.p_false)


# --------------------------------------------------------------------------- the run


def decode_run(
    active: np.ndarray,
    eatg: Eatg,
    *,
    signatures: list[tuple[int, int]] = (),
    params: DecoderParams = DEFAULT_DECODER,
    progress: Callable[[int, int], None] | None = None,
) -> DecodeResult:
    """Decode every user's node path from slot activity ``active`` (D, N) bool.

    ``progress(done, total)``, when given, is called after each window with the slots
    decoded so far and the number of slots (:data:`onebit.trackers.base.PROGRESS`).
    The whole run at once: :class:`WindowDecoder` fed every slot and flushed."""
    active = np.asarray(active, bool)
    dec = WindowDecoder(eatg, active.shape[1], signatures=signatures, params=params)
    dec.extend(active)
    dec.advance(final=True, progress=progress)
    return dec.result()


class WindowDecoder:
    """The window loop of :func:`decode_run`, resumable: slots arrive in pieces
    (:meth:`extend`), :meth:`advance` decodes every window whose slots have all arrived, and
    the result is the same however the slots were cut into pieces.

    A window ``[s, s + d_max)`` is decoded once slot ``s + d_max`` has arrived (strictly
    after the window: the last window of a run, which reaches the run's end, accepts all its
    slots, not ``tau`` -- that is decided only by ``advance(final=True)``). A decoded slot
    ``k`` can still change while ``k >= s - resume`` (``s`` the next window's first slot): a
    user that exits and re-enters at the same door within ``resume`` slots has the slots in
    between filled with the door node; :attr:`final_slots` is the count of slots that no
    later window changes. Sequential by nature (each window starts from the previous one's
    users)."""

    def __init__(
        self,
        eatg: Eatg,
        n_nodes: int,
        *,
        signatures: list[tuple[int, int]] = (),
        params: DecoderParams = DEFAULT_DECODER,
    ):
        self.eatg = eatg
        self.signatures = list(signatures)
        self.params = params
        self.n = int(n_nodes)
        self._active = np.zeros((0, self.n), bool)
        self._fresh = np.zeros((0, self.n), bool)
        self._ons = np.zeros((0, self.n), bool)
        self.n_slots = 0
        self.users: list[_User] = []
        self.rows: list[np.ndarray] = []  # per user, path over the capacity (-1 absent)
        self.alive: list[int] = []
        self.windows: list[dict] = []
        self.dormant: dict[int, tuple[int, int]] = {}  # exited user -> (slot after its exit, door node)
        self.s = 0
        self.done = False
        self._mis: dict = {}
        # the full-state baselines' transitions, on every node: the same for every window
        self._full = (
            window_transitions(eatg, np.arange(self.n), 1 if params.mode == "full1" else 2, dense=False)
            if params.mode in ("full1", "full2")
            else None
        )

    @property
    def final_slots(self) -> int:
        """Slots ``[0, final_slots)`` whose decoded nodes no later window changes."""
        return self.n_slots if self.done else max(0, self.s - self.params.resume)

    def extend(self, active: np.ndarray) -> None:
        """Append slots ``active`` (L, N) bool (final: their activity does not change later)."""
        active = np.asarray(active, bool).reshape(-1, self.n)
        if self.done:
            raise ValueError("WindowDecoder: slots added after the final advance")
        if active.shape[0] == 0:
            return
        old = self.n_slots
        need = old + active.shape[0]
        if need > self._active.shape[0]:  # capacity doubling: amortised O(1) per slot
            cap = max(need, 2 * self._active.shape[0], 64)
            self._active = _grow(self._active, cap, False)
            self._fresh = _grow(self._fresh, cap, False)
            self._ons = _grow(self._ons, cap, False)
            self.rows = [_grow(r, cap, -1) for r in self.rows]
        self._active[old:need] = active
        prev = self._active[old - 1 : old] if old else np.zeros((1, self.n), bool)
        self._ons[old:need] = onsets(np.vstack([prev, active]))[1:]  # on now, off in the slot before
        lo = max(0, old - max(self.params.fresh_slots, 1) + 1)  # the onsets the new slots' freshness looks back to
        self._fresh[old:need] = recent_onsets(self._ons[lo:need], self.params.fresh_slots)[old - lo :]
        self.n_slots = need

    def _entries(self, s: int, obs: np.ndarray, ons: np.ndarray, last: dict, alive: list) -> list[tuple[int, int]]:
        """The window's entry signatures (from slot ``s``; ``obs``/``ons`` its activity and
        onsets): an onset at ``outer``, then ``inner`` active later in the window, nobody near
        ``outer``. One ``(slot in the window, outer)`` per onset, whatever the signature, sorted."""
        hops, rows = self.eatg.hops, self.rows
        entries = []
        for outer, inner in self.signatures:
            for t in np.flatnonzero(ons[:, outer]):
                if not obs[t:, inner].any():
                    continue
                if any(hops[outer, lst[-1]] <= 1 for lst in last.values() if lst):
                    continue
                if any(
                    hops[outer, rows[u][s + t - 1]] <= 1 for u in alive if s + t - 1 >= 0 and rows[u][s + t - 1] >= 0
                ):
                    continue
                entries.append((t, outer))
        return sorted({(t, o) for t, o in entries})

    def _new_users(self, count: int, entries: list, obs: np.ndarray, s: int) -> list[int]:
        """``count`` users more in the window from slot ``s``: each at its entry (the first
        ``len(entries)``; then anywhere), a dormant user that just left by that door resumed
        (``DecoderParams.resume``), else a new one. Returns their indices."""
        users, rows, dormant, hops = self.users, self.rows, self.dormant, self.eatg.hops
        new = []
        for i in range(count):
            t0, node = entries[i] if i < len(entries) else (0, -1)
            seen = np.flatnonzero(obs.any(axis=0))
            back = [
                u
                for u, (slot, outer) in dormant.items()
                if s + t0 - slot <= self.params.resume
                and (outer == node or (node < 0 and seen.size and hops[outer, seen].min() <= 1))
            ]
            if back:  # an exit at this door just before: the same user walked through it
                u = max(back, key=lambda v: dormant[v][0])
                slot, door = dormant.pop(u)
                rows[u][slot : s + t0] = door
                users[u].start, users[u].entry_node = s + t0, door
                new.append(u)
                continue
            users.append(_User(len(users), s + t0, node))
            rows.append(np.full(self._active.shape[0], -1, dtype=np.int64))
            new.append(len(users) - 1)
        return new

    def _decode_window(self, obs: np.ndarray, prefixes: list, starts: list, entry_nodes: list) -> tuple:
        """``(paths, info)`` of the window's users: staying put without any motion, else the
        adaptive decoder or the full-state baseline of ``params.mode``."""
        params = self.params
        if not obs.any():
            # no motion at all: every known user stays where it was
            w = obs.shape[0]
            paths = np.array([[p[-1] if p else -1] * w for p in prefixes], dtype=np.int64).reshape(len(prefixes), w)
            return paths, dict(order=0, states=0, overlap=False)
        if params.mode == "adaptive":
            return _adaptive_window(obs, prefixes, starts, entry_nodes, self.eatg, params)
        order = 1 if params.mode == "full1" else 2
        paths = decode_users(
            obs,
            np.arange(self.n),
            prefixes,
            starts,
            entry_nodes,
            order=order,
            eatg=self.eatg,
            params=params,
            transitions=self._full,
        )
        return paths, dict(order=order, states=self.n, overlap=None)

    def advance(self, *, final: bool = False, progress: Callable[[int, int], None] | None = None) -> None:
        """Decode every window whose slots have all arrived (with ``final``: every window left,
        the last accepting all its slots -- no slot arrives after)."""
        params = self.params
        n_slots = self.n_slots
        active, ons, fresh = self._active[:n_slots], self._ons[:n_slots], self._fresh[:n_slots]
        hops = self.eatg.hops
        adj = hops == 1
        users, rows, dormant = self.users, self.rows, self.dormant
        d_max = n_slots if params.offline else params.d_max
        tau = n_slots if params.offline else params.tau
        if params.offline and not final:
            return
        s = self.s
        alive = self.alive
        while s < n_slots and (final or s + d_max < n_slots):
            e = min(s + d_max, n_slots)
            acc = e if e == n_slots else min(s + tau, n_slots)
            obs = active[s:e]
            counted = obs if params.count == "on" else fresh[s:e]
            ct, cj = np.nonzero(counted)  # one scan of the window, then its slots' nodes
            k_now = max(
                (max_independent(cj[a:b], adj, self._mis) for a, b in _runs(ct)),
                default=0,
            )
            last = {u: _last_nodes(rows[u], s) for u in alive}
            entries = self._entries(s, obs, ons[s:e], last, alive)
            k_pre = len(alive)
            k = max(k_pre + len(entries), k_now)
            if params.max_users > 0:  # the bound holds inside the decoder: never more users than it
                k = min(k, max(params.max_users, k_pre))
            cur = alive + self._new_users(k - k_pre, entries, obs, s)
            prefixes = [last.get(u, []) for u in cur]
            starts = [max(0, users[u].start - s) for u in cur]
            entry_nodes = [users[u].entry_node for u in cur]
            paths, info = self._decode_window(obs, prefixes, starts, entry_nodes)
            gone = []
            for i, u in enumerate(cur):
                rows[u][s:acc] = np.where(np.arange(s, acc) >= users[u].start, paths[i, : acc - s], -1)
                if _exits(rows[u][:acc], active[acc:e], self.signatures):
                    gone.append(u)
            alive = [u for u in cur if u not in gone]
            for u in gone:
                dormant[u] = (acc, int(rows[u][acc - 1]))
            self.windows.append(dict(slot=s, k=k, k_now=k_now, sig_in=len(entries), sig_out=len(gone), **info))
            s = acc
            if progress is not None:
                progress(s, n_slots)
        self.s, self.alive = s, alive
        if final:
            self.done = True

    def activity(self, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """(hi - lo, N) slot activity fed so far over slots ``[lo, hi)``."""
        return self._active[lo : self.n_slots if hi is None else hi]

    def paths(self, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """(U, hi - lo) decoded node paths of the users so far over slots ``[lo, hi)``."""
        hi = self.n_slots if hi is None else hi
        return np.array([r[lo:hi] for r in self.rows], dtype=np.int64).reshape(len(self.rows), max(hi - lo, 0))

    def result(self) -> DecodeResult:
        return DecodeResult(self.paths(), list(self.windows))


def _runs(t: np.ndarray) -> list[tuple[int, int]]:
    """``[(a, b)]``: the runs of equal values of the sorted ``t`` (``t[a:b]``)."""
    if t.size == 0:
        return []
    cut = np.flatnonzero(np.diff(t)) + 1
    return list(zip([0, *cut.tolist()], [*cut.tolist(), int(t.size)]))


def _grow(a: np.ndarray, cap: int, fill) -> np.ndarray:
    out = np.full((cap, *a.shape[1:]), fill, dtype=a.dtype)
    out[: a.shape[0]] = a
    return out


def recent_onsets(ons: np.ndarray, slots: int) -> np.ndarray:
    """(D, N) bool: the node turned on in this slot or one of the ``slots - 1`` before it.

    >>> recent_onsets(np.array([[1], [0], [0], [1]], bool), 2)[:, 0].tolist()
    [True, True, False, True]
    """
    out = ons.copy()
    for k in range(1, max(int(slots), 1)):
        out[k:] |= ons[:-k]
    return out


def _last_nodes(row: np.ndarray, s: int) -> list[int]:
    """The user's node at slot ``s - 1`` preceded by the last different node it came from
    (the second-order context), or ``[]`` if absent at ``s - 1``."""
    if s == 0 or row[s - 1] < 0:
        return []
    last = int(row[s - 1])
    recent = row[max(0, s - LOOKBACK) : s]
    before = recent[recent >= 0]
    came = np.flatnonzero(before != last)
    return [int(before[came[-1]]), last] if came.size else [last]


def _exits(row: np.ndarray, after: np.ndarray, signatures) -> bool:
    """The path ends ``inner -> outer`` of an exit signature and ``outer`` is silent after.

    ``outer`` is the last node the path is at (absent slots skipped), ``inner`` the last
    different one before it (:func:`_last_two`): read from the end, so a window costs the
    user's last dwell, not the run so far."""
    end, came = _last_two(row)
    if end < 0 or came < 0:
        return False
    for outer, inner in signatures:
        if end == outer and came == inner and not after[:, outer].any():
            return True
    return False


def _last_two(row: np.ndarray) -> tuple[int, int]:
    """``(end, came)``: the last node of ``row`` (``-1`` entries are absences) and the last node
    different from it before that, ``-1`` where there is none; looking back in growing steps."""
    end, hi, step = -1, len(row), 64
    while hi > 0:
        lo = max(0, hi - step)
        seg = row[lo:hi]
        if end < 0:
            at = np.flatnonzero(seg >= 0)
            if at.size:
                end = int(seg[at[-1]])
                seg = seg[: at[-1]]
        if end >= 0:
            diff = np.flatnonzero((seg >= 0) & (seg != end))
            if diff.size:
                return end, int(seg[diff[-1]])
        hi, step = lo, step * 4
    return end, -1


def _adaptive_window(obs, prefixes, starts, entry_nodes, eatg: Eatg, params: DecoderParams):
    """Algorithm 3: fork first-order HMMs on non-overlapping motion, else one second-order HMM."""
    hops = eatg.hops
    adj = hops == 1
    t, j, lab = motion_components(obs, hops)
    n_comp = int(lab.max()) + 1 if lab.size else 0
    comp_nodes = [np.unique(j[lab == c]) for c in range(n_comp)]
    multi = False
    for c in range(n_comp):
        tc, jc = t[lab == c], j[lab == c]
        for tt in np.unique(tc):
            if max_independent(np.unique(jc[tc == tt]), adj, {}) >= 2:
                multi = True
                break
    k = len(prefixes)
    # users near components: last node (or entry node) within NEAR_HOPS of the component's nodes
    anchor = [p[-1] if p else entry_nodes[i] for i, p in enumerate(prefixes)]
    near = np.zeros((k, n_comp), bool)
    for i, a in enumerate(anchor):
        if a >= 0:
            near[i] = [hops[a, cn].min() <= NEAR_HOPS for cn in comp_nodes]
    overlap = multi or (near.sum(axis=0) > 1).any() or (near.sum(axis=1) > 1).any()
    active_nodes = np.unique(j)
    if overlap:
        keep = np.unique(
            np.concatenate([active_nodes, [a for a in anchor if a >= 0], *[p for p in prefixes if p]]).astype(np.int64)
        )
        states = np.flatnonzero((hops[keep] <= 2).any(axis=0))
        paths = decode_users(obs, states, prefixes, starts, entry_nodes, order=2, eatg=eatg, params=params)
        return paths, dict(order=2, states=len(states), overlap=True)
    paths = np.full((k, obs.shape[0]), -1, dtype=np.int64)
    # pair users with components (each user near at most one component, each component near at most one user)
    free_users = [i for i in range(k) if not near[i].any()]
    free_comps = [c for c in range(n_comp) if not near[:, c].any()]
    pairs = [(i, int(np.flatnonzero(near[i])[0])) for i in range(k) if near[i].any()]
    if free_users and free_comps:  # users without a nearby component (new, uniform start) take the rest
        cost = np.array(
            [[0.0 if anchor[i] < 0 else hops[anchor[i], comp_nodes[c]].min() for c in free_comps] for i in free_users]
        )
        r, cc = _optimize.linear_sum_assignment(cost)
        pairs += [(free_users[a], free_comps[b]) for a, b in zip(r, cc)]
    paired = {i for i, _ in pairs}
    states_total = 0
    for i, c in pairs:
        mask = np.zeros_like(obs)
        sel = lab == c
        mask[t[sel], j[sel]] = True
        keep = np.unique(
            np.concatenate([comp_nodes[c], [n for n in prefixes[i]], [anchor[i]] if anchor[i] >= 0 else []]).astype(
                np.int64
            )
        )
        states = np.flatnonzero((hops[keep] <= 1).any(axis=0))
        states_total += len(states)
        paths[i] = decode_users(
            mask, states, [prefixes[i]], [starts[i]], [entry_nodes[i]], order=1, eatg=eatg, params=params
        )[0]
    for i in range(k):
        if i not in paired:  # no motion near this user: it stays (or, new without motion, waits)
            if prefixes[i]:
                paths[i, starts[i] :] = prefixes[i][-1]
            elif entry_nodes[i] >= 0:
                paths[i, starts[i] :] = entry_nodes[i]
    return paths, dict(order=1, states=states_total, overlap=False)
