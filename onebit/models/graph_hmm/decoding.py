"""Decoding users on a binary-sensor graph, shared by the HMM trackers (``findinghumo``,
``hmm1``, ``hmm2``, ``findinghumo-flow``): the configuration, slotting the motion log into
``b_j(t)`` (:func:`slot_activity`), the EATG of a run (:func:`build_eatg`), the Adaptive-HMM /
full-state decoding of the whole run (:func:`decode_motion`), the user cap and the TRACKS table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.frames import motion_frames, silent_stretches
from onebit.core.site import Site
from onebit.core.tables import MOTION, TRACKS, check_schema, conform
from onebit.models.graph_hmm.adaptive import DecodeResult, DecoderParams, decode_run
from onebit.models.graph_hmm.config import (  # noqa: F401 (re-exported: the trackers import them from here)
    DECODINGS,
    JOINT,
    RESUME_SLOTS,
    HmmConfig,
)
from onebit.models.graph_hmm.eatg import Eatg, hop_matrix, layout_eatg, read_eatg, trained_eatg
from onebit.models.graph_hmm.kernels import cap_users_pass

#: One row per HMM window: first slot, users K (and K now), entry/exit signatures, HMM order,
#: states and whether the motion overlapped (null for the full-state baselines).
WINDOWS = pl.Schema(
    {
        "slot": pl.Int64,
        "k": pl.Int64,
        "k_now": pl.Int64,
        "sig_in": pl.Int64,
        "sig_out": pl.Int64,
        "order": pl.Int64,
        "states": pl.Int64,
        "overlap": pl.Boolean,
    }
)


def available(site: Site) -> str | None:
    """Why an HMM tracker cannot run on ``site`` (``None``: it can)."""
    if not site.motion_sensors:
        return "site has no motion sensors"
    if site.sensor_graph is None or not site.sensor_graph.edges:
        return "site has no [sensor_graph] with edges"
    return None


def slot_activity(
    motion: pl.DataFrame, nodes: tuple[str, ...], period: float, sampling: str = "mid", *, t0: float | None = None
) -> tuple[np.ndarray, float]:
    """(D, N) bool activity ``b_j(t)`` per slot and node, and ``t0`` (slot ``k`` covers
    ``[t0 + kT, t0 + (k+1)T)``, the grid of ``motion_frames``).

    ``sampling = "any"``: ``b_j(k) = 1`` when ``j`` was on at some time in slot ``k``
    (``motion_frames``' ``on``). ``sampling = "mid"`` (default): the binary series is sampled
    once per slot, at its mid time ``t0 + (k + 1/2) T``; an on-period ``[t_on, t_off)`` that
    contains no mid time (shorter than a slot) is kept in the slot holding its own mid time
    ``(t_on + t_off) / 2``, so no activation is lost::

        b_j(k) = 1  iff  some on-period [t_on, t_off) of j has t_on <= t0 + (k + 1/2) T < t_off,
                         or lies inside slot k with no mid time in it and (t_on + t_off)/2 in slot k

    With "any", the slot in which a user passes from ``m_a`` to ``m_b`` shows both nodes (and
    the PIR's hold keeps ``m_a`` on into the next slot); the mid-time sample shows the node
    the user is at in the middle of the slot -- the state the HMM decodes per slot.
    Vectorised: one difference array over (slot, node).
    """

    frames = motion_frames(motion, list(nodes), period=period, t0=t0)
    if frames.height == 0:
        return np.zeros((0, len(nodes)), bool), 0.0
    n = len(nodes)
    t0 = float(frames["t"].min())
    if sampling == "any":
        return frames["on"].to_numpy().reshape(-1, n), t0
    d = frames.height // n
    return mid_activity(motion, nodes, period, t0=t0, grid_slots=d, slot0=0, n_slots=d), t0


def mid_activity(
    motion: pl.DataFrame, nodes: tuple[str, ...], period: float, *, t0: float, grid_slots: int, slot0: int, n_slots: int
) -> np.ndarray:
    """``(n_slots, N)`` activity of the ``"mid"`` sampling of :func:`slot_activity` over the
    slots ``[slot0, slot0 + n_slots)`` of the grid ``t0 + k T`` (``grid_slots`` slots: an
    on-period still open at the end lasts to the grid's end). The same arithmetic as the whole
    run's, so the slots are bit for bit those of :func:`slot_activity`, when ``motion`` holds
    every edge at or after ``t0 + (slot0 - 1) T`` and each sensor's last edge before that (a
    follower slots only the recent edges: :mod:`onebit.trackers.findinghumo.lagged`)."""
    n = len(nodes)
    d = grid_slots
    idx = {m: i for i, m in enumerate(nodes)}
    iv = (
        motion.select("t", "sensor", "on")
        .filter(pl.col("sensor").is_in(list(nodes)))
        .sort("t", maintain_order=True)
        .with_columns(t_off=pl.col("t").shift(-1).over("sensor"))
        .filter(pl.col("on"))
        .with_columns(pl.col("t_off").fill_null(t0 + d * period))
    )
    if iv.height == 0 or n_slots <= 0:
        return np.zeros((max(n_slots, 0), n), bool)
    j = np.array([idx[s] for s in iv["sensor"].to_list()], dtype=np.int64)
    a = (iv["t"].to_numpy() - t0) / period - 0.5
    b = (iv["t_off"].to_numpy() - t0) / period - 0.5
    first = np.ceil(a).astype(np.int64)
    last = np.ceil(b).astype(np.int64) - 1
    short = last < first
    own = np.floor((a + b) / 2 + 0.5).astype(np.int64)
    first = np.clip(np.where(short, own, first), 0, d - 1)
    last = np.clip(np.where(short, own, last), 0, d - 1)
    keep = (last >= slot0) & (first < slot0 + n_slots)  # the on-periods that reach the slots asked for
    first = np.maximum(first[keep] - slot0, 0)
    last = np.minimum(last[keep] - slot0, n_slots - 1)
    j = j[keep]
    diff = np.zeros((n_slots + 1, n), np.int64)
    np.add.at(diff, (first, j), 1)
    np.add.at(diff, (last + 1, j), -1)
    return np.cumsum(diff, axis=0)[:n_slots] > 0


def build_eatg(site: Site, active: np.ndarray, cfg: HmmConfig) -> Eatg:
    g = site.sensor_graph
    hops = hop_matrix(g.nodes, g.edges)
    if cfg.eatg == "file":
        return read_eatg(cfg.eatg_file, g.nodes, hops)
    if cfg.eatg == "layout" or active.shape[0] < 2:
        return layout_eatg(g.nodes, hops, stay=cfg.stay, turn_back=cfg.turn_back)
    return trained_eatg(
        active,
        g.nodes,
        hops,
        horizon=cfg.d_max,
        prior_strength=cfg.prior_strength,
        stay=cfg.stay,
        turn_back=cfg.turn_back,
    )


@dataclass(frozen=True)
class DecodedRun:
    """What :func:`decode_motion` made: the slot activity ``(D, N)`` and its ``t0``, the EATG,
    the decoder's result (paths ``(U, D)``, windows), the entry/exit signatures as node
    indices, and the silent stretches of the log (the empty room)."""

    active: np.ndarray
    t0: float
    eatg: Eatg
    result: DecodeResult
    signatures: list[tuple[int, int]]
    silent: pl.DataFrame


#: the :class:`HmmConfig` fields :func:`decode_motion` reads (slots, EATG, decoder, silences)
DECODE_FIELDS = (
    "period",
    "sampling",
    "eatg",
    "eatg_file",
    "d_max",
    "tau",
    "stay",
    "turn_back",
    "prior_strength",
    "p_hit",
    "p_false",
    "sweeps",
    "restarts",
    "offline",
    "max_users",
    "count",
    "fresh_slots",
    "absent_after",
)
_LAST: dict = {}  # the last decoded run of this process and what it was decoded from


def decode_key(mode: str, cfg: HmmConfig) -> tuple:
    """What :func:`decode_motion` shares a decoded run by (besides the motion table and the
    site): the mode and the config's :data:`DECODE_FIELDS`."""
    return (mode, tuple(getattr(cfg, f) for f in DECODE_FIELDS))


def decode_motion(mode: str, inputs: dict, site: Site, cfg: HmmConfig, *, progress=None) -> DecodedRun:
    """Slot the ``motion`` table, learn the EATG and decode the users (:func:`decode_run`,
    ``mode`` ``"adaptive"`` / ``"full1"`` / ``"full2"``).

    Trackers that decode the same thing share it: the last run decoded in this process is
    returned again when ``mode``, the ``motion`` table and the site are the same objects and
    the config's :data:`DECODE_FIELDS` are equal (``findinghumo-flow`` with its default
    ``decoder = "full2"`` after ``hmm2``; ``findinghumo`` after ``findinghumo-flow`` with
    ``decoder = "adaptive"``). Its arrays are read-only, so no tracker can change what another
    reads."""
    key = decode_key(mode, cfg)
    if _LAST.get("key") == key and _LAST.get("motion") is inputs["motion"] and _LAST.get("site") is site:
        if progress is not None:  # the shared decode's progress, counted up again
            for done, total in _LAST["progress"]:
                progress(done, total)
        return _LAST["run"]
    calls: list[tuple[int, int]] = []

    def told(done: int, total: int) -> None:
        calls.append((done, total))
        if progress is not None:
            progress(done, total)

    motion = check_schema(inputs["motion"], MOTION, name="motion")
    g = site.sensor_graph
    nodes = g.nodes
    active, t0 = slot_activity(motion, nodes, cfg.period, cfg.sampling)
    eatg = build_eatg(site, active, cfg)
    sigs = signature_indices(g, eatg)
    params = decoder_params(site, cfg, mode)
    res = decode_run(active, eatg, signatures=sigs, params=params, progress=told)
    silent = silent_stretches([motion.filter(pl.col("sensor").is_in(list(nodes)))], min_s=cfg.absent_after)
    for a in (active, res.paths, eatg.hops, eatg.a1, eatg.a2):
        a.flags.writeable = False
    run = DecodedRun(active, t0, eatg, res, sigs, silent)
    _LAST.clear()
    _LAST.update(key=key, motion=inputs["motion"], site=site, run=run, progress=calls)
    return run


def signature_indices(g, eatg: Eatg) -> list[tuple[int, int]]:
    """:func:`door_signatures` of the sensor graph as EATG node indices."""
    idx = eatg.index
    return [(idx[a], idx[b]) for a, b in door_signatures(g) if a in idx and b in idx]


def decoder_params(site: Site, cfg: HmmConfig, mode: str) -> DecoderParams:
    """The window decoder's parameters of an HMM tracker's config (``mode``: adaptive, full1, full2)."""
    return DecoderParams(
        mode=mode,
        d_max=cfg.d_max,
        tau=cfg.tau,
        p_hit=cfg.p_hit,
        p_false=cfg.p_false,
        sweeps=cfg.sweeps,
        restarts=cfg.restarts,
        offline=cfg.offline,
        max_users=user_bound(site, cfg),
        count=cfg.count,
        fresh_slots=cfg.fresh_slots,
    )


def user_bound(site: Site, cfg: HmmConfig) -> int:
    """The most users decoded at once: ``max_users``, else the site's ``targets``, else 0 (none)."""
    return int(cfg.max_users or (site.targets or 0))


def windows_table(res: DecodeResult) -> pl.DataFrame:
    """The decoder's windows as a :data:`WINDOWS` table."""
    return pl.DataFrame(res.windows, schema=WINDOWS, orient="row") if res.windows else pl.DataFrame(schema=WINDOWS)


def door_signatures(g) -> list[tuple[str, str]]:
    """The graph's entry/exit signatures ``(outer, inner)``: its own, else one per door node
    (an ``entries``/``exits`` node) and each of its neighbours that is not a door -- so a
    site that only names its doors (``D###`` sensors of a CASAS home) gets the paper's
    ``Sig_in`` / ``Sig_out`` logic."""
    if g.signatures:
        return list(g.signatures)
    doors = list(dict.fromkeys([*g.entries, *g.exits]))
    nbr: dict[str, list[str]] = {}
    for a, b in g.edges:
        nbr.setdefault(a, []).append(b)
        nbr.setdefault(b, []).append(a)
    return [(d, n) for d in doors for n in sorted(set(nbr.get(d, ()))) if n not in doors]


def cap_users(
    paths: np.ndarray, active: np.ndarray, hops: np.ndarray, cap: int, *, compiled: bool = True
) -> np.ndarray:
    """At most ``cap`` users at a time: ``(U, D)`` decoded node paths -> ``(min(U, cap), D)``.

    The decoder's user count ``K = max(K_pre + Sig_in - Sig_out, K_now)`` can only grow by
    ``K_now`` (independent active nodes) without an exit signature to bring it down: one
    resident whose PIRs hold ``ON`` a few seconds after she passed shows two nodes two hops
    apart, a "second user" that then stays for the rest of the log. When the number of
    people is known (``targets``), ``cap`` identities are kept (:class:`UserCap` slot by slot
    online; here all slots at once): at each slot the present
    users are ranked by whether their node is active now, then by how recently it was, then
    by whether an identity already holds them; the first ``cap`` are reported. An identity
    keeps its user while the user is kept; a newly kept user takes the free identity whose
    last node is nearest in hops to it. ``cap <= 0`` or ``U <= cap`` returns ``paths``.
    Sequential over slots (each depends on the last): compiled
    (:func:`onebit.models.graph_hmm.kernels.cap_users_pass`); ``compiled=False`` runs
    :func:`cap_users_reference`, its test oracle.
    """
    U, D = paths.shape
    if cap <= 0 or U <= cap:
        return paths
    if not compiled:
        return cap_users_reference(paths, active, hops, cap)
    return cap_users_pass(
        np.ascontiguousarray(paths, dtype=np.int64),
        np.ascontiguousarray(active, dtype=np.bool_),
        np.ascontiguousarray(hops, dtype=np.int64),
        int(cap),
    )


def cap_users_reference(paths: np.ndarray, active: np.ndarray, hops: np.ndarray, cap: int) -> np.ndarray:
    """:func:`cap_users` in numpy, vectorised over the users of a slot (the oracle of its kernel):
    one :class:`UserCap` given every slot at once."""
    return UserCap(cap, hops).step(paths, active)


class UserCap:
    """The identities of :func:`cap_users`, kept slot by slot so that slots can come in pieces.

    At each slot the present users are ranked by whether their node is active now, then by
    how recently it was, then by whether an identity already holds them; the first ``cap``
    are reported. An identity keeps its user while the user is kept; a newly kept user takes
    the free identity whose last node is nearest in hops to it. Sequential over slots (each
    depends on the last); vectorised over users within one. :meth:`step` on slots cut into
    pieces gives the pieces of one :meth:`step` on them all (the users may grow in number
    between pieces: rows of users that appear later are appended)."""

    def __init__(self, cap: int, hops: np.ndarray):
        self.cap = int(cap)
        self.hops = hops
        self.holder = np.full(cap, -1, dtype=np.int64)  # identity -> decoded user
        self.last_node = np.full(cap, -1, dtype=np.int64)
        self.seen = np.zeros(0, dtype=np.int64)  # last slot each user's node was active
        self.slot = 0

    def step(self, paths: np.ndarray, active: np.ndarray) -> np.ndarray:
        """``(U, L)`` paths and ``(L, N)`` activity of the next ``L`` slots -> ``(cap, L)``."""
        cap, hops = self.cap, self.hops
        U, L = paths.shape
        if U > self.seen.size:
            self.seen = np.concatenate([self.seen, np.full(U - self.seen.size, -1, dtype=np.int64)])
        out = np.full((cap, L), -1, dtype=np.int64)
        holder, last_node, seen = self.holder, self.last_node, self.seen
        users = np.arange(U)
        for i_s in range(L):
            s = self.slot + i_s
            node = paths[:, i_s]
            here = node >= 0
            lit = here & active[i_s, np.clip(node, 0, None)]
            seen = np.where(lit, s, seen)
            held = np.isin(users, holder)
            order = np.lexsort((~held, -seen, ~lit))  # active now, then recently, then already held
            keep = [int(u) for u in order if here[u]][:cap]
            holder = np.where(np.isin(holder, keep), holder, -1)
            for u in keep:
                if u in holder:
                    continue
                free = np.flatnonzero(holder < 0)
                near = [hops[last_node[i], node[u]] if last_node[i] >= 0 else 0 for i in free]
                i = int(free[int(np.argmin(near))])
                holder[i] = u
            ok = holder >= 0
            out[ok, i_s] = node[holder[ok]]
            last_node = np.where(ok, out[:, i_s], last_node)
        self.holder, self.last_node, self.seen = holder, last_node, seen
        self.slot += L
        return out


def tracks_table(
    name: str, paths: np.ndarray, nodes, site: Site, t0: float, period: float, *, slot0: int = 0
) -> pl.DataFrame:
    """One row per user and slot present: ``paths`` (U, L) covers slots ``slot0 ..``, a row's
    ``t`` is its slot's mid time ``t0 + (slot + 1/2) T``."""
    u, s = np.nonzero(paths >= 0)
    pos = {m.id: m.position for m in site.motion_sensors}
    xy = np.array([pos[n] for n in nodes]).reshape(-1, 2)
    k = paths[u, s]
    df = pl.DataFrame(
        {
            "tracker": name,
            "track": [f"user{i + 1}" for i in u.tolist()],
            "t": t0 + (s + slot0 + 0.5) * period,
            "x": xy[k, 0] if k.size else np.zeros(0),
            "y": xy[k, 1] if k.size else np.zeros(0),
            "node": np.asarray(nodes, dtype=object)[k].tolist(),
        },
        schema_overrides={"track": pl.String, "node": pl.String, "tracker": pl.String},
    )
    return conform(df, TRACKS).sort(["t", "track"])
