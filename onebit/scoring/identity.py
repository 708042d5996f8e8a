"""Identity per event: who is who at home (issue 22 item 3; definitions in docs/metrics.md).

Inputs: ``truth_events`` (:data:`~onebit.core.tables.TRUTH_EVENTS`: t, sensor, residents
``"1"``/``"1;2"``) and a tracker's ``<tracker>_events``
(:data:`~onebit.core.tables.TRACKER_EVENTS`: t, sensor, track or null). A truth event is
matched to the tracker event of the same sensor within ``match_tol_s`` (1 ms) of it, or, when there is none, a repeated firing of a
sensor still on (the reader keeps only its first ``ON``) to the tracker event of its sensor at
most ``REPEAT_S`` (5 s) before it; one with no match, or matched to a null track, is
*unattributed* and counts as wrong everywhere.

* **accuracy** -- the share of truth events whose track, under the best one-to-one relabelling
  ``m`` of tracks to residents, names one of the event's residents::

      acc = max_m  (1/E) sum_e [ m(track_e) in residents_e ]

  ``m`` is found by the Hungarian method (``scipy.optimize.linear_sum_assignment``) on
  ``G[track, r]`` = events of the track that name ``r`` (an event names each resident once,
  so ``sum_track G[track, m(track)]`` counts each event at most once). Tracks left without a
  resident (more tracks than residents) score 0.
* **ARI** -- the adjusted Rand index (Hubert & Arabie 1985) between the resident of each
  single-resident truth event and its track; an unattributed event is a cluster of its own
  (it agrees with nothing). 1 = the same partition, ~0 = chance::

      ARI = (sum_ij C(n_ij, 2) - [sum_i C(a_i, 2) sum_j C(b_j, 2)] / C(n, 2))
            / (1/2 [sum_i C(a_i, 2) + sum_j C(b_j, 2)] - [sum_i C(a_i, 2) sum_j C(b_j, 2)] / C(n, 2))

* **switches per hour** -- per resident, its single-resident events in time order that were
  attributed (unattributed ones skipped); a switch is a change of track between consecutive
  ones; summed over residents, per hour of the truth's span.
* **count error** -- per minute of the truth's span, ``|n_est - n_true|`` averaged: ``n_true``
  the time-averaged number of residents present (a resident is present from its first to its
  last labelled event, except in gaps between its events longer than ``absent_after_s``,
  600 s); ``n_est`` the tracker's time-averaged number of tracks (rows of its TRACKS table
  in the minute x the slot length / 60 s), or a constant for a baseline.

Baselines, scored by the same functions (:func:`baseline_events`):

* ``busier`` -- every event to one track: accuracy = the share of events naming the busier
  resident (the one named by most events).
* ``habits`` (supervised; only with a known-residents profile) -- every event to the resident
  with the most labelled events at its sensor in the profile (at its sensor in its bin of the
  profile's clock, when the profile has one): what a user with labelled days tries first.
* ``nearest`` -- a greedy online tracker a user would write first: ``K`` pseudo-tracks (``K`` =
  the number of residents in the truth: told, not estimated); each event, in time order, goes to
  the pseudo-track whose most recent event is at the nearest sensor (sensor-graph hops; ties:
  the most recently used); while fewer than ``K`` exist, an event more than 1 hop from every
  pseudo-track's last sensor starts a new one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.tables import TRACKER_EVENTS, TRUTH_EVENTS
from onebit.trackers.residents.known import clock_of

#: A truth event and a tracker event of the same sensor this close (s) are the same event.
MATCH_TOL_S = 1e-3
#: A truth event this soon (s) after a tracker event of its sensor, with none of its own, is a
#: repeated firing of that sensor while on (:func:`matched`).
REPEAT_S = 5.0
#: A resident absent this long between two of its events (s) is not counted present in between.
ABSENT_AFTER_S = 600.0


@dataclass(frozen=True)
class IdentityScores:
    """The identity metrics of one tracker (or baseline) on one truth (module docstring)."""

    accuracy: float
    ari: float
    switches_per_hour: float
    count_error: float | None
    events: int
    attributed: float
    mapping: dict[str, str]

    def rows(self, stage: str) -> list[tuple[str, str, float, str]]:
        out = [
            (stage, "identity_accuracy", self.accuracy, "fraction of events"),
            (stage, "identity_ari", self.ari, "ARI"),
            (stage, "identity_switches_per_hour", self.switches_per_hour, "switches/h"),
            (stage, "identity_attributed", self.attributed, "fraction of events"),
            (stage, "identity_events", float(self.events), "events"),
        ]
        if self.count_error is not None:
            out.append((stage, "count_error_per_minute", self.count_error, "people"))
        return out


def matched(truth_events: pl.DataFrame, tracker_events: pl.DataFrame, *, tol: float = MATCH_TOL_S) -> pl.DataFrame:
    """Truth events (t, sensor, residents) with the ``track`` of the tracker event of the same
    sensor nearest in time within ``tol`` (null: unattributed), sorted by t. A truth event with
    none there that follows a tracker event of its sensor by at most :data:`REPEAT_S` is a
    repeated firing of a sensor still on (the motion reader rejects a repeated ``ON``: no state
    change, counted) and takes that event's track."""
    te = truth_events.select(list(TRUTH_EVENTS)).sort("t")
    ev = tracker_events.select(list(TRACKER_EVENTS)).filter(pl.col("track").is_not_null()).sort("t")
    if te.height == 0:
        return te.with_columns(track=pl.lit(None, pl.String))
    right = ev.rename({"t": "_t"}).with_columns(t=pl.col("_t"))
    exact = te.join_asof(right, on="t", by="sensor", strategy="nearest", check_sortedness=False, tolerance=tol)
    repeat = te.join_asof(
        right, on="t", by="sensor", strategy="backward", check_sortedness=False, tolerance=REPEAT_S
    ).select(pl.col("track").alias("_repeat"))
    return (
        pl.concat([exact, repeat], how="horizontal")
        .with_columns(pl.coalesce("track", "_repeat").alias("track"))
        .drop("_t", "_repeat")
    )


