"""Decoding users on a binary-sensor graph, shared by the HMM trackers (``findinghumo``,
``hmm1``, ``hmm2``, ``findinghumo-flow``): the configuration, slotting the motion log into
``b_j(t)`` (:func:`slot_activity`), the EATG of a run (:func:`build_eatg`), the Adaptive-HMM /
full-state decoding of the whole run (:func:`decode_motion`), the user cap and the TRACKS table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.config import check_choice, check_range
from onebit.core.frames import ABSENT_AFTER_S, motion_frames, silent_stretches
from onebit.core.site import Site
from onebit.core.tables import MOTION, TRACKS, check_schema, conform
from onebit.models.graph_hmm.adaptive import DecodeResult, DecoderParams, decode_run
from onebit.models.graph_hmm.eatg import Eatg, hop_matrix, layout_eatg, trained_eatg
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


#: where the joint re-decoding of meetings runs (:attr:`HmmConfig.joint`)
JOINT = ("off", "before-cpda", "after-cpda")


@dataclass(frozen=True, kw_only=True)
class HmmConfig:
    """Shared configuration of the HMM trackers (``run.toml`` sections ``[findinghumo]``,
    ``[hmm1]``, ``[hmm2]``); defaults are the paper's (section IV-A). The trackers work on
    the sensor graph: no field is a length.

    period : length T of a unit timeslot (s).
    sampling : how the binary series becomes ``b_j(t)`` per slot: ``"mid"`` -- the state at
        the slot's mid time (short on-periods kept in their own slot) -- or ``"any"`` -- on at
        some time in the slot (:func:`slot_activity`).
    d_max : HMM window length in slots (d_max T = 5 s).
    tau : acceptance threshold: the first ``tau`` slots of a window are kept, the next window
        starts there (the paper does not give a value).
    eatg : ``"trained"`` -- A', A'' learned from the run's own motion data (eqs. 1, 2),
        smoothed with the layout -- or ``"layout"`` (physical layout only).
    stay : layout prior probability of staying at a node for one slot.
    turn_back : layout prior probability of turning back after one hop.
    prior_strength : pseudo-counts of the layout prior per row of the trained EATG.
    p_hit : probability that the node a user is at is seen active in a slot.
    p_false : probability that a node nobody is at is seen active in a slot.
    sweeps : explain-away sweeps over the users per window (coordinate ascent).
    restarts : coordinate-ascent runs per window over different user decoding orders (every
        order when K! <= restarts, else rotations); the highest joint log-likelihood is kept.
    offline : decode the whole run as one window (the paper's offline baselines).
    absent_after : s; the empty room: no track row inside a stretch this long in which every
        sensor is off and nothing fires (nobody present); 0 = users stay where they were.
    max_users : the most users at once; 0 = the site's ``targets`` (the most people present at
        once), no bound when the site does not say. It bounds the decoder itself (a window
        never decodes more users, :func:`~onebit.models.graph_hmm.adaptive.decode_run`) and
        the output (:func:`cap_users`, which then has nothing left to cut).
    count : what ``K_now`` counts (:mod:`onebit.models.graph_hmm.adaptive`, item 1):
        ``"fresh"`` -- nodes that turned on in the last ``fresh_slots`` slots -- or ``"on"``
        -- every node on (the paper's literal reading; lingering sensors become users).
    fresh_slots : slots an onset counts as fresh for ``K_now``.
    joint : re-decode every meeting of two users jointly (beyond the paper,
        :mod:`onebit.models.graph_hmm.joint`); ``"off"``, ``"before-cpda"`` (on the HMM's
        output, what CPDA then starts from) or ``"after-cpda"``. The baselines ``hmm1`` /
        ``hmm2`` default to ``"off"`` (the paper's full-state HMMs as it describes them).
    joint_pad : slots a joint re-decoding window extends either side of a meeting.
    """

    period: float = 1.0
    sampling: str = "mid"
    d_max: int = 5
    tau: int = 3
    eatg: str = "trained"
    stay: float = 0.6
    turn_back: float = 0.05
    prior_strength: float = 2.0
    p_hit: float = 0.9
    p_false: float = 0.05
    sweeps: int = 3
    restarts: int = 6
    offline: bool = False
    absent_after: float = ABSENT_AFTER_S
    max_users: int = 0
    count: str = "fresh"
    fresh_slots: int = 2
    joint: str = "off"
    joint_pad: int = 4

    def __post_init__(self) -> None:
        check_range(self, "period", 1e-3, None)
        check_choice(self, "sampling", ("mid", "any"))
        check_range(self, "d_max", 1, 1000, types=(int,))
        check_range(self, "tau", 1, self.d_max if isinstance(self.d_max, int) else None, types=(int,))
        check_choice(self, "eatg", ("trained", "layout"))
        check_range(self, "stay", 0.0, 0.999)
        check_range(self, "turn_back", 0.0, 1.0)
        check_range(self, "prior_strength", 0.0, None)
        check_range(self, "p_hit", 0.5, 0.999)
        check_range(self, "p_false", 1e-6, 0.5)
        check_range(self, "sweeps", 1, 20, types=(int,))
        check_range(self, "restarts", 1, 20, types=(int,))
        check_choice(self, "offline", (False, True))
        check_range(self, "absent_after", 0.0, 1e12)
        check_range(self, "max_users", 0, 10_000, types=(int,))
        check_choice(self, "count", ("fresh", "on"))
        check_range(self, "fresh_slots", 1, 1000, types=(int,))
        check_choice(self, "joint", JOINT)
        check_range(self, "joint_pad", 0, 100, types=(int,))


def available(site: Site) -> str | None:
    """Why an HMM tracker cannot run on ``site`` (``None``: it can)."""
    if not site.motion_sensors:
        return "site has no motion sensors"
    if site.sensor_graph is None or not site.sensor_graph.edges:
        return "site has no [sensor_graph] with edges"
    return None


def slot_activity(
    motion: pl.DataFrame, nodes: tuple[str, ...], period: float, sampling: str = "mid"
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

    frames = motion_frames(motion, list(nodes), period=period)
    if frames.height == 0:
        return np.zeros((0, len(nodes)), bool), 0.0
    n = len(nodes)
    t0 = float(frames["t"].min())
    if sampling == "any":
        return frames["on"].to_numpy().reshape(-1, n), t0
    d = frames.height // n
    idx = {m: i for i, m in enumerate(nodes)}
    iv = (
        motion.select("t", "sensor", "on")
        .filter(pl.col("sensor").is_in(list(nodes)))
        .sort("t", maintain_order=True)
        .with_columns(t_off=pl.col("t").shift(-1).over("sensor"))
        .filter(pl.col("on"))
        .with_columns(pl.col("t_off").fill_null(t0 + d * period))
    )
    if iv.height == 0:
        return np.zeros((d, n), bool), t0
    j = np.array([idx[s] for s in iv["sensor"].to_list()], dtype=np.int64)
    a = (iv["t"].to_numpy() - t0) / period - 0.5
    b = (iv["t_off"].to_numpy() - t0) / period - 0.5
    first = np.ceil(a).astype(np.int64)
    last = np.ceil(b).astype(np.int64) - 1
    short = last < first
    own = np.floor((a + b) / 2 + 0.5).astype(np.int64)
    first = np.clip(np.where(short, own, first), 0, d - 1)
    last = np.clip(np.where(short, own, last), 0, d - 1)
    diff = np.zeros((d + 1, n), np.int64)
    np.add.at(diff, (first, j), 1)
    np.add.at(diff, (last + 1, j), -1)
    return np.cumsum(diff, axis=0)[:d] > 0, t0


def build_eatg(site: Site, active: np.ndarray, cfg: HmmConfig) -> Eatg:
    g = site.sensor_graph
    hops = hop_matrix(g.nodes, g.edges)
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


def decode_motion(mode: str, inputs: dict, site: Site, cfg: HmmConfig, *, progress=None) -> DecodedRun:
    """Slot the ``motion`` table, learn the EATG and decode the users (:func:`decode_run`,
    ``mode`` ``"adaptive"`` / ``"full1"`` / ``"full2"``)."""
    motion = check_schema(inputs["motion"], MOTION, name="motion")
    g = site.sensor_graph
    nodes = g.nodes
    active, t0 = slot_activity(motion, nodes, cfg.period, cfg.sampling)
    eatg = build_eatg(site, active, cfg)
    idx = eatg.index
    sigs = [(idx[a], idx[b]) for a, b in door_signatures(g) if a in idx and b in idx]
    params = DecoderParams(
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
    res = decode_run(active, eatg, signatures=sigs, params=params, progress=progress)
    silent = silent_stretches([motion.filter(pl.col("sensor").is_in(list(nodes)))], min_s=cfg.absent_after)
    return DecodedRun(active, t0, eatg, res, sigs, silent)


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
    people is known (``targets``), ``cap`` identities are kept: at each slot the present
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
    """:func:`cap_users` in numpy, vectorised over the users of a slot (the oracle of its kernel)."""
    U, D = paths.shape
    out = np.full((cap, D), -1, dtype=np.int64)
    holder = np.full(cap, -1, dtype=np.int64)  # identity -> decoded user
    last_node = np.full(cap, -1, dtype=np.int64)
    seen = np.full(U, -1, dtype=np.int64)  # last slot each user's node was active
    users = np.arange(U)
    for s in range(D):
        node = paths[:, s]
        here = node >= 0
        lit = here & active[s, np.clip(node, 0, None)]
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
        out[ok, s] = node[holder[ok]]
        last_node = np.where(ok, out[:, s], last_node)
    return out


def tracks_table(name: str, paths: np.ndarray, nodes, site: Site, t0: float, period: float) -> pl.DataFrame:
    u, s = np.nonzero(paths >= 0)
    pos = {m.id: m.position for m in site.motion_sensors}
    xy = np.array([pos[n] for n in nodes]).reshape(-1, 2)
    k = paths[u, s]
    df = pl.DataFrame(
        {
            "tracker": name,
            "track": [f"user{i + 1}" for i in u.tolist()],
            "t": t0 + (s + 0.5) * period,
            "x": xy[k, 0] if k.size else np.zeros(0),
            "y": xy[k, 1] if k.size else np.zeros(0),
            "node": np.asarray(nodes, dtype=object)[k].tolist(),
        },
        schema_overrides={"track": pl.String, "node": pl.String, "tracker": pl.String},
    )
    return conform(df, TRACKS).sort(["t", "track"])
