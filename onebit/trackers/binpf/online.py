"""The ``binpf`` filter run online: frame by frame, each frame's tracks committed after a fixed lag.

The filter (:mod:`onebit.trackers.binpf.filter`) is sequential: frame :math:`k`'s particles are
frame :math:`k - 1`'s, predicted and weighed by frame :math:`k`'s readings.
:class:`OnlineBinPF` keeps its whole state between calls -- the particles and their
smoothing histories, existences, labels, the random generator -- and steps the compiled
frame loop (:func:`onebit.trackers.binpf.kernels.run_frames`) one frame at a time as frames
become final, drawing the same numbers in the same order as a run over the whole log.

Two steps of the batch stage look at the whole log and cannot be online as they are:

* *reporting back to birth*: a track is reported at every frame where :math:`r \\ge r_{out}`
  once it is confirmed *at some frame*, even one long after;
* *tracklet joining*: one minimum-cost assignment of every tracklet end to every start of
  the run (:mod:`onebit.trackers.binpf.link`), an end being a tracklet's last reported row
  over the whole log.

With a commit lag of :math:`D` frames (``[binpf] commit_lag``, at least ``smooth_lag``) both
are bounded:

* frame :math:`c` is *committed* once frame :math:`c + D` has been filtered: its smoothed
  positions are final (:math:`D \\ge` ``smooth_lag``) and a track's row at :math:`c` is
  reported when :math:`r \\ge r_{out}` there and the track was confirmed by frame
  :math:`c + D`; at most ``max_out`` per frame, the largest :math:`r` first;
* joining is causal: a tracklet that starts (is first reported) at committed frame :math:`c`
  may continue one that ended at :math:`e_A \\in [c - g_{\\max} - 1, c - 1]` and whose track
  is gone by :math:`c` (deleted or merged: it can never be reported again), with
  :mod:`~onebit.trackers.binpf.link`'s gate and cost, by one minimum-cost assignment of the
  frame's starts to the open ends (the largest matching, then the cheapest). The frames of
  the gap are filled as in the batch (linear, cheapest join first, while fewer than
  ``max_out`` tracks are committed there) and published when the join is made, dated at
  their own frames.

The batch stage with ``commit_lag > 0`` runs this driver over the whole log
(:func:`run_lagged`), so ``onebit run`` and ``onebit follow`` with the same config give the
same tracks, whatever the polls (``tests/trackers/binpf/test_online.py``;
``tests/pipeline/test_follow_binpf.py`` replays a simulated array). With ``commit_lag = 0``
(the default) the batch stage keeps its whole-log steps; ``onebit follow`` then runs this
driver with :data:`DEFAULT_COMMIT_LAG` and its report says where the two differ.

The frame period is the median spacing of the first :data:`PERIOD_FRAMES` frames (the batch
stage with ``commit_lag = 0`` takes the whole log's: the same number on a regular grid).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import polars as pl

from onebit.core.tables import FRAMES, TRACKS, check_schema, conform
from onebit.trackers.binpf import kernels
from onebit.trackers.binpf.filter import FilterParams, FilterResult, kernel_params
from onebit.trackers.binpf.link import best_joins, join_costs

#: ``onebit follow``'s commit lag (frames) when the config's ``commit_lag`` is 0.
DEFAULT_COMMIT_LAG = 6
#: Frames whose spacing gives the frame period.
PERIOD_FRAMES = 8


@dataclass
class _Link:
    """The causal joining's state: each label's chain label, the tracklets' last reported
    frame and position, and the committed count of recent frames."""

    chain: dict[int, int] = field(default_factory=dict)
    last: dict[int, tuple[int, float, float]] = field(default_factory=dict)  # label -> (frame, x, y)
    joined: set[int] = field(default_factory=set)  # ends already continued
    count: dict[int, int] = field(default_factory=dict)  # committed rows per recent frame
    joins: int = 0


@dataclass
class OnlineBinPF:
    """What :func:`step` and :func:`advance` keep between calls (see the module docstring)."""

    p: FilterParams
    sensors: np.ndarray
    radii: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    lag: int
    link: bool
    link_gap: int
    link_speed: float
    link_slack: float
    log_particles: int = 0
    collect: bool = False  # keep every row, count and particle (the batch stage's tables)
    rng: np.random.Generator | None = None
    seed: int = 0
    started: bool = False
    times: list[float] = field(default_factory=list)  # every frame's time
    pending: list[np.ndarray] = field(default_factory=list)  # final frames not filtered yet
    filtered: int = 0  # frames filtered
    committed: int = 0  # frames committed
    # the compiled loop's state (kernels.run_frames)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    # per frame not yet committed: (labels, r, xy (filled once final))
    window: dict[int, list] = field(default_factory=dict)
    confirmed_at: dict[int, int] = field(default_factory=dict)  # label -> first frame confirmed
    links: _Link = field(default_factory=_Link)
    # collect=True: every row (frame, label, x, y, r, reported), counts, particles
    rows: list[tuple] = field(default_factory=list)
    counts: list[np.ndarray] = field(default_factory=list)
    particles: list[tuple] = field(default_factory=list)
    ended: bool = False


def start(
    p: FilterParams,
    sensors: np.ndarray,
    radii: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    lag: int,
    link: bool = True,
    link_gap: int = 10,
    link_speed: float = 1.5,
    link_slack: float = 1.0,
    seed: int = 0,
    log_particles: int = 0,
    collect: bool = False,
) -> OnlineBinPF:
    """A filter before its first frame; ``p.period`` is replaced by the frames' own spacing."""
    if lag < p.smooth_lag:
        raise ValueError(f"commit lag {lag} < smooth_lag {p.smooth_lag}: positions would not be final")
    sensors = np.ascontiguousarray(sensors, dtype=np.float64).reshape(-1, 2)
    return OnlineBinPF(
        p=p,
        sensors=sensors,
        radii=np.ascontiguousarray(radii, dtype=np.float64),
        lo=np.asarray(lo, dtype=np.float64),
        hi=np.asarray(hi, dtype=np.float64),
        lag=int(lag),
        link=link,
        link_gap=link_gap,
        link_speed=link_speed,
        link_slack=link_slack,
        seed=seed,
        log_particles=log_particles,
        collect=collect,
    )