def relabelling(m: pl.DataFrame) -> tuple[dict[str, str], int]:
    """The best one-to-one map track -> resident (Hungarian) and the events it gets right."""
    from scipy.optimize import linear_sum_assignment

    att = m.filter(pl.col("track").is_not_null())
    if att.height == 0:
        return {}, 0
    pairs = att.with_columns(r=pl.col("residents").str.split(";")).explode("r").group_by("track", "r").len()
    tracks = sorted(pairs["track"].unique().to_list())
    res = sorted(pairs["r"].unique().to_list())
    g = np.zeros((len(tracks), len(res)), dtype=np.int64)
    ti = {t: i for i, t in enumerate(tracks)}
    ri = {r: i for i, r in enumerate(res)}
    for t, r, n in pairs.iter_rows():
        g[ti[t], ri[r]] = n
    rows, cols = linear_sum_assignment(g, maximize=True)
    mapping = {tracks[i]: res[j] for i, j in zip(rows, cols) if g[i, j] > 0}
    return mapping, int(sum(g[i, j] for i, j in zip(rows, cols)))


def adjusted_rand_index(a: np.ndarray, b: np.ndarray) -> float:
    """ARI of two labelings (integer arrays of equal length; module docstring). 1.0 when both
    are one cluster or all singletons identically; 0 for fewer than 2 items."""
    n = a.size
    if n < 2:
        return 0.0
    _, ai = np.unique(a, return_inverse=True)
    _, bi = np.unique(b, return_inverse=True)
    cont = np.zeros((ai.max() + 1, bi.max() + 1), dtype=np.float64)
    np.add.at(cont, (ai, bi), 1.0)

    def c2(x):
        return x * (x - 1) / 2.0

    s_ij = c2(cont).sum()
    s_a = c2(cont.sum(axis=1)).sum()
    s_b = c2(cont.sum(axis=0)).sum()
    expected = s_a * s_b / c2(n)
    top = 0.5 * (s_a + s_b)
    if top == expected:
        return 1.0 if s_ij == expected else 0.0
    return float((s_ij - expected) / (top - expected))


def presence_count(
    truth_events: pl.DataFrame, minutes: np.ndarray, *, absent_after_s: float = ABSENT_AFTER_S
) -> np.ndarray:
    """Time-averaged number of residents present in each minute starting at ``minutes`` (s)."""
    single = truth_events.with_columns(r=pl.col("residents").str.split(";")).explode("r").sort("r", "t")
    out = np.zeros(minutes.size)
    for _, grp in single.group_by("r", maintain_order=True):
        t = grp["t"].to_numpy()
        gaps = np.flatnonzero(np.diff(t) > absent_after_s)
        starts = np.r_[t[0], t[gaps + 1]]
        ends = np.r_[t[gaps], t[-1]]
        for s, e in zip(starts, ends):
            out += np.clip(np.minimum(minutes + 60.0, e) - np.maximum(minutes, s), 0.0, 60.0) / 60.0
    return out


