"""Known residents: who fired each motion event, with a profile learned from labelled days.

Beyond the papers. Where a home has some labelled days (CASAS resident annotations; a week a
carer annotated), each resident's way of moving through it -- which sensors they fire after
which, where they spend their time -- is learned once as a *profile*, and new days are then
decoded by an exact hidden Markov model whose hidden state is who fired each event and where
everyone else last was. Supervised per-event resident identification is the published anchor
for two-resident homes (0.88-0.95); the unsupervised ``residents`` decoder is the answer when
no labelled day exists.

Profile (learned by :func:`learn_profile`, table
:data:`~onebit.core.tables.RESIDENTS_PROFILE`): for each resident ``r``, ``n_r(a, s)`` the
number of times ``r``'s labelled event at sensor ``a`` was followed by ``r``'s next labelled
event at ``s``, and ``h_r(s)`` the number of ``r``'s labelled events at ``s`` (an event labelled
with two residents counts for both).

Motion of one resident (K1): a first-order Markov chain over the sensors, its rows shrunk
towards the residents model's Laplace kernel on the site's distances (so a transition never
seen in training keeps the probability geometry gives it), and a resident not seen yet firing
by their habit::

    T_r(a, s) = (n_r(a, s) + beta k_l(a, s)) / (n_r(a, .) + beta),
    k_l(a, s) = exp(-d(a, s) / l) / sum_u exp(-d(a, u) / l)                       (K1)
    T_r(0, s) = (h_r(s) + 1) / (h_r(.) + S)            (0: r has not fired yet)

Who fired (K2). Every event is fired by exactly one of the ``K`` residents, each a priori
equally likely (a constant ``K^-n``), so with ``z_i`` the resident of event ``i`` and
``last_r(i)`` the sensor of ``r``'s latest event before ``i`` (0 if none)::

    P(z_1..n | s_1..n)  propto  prod_i T_{z_i}(last_{z_i}(i), s_i)                 (K2)

Clock (K3, optional). People keep routines: who is at a sensor depends on the time of day
(in a scripted session, on how far into the session it is). A profile learned with a clock
also counts each resident's events per sensor in each of ``n`` bins of it, ``h_r(s, b)``, and
each event is weighed by how likely each resident is to be the one at its sensor at that
time -- a per-event expert in a product with the chains (weight ``w``,
``profile_clock_weight``)::

    log phi_r(s, b) = w ln[ (h_r(s, b) + 1) / sum_u (h_u(s, b) + 1) ]                    (K3)

so (K2) becomes ``prod_i T_{z_i}(last_{z_i}(i), s_i) phi_{z_i}(s_i, b_i)``: a factor per
event and firer, which the same recursion carries exactly.

State. After event ``i`` its firer is at ``s_i``; (K2) depends on the past only through the
others' last sensors, so the state is ``x_i = (z_i, p_{-z_i})``: ``K (S + 1)^(K - 1)`` states
(``2 (S + 1)`` for two residents). Forward-backward over ``x`` gives the exact marginals
``P(z_i = r | s_1..n)`` (:func:`posteriors`); each event goes to its most probable resident
(the marginal maximum: the attribution that maximises the expected number of events right,
the per-event accuracy). The recursion runs over the joint positions ``p`` (``(S + 1)^K``
values) once per event:

    G_i(p) = sum_r alpha_i(r, p_{-r}) [p_r = s_i]
    alpha_{i+1}(r, q) = sum_{p: p_{-r} = q} G_i(p) T_r(p_r, s_{i+1})
    beta_i(p) = sum_r T_r(p_r, s_{i+1}) beta_{i+1}(r, p_{-r})

in log space, vectorised over ``p``; sequential over events (numpy per step: tens of
microseconds for two residents). :func:`onebit._testing.oracles.posteriors_bruteforce` enumerates all ``K^n`` firer
sequences of a short log (the test oracle).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

import numpy as np
import polars as pl
from scipy.special import logsumexp

from onebit.core.compiled import kernel, numba_loaded
from onebit.core.errors import ConfigError, InputError
from onebit.core.tables import RESIDENTS_PROFILE, conform

#: Largest joint state space ``(S + 1)^K`` decoded (memory and time per event grow with it).
MAX_JOINT = 2_000_000


@dataclass(frozen=True)
class Clock:
    """The profile's clock (K3): ``kind`` ``"session"`` (the phase of the log, first to last
    event: scripted sessions) or ``"day"`` (the time of day, from the site's ``epoch``: homes
    over days), cut into ``bins`` equal parts."""

    kind: str
    bins: int

    def __post_init__(self) -> None:
        if self.kind not in ("session", "day"):
            raise ConfigError(f"profile clock {self.kind!r}: 'session' or 'day'")
        if not (isinstance(self.bins, int) and 1 <= self.bins <= 1440):
            raise ConfigError(f"profile clock bins = {self.bins!r}: an integer in [1, 1440]")

    def bin(self, t: np.ndarray, *, epoch: str | None) -> np.ndarray:
        """The bin of every time ``t`` (seconds on the run's clock, sorted)."""
        t = np.asarray(t, dtype=float)
        if t.size == 0:
            return np.zeros(0, dtype=np.int64)
        if self.kind == "session":
            span = float(t[-1] - t[0])
            phase = (t - t[0]) / span if span > 0 else np.zeros_like(t)
        else:
            if epoch is None:
                raise ConfigError("the profile's clock is 'day' (time of day) but the site has no epoch")
            e = datetime.fromisoformat(str(epoch))
            sod = e.hour * 3600.0 + e.minute * 60.0 + e.second + e.microsecond / 1e6
            phase = np.mod(sod + t, 86400.0) / 86400.0
        return np.minimum((phase * self.bins).astype(np.int64), self.bins - 1)

    def label(self, k: int) -> str:
        return f"{self.kind} {k}/{self.bins}"


def clock_of(profile: pl.DataFrame) -> Clock | None:
    """The clock of a profile's binned habit rows (``None``: it has none)."""
    labels = profile["bin"].drop_nulls().unique().to_list() if "bin" in profile.columns else []
    if not labels:
        return None
    kinds = {(x.split()[0], int(x.split("/")[1])) for x in labels}
    if len(kinds) > 1:
        raise InputError(f"the profile mixes clocks: {sorted(kinds)} (one kind and one number of bins)")
    ((kind, bins),) = kinds
    return Clock(kind, bins)


def learn_profile(
    labelled: list[pl.DataFrame], *, clock: Clock | None = None, epochs: list[str | None] | None = None
) -> pl.DataFrame:
    """The profile (:data:`RESIDENTS_PROFILE`) of labelled event logs: each a ``truth_events``
    table (t, sensor, residents ``"1"``/``"1;2"``), one per session; counts summed over them.
    A resident's chain restarts in each session (no transition across sessions). With a
    ``clock`` the habit rows are also counted per bin of it (``epochs``: each session's site
    epoch, for the ``day`` clock)."""
    trans: dict[tuple[str, str | None, str, str | None], float] = {}
    for k, te in enumerate(labelled):
        te = te.sort("t")
        bins = clock.bin(te["t"].to_numpy(), epoch=(epochs or [None] * len(labelled))[k]) if clock else None
        last: dict[str, str] = {}
        for i, (s, rs) in enumerate(te.select("sensor", "residents").iter_rows()):
            for r in rs.split(";"):
                keys = [(r, None, s, None)]
                if bins is not None:
                    keys.append((r, None, s, clock.label(int(bins[i]))))
                if r in last:
                    keys.append((r, last[r], s, None))
                for key in keys:
                    trans[key] = trans.get(key, 0.0) + 1.0
                last[r] = s
    rows = sorted(trans.items(), key=lambda kv: (kv[0][0], kv[0][1] or "", kv[0][2], kv[0][3] or ""))
    df = pl.DataFrame(
        {
            "resident": [k[0] for k, _ in rows],
            "from": [k[1] for k, _ in rows],
            "to": [k[2] for k, _ in rows],
            "count": [v for _, v in rows],
            "bin": [k[3] for k, _ in rows],
        },
        schema=RESIDENTS_PROFILE,
    )
    return conform(df, RESIDENTS_PROFILE)


def clock_bonus(
    profile: pl.DataFrame,
    residents: tuple[str, ...],
    nodes: tuple[str, ...],
    node: np.ndarray,
    t: np.ndarray,
    *,
    epoch: str | None,
    weight: float,
) -> np.ndarray | None:
    """``phi_r(s_i, b_i)`` of (K3) for every event and resident (``n x K``), ``None`` when the
    profile has no clock or ``weight`` is 0."""
    clock = clock_of(profile)
    if clock is None or weight == 0:
        return None
    S, K = len(nodes), len(residents)
    index = {n: k for k, n in enumerate(nodes)}
    ri = {r: k for k, r in enumerate(residents)}
    h = np.ones((K, clock.bins, S))  # one pseudo-event per resident, bin and sensor (K3)
    rows = profile.filter(pl.col("bin").is_not_null() & pl.col("to").is_in(list(nodes)))
    for r, s, c, b in rows.select("resident", "to", "count", "bin").iter_rows():
        h[ri[r], int(b.split()[1].split("/")[0]), index[s]] += c
    log_p = np.log(h / h.sum(axis=0, keepdims=True))  # ln P(resident | sensor, bin), add-one
    b = clock.bin(t, epoch=epoch)
    return weight * log_p[:, b, node].T


@dataclass(frozen=True)
class Chains:
    """(K1) on the run's sensors: ``log_t[r]`` is ``(S + 1) x S`` -- rows the last sensor of
    resident ``r`` (row ``S``: not fired yet), columns the next sensor."""

    residents: tuple[str, ...]
    log_t: np.ndarray


def chains(profile: pl.DataFrame, nodes: tuple[str, ...], dist: np.ndarray, *, spread: float, prior: float) -> Chains:
    """The chains (K1) of ``profile`` on ``nodes`` (distances ``dist`` in metres; ``spread`` =
    ``l``, ``prior`` = ``beta``). Profile rows at sensors not in ``nodes`` are ignored."""
    residents = tuple(sorted(profile["resident"].unique().to_list()))
    S = len(nodes)
    index = {n: k for k, n in enumerate(nodes)}
    kern = -np.asarray(dist, dtype=float) / spread
    kern = np.exp(kern - logsumexp(kern, axis=1, keepdims=True))
    log_t = np.empty((len(residents), S + 1, S))
    for k, r in enumerate(residents):
        mine = profile.filter((pl.col("resident") == r) & pl.col("to").is_in(list(nodes)))
        moves = mine.filter(pl.col("from").is_in(list(nodes)))
        n = np.zeros((S, S))
        np.add.at(
            n,
            (
                np.array([index[a] for a in moves["from"].to_list()], dtype=np.int64),
                np.array([index[s] for s in moves["to"].to_list()], dtype=np.int64),
            ),
            moves["count"].to_numpy(),
        )
        habit = mine.filter(pl.col("from").is_null())
        h = np.zeros(S)
        np.add.at(h, np.array([index[s] for s in habit["to"].to_list()], dtype=np.int64), habit["count"].to_numpy())
        t = (n + prior * kern) / (n.sum(axis=1, keepdims=True) + prior)
        log_t[k, :S] = np.log(t)
        log_t[k, S] = np.log((h + 1.0) / (h.sum() + S))
    return Chains(residents, log_t)


def _expand(alpha_i: np.ndarray, j: int, K: int, S1: int) -> np.ndarray:
    """``G_i(p)``: the joint positions of the state ``alpha_i(r, q)`` (firer ``r`` at ``j``)."""
    g = np.full((S1,) * K, -np.inf)
    for r in range(K):
        idx = [slice(None)] * K
        idx[r] = j
        g[tuple(idx)] = np.logaddexp(g[tuple(idx)], alpha_i[r].reshape((S1,) * (K - 1)))
    return g


def _along(v: np.ndarray, axis: int, K: int) -> np.ndarray:
    """``v`` (length S + 1) shaped to broadcast along ``axis`` of a K-dimensional array."""
    shape = [1] * K
    shape[axis] = v.size
    return v.reshape(shape)


def posteriors(node: np.ndarray, ch: Chains, bonus: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """``P(z_i = r | s_1..n)`` for every event (``n x K``) and ``log P(s_1..n)`` (module
    docstring). ``node``: event sensors as indices into the chains' columns, in time order;
    ``bonus``: ``log phi_{z_i}(s_i, b_i)`` of (K3), ``n x K`` (``None``: none)."""
    K = len(ch.residents)
    S = ch.log_t.shape[2]
    S1 = S + 1
    n = len(node)
    if n == 0:
        return np.zeros((0, K)), 0.0
    bonus = np.zeros((n, K)) if bonus is None else np.asarray(bonus, dtype=float)
    if S1**K > MAX_JOINT:
        raise ValueError(f"{K} residents on {S} sensors: {S1**K} joint states, more than {MAX_JOINT}")
    # lt[r]: (S + 1) x (S + 1), last column unused: a row index S is "not fired yet"
    lt = np.concatenate([ch.log_t, np.full((K, S1, 1), -np.inf)], axis=2)
    alpha = np.empty((n, K, S1 ** (K - 1)))
    g = np.full((S1,) * K, -np.inf)
    g[(S,) * K] = 0.0  # nobody has fired
    for i in range(n):
        j = int(node[i])
        for r in range(K):
            alpha[i, r] = logsumexp(g + _along(lt[r, :, j], r, K), axis=r).reshape(-1) + bonus[i, r]
        g = _expand(alpha[i], j, K, S1)
    log_z = float(logsumexp(g))
    beta = np.zeros((n, K, S1 ** (K - 1)))
    for i in range(n - 2, -1, -1):
        jn = int(node[i + 1])
        terms = [
            _along(lt[r, :, jn] + bonus[i + 1, r], r, K) + np.expand_dims(beta[i + 1, r].reshape((S1,) * (K - 1)), r)
            for r in range(K)
        ]
        b = np.logaddexp.reduce(np.broadcast_arrays(*terms), axis=0) if K > 1 else terms[0]
        j = int(node[i])
        for r in range(K):
            idx = [slice(None)] * K
            idx[r] = j
            beta[i, r] = b[tuple(idx)].reshape(-1)
    post = logsumexp(alpha + beta, axis=2) - log_z
    return np.exp(post), log_z


# --------------------------------------------------------------------------- turns (K4)
#
# The chains (K1-K3) hold both residents present and firing in turn. In a home over days that
# is seldom so: one is out or asleep for hours, and the one awake fires run after run of events.
# ``profile_model = "turns"`` decodes who fired each event by that, from the same profile:
#
#     P(z_i = r | z_{i-1} = q) = s_i [r = q] + (1 - s_i) / (K - 1) [r != q],
#     s_i = 1/K + (1 - 1/K) exp(-(t_i - t_{i-1}) / tau)                                  (K4)
#     emission  e_r(i) = P(r | s_i, b_i) = (h_r(s_i, b_i) + 1) / sum_u (h_u(s_i, b_i) + 1)
#
# (the habit of (K3) as a scaled likelihood; per sensor when the profile has no clock): a person
# who fired an event a moment ago most likely fired this one too, and after a long silence anyone
# may have (``s -> 1/K``). Forward-backward gives ``P(z_i = r | all events)``; each event goes to
# its most probable resident. Inherently sequential over events: compiled
# (:func:`turn_posteriors`), :func:`turn_posteriors_reference` its oracle.


def habit_log_probs(
    profile: pl.DataFrame, residents: tuple[str, ...], nodes: tuple[str, ...], node: np.ndarray, t: np.ndarray, *, epoch
) -> np.ndarray:
    """``ln P(r | s_i, b_i)`` of (K4) for every event and resident (``n x K``): by the profile's
    clock bins when it has a clock, else by its per-sensor habit rows; add-one."""
    S, K = len(nodes), len(residents)
    index = {n: k for k, n in enumerate(nodes)}
    ri = {r: k for k, r in enumerate(residents)}
    clock = clock_of(profile)
    bins = clock.bins if clock is not None else 1
    h = np.ones((K, bins, S))
    habit = profile.filter(pl.col("from").is_null() & pl.col("to").is_in(list(nodes)))
    habit = habit.filter(pl.col("bin").is_not_null()) if clock is not None else habit.filter(pl.col("bin").is_null())
    for r, s_, c, b in habit.select("resident", "to", "count", "bin").iter_rows():
        if r in ri:
            h[ri[r], int(b.split()[1].split("/")[0]) if clock is not None else 0, index[s_]] += c
    log_p = np.log(h / h.sum(axis=0, keepdims=True))
    b = clock.bin(t, epoch=epoch) if clock is not None else np.zeros(len(node), dtype=np.int64)
    return log_p[:, b, node].T


def turn_posteriors_reference(log_e: np.ndarray, t: np.ndarray, tau: float) -> np.ndarray:
    """(K4)'s posteriors, written step by step in log space (the oracle of :func:`turn_posteriors`)."""
    n, K = log_e.shape
    if n == 0:
        return np.zeros((0, K))
    fwd = np.empty((n, K))
    fwd[0] = log_e[0] - np.log(K)
    for i in range(1, n):
        stay = 1.0 / K + (1.0 - 1.0 / K) * np.exp(-(t[i] - t[i - 1]) / tau)
        move = (1.0 - stay) / max(K - 1, 1)
        a = np.full((K, K), np.log(max(move, 1e-300)))
        np.fill_diagonal(a, np.log(stay))
        fwd[i] = logsumexp(fwd[i - 1][:, None] + a, axis=0) + log_e[i]
    bwd = np.zeros((n, K))
    for i in range(n - 2, -1, -1):
        stay = 1.0 / K + (1.0 - 1.0 / K) * np.exp(-(t[i + 1] - t[i]) / tau)
        move = (1.0 - stay) / max(K - 1, 1)
        a = np.full((K, K), np.log(max(move, 1e-300)))
        np.fill_diagonal(a, np.log(stay))
        bwd[i] = logsumexp(a + (log_e[i + 1] + bwd[i + 1])[None, :], axis=1)
    post = fwd + bwd
    post -= logsumexp(post, axis=1, keepdims=True)
    return np.exp(post)


@kernel
def _turns_kernel(e, t, tau):  # pragma: no cover - compiled
    n, K = e.shape
    fwd = np.zeros((n, K))
    bwd = np.ones((n, K))
    s = 0.0
    for r in range(K):
        fwd[0, r] = e[0, r] / K
        s += fwd[0, r]
    for r in range(K):
        fwd[0, r] /= s
    for i in range(1, n):
        stay = 1.0 / K + (1.0 - 1.0 / K) * np.exp(-(t[i] - t[i - 1]) / tau)
        move = (1.0 - stay) / max(K - 1, 1)
        tot = 0.0
        for r in range(K):
            acc = 0.0
            for q in range(K):
                acc += fwd[i - 1, q] * (stay if q == r else move)
            fwd[i, r] = acc * e[i, r]
            tot += fwd[i, r]
        for r in range(K):
            fwd[i, r] /= tot
    for i in range(n - 2, -1, -1):
        stay = 1.0 / K + (1.0 - 1.0 / K) * np.exp(-(t[i + 1] - t[i]) / tau)
        move = (1.0 - stay) / max(K - 1, 1)
        tot = 0.0
        for q in range(K):
            acc = 0.0
            for r in range(K):
                acc += (stay if q == r else move) * e[i + 1, r] * bwd[i + 1, r]
            bwd[i, q] = acc
            tot += acc
        for q in range(K):
            bwd[i, q] /= tot
    post = fwd * bwd
    for i in range(n):
        tot = 0.0
        for r in range(K):
            tot += post[i, r]
        for r in range(K):
            post[i, r] /= tot
    return post


def turn_posteriors(log_e: np.ndarray, t: np.ndarray, tau: float) -> np.ndarray:
    """``P(z_i = r | all events)`` of (K4), ``n x K`` (compiled; scaled forward-backward)."""
    if log_e.shape[0] == 0:
        return np.zeros(log_e.shape)
    if log_e.size <= 20_000 and not numba_loaded():  # small: numba's start-up costs more than the loop
        return turn_posteriors_reference(log_e, t, tau)
    e = np.exp(log_e - log_e.max(axis=1, keepdims=True))
    return _turns_kernel(np.ascontiguousarray(e), np.ascontiguousarray(t, dtype=np.float64), float(tau))