def _begin(st: OnlineBinPF, period: float) -> None:
    """Allocate the compiled loop's state (as :func:`onebit.trackers.binpf.filter.run_filter`)."""
    p = FilterParams(**{**st.p.__dict__, "period": period})
    st.p = p
    N, L, M = p.particles, p.smooth_lag, p.max_tracks
    st.rng = np.random.default_rng(st.seed)
    st.arrays = {
        "state": np.zeros(3, dtype=np.int64),
        "x": np.zeros((M, N, 4)),
        "hist": np.zeros((M, N, L + 1, 2)),
        "rowidx": np.full((M, L + 1), -1, dtype=np.int64),
        "r": np.zeros(M),
        "labels": np.zeros(M, dtype=np.int64),
        "confirmed": np.zeros(M, dtype=bool),
        "ever": np.zeros(4 * M, dtype=bool),
        "est": np.zeros((2 * M * (L + 2), 2)),
        "rows_frame": np.zeros(2 * M * (L + 2), dtype=np.int64),
        "rows_label": np.zeros(2 * M * (L + 2), dtype=np.int64),
        "rows_r": np.zeros(2 * M * (L + 2)),
        "kp": kernel_params(p, st.log_particles),
        "dbuf": np.empty((M, st.sensors.shape[0], N)),  # footprints, near rows only (kernels.footprints_into)
    }
    st.started = True