def track_count(tracks: pl.DataFrame, minutes: np.ndarray) -> np.ndarray:
    """Time-averaged number of tracks in each minute: rows of TRACKS in it x slot length / 60."""
    if tracks.height == 0:
        return np.zeros(minutes.size)
    ts = np.unique(tracks["t"].to_numpy())
    period = float(np.min(np.diff(ts))) if ts.size > 1 else 60.0
    k = np.floor((tracks["t"].to_numpy() - minutes[0]) / 60.0).astype(np.int64)
    k = k[(k >= 0) & (k < minutes.size)]
    return np.bincount(k, minlength=minutes.size) * period / 60.0


def identity_scores(
    truth_events: pl.DataFrame,
    tracker_events: pl.DataFrame,
    *,
    tracks: pl.DataFrame | None = None,
    constant_count: float | None = None,
    absent_after_s: float = ABSENT_AFTER_S,
) -> IdentityScores:
    """Every identity metric (module docstring) of one tracker's events against the truth;
    the count error from its ``tracks`` (or a baseline's ``constant_count``; neither: None)."""
    m = matched(truth_events, tracker_events)
    e = m.height
    mapping, right = relabelling(m)
    acc = right / e if e else 0.0
    single = m.filter(~pl.col("residents").str.contains(";"))
    codes = {t: i for i, t in enumerate(sorted(single["track"].drop_nulls().unique().to_list()))}
    tr = single["track"].to_list()
    lone = len(codes)
    b = np.array([codes[t] if t is not None else lone + i for i, t in enumerate(tr)], dtype=np.int64)
    ari = adjusted_rand_index(single["residents"].to_numpy(), b) if single.height else 0.0
    sw = 0
    for _, grp in single.filter(pl.col("track").is_not_null()).group_by("residents", maintain_order=True):
        seq = grp.sort("t")["track"].to_numpy()
        sw += int((seq[1:] != seq[:-1]).sum())
    span_h = (float(m["t"].max()) - float(m["t"].min())) / 3600.0 if e > 1 else 0.0
    count_err = None
    if e and (tracks is not None or constant_count is not None):
        t0 = float(np.floor(m["t"].min()))
        minutes = np.arange(t0, float(m["t"].max()), 60.0) if m["t"].max() > t0 else np.array([t0])
        true_n = presence_count(m, minutes, absent_after_s=absent_after_s)
        est = np.full(minutes.size, float(constant_count)) if tracks is None else track_count(tracks, minutes)
        count_err = float(np.mean(np.abs(est - true_n)))
    return IdentityScores(
        accuracy=float(acc),
        ari=float(ari),
        switches_per_hour=(sw / span_h if span_h > 0 else 0.0),
        count_error=count_err,
        events=e,
        attributed=float(m["track"].is_not_null().mean()) if e else 0.0,
        mapping=mapping,
    )


def busier_events(truth_events: pl.DataFrame) -> pl.DataFrame:
    """Baseline ``busier``: every truth event to one pseudo-track."""
    return truth_events.select("t", "sensor", pl.lit("all").alias("track")).select(list(TRACKER_EVENTS))


def nearest_events(truth_events: pl.DataFrame, hops: dict[tuple[str, str], int], k: int) -> pl.DataFrame:
    """Baseline ``nearest`` (module docstring): an inherently sequential greedy pass over the
    events in time order. ``hops[(a, b)]``: graph hops between sensors (absent: unreachable)."""
    ev = truth_events.sort("t")
    last: list[str] = []  # last sensor of each pseudo-track
    used: list[int] = []  # event index of its last use
    out = []
    far = 10**9
    for i, s in enumerate(ev["sensor"].to_list()):
        d = [0 if s == x else hops.get((s, x), far) for x in last]
        if not last or (len(last) < k and min(d) > 1):
            last.append(s)
            used.append(i)
            out.append(f"p{len(last)}")
            continue
        best = min(range(len(last)), key=lambda j: (d[j], -used[j]))
        last[best], used[best] = s, i
        out.append(f"p{best + 1}")
    return ev.select("t", "sensor").with_columns(track=pl.Series(out, dtype=pl.String)).select(list(TRACKER_EVENTS))


