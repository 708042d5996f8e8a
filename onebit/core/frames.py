"""Edges on a grid of slots, and the empty room: the sampling every tracker of toggle sensors shares.

:func:`motion_frames` samples accepted toggle edges (MOTION, PROXIMITY) on a grid of slots of
length ``period`` (a tracker's processing period t_P): ``on`` = the sensor was on at some time
in the slot, ``fired`` = a rising edge in the slot (Schiff & Goldberg's S_i = 1 for the
iteration); :func:`refractory_state` adds their trigger semantics. :func:`silent_stretches`
finds the stretches in which no sensor is on and nothing happens (nobody present) and
:func:`outside_silence` drops a tracker's estimates inside them.

Each tracker samples with its own period (the intruder filter's t_P = 2 s, an HMM's 1 s slots),
from the ``motion`` table the reader stage made once; no slot table is built for the whole run
(slots x sensors over a log of months is tens of millions of rows).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import polars as pl

from onebit.core.config import MAX_FRAME_CELLS, check_size
from onebit.core.errors import ConfigError
from onebit.core.tables import FRAMES


def motion_frames(
    motion: pl.DataFrame,
    sensors: Sequence[str],
    *,
    period: float,
    t0: float | None = None,
    t1: float | None = None,
) -> pl.DataFrame:
    """Sample accepted edges (MOTION) on slots of length ``period``: a FRAMES table.

    Slot ``k`` covers ``[t0 + k*period, t0 + (k+1)*period)`` and ``t`` is its start. For
    every slot x sensor (sensor-major order within a slot)::

        on    = state at the slot start (after edges at exactly that time) or a rising edge in the slot
        fired = a rising edge (off -> on) in the slot

    ``t0`` defaults to ``floor(first edge / period) * period`` (slots stay aligned on
    multiples of ``period``), the number of slots to the one holding the last edge; with
    ``t1`` given, slots cover ``[t0, t1)`` (``ceil((t1 - t0) / period)`` slots). Every
    sensor starts off; edges before ``t0`` set the state at the first slot.
    """
    sensors, ev, grid = slot_grid(motion, sensors, period=period, t0=t0, t1=t1)
    if grid is None:
        return pl.DataFrame(schema=FRAMES)
    t0, n = grid
    return _frames_arrays(ev, sensors, t0=t0, period=period, n=n)


def slot_grid(
    motion: pl.DataFrame, sensors: Sequence[str], *, period: float, t0: float | None, t1: float | None
) -> tuple[list[str], pl.DataFrame, tuple[float, int] | None]:
    """The slots of :func:`motion_frames`: ``(sensors without repeats, their edges sorted by t,
    (t0, number of slots) or None when there is no slot)`` (the rules in its docstring). More than
    :data:`~onebit.core.config.MAX_FRAME_CELLS` slots x sensors is a :class:`ConfigError` naming the period."""
    if not (isinstance(period, (int, float)) and math.isfinite(period) and period > 0):
        raise ConfigError(f"period = {period!r}: must be a finite number > 0 (seconds)")
    sensors = list(dict.fromkeys(sensors))
    ev = motion.select("t", "sensor", "on").filter(pl.col("sensor").is_in(sensors)).sort("t", maintain_order=True)
    if t0 is None:
        if ev.height == 0 and t1 is None:
            return sensors, ev, None
        first = float(ev["t"].min()) if ev.height else 0.0
        t0 = math.floor(first / period) * period
    if t1 is None:
        last = float(ev["t"].max()) if ev.height else t0
        span = (last - t0) / period
        _check_slots(span + 1, len(sensors), period)
        n = max(int(math.floor(span)) + 1, 1)
    else:
        span = (t1 - t0) / period
        _check_slots(span, len(sensors), period)
        n = max(int(math.ceil(span - 1e-12)), 0)
    return sensors, ev, ((t0, n) if n > 0 and sensors else None)


def _check_slots(slots: float, sensors: int, period: float) -> None:
    check_size(
        slots * max(sensors, 1),
        MAX_FRAME_CELLS,
        what=f"frame rows ({slots:,.0f} slots of {period:g} s x {sensors} sensors)",
        field=f"period = {period:g} s",
        hint="a longer period",
    )


def _frames_arrays(ev: pl.DataFrame, sensors: list[str], *, t0: float, period: float, n: int) -> pl.DataFrame:
    """The FRAMES table of :func:`motion_frames` with numpy, one sensor at a time: the state at
    each slot start is the sensor's last edge at or before it (``searchsorted``), a slot fired
    when a rising edge falls in it; the whole grid is built as flat arrays (slot-major, sensors
    in order), never joined. Equal to :func:`onebit._testing.oracles.motion_frames_reference` (tested)."""
    k = len(sensors)
    slot_t = t0 + np.arange(n, dtype=np.int64).astype(np.float64) * period
    state = np.zeros((n, k), dtype=np.bool_)
    fired = np.zeros((n, k), dtype=np.bool_)
    code = ev["sensor"].replace_strict(sensors, list(range(k)), return_dtype=pl.Int64).to_numpy()
    t_all = ev["t"].to_numpy().astype(np.float64)
    on_all = ev["on"].to_numpy().astype(np.bool_)
    for i in range(k):
        sel = code == i
        if not sel.any():
            continue
        t, on = t_all[sel], on_all[sel]
        last = np.searchsorted(t, slot_t, side="right") - 1  # the last edge at or before each slot start
        state[:, i] = np.where(last >= 0, on[np.maximum(last, 0)], False)
        slot = np.floor((t - t0) / period).astype(np.int64)
        rising = on & (slot >= 0) & (slot < n)
        fired[slot[rising], i] = True
    names = pl.Series("sensor", sensors, dtype=pl.String)
    return pl.DataFrame(
        {
            "slot": np.repeat(np.arange(n, dtype=np.int64), k),
            "t": np.repeat(slot_t, k),
            "sensor": names.gather(np.tile(np.arange(k), n)),
            "on": (state | fired).ravel(),
            "fired": fired.ravel(),
        },
        schema=FRAMES,
    )


def refractory_state(frames: pl.DataFrame, refractory: Mapping[str, float], *, period: float) -> pl.DataFrame:
    """The paper's trigger semantics per slot: ``beta`` (remaining blind time) and ``B``.

    Schiff & Goldberg, section VII-B.1, with S = ``fired``::

        beta_{i,tau} = f_i                          if S_{i,tau} = 1
                     = max(0, beta_{i,tau-1} - t_P) otherwise,      beta_{i,0} = 0

    and ``blind`` = (beta_{i,tau-1} > 0): the sensor is in its refractory period during slot
    tau because it fired in an earlier slot less than f_i seconds before (B_{i,tau} = 1).
    Closed form (no recursion): with ``last`` the latest earlier slot where the sensor fired,
    ``beta_{i,tau-1} = max(0, f_i - (tau - 1 - last) * t_P)``, computed with a forward fill.
    Returns frames + columns ``beta`` (after the slot) and ``blind``.
    """
    ref = pl.DataFrame(
        {"sensor": list(refractory), "_f": [float(v) for v in refractory.values()]},
        schema={"sensor": pl.String, "_f": pl.Float64},
    )
    df = frames.join(ref, on="sensor", how="left").with_columns(pl.col("_f").fill_null(0.0))
    last_fire = (
        pl.when(pl.col("fired")).then(pl.col("slot")).otherwise(None).forward_fill().over("sensor", order_by="slot")
    )
    df = df.with_columns(_last=last_fire)
    beta = (
        pl.when(pl.col("_last").is_null())
        .then(0.0)
        .otherwise((pl.col("_f") - (pl.col("slot") - pl.col("_last")).cast(pl.Float64) * period).clip(lower_bound=0.0))
    )
    prev_beta = beta.shift(1).over("sensor", order_by="slot").fill_null(0.0)
    df = df.with_columns(beta=beta).with_columns(blind=prev_beta > 0)
    return df.drop("_f", "_last").sort(["slot"], maintain_order=True)


# --------------------------------------------------------------------------- the empty room

#: Schema of :func:`silent_stretches`.
SILENT = pl.Schema({"t_start": pl.Float64, "t_end": pl.Float64})

#: Default ``absent_after`` of the trackers (s): a stretch this long with every sensor off and
#: no event is taken as nobody present (a walker trips a sensor every few seconds; a PIR's hold
#: keeps it on while someone moves under it).
ABSENT_AFTER_S = 60.0


def silent_stretches(events: Sequence[pl.DataFrame], *, min_s: float) -> pl.DataFrame:
    """Stretches of at least ``min_s`` seconds in which no sensor is on and nothing happens.

    ``events``: tables with ``t`` and ``sensor`` and either ``on`` (toggle edges: MOTION,
    PROXIMITY) or no ``on`` (instantaneous events such as crossings). Every sensor starts off;
    the number of sensors on after each edge is a cumulative sum of +-1 over the edges in time
    order (vectorised; repeated states count once). A gap between two consecutive events
    during which that number is 0, of length ``>= min_s``, is silent: nobody is present (or
    nobody the sensors can see). The stretch before the first and after the last event is
    outside the data and not reported. ``min_s <= 0`` gives no stretch.
    """
    parts = []
    for df in events:
        if df is None or df.height == 0:
            continue
        if "on" in df.columns:
            e = df.select("t", "sensor", "on").sort("t", maintain_order=True)
            e = e.filter(pl.col("on") != pl.col("on").shift(1, fill_value=False).over("sensor"))
            parts.append(e.select("t", pl.when(pl.col("on")).then(1).otherwise(-1).cast(pl.Int64).alias("d")))
        else:
            parts.append(df.select("t", pl.lit(0, pl.Int64).alias("d")))
    if min_s <= 0 or not parts:
        return pl.DataFrame(schema=SILENT)
    ev = pl.concat(parts).sort("t", maintain_order=True).with_columns(n_on=pl.col("d").cum_sum())
    gaps = ev.select(
        t_start=pl.col("t"),
        t_end=pl.col("t").shift(-1),
        n_on=pl.col("n_on"),
    ).filter((pl.col("n_on") <= 0) & pl.col("t_end").is_not_null() & (pl.col("t_end") - pl.col("t_start") >= min_s))
    return gaps.select("t_start", "t_end").cast(dict(SILENT))


def outside_silence(tracks: pl.DataFrame, silent: pl.DataFrame) -> pl.DataFrame:
    """``tracks`` (any table with ``t``) without the rows strictly inside a silent stretch."""
    if silent.height == 0 or tracks.height == 0:
        return tracks
    marked = (
        tracks.with_row_index("_row")
        .sort("t")
        .join_asof(silent.sort("t_start"), left_on="t", right_on="t_start", strategy="backward", check_sortedness=False)
    )
    keep = marked.filter(~((pl.col("t") > pl.col("t_start")) & (pl.col("t") < pl.col("t_end"))).fill_null(False))
    return keep.sort("_row").select(tracks.columns)