def _filter_frame(st: OnlineBinPF, z: np.ndarray) -> None:
    """One frame through the compiled loop; its rows enter the window, final rows get positions."""
    a = st.arrays
    k = st.filtered
    M, L = st.p.max_tracks, st.p.smooth_lag
    base_rows = int(a["state"][2])
    next_label = int(a["state"][1])
    if a["ever"].size < next_label + M:
        a["ever"] = np.concatenate([a["ever"], np.zeros(max(M, a["ever"].size), dtype=bool)])
    if a["est"].shape[0] < base_rows + M:  # (rows are compacted below: this rarely grows)
        n = 2 * (base_rows + M)
        a["est"] = np.concatenate([a["est"], np.zeros((n - a["est"].shape[0], 2))])
        for key in ("rows_frame", "rows_label", "rows_r"):
            a[key] = np.concatenate([a[key], np.zeros(n - a[key].size, dtype=a[key].dtype)])
    counts = np.zeros((1, 4), dtype=np.int64)
    pxy, _pfr, plab = kernels.run_frames(
        z.reshape(1, -1), 0, 1, a["state"], a["x"], a["hist"], a["rowidx"], a["r"], a["labels"],
        a["confirmed"], a["ever"], a["est"], a["rows_frame"], a["rows_label"], a["rows_r"], counts,
        st.sensors, st.radii, st.lo, st.hi, st.rng, a["kp"], a["dbuf"],
    )  # fmt: skip
    n_rows = int(a["state"][2])
    labels = a["rows_label"][base_rows:n_rows].copy()
    rr = a["rows_r"][base_rows:n_rows].copy()
    st.window[k] = [labels, rr, None, base_rows]
    for lab in labels[a["ever"][labels]]:  # (a track is flagged while live: these are all)
        st.confirmed_at.setdefault(int(lab), k)
    if st.collect:
        st.counts.append(counts[0].copy())
        if pxy.shape[0]:
            st.particles.append((pxy.copy(), np.full(pxy.shape[0], k, np.int64), plab.copy()))
    st.filtered = k + 1
    # rows of frames <= k - L are final: copy their positions out, then drop them from the arrays
    done = k - L
    if done >= 0 and done in st.window and st.window[done][2] is None:
        w = st.window[done]
        lo_row = w[3]
        w[2] = a["est"][lo_row : lo_row + w[0].size].copy()
        _compact(st, lo_row + w[0].size)


def _compact(st: OnlineBinPF, upto: int) -> None:
    """Drop rows ``< upto`` (final and copied out) from the row arrays; renumber the others."""
    a = st.arrays
    if upto <= 0:
        return
    n = int(a["state"][2])
    for key in ("est", "rows_frame", "rows_label", "rows_r"):
        a[key][: n - upto] = a[key][upto:n]
    a["state"][2] = n - upto
    ri = a["rowidx"]
    ri[ri >= 0] -= upto
    for w in st.window.values():
        if w[2] is None:
            w[3] -= upto


def _commit(st: OnlineBinPF, c: int, *, final: bool) -> list[tuple[int, int, float, float]]:
    """Frame ``c``'s reported rows, chain-labelled, plus the gap rows of the joins made at ``c``:
    ``[(frame, label, x, y)]``."""
    labels, rr, xy, _ = st.window.pop(c)
    p = st.p
    horizon = st.filtered - 1 if final else c + st.lag
    conf = np.array([st.confirmed_at.get(int(lb), horizon + 1) <= horizon for lb in labels], dtype=bool)
    rep = conf & (rr >= p.r_out)
    if p.max_out > 0 and rep.sum() > p.max_out:
        idx = np.flatnonzero(rep)
        order = idx[np.argsort(-rr[idx], kind="stable")]
        rep[order[p.max_out :]] = False
    if st.collect:
        st.rows.append((c, labels, xy, rr, rep))
    out: list[tuple[int, int, float, float]] = []
    lk = st.links
    lab_rep, xy_rep = labels[rep], xy[rep]
    new = [i for i, lb in enumerate(lab_rep.tolist()) if lb not in lk.chain]
    fills: list[tuple[int, int, float, float]] = []
    if st.link and new:
        alive = set(labels.tolist())
        ends = sorted(
            lb
            for lb, (e, _x, _y) in lk.last.items()
            if lb not in lk.joined and lb not in alive and c - st.link_gap - 1 <= e <= c - 1
        )
        if ends:
            e_f = np.array([lk.last[lb][0] for lb in ends], dtype=np.int64)
            e_xy = np.array([lk.last[lb][1:] for lb in ends], dtype=float)
            s_f = np.full(len(new), c, dtype=np.int64)
            s_xy = xy_rep[new]
            cost = join_costs(
                s_f, s_xy, e_f, e_xy, period=p.period, max_gap=st.link_gap, max_speed=st.link_speed, slack=st.link_slack
            )
            r_idx, c_idx = best_joins(cost)
            for a_i, b_i in sorted(zip(r_idx.tolist(), c_idx.tolist()), key=lambda ab: cost[ab[0], ab[1]]):
                a_lab, b_lab = ends[a_i], int(lab_rep[new[b_i]])
                lk.chain[b_lab] = lk.chain[a_lab]
                lk.joined.add(a_lab)
                lk.joins += 1
                e = int(e_f[a_i])
                gap = np.arange(e + 1, c)
                if p.max_out > 0:
                    gap = gap[np.array([lk.count.get(int(g), 0) < p.max_out for g in gap], dtype=bool)]
                w = (gap - e) / (c - e)
                for g, wi in zip(gap.tolist(), w.tolist()):
                    fx = (1 - wi) * e_xy[a_i, 0] + wi * s_xy[b_i, 0]
                    fy = (1 - wi) * e_xy[a_i, 1] + wi * s_xy[b_i, 1]
                    lk.count[g] = lk.count.get(g, 0) + 1
                    fills.append((g, lk.chain[a_lab], fx, fy))
    for i, lb in enumerate(lab_rep.tolist()):
        lk.chain.setdefault(lb, lb)
        lk.last[lb] = (c, float(xy_rep[i, 0]), float(xy_rep[i, 1]))
        out.append((c, lk.chain[lb], float(xy_rep[i, 0]), float(xy_rep[i, 1])))
    lk.count[c] = lk.count.get(c, 0) + len(lab_rep)
    # what no later frame can use: ends older than the gate, counts of frames before it
    old = c - st.link_gap - 1
    for lb in [lb for lb, v in lk.last.items() if v[0] < old]:
        del lk.last[lb]
        lk.joined.discard(lb)
    for g in [g for g in lk.count if g < old]:
        del lk.count[g]
    return fills + out


