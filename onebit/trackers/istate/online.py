"""The ``istate`` filter run online: one stage at a time, as soon as its readings are final.

O'Kane's filter is sequential by nature: the I-state of stage ``k`` is the update of stage
``k - 1``'s by the readings of stage ``k`` alone (forward projection by ``v T``, then the
detections). :class:`OnlineIState` keeps the I-state, the point summary's previous positions,
the region-pair memo, each sensor's last state and the stage buckets of readings between calls;
:func:`advance` takes the readings that became final (every row at or before ``until``: the
caller's settled time), runs the stages whose readings are all in, and returns their ``tracks``
rows -- the rows the batch stage (:func:`onebit.trackers.istate.stage.run`) gives on the whole
log:

* **the stage grid** ``t_k = k T`` runs from the first reading (known once the first final
  reading is in: every earlier one would be final too) to the last one; stage ``k`` runs once
  ``until >= t_k`` (its readings ``(t_{k-1}, t_k]`` and the states at ``t_k`` are final) and a
  reading at ``t > t_{k-1}`` shows the grid reaches it;
* **readings** are :func:`~onebit.trackers.istate.stage.state_readings` and
  :func:`~onebit.trackers.istate.stage.crossing_readings` of that stage alone (each sensor's
  state carried over from the stages before), in the batch order (by sensor index);
* **silent stretches** (:func:`onebit.core.frames.silent_stretches`): a stage's row is held
  until a final event at or after ``t_k`` closes the gap around it, then dropped if the gap is
  silent, as the batch drops it.

Online only where the batch filter is: with ``latency_auto = false`` (by default ``latency_s``
is raised to the whole log's time resolution, which a prefix does not know) and without
``reliable_negatives`` (a negative reading comes from every sensor of the whole log, also
before its first edge). Otherwise :func:`supported` says why and ``onebit follow`` re-runs the
stage on the settled prefix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import polars as pl
import shapely

from onebit.core.errors import ConfigError
from onebit.core.site import Site
from onebit.core.tables import TRACKS, conform
from onebit.trackers.istate.core import IState, PairMemo, SiteFrame, grow, info_state_update
from onebit.trackers.istate.stage import NAME, IStateConfig, _point_summary, sensing_regions


def supported(config: IStateConfig) -> str | None:
    """Why the filter cannot run online with ``config`` equal to the batch run, or ``None``."""
    if config.latency_auto:
        return "latency_auto = true raises latency_s to the whole log's time resolution"
    if config.reliable_negatives:
        return "reliable_negatives = true reads a 0 from every sensor of the whole log"
    return None


@dataclass
class OnlineIState:
    """What :func:`advance` keeps between calls."""

    config: IStateConfig
    n: int
    index: dict[str, int]
    kinds: dict[str, str]
    frame: SiteFrame
    free: object
    positive: np.ndarray  # every sensor's sensing region, in the frame
    step: float
    eta: IState
    memo: PairMemo = field(default_factory=PairMemo)
    prev: np.ndarray | None = None
    k0: int | None = None  # the first stage (t_0 = k0 T)
    k: int = 0  # the next stage to run
    k_last: int = -1  # the last stage the readings so far reach
    fed: dict[str, int] = field(default_factory=dict)  # rows of each input consumed
    state: dict[str, bool] = field(default_factory=dict)  # each sensor's state after the edges consumed
    carried: dict[str, bool] = field(default_factory=dict)  # each sensor's state at the last stage run
    buckets: dict[int, list] = field(default_factory=dict)  # stage -> readings [(kind, sensor, t, on)]
    n_on: int = 0  # sensors on after the last event (silent stretches)
    last_event: float | None = None
    silent: list[tuple[float, float]] = field(default_factory=list)
    held: list[tuple[float, np.ndarray]] = field(default_factory=list)  # stages run, rows not out yet
    ended: bool = False


def start(site: Site, config: IStateConfig) -> OnlineIState:
    why = supported(config)
    if why is not None:
        raise ConfigError(f"istate cannot run online: {why}")
    n = config.targets or (site.targets or 0)
    if n < 1:
        raise ConfigError("istate: the number of targets is unknown; set 'targets' in site.toml or [istate] targets")
    sr = sensing_regions(site, config)
    frame = SiteFrame.of(site.free_space)
    free = frame.outer(site.free_space)
    return OnlineIState(
        config=config,
        n=n,
        index={s: i for i, s in enumerate(sr.ids)},
        kinds=dict(zip(sr.ids, sr.kind)),
        frame=frame,
        free=free,
        positive=frame.outer(sr.positive),
        step=float(frame.length(config.max_speed * config.period_s)),
        eta=IState.initial(free, n),
    )


def advance(state: OnlineIState, inputs: dict[str, pl.DataFrame], *, until: float, final: bool) -> pl.DataFrame:
    """Consume the rows of ``inputs`` (``motion``, ``proximity``, ``crossings``: every final row
    so far, each sorted by ``t``) at or before ``until`` (all when ``final``), run the stages
    that became final and return the TRACKS rows now decided."""
    out = pl.DataFrame(schema=TRACKS)
    if state.ended:
        return out
    T = state.config.period_s
    until = math.inf if final else until
    _ingest(state, inputs, until)
    if state.k0 is None:
        if final:
            state.ended = True
        return out
    t0 = float(np.float64(state.k0) * T)
    while state.k <= state.k_last:
        tk = float(np.float64(state.k0 + state.k) * T)
        if tk > until:
            break
        _run_stage(state, state.k, tk, t0)
        state.k += 1
    rows = []
    keep = []
    for tk, xy in state.held:
        decided = final or (state.last_event is not None and state.last_event >= tk)
        if not decided:
            keep.append((tk, xy))
            continue
        if not any(a < tk < b for a, b in state.silent):
            rows.append((tk, xy))
    state.held = keep  # a stretch can only hold a row still held (later stages are after every event so far)
    state.silent = [s for s in state.silent if keep and s[1] > keep[0][0]]
    if final:
        state.ended = True
    if not rows:
        return out
    n = state.n
    xy = state.frame.xy_to_site(np.stack([r[1] for r in rows]))
    df = pl.DataFrame(
        {
            "tracker": [NAME] * (len(rows) * n),
            "track": np.tile([f"target{i + 1}" for i in range(n)], len(rows)).tolist(),
            "t": np.repeat([r[0] for r in rows], n),
            "x": xy[:, :, 0].ravel(),
            "y": xy[:, :, 1].ravel(),
        }
    )
    return conform(df, TRACKS).with_columns(pl.col("x").fill_nan(None), pl.col("y").fill_nan(None))


def _ingest(state: OnlineIState, inputs: dict[str, pl.DataFrame], until: float) -> None:
    """The new final rows: per-sensor state changes into the stage buckets and the event stream."""
    parts = []
    for key in ("motion", "proximity", "crossings"):
        df = inputs.get(key)
        if df is None or df.height == 0:
            continue
        done = state.fed.get(key, 0)
        end = df.height if math.isinf(until) else int(df["t"].search_sorted(until, side="right"))
        if end <= done:
            continue
        state.fed[key] = end
        new = df.slice(done, end - done)
        if key == "crossings":
            new = new.filter(pl.col("beam").is_in(list(state.index)))
            parts.append(new.select("t", pl.col("beam").alias("sensor"), pl.lit(None, pl.Boolean).alias("on")))
        else:
            new = new.filter(pl.col("sensor").is_in(list(state.index)))
            parts.append(new.select("t", "sensor", "on"))
    if not parts:
        return
    ev = pl.concat(parts).sort("t", maintain_order=True)
    if ev.height == 0:
        return
    T = state.config.period_s
    if state.k0 is None:  # the first final reading is the first of the log
        state.k0 = int(np.floor(float(ev["t"][0]) / T + 1e-9))
    t0 = float(np.float64(state.k0) * T)
    min_s = state.config.absent_after
    for t, sensor, on in ev.iter_rows():
        if on is not None:  # an edge: only state changes count (every sensor starts off)
            if on == state.state.get(sensor, False):
                continue
            state.state[sensor] = on
            d = 1 if on else -1
        else:
            d = 0
        if min_s > 0 and state.last_event is not None and state.n_on <= 0 and t - state.last_event >= min_s:
            state.silent.append((state.last_event, t))
        state.n_on += d
        state.last_event = t
        k = max(math.ceil((t - t0) / T - 1e-9), 0)
        state.buckets.setdefault(k, []).append((sensor, t, on))
        state.k_last = max(state.k_last, int(math.ceil(t / T - 1e-9)) - state.k0)


def _run_stage(state: OnlineIState, k: int, tk: float, t0: float) -> None:
    """Stage ``k``: its readings (as the batch's ``state_readings`` / ``crossing_readings``), the
    I-state update and the point summary."""
    cfg = state.config
    v, hold = cfg.max_speed, cfg.latency_s
    per: dict[str, list] = {}
    for sensor, t, on in state.buckets.pop(k, []):
        per.setdefault(sensor, []).append((t, on))
    det: list[tuple[int, float]] = []
    for sensor in set(state.carried) | set(per):
        rows = per.get(sensor, [])
        if sensor in state.kinds and state.kinds[sensor] == "beam" and rows and rows[0][1] is None:
            tc = max(t for t, _ in rows)  # the latest crossing of the beam in the stage
            det.append((state.index[sensor], v * (tk - tc + hold)))
            continue
        on_now = rows[-1][1] if rows else state.carried.get(sensor, False)
        state.carried[sensor] = on_now
        offs = [t for t, on in rows if not on]
        if on_now:
            det.append((state.index[sensor], v * hold))
        elif rows and offs:
            det.append((state.index[sensor], v * (tk - max(offs) + hold)))
    det.sort()
    idx = np.array([i for i, _ in det], dtype=np.int64)
    infl = np.array([x for _, x in det], dtype=float)
    geoms = (
        shapely.intersection(grow(state.positive[idx], state.frame.length(infl)), state.free)
        if len(det)
        else np.zeros(0, object)
    )
    rejected: list | None = [] if cfg.contradictions == "reject" else None
    state.eta = info_state_update(
        state.eta,
        geoms,
        step=state.step if k else 0.0,
        free_space=state.free,
        shape=cfg.shape,
        max_elements=cfg.max_elements or None,
        negatives=np.zeros(0, object),
        substeps=cfg.substeps,
        memo=state.memo,
        rejected=rejected,
    )
    state.prev = _point_summary(state.eta, state.prev, state.n)
    state.held.append((tk, state.prev))
