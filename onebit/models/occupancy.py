"""How many people are home: a door-gated hidden Markov model of the count, over minutes.

Beyond the papers. The trackers of a home decode who fired each event, but the first question
a home's user asks is simpler: how many people are in? A motion log answers it through three
things, each a term below: people come and go through the house door (the count changes at
door events), an empty home is silent (a sensor that fires needs someone), and two sensors far
apart firing at once need two people. Where labelled days exist (``truth_count.csv``), the
same model is learned from them -- which sensors are on with 0, 1, 2 people in, when people
go out, and the count by time of day -- and decodes later days.

Bins. Time is cut into bins of ``bin_s`` (60 s), bin ``b`` covering
``[t0 + b bin_s, t0 + (b + 1) bin_s)``, ``t0`` a multiple of ``bin_s`` (so bins line up with the
clock). Per bin (:func:`features`):

* ``door_b`` -- an edge (on or off) of an entry/exit sensor of the site's sensor graph;
* ``active_b`` -- an ON edge of another sensor, or (``held``) a level sensor on in the bin
  (a force sensor under a sleeper, a pressure mat under someone sitting);
* ``far_b`` -- two ON edges at most ``window_s`` apart at sensors ``far_hops`` or more hops
  apart on the sensor graph (straight-line ``far_m`` metres without a graph; sensors the
  graph does not join are not far): one person cannot have fired both -- unless one of the
  two sensors is out of place, eq. (F1) below;
* ``firings_b`` / ``strays_b`` -- the bin's ON edges of non-door sensors, and how many of them
  the one walker of (W1)-(W2) below leaves unexplained (with ``walk_s`` > 0 and a sensor graph);
* ``fired_bs`` / ``held_bs`` -- which sensors had an ON edge / were on (level sensors) in the bin;
* ``hour_b`` -- the hour of day (from the site's epoch).

Sensors out of place (a floor plan's far pairs). A plan can be wrong about a sensor: moved
since it was drawn, or seeing through a doorway into the next room. One person beside such a
sensor makes far pairs with every sensor around them, all with that one sensor at an end, while
a second person's far pairs fall on the sensors people use in proportion to their use. Over
the decoded span, with ``n_s`` the ON edges of sensor ``s`` (``N`` in all) and ``p_s`` the far
pairs with an end at ``s`` (``P`` pairs)::

    lambda_s = (p_s / 2P) / (n_s / N);   s is out of place when lambda_s >= far_lift, p_s >= far_lift_min   (F1)

and the far pairs with an end at a sensor out of place are left out of ``far_b``. A model
learned from labelled days has (F1) off: its learned ``F`` already holds that home's misplaced
sensors (measured on ARAS House B, (F1) there raised the count error from 0.167 to 0.177).
``far_lift = 2``: on the one- and two-resident sessions the defaults were chosen on, the
sensor with the most far-pair ends has ``lambda`` 0.8-1.5 with two people in, and 2.85-13.8
where one person's session has a sensor out of place (a Kyoto plan's M025 in most of them);
rarely firing sensors reach 2-5 in both and are left out too (docs/homes.md).

One walker or two (a graph learned from the log, no plan). On a learned graph hops are not
distances: two sensors many hops apart may be neighbours the log rarely joined, so a single far
pair is weak evidence. Stronger is how much of the log one walker can explain. Firing ``j``
(ON edge at sensor ``s_j``, time ``t_j``) can follow firing ``i < j`` on one walker's path when::

    hops(s_i, s_j) <= walk_slack + (t_j - t_i + tick) / walk_s                             (W1)

(``walk_s`` seconds per hop; ``walk_slack`` hops of the graph's looseness; sensors the graph
does not join: hops 0, nothing known). ``tick`` is the slack of the log's clock: a logger that
polls its sensors once every ``clock_s`` stamps the events of one poll together (CASAS: within
a few hundredths of a second, at one phase of the second), each event late by ``U(0, clock_s)``,
so two stamps ``dt`` apart are ``dt + (U_i - U_j)`` apart in truth, and the firings stamped by
one poll come in the poll's order, not the walk's. ``|U_i - U_j| <= clock_s / 2`` for 3 pairs in
4, and that is the slack given: the whole period would let one walker reach a second person
two hops further (on a generated polled two-walker log it decodes 1). Such a log is told by
the phase of its firings' times modulo ``clock_s``, their mean resultant length::

    R = | mean_j exp(2 pi i t_j / clock_s) |,   tick = clock_s / 2 if R >= tick_phase else 0    (W0)

near 1 when every stamp shares one phase, near 0 on a log stamped to the microsecond. A site
with an entry/exit sensor keeps ``tick = 0`` (the homes with door sensors, ARAS, were measured
without it; their 1 Hz readings are a tick too). A re-fire of a sensor the walker stood at, or of one it
just left (lingering, a late PIR), is feasible, so lingering is one source. The walker's path
is the longest chain of firings linked by (W1) (a longest path in the DAG of feasible links,
each firing linked to at most ``M = 64`` predecessors)::

    L_j = 1 + max(0, max{L_i : i in [j - M, j), (W1) holds for (i, j)})                      (W2)

traced back from the largest ``L_j``; the firings off it are strays: ``strays_b`` of the bin's
``firings_b``. One walker leaves a few (glitches, the graph's missing edges); two walkers active
at once leave more: the firings of one of them whenever the other is out of its reach.
The firings are the ON edges of non-door sensors; a level sensor held on adds none.

The model. Hidden count ``n_b`` in ``0..K`` (``K`` = ``targets`` of the site, else the
largest count of the labelled days, else ``max_people``)::

    P(n_b = j | n_{b-1} = i) = D[i, j]  if door_b   else  Q[i, j]                       (O1)
    P(obs_b | n_b = n) = A[n, active_b] F[n, far_b] H(hour_b, n)^w  G(strays_b | firings_b, n)
                         [prod_s P(fired_bs | n) P(held_bs | n)]^v   [learned sensors only]  (O2)
    G(u | m, n) = g_n^u (1 - g_n)^(m - u)                                                    (O3)

(O3) is the binomial of the strays, without its coefficient (the same for every ``n``); it is
used when ``walk_s > 0`` and the site has a sensor graph, and then replaces ``F`` (the far pairs
are the same evidence, coarser).

Unlearned (no ``count_profile``), the constants are the defaults of the config:
``D[i, j]`` keeps the count with ``door_stay`` and moves it by one with the rest (by two
with a tenth of it), ``Q[i, i] = 1 - quiet_change`` (a change without a door event: a
missed door, or a home with no door sensor); ``A[0, 1] = noise`` (a sensor fires in an
empty home), ``A[n, 1] = activity`` for ``n >= 1`` (activity tells an empty home from an
occupied one, not one person from two: people's own habits dominate it); ``F[n, 1] = far_noise`` for ``n <= 1``,
``far_rate`` for ``n >= 2``; ``g_n = stray_one`` for ``n <= 1``, ``stray_two`` for
``n >= 2``; no clock; start ``P(n_0 = n)`` proportional to ``2^-n``. A site
without a door sensor (no entry/exit node) never sees anyone leave: there a silent bin is no
evidence of an empty home (``A[n, 0] = 1`` for every ``n``), so a sleeper's hours of silence keep
the count, and only activity (``A[0, 1] = noise``) and far pairs move it.

Learned (:func:`stats` on labelled bins, :func:`model_from_stats`): every table above is the
labelled bins' frequencies with a Dirichlet prior of ``prior`` pseudo-counts per cell (the
unlearned value's shape for ``D`` and ``Q``), the per-sensor terms replace ``A`` (they hold
the same information, finer), ``H(h, n)`` is the share of the labelled bins of hour ``h``
with ``n`` people, weighted by ``w = clock_weight``. The learned model has no stray term (O3):
its far pairs ``F``, learned, hold the same evidence for that home (measured on ARAS House B, a
stray term learned the same way raised the count error from 0.167 to 0.240).

Decoding: the most probable count sequence (Viterbi, :func:`viterbi`; inherently sequential
over bins, compiled with numba, :func:`viterbi_reference` its plain oracle), written as a step
function ``(t, present)`` at each bin start (:func:`people_steps`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import polars as pl

from onebit.core.compiled import kernel, numba_loaded
from onebit.core.lazy import lazy_module
from onebit.core.params import param, validate
from onebit.core.tables import COUNT_PROFILE, MOTION, check_schema
from onebit.core.units import length
from onebit.models.walks import clock_tick, far_lift_of, far_pairs, lifted_sensors, one_walker

nx = lazy_module("networkx")

#: The ``present`` step function of a count: (t, present).
PEOPLE = pl.Schema({"t": pl.Float64, "present": pl.Int64})


@dataclass(frozen=True)
class Features:
    """Per-bin evidence (module docstring); ``sensors`` names the columns of ``fired``/``held``."""

    t0: float
    bin_s: float
    door: np.ndarray
    active: np.ndarray
    far: np.ndarray
    fired: np.ndarray
    held: np.ndarray
    hour: np.ndarray
    sensors: tuple[str, ...]
    #: per bin: ON edges of non-door sensors, and those off the one walker's path (W1)-(W2)
    firings: np.ndarray | None = None
    strays: np.ndarray | None = None

    @property
    def bins(self) -> int:
        return int(self.door.size)

    @property
    def starts(self) -> np.ndarray:
        return self.t0 + self.bin_s * np.arange(self.bins)


def hours_of(t: np.ndarray, epoch_seconds_of_day: float | None) -> np.ndarray:
    """Hour of day (0-23) of times ``t`` (s since the epoch) when the epoch's time of day is
    known, else ``-1``."""
    if epoch_seconds_of_day is None:
        return np.full(np.shape(t), -1, dtype=np.int64)
    return (((np.asarray(t, dtype=float) + epoch_seconds_of_day) % 86_400.0) // 3600.0).astype(np.int64)


def features(
    motion: pl.DataFrame,
    sensors: list[str],
    doors: set[str],
    levels: set[str],
    far: np.ndarray,
    *,
    bin_s: float,
    window_s: float,
    held: bool,
    epoch_seconds_of_day: float | None,
    span: tuple[float, float] | None = None,
    hops: np.ndarray | None = None,
    walk_s: float = 0.0,
    walk_slack: float = 2.0,
    tick: float = 0.0,
    far_lift: float = 0.0,
    far_lift_min: int = 5,
) -> Features:
    """The bins' evidence from a MOTION table (t, sensor, on) restricted to ``sensors``.

    ``far[a, b]``: whether sensors ``a`` and ``b`` (indices into ``sensors``) are too far
    apart for one person to fire both within ``window_s``. ``span``: the time range to cover
    (default: the motion's first to last edge). ``hops``: the sensors' hop distances (0 where
    the graph does not join them), for the strays of one walker (W1)-(W2) when ``walk_s > 0``
    (else no firing is a stray); ``tick``: the slack of the log's clock in (W1), eq. W0;
    ``far_lift``/``far_lift_min``: the far pairs of out-of-place sensors left out, eq. F1."""
    index = {s: k for k, s in enumerate(sensors)}
    m = motion.filter(pl.col("sensor").is_in(sensors)).sort("t")
    t = m["t"].to_numpy().astype(float)
    on = m["on"].to_numpy().astype(bool)
    k = np.array([index[s] for s in m["sensor"].to_list()], dtype=np.int64)
    lo, hi = span if span is not None else ((float(t[0]), float(t[-1])) if t.size else (0.0, 0.0))
    t0 = np.floor(lo / bin_s) * bin_s
    B = max(int(np.floor((hi - t0) / bin_s)) + 1, 1)
    b = np.clip(((t - t0) // bin_s).astype(np.int64), 0, B - 1)
    S = len(sensors)
    is_door = np.array([s in doors for s in sensors], dtype=bool)
    is_level = np.array([s in levels for s in sensors], dtype=bool)
    door = np.zeros(B, dtype=bool)
    door[b[is_door[k]]] = True
    fired = np.zeros((B, S), dtype=bool)
    fired[b[on], k[on]] = True
    held_bs = _held(b, k, on, B, S) & is_level[None, :]
    active = fired[:, ~is_door].any(axis=1)
    if held:
        active |= held_bs[:, ~is_door].any(axis=1)
    sel = on & ~is_door[k]
    ts, ks, bs = t[sel], k[sel], b[sel]
    first, second = far_pairs(ts, ks, far, window_s)
    if far_lift > 0 and first.size:
        odd = lifted_sensors(ks, first, second, S, lift=far_lift, least=far_lift_min)
        keep = ~(odd[ks[first]] | odd[ks[second]])
        first, second = first[keep], second[keep]
    far_b = np.zeros(B, dtype=bool)
    far_b[bs[second]] = True
    hour = hours_of(t0 + bin_s * np.arange(B) + bin_s / 2, epoch_seconds_of_day)
    firings = strays = None  # no walker: no stray term
    if hops is not None and walk_s > 0:
        firings = np.bincount(bs, minlength=B)[:B]
        off = ~one_walker(ts, ks, hops, walk_s=walk_s, walk_slack=walk_slack, tick=tick)
        strays = np.bincount(bs[off], minlength=B)[:B]
    return Features(float(t0), float(bin_s), door, active, far_b, fired, held_bs, hour, tuple(sensors), firings, strays)


def _held(b: np.ndarray, k: np.ndarray, on: np.ndarray, B: int, S: int) -> np.ndarray:
    """``held[b, s]``: sensor ``s`` on at some time in bin ``b`` (from its edges; a sensor on
    when the log ends stays on to the last bin)."""
    out = np.zeros((B, S), dtype=bool)
    if b.size == 0:
        return out
    order = np.lexsort((np.arange(b.size), k))
    kb, bb, ob = k[order], b[order], on[order]
    for s in np.unique(kb):
        sel = kb == s
        bs, os_ = bb[sel], ob[sel]
        # runs: each ON edge to the next edge of the sensor (an OFF, or the log's end)
        starts = np.flatnonzero(os_)
        ends = np.where(starts + 1 < bs.size, bs[np.minimum(starts + 1, bs.size - 1)], B - 1)
        diff = np.zeros(B + 1, dtype=np.int64)
        np.add.at(diff, bs[starts], 1)
        np.add.at(diff, ends + 1, -1)
        out[:, s] = np.cumsum(diff[:B]) > 0
    return out


@dataclass(frozen=True)
class CountModel:
    """The model's log tables (module docstring): ``K + 1`` states."""

    log_start: np.ndarray
    log_door: np.ndarray
    log_quiet: np.ndarray
    log_active: np.ndarray | None
    log_far: np.ndarray
    log_hour: np.ndarray | None
    #: per-sensor terms (learned): (K + 1, S, 2) each, on the model's ``sensors``
    log_fired: np.ndarray | None = None
    log_held: np.ndarray | None = None
    sensors: tuple[str, ...] = ()
    clock_weight: float = 1.0
    sensor_weight: float = 1.0
    #: (O3): ``[ln(1 - g_n), ln g_n]`` per count, ``(K + 1, 2)``; ``None``: no stray term
    log_stray: np.ndarray | None = None

    @property
    def K(self) -> int:
        return int(self.log_start.size) - 1

    def emissions(self, f: Features) -> np.ndarray:
        """``ln P(obs_b | n)`` of (O2) for every bin and count: ``(B, K + 1)``."""
        B = f.bins
        ll = self.log_far[:, f.far.astype(np.int64)].T.copy()
        if self.log_active is not None:
            ll += self.log_active[:, f.active.astype(np.int64)].T
        if self.log_fired is not None:
            idx = {s: j for j, s in enumerate(f.sensors)}
            cols = [idx.get(s, -1) for s in self.sensors]
            for j, c in enumerate(cols):
                fired = f.fired[:, c].astype(np.int64) if c >= 0 else np.zeros(B, np.int64)
                held = f.held[:, c].astype(np.int64) if c >= 0 else np.zeros(B, np.int64)
                ll += self.sensor_weight * (self.log_fired[:, j, fired].T + self.log_held[:, j, held].T)
        if self.log_hour is not None and self.clock_weight > 0:
            known = f.hour >= 0
            ll[known] += self.clock_weight * self.log_hour[f.hour[known]]
        if self.log_stray is not None and f.strays is not None:
            u = f.strays.astype(float)[:, None]
            ll += u * self.log_stray[:, 1] + (f.firings.astype(float)[:, None] - u) * self.log_stray[:, 0]
        return ll


def default_model(
    K: int,
    *,
    door_stay: float,
    quiet_change: float,
    noise: float,
    activity: float,
    far_noise: float,
    far_rate: float,
    stray_one: float | None = None,
    stray_two: float | None = None,
) -> CountModel:
    """The unlearned model (module docstring); with ``stray_one`` and ``stray_two`` the stray
    term (O3) replaces the far pairs' ``F``."""
    n = np.arange(K + 1)
    start = 2.0**-n
    door = _band(K, door_stay)
    quiet = np.full((K + 1, K + 1), 0.0)
    quiet[:] = quiet_change / max(K, 1)
    np.fill_diagonal(quiet, 1.0 - quiet_change)
    if K == 0:
        quiet[:] = 1.0
    p_active = np.where(n == 0, noise, activity)
    p_far = np.where(n <= 1, far_noise, far_rate)
    walk = stray_one is not None and stray_two is not None
    if walk:
        p_far = np.full(K + 1, 0.5)  # F neutral: (O3) carries that evidence
        g = np.where(n <= 1, stray_one, stray_two)
    return CountModel(
        log_start=np.log(start / start.sum()),
        log_door=np.log(door),
        log_quiet=np.log(quiet),
        log_active=np.log(np.column_stack([1.0 - p_active, p_active])),
        log_far=np.log(np.column_stack([1.0 - p_far, p_far])) if not walk else np.zeros((K + 1, 2)),
        log_hour=None,
        log_stray=np.log(np.column_stack([1.0 - g, g])) if walk else None,
    )


def _band(K: int, stay: float) -> np.ndarray:
    """Door transitions: stay with ``stay``; the rest to the counts one away (a tenth of it to
    two away), renormalised at the ends."""
    m = np.zeros((K + 1, K + 1))
    for i in range(K + 1):
        for j in range(K + 1):
            d = abs(i - j)
            m[i, j] = stay if d == 0 else (1.0 - stay) * (1.0 if d == 1 else 0.1 if d == 2 else 0.0)
    m += 1e-12
    return m / m.sum(axis=1, keepdims=True)


def truth_bins(truth_count: pl.DataFrame, f: Features) -> np.ndarray:
    """The labelled count of every bin: the time-average of ``truth_count`` (t, end, count)
    over the bin, rounded; ``-1`` where no interval covers the bin."""
    starts = f.starts
    total = np.zeros(f.bins)
    cover = np.zeros(f.bins)
    for a, e, c in truth_count.select("t", "end", "count").iter_rows():
        lo = np.clip(a, starts, starts + f.bin_s)
        hi = np.clip(e, starts, starts + f.bin_s)
        w = np.maximum(hi - lo, 0.0)
        total += w * c
        cover += w
    out = np.full(f.bins, -1, dtype=np.int64)
    ok = cover >= 0.5 * f.bin_s
    out[ok] = np.floor(total[ok] / cover[ok] + 0.5).astype(np.int64)
    return out


def stats(f: Features, y: np.ndarray) -> pl.DataFrame:
    """The sufficient statistics (:data:`~onebit.core.tables.COUNT_PROFILE`) of labelled bins
    ``y`` (``-1``: unlabelled, skipped): counts per term, state and key; additive over days."""
    rows: list[tuple[str, int, str, float]] = []
    ok = y >= 0
    for n in np.unique(y[ok]):
        sel = ok & (y == n)
        rows.append(("bins", int(n), "", float(sel.sum())))
        rows.append(("active", int(n), "1", float(f.active[sel].sum())))
        rows.append(("far", int(n), "1", float(f.far[sel].sum())))
        for j, s in enumerate(f.sensors):
            rows.append(("fired", int(n), s, float(f.fired[sel, j].sum())))
            rows.append(("held", int(n), s, float(f.held[sel, j].sum())))
        hours, counts = np.unique(f.hour[sel & (f.hour >= 0)], return_counts=True)
        rows += [("hour", int(n), str(int(h)), float(c)) for h, c in zip(hours, counts)]
    pair = ok[1:] & ok[:-1]
    for term, gate in (("door", f.door[1:]), ("quiet", ~f.door[1:])):
        sel = pair & gate
        src, dst = y[:-1][sel], y[1:][sel]
        if src.size:
            keys, counts = np.unique(np.column_stack([src, dst]), axis=0, return_counts=True)
            rows += [(term, int(a), str(int(b)), float(c)) for (a, b), c in zip(keys, counts)]
    first = np.flatnonzero(ok)
    if first.size:
        rows.append(("start", int(y[first[0]]), "", 1.0))
    return pl.DataFrame(rows, schema=COUNT_PROFILE, orient="row")


def model_from_stats(
    st: pl.DataFrame, K: int, *, prior: float, clock_weight: float, unlearned: CountModel, sensor_weight: float = 1.0
) -> CountModel:
    """The learned model (module docstring) of summed statistics ``st``, on counts ``0..K``."""
    st = st.group_by("term", "state", "key").agg(pl.col("count").sum())
    get = {(a, int(b), c): float(v) for a, b, c, v in st.iter_rows()}
    bins = np.array([get.get(("bins", n, ""), 0.0) for n in range(K + 1)])
    sensors = tuple(sorted({c for a, _, c, _ in st.iter_rows() if a == "fired"})) if sensor_weight > 0 else ()

    def bern(term: str, key: str) -> np.ndarray:
        on = np.array([get.get((term, n, key), 0.0) for n in range(K + 1)])
        p = (on + prior * 0.5) / (bins + prior)
        return np.log(np.column_stack([1.0 - p, p]))

    def trans(term: str, shape: np.ndarray) -> np.ndarray:
        c = np.array([[get.get((term, i, str(j)), 0.0) for j in range(K + 1)] for i in range(K + 1)])
        p = c + prior * np.exp(shape) * (K + 1)
        return np.log(p / p.sum(axis=1, keepdims=True))

    hour = np.array([[get.get(("hour", n, str(h)), 0.0) for n in range(K + 1)] for h in range(24)])
    has_clock = hour.sum() > 0
    log_hour = np.log((hour + prior) / (hour + prior).sum(axis=1, keepdims=True)) if has_clock else None
    start = np.array([get.get(("start", n, ""), 0.0) for n in range(K + 1)]) + np.exp(unlearned.log_start)
    return CountModel(
        log_start=np.log(start / start.sum()),
        log_door=trans("door", unlearned.log_door),
        log_quiet=trans("quiet", unlearned.log_quiet),
        log_active=None if sensors else bern("active", "1"),
        log_far=bern("far", "1"),
        log_hour=log_hour,
        log_fired=np.stack([bern("fired", s) for s in sensors], axis=1) if sensors else None,
        log_held=np.stack([bern("held", s) for s in sensors], axis=1) if sensors else None,
        sensors=sensors,
        clock_weight=clock_weight,
        sensor_weight=sensor_weight,
    )


def learned_people(st: pl.DataFrame) -> int:
    """The largest count the statistics saw (0 when they are empty)."""
    seen = st.filter(pl.col("term") == "bins")["state"]
    return int(seen.max()) if seen.len() else 0


def viterbi_reference(ll: np.ndarray, door: np.ndarray, log_door, log_quiet, log_start) -> np.ndarray:
    """The most probable count sequence of (O1)-(O2), written step by step (the oracle)."""
    B, N = ll.shape
    if B == 0:
        return np.zeros(0, dtype=np.int64)
    delta = log_start + ll[0]
    back = np.zeros((B, N), dtype=np.int64)
    for b in range(1, B):
        trans = log_door if door[b] else log_quiet
        cand = delta[:, None] + trans
        back[b] = np.argmax(cand, axis=0)
        delta = cand[back[b], np.arange(N)] + ll[b]
    path = np.zeros(B, dtype=np.int64)
    path[-1] = int(np.argmax(delta))
    for b in range(B - 1, 0, -1):
        path[b - 1] = back[b, path[b]]
    return path


@kernel
def _viterbi_kernel(ll, door, log_door, log_quiet, log_start):  # pragma: no cover - compiled
    B, N = ll.shape
    path = np.zeros(B, dtype=np.int64)
    if B == 0:
        return path
    back = np.zeros((B, N), dtype=np.int64)
    delta = log_start + ll[0]
    new = np.empty(N)
    for b in range(1, B):
        for j in range(N):
            best, arg = -np.inf, 0
            for i in range(N):
                v = delta[i] + (log_door[i, j] if door[b] else log_quiet[i, j])
                if v > best:
                    best, arg = v, i
            back[b, j] = arg
            new[j] = best + ll[b, j]
        delta[:] = new
    best, arg = -np.inf, 0
    for j in range(N):
        if delta[j] > best:
            best, arg = delta[j], j
    path[B - 1] = arg
    for b in range(B - 1, 0, -1):
        path[b - 1] = back[b, path[b]]
    return path


#: Below this many cells (bins x counts) a process that has not loaded numba yet decodes with
#: the plain recursion: a few thousand steps of numpy cost less than numba's start-up.
SMALL = 20_000


def viterbi(ll: np.ndarray, door: np.ndarray, model: CountModel) -> np.ndarray:
    """:func:`viterbi_reference`, compiled (equal paths: the tests compare them); small
    problems in a process without numba loaded take the reference (:data:`SMALL`)."""
    if ll.size <= SMALL and not numba_loaded():
        return viterbi_reference(ll, door, model.log_door, model.log_quiet, model.log_start)
    return _viterbi_kernel(
        np.ascontiguousarray(ll, dtype=np.float64),
        np.ascontiguousarray(door, dtype=np.bool_),
        np.ascontiguousarray(model.log_door),
        np.ascontiguousarray(model.log_quiet),
        np.ascontiguousarray(model.log_start),
    )


def people_steps(starts: np.ndarray, count: np.ndarray) -> pl.DataFrame:
    """The step function of a per-bin count: a row at the first bin and at every change."""
    if count.size == 0:
        return pl.DataFrame(schema=PEOPLE)
    keep = np.r_[True, count[1:] != count[:-1]]
    return pl.DataFrame({"t": starts[keep].astype(float), "present": count[keep].astype(np.int64)}, schema=PEOPLE)


@dataclass(frozen=True, kw_only=True)
class OccupancyConfig:
    """``[occupancy]``: the count model's constants (module docstring, eq. O1-O2)."""

    bin_s: float = param(60.0, "seconds per bin (the count is decided per bin)", lo=1.0, hi=86_400.0, unit="s")
    max_people: int = param(4, "K when neither targets nor a learned profile gives it", lo=1, hi=16)
    window_s: float = param(
        1.0,
        "two ON edges at most this far apart at sensors far_hops or more hops apart on the sensor graph "
        "(far_m apart without a graph) need two people",
        lo=0.0,
        hi=600.0,
        unit="s",
    )
    far_hops: int = param(4, "hops on the sensor graph that make two sensors far (see window_s)", lo=1, hi=1000)
    far_m: float = length(5.0, "distance that makes two sensors far on a site without a sensor graph", lo=0.0)
    held: bool = param(True, "a level sensor on in a bin (a force sensor, a pressure mat) is activity")
    door_stay: float = param(
        0.5,
        "D[i, i]: a door event that changes nothing (someone looks out, a visitor at the door)",
        lo=1e-6,
        hi=1.0 - 1e-6,
    )
    quiet_change: float = param(
        1e-4, "probability of a change of the count in a bin without a door event", lo=1e-12, hi=0.5
    )
    noise: float = param(0.02, "A[0, 1]: a sensor fires in an empty home in a bin", lo=1e-9, hi=0.5)
    activity: float = param(
        0.3,
        "A[n, 1], n >= 1: a sensor fires (or a level sensor is on) in a bin with someone in",
        lo=1e-6,
        hi=1.0 - 1e-6,
    )
    far_noise: float = param(
        0.05,
        "F[n, 1] with at most one person in: far pairs (lingering sensors, a door slammed by the wind)",
        lo=1e-9,
        hi=0.5,
    )
    far_rate: float = param(0.5, "F[n, 1] with two or more people in: far pairs", lo=1e-9, hi=1.0 - 1e-9)
    far_lift: float = param(
        2.0,
        "(F1): a sensor whose share of the far pairs' ends is this many times its share of the firings is out "
        "of place (misplaced on the plan, or seeing farther): its far pairs are not evidence (0: never)",
        lo=0.0,
        hi=1e6,
    )
    far_lift_min: int = param(5, "(F1): far pairs a sensor needs before it can count as out of place", lo=1, hi=10**9)
    prior: float = param(1.0, "pseudo-counts per cell of every learned table (Dirichlet)", lo=1e-6, hi=1e6)
    clock_weight: float = param(0.0, "w: weight of the learned count by hour of day (0: no clock)", lo=0.0, hi=100.0)
    sensor_weight: float = param(
        0.0,
        "v: weight of the learned per-sensor terms (0: the learned A instead; below 1 tempers the "
        "naive-Bayes product of correlated sensors)",
        lo=0.0,
        hi=100.0,
    )
    profile: bool = param(True, "use the dataset's count_profile.csv when it has one (off: always the defaults)")
    walk_s: float = param(
        0.5,
        "(W1): seconds per hop of one walker; 0 (or a site without a sensor graph): no stray term (O3), the "
        "far pairs F instead",
        lo=0.0,
        hi=3600.0,
        unit="s",
    )
    walk_slack: float = param(2.0, "(W1): hops of slack of one walker's walk", lo=0.0, hi=1000.0)
    clock_s: float = param(
        1.0,
        "(W0): the polling period of a logger that stamps events at one phase of it (CASAS: 1 s); a log so "
        "stamped gives (W1) half of it as slack in time (0: never)",
        lo=0.0,
        hi=60.0,
        unit="s",
    )
    tick_phase: float = param(
        0.9,
        "(W0): mean resultant length of the firings' phases modulo clock_s from which the log counts as polled",
        lo=0.0,
        hi=1.0,
    )
    stray_one: float = param(
        0.05,
        "(O3) g_n: the share of firings one walker leaves unexplained with at most one person in",
        lo=1e-9,
        hi=1.0 - 1e-9,
    )
    stray_two: float = param(
        0.09, "(O3) g_n: the share of firings one walker leaves unexplained with two or more", lo=1e-9, hi=1.0 - 1e-9
    )

    def __post_init__(self) -> None:
        validate(self)


#: The per-bin table of a run: bin start, evidence, decoded count.
BINS = pl.Schema({"t": pl.Float64, "door": pl.Boolean, "active": pl.Boolean, "far": pl.Boolean, "present": pl.Int64})


def epoch_seconds_of_day(epoch: str | None) -> float | None:
    """Seconds after midnight of an ISO epoch (``None`` without one)."""
    if not epoch:
        return None
    from datetime import datetime

    d = datetime.fromisoformat(epoch.replace("Z", "+00:00"))
    return float(d.hour * 3600 + d.minute * 60 + d.second + d.microsecond / 1e6)


def hop_matrix(site, sensors: list[str]) -> np.ndarray | None:
    """Hops between the sensors on the site's sensor graph (``inf`` where it does not join
    them); ``None`` without a graph."""
    g = site.sensor_graph
    if g is None or not list(g.edges):
        return None
    S = len(sensors)
    gr = nx.Graph()
    gr.add_nodes_from(sensors)
    gr.add_edges_from((a, b) for a, b in g.edges if a in gr and b in gr)
    idx = {s: k for k, s in enumerate(sensors)}
    hops = np.full((S, S), np.inf)
    for a, lengths in nx.all_pairs_shortest_path_length(gr):
        for b, d in lengths.items():
            hops[idx[a], idx[b]] = d
    return hops


def far_matrix(site, sensors: list[str], cfg: OccupancyConfig) -> np.ndarray:
    """Whether two sensors are too far apart for one person to fire both within ``window_s``:
    ``far_hops`` or more hops on the site's sensor graph (two sensors the graph does not join
    are not known to be far: not far), or ``far_m``
    metres apart without a graph."""
    hops = hop_matrix(site, sensors)
    if hops is not None:
        return np.isfinite(hops) & (hops >= cfg.far_hops)  # not joined: nothing known, not far
    pos = {m.id: m.position for m in site.motion_sensors}
    xy = np.array([pos[s] for s in sensors], dtype=float).reshape(-1, 2)
    d = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    return d >= cfg.far_m


def people_bound(site, cfg: OccupancyConfig, profile: pl.DataFrame | None) -> int:
    """``K``: the site's ``targets`` (an upper bound), else the largest count of the learned
    days, else ``max_people``."""
    if site.targets is not None:
        return max(int(site.targets), 1)
    if profile is not None and profile.height:
        return max(learned_people(profile), 1)
    return cfg.max_people


def estimate(
    motion: pl.DataFrame,
    site,
    cfg: OccupancyConfig,
    profile: pl.DataFrame | None = None,
    *,
    span: tuple[float, float] | None = None,
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """The count of a home over the motion log: ``(bins, people)`` -- the per-bin table
    (:data:`BINS`) and the step function (:data:`PEOPLE`). ``profile``: the statistics of
    labelled days (:data:`~onebit.core.tables.COUNT_PROFILE`), used when ``cfg.profile``."""
    motion = check_schema(motion, MOTION, name="motion")
    doors = site_doors(site)
    if motion.filter(pl.col("sensor").is_in([m.id for m in site.motion_sensors])).height == 0 and span is None:
        return pl.DataFrame(schema=BINS), pl.DataFrame(schema=PEOPLE)
    use = profile if (cfg.profile and profile is not None and profile.height) else None
    f = site_features(motion, site, cfg, span, learned=use is not None)
    K = people_bound(site, cfg, use)
    model = default_model(
        K,
        door_stay=cfg.door_stay,
        quiet_change=cfg.quiet_change,
        noise=cfg.noise,
        activity=cfg.activity,
        far_noise=cfg.far_noise,
        far_rate=cfg.far_rate,
        **(dict(stray_one=cfg.stray_one, stray_two=cfg.stray_two) if f.strays is not None else {}),
    )
    if not doors and use is None:  # no door sensor: nobody is seen leaving, so silence is no evidence of it
        model = replace(model, log_active=np.column_stack([np.zeros(K + 1), model.log_active[:, 1]]))
    if use is not None:
        model = model_from_stats(
            use, K, prior=cfg.prior, clock_weight=cfg.clock_weight, unlearned=model, sensor_weight=cfg.sensor_weight
        )
    count = viterbi(model.emissions(f), f.door, model)
    bins = pl.DataFrame(
        {"t": f.starts, "door": f.door, "active": f.active, "far": f.far, "present": count}, schema=BINS
    )
    return bins, people_steps(f.starts, count)


def learn_stats(motion: pl.DataFrame, truth_count: pl.DataFrame, site, cfg: OccupancyConfig) -> pl.DataFrame:
    """The statistics (:func:`stats`) of one labelled dataset: its motion log's bins against
    its ``truth_count`` over the truth's span."""
    span = (float(truth_count["t"].min()), float(truth_count["end"].max()) - 1e-9)
    f = site_features(check_schema(motion, MOTION, name="motion"), site, cfg, span, learned=True)
    return stats(f, truth_bins(truth_count, f))


def out_of_place(motion: pl.DataFrame, site, cfg: OccupancyConfig) -> pl.DataFrame:
    """The sensors (F1) finds out of place over the whole of ``motion``: one row per sensor
    with ``sensor``, ``ons`` (its ON edges), ``far_ends`` (far pairs with an end at it) and
    ``lift`` (``lambda_s``), largest ``lift`` first. Empty when ``cfg.far_lift`` is 0, and on a
    site where the count weighs one walker's strays instead of far pairs (a sensor graph and
    ``walk_s > 0``): there the far pairs are not evidence, and a learned graph's positions are
    no plan to be out of place on."""
    schema = {"sensor": pl.String, "ons": pl.Int64, "far_ends": pl.Int64, "lift": pl.Float64}
    if cfg.far_lift <= 0 or (cfg.walk_s > 0 and site.sensor_graph is not None):
        return pl.DataFrame(schema=schema)
    sensors = [m.id for m in site.motion_sensors]
    doors = site_doors(site)
    m = check_schema(motion, MOTION, name="motion").filter(
        pl.col("on") & pl.col("sensor").is_in(sensors) & ~pl.col("sensor").is_in(list(doors))
    )
    m = m.sort("t")
    index = {s: k for k, s in enumerate(sensors)}
    ks = np.array([index[s] for s in m["sensor"].to_list()], dtype=np.int64)
    first, second = far_pairs(m["t"].to_numpy().astype(float), ks, far_matrix(site, sensors, cfg), cfg.window_s)
    if first.size == 0:
        return pl.DataFrame(schema=schema)
    n, ends, lam = far_lift_of(ks, first, second, len(sensors))
    odd = (lam >= cfg.far_lift) & (ends >= cfg.far_lift_min)
    rows = [(sensors[j], int(n[j]), int(ends[j]), float(lam[j])) for j in np.flatnonzero(odd)]
    return pl.DataFrame(rows, schema=schema, orient="row").sort("lift", descending=True)


def site_doors(site) -> set[str]:
    """The site's entry/exit nodes (its door sensors): empty without a sensor graph."""
    g = site.sensor_graph
    return set(g.entries) | set(g.exits) if g is not None else set()


def site_features(
    motion: pl.DataFrame, site, cfg: OccupancyConfig, span: tuple[float, float] | None, *, learned: bool = False
) -> Features:
    """:func:`features` of a motion table on the site's motion sensors, doors, level sensors and
    far pairs, with the config's bins and window. ``learned``: for a model learned from labelled
    days, whose far-pair term ``F`` already holds that home's out-of-place sensors: no (F1)."""
    sensors = [m.id for m in site.motion_sensors]
    hops = hop_matrix(site, sensors) if cfg.walk_s > 0 else None
    doors = site_doors(site)
    tick = 0.0
    if hops is not None and not doors:  # (W0); sites with a door sensor were measured without it
        on = motion.filter(pl.col("on") & pl.col("sensor").is_in(sensors))["t"].to_numpy()
        tick = clock_tick(on, clock_s=cfg.clock_s, tick_phase=cfg.tick_phase)
    return features(
        motion,
        sensors,
        doors,
        set(site.level_sensors),
        far_matrix(site, sensors, cfg),
        bin_s=cfg.bin_s,
        window_s=cfg.window_s,
        held=cfg.held,
        epoch_seconds_of_day=epoch_seconds_of_day(site.epoch),
        span=span,
        hops=None if hops is None else np.where(np.isfinite(hops), hops, 0.0),  # not joined: nothing known
        walk_s=cfg.walk_s,
        walk_slack=cfg.walk_slack,
        tick=tick,
        far_lift=0.0 if learned else cfg.far_lift,
        far_lift_min=cfg.far_lift_min,
    )