def step(st: OnlineBinPF, times: np.ndarray, on: np.ndarray, *, final: bool) -> list[tuple[int, int, float, float]]:
    """Feed final frames (``times (n,)``, levels ``on (n, S)``); filter what can be filtered and
    return the rows committed, ``[(frame, label, x, y)]`` (frames counted from the first)."""
    if st.ended:
        return []
    st.times.extend(float(t) for t in times)
    st.pending.extend(np.asarray(on, dtype=np.bool_))
    out: list[tuple[int, int, float, float]] = []
    if not st.started:
        if len(st.times) < PERIOD_FRAMES and not final:
            return out
        d = np.diff(np.asarray(st.times[:PERIOD_FRAMES]))
        d = d[d > 0]
        _begin(st, float(np.median(d)) if d.size else 1.0)
    for z in st.pending:
        _filter_frame(st, np.ascontiguousarray(z))
        while st.committed + st.lag < st.filtered and st.window.get(st.committed, [None, None, None])[2] is not None:
            out += _commit(st, st.committed, final=False)
            st.committed += 1
    st.pending = []
    if final:
        a = st.arrays
        for w in st.window.values():  # the positions of the last frames are as final as they get
            if w[2] is None:
                w[2] = a["est"][w[3] : w[3] + w[0].size].copy()
        while st.committed < st.filtered:
            out += _commit(st, st.committed, final=True)
            st.committed += 1
        st.ended = True
    return out


# --------------------------------------------------------------------------- tables


def tracks_table(st: OnlineBinPF, rows: list[tuple[int, int, float, float]], tracker: str = "binpf") -> pl.DataFrame:
    """TRACKS rows of ``rows`` (``track`` = ``b<label>``), sorted by ``t`` then ``track``."""
    if not rows:
        return pl.DataFrame(schema=TRACKS)
    f = np.array([r[0] for r in rows], dtype=np.int64)
    t = np.asarray(st.times)[f]
    df = pl.DataFrame(
        {
            "tracker": [tracker] * len(rows),
            "track": [f"b{r[1]}" for r in rows],
            "t": t,
            "x": [r[2] for r in rows],
            "y": [r[3] for r in rows],
        }
    )
    return conform(df, TRACKS).sort(["t", "track"], maintain_order=True)