def habits_events(truth_events: pl.DataFrame, profile: pl.DataFrame, *, epoch: str | None = None) -> pl.DataFrame:
    """Baseline ``habits`` (supervised): every event to the resident whose profile has the most
    events at its sensor -- in its bin of the profile's clock when the profile has one (the
    ``day`` clock from the site's ``epoch``) -- (ties: the resident first in text order); a
    sensor the profile never saw (at that time) falls back to the sensor over all times, then
    to the resident with the most events overall."""
    habit = profile.filter(pl.col("from").is_null())
    overall = (
        habit.filter(pl.col("bin").is_null())
        .group_by("resident")
        .agg(pl.col("count").sum())
        .sort(["count", "resident"], descending=[True, False])
    )
    default = overall["resident"][0] if overall.height else None

    def best(rows: pl.DataFrame, keys: list[str]) -> pl.DataFrame:
        return rows.sort([*keys, "count", "resident"], descending=[False] * len(keys) + [True, False]).unique(
            keys, keep="first"
        )

    ev = truth_events.sort("t").select("t", "sensor")
    by_sensor = best(habit.filter(pl.col("bin").is_null()), ["to"]).select(
        pl.col("to").alias("sensor"), pl.col("resident").alias("_any")
    )
    ev = ev.join(by_sensor, on="sensor", how="left")
    clock = clock_of(profile)
    if clock is not None:
        b = clock.bin(ev["t"].to_numpy(), epoch=epoch)
        ev = ev.with_columns(bin=pl.Series([clock.label(int(k)) for k in b], dtype=pl.String))
        by_bin = best(habit.filter(pl.col("bin").is_not_null()), ["to", "bin"]).select(
            pl.col("to").alias("sensor"), "bin", pl.col("resident").alias("_then")
        )
        ev = ev.join(by_bin, on=["sensor", "bin"], how="left").with_columns(pl.coalesce("_then", "_any").alias("_any"))
    return ev.with_columns(track=pl.col("_any").fill_null(default)).select(list(TRACKER_EVENTS))


def baseline_rows(
    truth_events: pl.DataFrame,
    hops: dict[tuple[str, str], int],
    *,
    profile: pl.DataFrame | None = None,
    epoch: str | None = None,
) -> list[tuple[str, str, float, str]]:
    """Report rows of the baselines (``identity-busier``, ``identity-nearest``, and with a
    known-residents ``profile`` the supervised ``identity-habits``)."""
    k = max(1, truth_events["residents"].str.split(";").explode().n_unique())
    busy = identity_scores(truth_events, busier_events(truth_events), constant_count=1.0)
    near = identity_scores(truth_events, nearest_events(truth_events, hops, k), constant_count=float(k))
    rows = busy.rows("identity-busier") + near.rows("identity-nearest")
    if profile is not None and profile.height:
        n = float(profile["resident"].n_unique())
        rows += identity_scores(truth_events, habits_events(truth_events, profile, epoch=epoch), constant_count=n).rows(
            "identity-habits"
        )
    return rows


def graph_hops(site) -> dict[tuple[str, str], int]:
    """``(a, b) -> hops`` of the site's sensor graph (empty without one)."""
    g = site.sensor_graph
    if g is None:
        return {}
    import networkx as nx

    graph = g.to_networkx()
    return {(a, b): int(d) for a, row in nx.all_pairs_shortest_path_length(graph) for b, d in row.items()}


#: The error table's meeting: the other resident's latest labelled event this close in hops ...
MEET_HOPS = 1
#: ... and this recent (s).
MEET_S = 30.0
#: A run of consecutive wrong events at least this long is a swap (an identity held the wrong way).
SWAP_RUN = 5

ERRORS = pl.Schema(
    {
        "t": pl.Float64,
        "sensor": pl.String,
        "residents": pl.String,
        "decoded": pl.String,
        "other_sensor": pl.String,
        "other_hops": pl.Int64,
        "other_age_s": pl.Float64,
        "run": pl.Int64,
        "run_length": pl.Int64,
        "kind": pl.String,
        "met_t": pl.Float64,
        "met_sensor": pl.String,
        "parted_t": pl.Float64,
        "parted_sensor": pl.String,
        "resolved_by": pl.String,
    }
)

#: What information could have resolved an error of each kind (the error table's ``resolved_by``).
RESOLVED_BY = {
    "meeting": "who, not where: a per-person signal at the meeting (wearable tag, door code, height or gait)",
    "swap": "the identities after the meeting: these residents' own labelled day, or an item sensor of a task "
    "between parting and this event",
    "apart": "nothing in the sensors: the labels give this sensor to the other resident here (a rare visit, "
    "or the annotation's most likely resident)",
}