def frame_levels(frames: pl.DataFrame, ids: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """``(times (T,), on (T, S))``: each sensor's level per frame, sensors in site order, a
    sensor without a row in a frame off."""
    frames = frames.filter(pl.col("sensor").is_in(list(ids)))
    slots = frames.select("slot", "t").unique("slot").sort("slot")
    if slots.height == 0:
        return np.zeros(0), np.zeros((0, len(ids)), dtype=bool)
    k = np.searchsorted(slots["slot"].to_numpy(), frames["slot"].to_numpy())
    col = frames["sensor"].replace_strict(list(ids), list(range(len(ids))), return_dtype=pl.Int64).to_numpy()
    on = np.zeros((slots.height, len(ids)), dtype=bool)
    on[k, col] = frames["on"].to_numpy()
    return slots["t"].to_numpy().astype(float), on


@dataclass
class FollowBinPF:
    """:func:`advance`'s state: the driver and the input consumed so far."""

    driver: OnlineBinPF
    ids: tuple[str, ...]


def advance(state: FollowBinPF, frames: pl.DataFrame, *, until: float, final: bool) -> pl.DataFrame:
    """Consume the frames of ``frames`` (FRAMES, every final row so far) with ``t <= until``
    (all when ``final``) after the last one consumed; return the TRACKS rows committed."""
    drv = state.driver
    if drv.ended:
        return pl.DataFrame(schema=TRACKS)
    frames = check_schema(frames, FRAMES, name="proximity_frames")
    new = frames if not drv.times else frames.filter(pl.col("t") > drv.times[-1])
    if not final:
        new = new.filter(pl.col("t") <= until)
    times, on = frame_levels(new, state.ids)
    rows = step(drv, times, on, final=final)
    return tracks_table(drv, rows)


def run_lagged(
    times: np.ndarray,
    on: np.ndarray,
    p: FilterParams,
    sensors: np.ndarray,
    radii: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    lag: int,
    link: bool,
    link_gap: int,
    link_speed: float,
    link_slack: float,
    seed: int,
    log_particles: int,
    progress=None,
) -> tuple[FilterResult, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]]:
    """The whole log through the online driver (the batch stage with ``commit_lag > 0``):
    the filter's rows as a :class:`FilterResult` (``reported`` by the lagged rule) and the
    committed tracks ``(frame, label, x, y, joins)``, sorted by frame then label."""
    st = start(
        p, sensors, radii, lo, hi, lag=lag, link=link, link_gap=link_gap, link_speed=link_speed,
        link_slack=link_slack, seed=seed, log_particles=log_particles, collect=True,
    )  # fmt: skip
    T = len(times)
    rows: list[tuple[int, int, float, float]] = []
    step_n = 1000
    for k0 in range(0, T, step_n):
        k1 = min(T, k0 + step_n)
        rows += step(st, times[k0:k1], on[k0:k1], final=k1 == T)
        if progress is not None:
            progress(k1, T)
    if T == 0:
        rows += step(st, times, on, final=True)
    res = _result(st, T)
    f = np.array([r[0] for r in rows], dtype=np.int64)
    lab = np.array([r[1] for r in rows], dtype=np.int64)
    x = np.array([r[2] for r in rows], dtype=float)
    y = np.array([r[3] for r in rows], dtype=float)
    o = np.lexsort((lab, f))
    return res, (f[o], lab[o], x[o], y[o], st.links.joins)


def _result(st: OnlineBinPF, T: int) -> FilterResult:
    """The collected rows as a :class:`FilterResult`."""
    if st.rows:
        fr = np.concatenate([np.full(r[1].size, r[0], np.int64) for r in st.rows])
        lab = np.concatenate([r[1] for r in st.rows]).astype(np.int64)
        xy = np.concatenate([r[2].reshape(-1, 2) for r in st.rows])
        rr = np.concatenate([r[3] for r in st.rows])
        rep = np.concatenate([r[4] for r in st.rows])
    else:
        fr = lab = np.zeros(0, np.int64)
        xy = np.zeros((0, 2))
        rr = np.zeros(0)
        rep = np.zeros(0, bool)
    counts = np.stack(st.counts) if st.counts else np.zeros((T, 4), np.int64)
    if st.particles:
        pxy = np.concatenate([q[0] for q in st.particles])
        pfr = np.concatenate([q[1] for q in st.particles])
        plab = np.concatenate([q[2] for q in st.particles])
    else:
        pxy, pfr, plab = np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, np.int64)
    return FilterResult(
        frame=fr, label=lab, x=xy[:, 0].copy(), y=xy[:, 1].copy(), r=rr, reported=rep,
        births=counts[:, 0].copy(), deaths=counts[:, 1].copy(), merges=counts[:, 2].copy(), live=counts[:, 3].copy(),
        particles_xy=pxy, particles_frame=pfr, particles_label=plab,
    )  # fmt: skip


def delay_frames(st: OnlineBinPF) -> float:
    """The commit lag in seconds of log time (``lag`` frames of the frame period)."""
    return st.lag * st.p.period if st.started else math.nan