def _other_resident(t: list, sens: list, res: list, hops: dict) -> tuple[list, list[bool]]:
    """Per labelled event, the other resident's latest labelled event before it -- ``(sensor,
    hops, age)``, Nones without one -- and whether they met there (within ``MEET_HOPS`` hops
    and ``MEET_S`` seconds)."""
    other: list[tuple[str | None, int | None, float | None]] = []
    met = []
    latest: dict[frozenset, int] = {}  # the latest event of each set of residents
    for i in range(len(t)):
        mine = frozenset(res[i])
        j = max((k for key, k in latest.items() if not key & mine), default=-1)
        latest[mine] = i
        o, oh, age = None, None, None
        if j >= 0:
            o, age = sens[j], t[i] - t[j]
            oh = 0 if sens[i] == sens[j] else hops.get((sens[i], sens[j]))
        other.append((o, oh, age))
        met.append(oh is not None and oh <= MEET_HOPS and age is not None and age <= MEET_S)
    return other, met


def error_table(
    truth_events: pl.DataFrame, tracker_events: pl.DataFrame, hops: dict[tuple[str, str], int]
) -> pl.DataFrame:
    """Every identity error of a tracker (:data:`ERRORS`), for a diagnosis: a labelled event
    whose track, under the best relabelling, names none of its residents (or has no track).

    For each: the resident it was given (``decoded``; null: unattributed), where the *other*
    resident was -- the sensor of the latest labelled event before it that does not name its
    resident, its distance in sensor-graph hops (null: unreachable or none) and age -- and its
    run of consecutive errors (in the order of the labelled events). ``kind``:

    * ``meeting`` -- the other resident fired within ``MEET_HOPS`` hops in the last ``MEET_S``
      seconds: where they were cannot tell them apart; only who they are could (a per-person
      signal: a wearable, a door code, gait or height from a depth sensor);
    * ``swap`` -- apart, in a run of at least ``SWAP_RUN`` errors: an identity held the wrong way
      since an earlier meeting or start; a later habit cue did not turn it back;
    * ``apart`` -- apart, a short run: the event looks like the other resident's (the
      annotations give the resident who *most likely* caused it; some are the other's).

    Where the residents met and parted: ``met_t``/``met_sensor`` the latest labelled event at
    or before the start of the error's run where they met (as for ``meeting``; null: they had
    not met), ``parted_t``/``parted_sensor`` the first labelled event after it where they were
    apart (null for a meeting error). ``resolved_by``: what information could have resolved an
    error of its kind (:data:`RESOLVED_BY`).
    """
    m = matched(truth_events, tracker_events)
    mapping, _ = relabelling(m)
    m = m.with_columns(decoded=pl.col("track").replace_strict(mapping, default=None, return_dtype=pl.String))
    ok = pl.col("residents").str.split(";").list.contains(pl.col("decoded")).fill_null(False)
    m = m.with_columns(wrong=~ok)
    t = m["t"].to_list()
    sens = m["sensor"].to_list()
    res = [r.split(";") for r in m["residents"].to_list()]
    wrong = m["wrong"].to_list()
    n = len(t)
    other, met = _other_resident(t, sens, res, hops)
    runs: list[int] = []  # the length of each run of consecutive errors
    for i, bad in enumerate(wrong):
        if bad and (i == 0 or not wrong[i - 1]):
            runs.append(0)
        if bad:
            runs[-1] += 1
    upto = [-1] * n  # the latest meeting at or before each event
    for i in range(n):
        upto[i] = i if met[i] else (upto[i - 1] if i else -1)
    apart_after = [None] * (n + 1)  # the first event apart after each event
    for i in range(n - 1, -1, -1):
        apart_after[i] = i + 1 if i + 1 < n and not met[i + 1] else apart_after[i + 1]
    rows = []
    run, start = -1, 0
    for i, bad in enumerate(wrong):
        if not bad:
            continue
        if i == 0 or not wrong[i - 1]:
            run, start = run + 1, i
        o, oh, age = other[i]
        kind = "meeting" if met[i] else ("swap" if runs[run] >= SWAP_RUN else "apart")
        # where they last met at or before the run's start, and the first event after it apart
        k = i if met[i] else upto[start]
        p = apart_after[k] if k >= 0 and not met[i] else None
        rows.append(
            (
                t[i],
                sens[i],
                m["residents"][i],
                m["decoded"][i],
                o,
                oh,
                age,
                run,
                runs[run],
                kind,
                t[k] if k >= 0 else None,
                sens[k] if k >= 0 else None,
                t[p] if p is not None else None,
                sens[p] if p is not None else None,
                RESOLVED_BY[kind],
            )
        )
    return pl.DataFrame(rows, schema=ERRORS, orient="row")
