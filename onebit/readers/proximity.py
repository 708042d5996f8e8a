"""``proximity.csv`` (t, sensor, value) -> the ``proximity`` table and frames at chosen instants.

The raw log has the same shape as a PIR toggle log, so typing, state-change checks and the
debounce (relay chatter, minimum on-time) are :func:`onebit.readers.motion.read_motion`'s.
Singh et al. (section 6) sample such a log at regular instants, taking "the reading of a
sensor at any time [to be] the one after its last toggle": :func:`proximity_frames` does
exactly that (``join_asof`` backward; every sensor starts off).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.config import MAX_FRAME_CELLS, MAX_STEPS, check_size
from onebit.core.params import param, validate
from onebit.core.tables import FRAMES, PROXIMITY, conform
from onebit.readers.logs import CsvLog
from onebit.readers.motion import TOGGLE_COLUMNS, DebounceRules, MotionRead, read_motion, read_motion_csv
from onebit.readers.rows import RawRows

__all__ = [
    "ProximityConfig",
    "read_proximity",
    "read_proximity_csv",
    "proximity_frames",
    "TOGGLE_COLUMNS",
]


@dataclass(frozen=True, kw_only=True)
class ProximityConfig:
    """The ``[proximity]`` section of ``run.toml``: how binary sensor edges become frames."""

    period: float = param(1.0, "seconds between sampling instants", lo=1e-9, unit="s")
    start: float = param(-1.0, "time of the first instant; negative = floor(first edge / period) * period", unit="s")
    instants: int = param(
        0,
        "number of instants; 0 = up to the last accepted edge (instants x sensors at most "
        f"{MAX_FRAME_CELLS:,}, checked when the frames are made)",
        lo=0,
        hi=MAX_STEPS,
    )
    chatter_window: float = param(
        0.0,
        'a 1->0 edge followed within this time by 0->1 on the same sensor is undone (Singh et al.: "neglect '
        'every 1->0 transition immediately followed by 0->1")',
        lo=0.0,
        unit="s",
    )
    min_on: float = param(0.0, "shorter on-pulses are suppressed", lo=0.0, unit="s")

    def __post_init__(self) -> None:
        validate(self)

    @property
    def rules(self) -> DebounceRules:
        return DebounceRules(chatter_window=self.chatter_window, min_on=self.min_on)


def read_proximity(
    raw: RawRows | Path | CsvLog,
    sensors: Sequence[str],
    *,
    epoch=None,
    path: Path | None = None,
    rules: DebounceRules | None = None,
    held: frozenset[str] = frozenset(),
) -> MotionRead:
    """Type, check and debounce a proximity toggle log: the proximity reader of
    ``proximity.csv`` (typed in one read, line by line only where it must) or of an MCAP
    channel's rows; ``motion`` holds PROXIMITY rows (``held``: level sensors, whose repeated
    states are held states, :func:`read_motion`)."""
    res = read_motion(raw, sensors, epoch=epoch, path=path, rules=rules, held=held)
    return MotionRead(conform(res.motion, PROXIMITY), res.rejects, res.suppressed, res.reordered, res.held)


def read_proximity_csv(
    path: str | Path,
    sensors: Sequence[str],
    *,
    epoch=None,
    rules: DebounceRules | None = None,
    held: frozenset[str] = frozenset(),
) -> MotionRead:
    """:func:`read_proximity` of ``proximity.csv`` (a clean file typed in one read, :func:`read_motion_csv`)."""
    res = read_motion_csv(Path(path), sensors, epoch=epoch, rules=rules, held=held)
    return MotionRead(conform(res.motion, PROXIMITY), res.rejects, res.suppressed, res.reordered, res.held)


def _frame_span(ev: pl.DataFrame, sensors: list[str], period: float, start, instants):
    """``(start, instants)`` of :func:`proximity_frames` (defaults from the edges), checked
    against :data:`~onebit.core.config.MAX_STEPS` and :data:`~onebit.core.config.MAX_FRAME_CELLS`;
    ``None`` when there is no frame to make."""
    if start is None:
        if ev.height == 0 and not instants:
            return None
        start = math.floor(float(ev["t"].min()) / period) * period if ev.height else 0.0
    if not instants:
        last = float(ev["t"].max()) if ev.height else start
        span = (last - start) / period + 1e-9
        check_size(span, MAX_STEPS, what="instants over the log", field=f"[proximity] period = {period:g} s")
        instants = max(int(math.floor(span)) + 1, 1)
    if not sensors:
        return None
    check_size(
        float(instants) * len(sensors),
        MAX_FRAME_CELLS,
        what=f"frame rows ({instants:,} instants x {len(sensors)} sensors)",
        field=f"[proximity] period = {period:g} s / instants",
        hint="a longer period or fewer instants",
    )
    return float(start), int(instants)


def proximity_frames(
    proximity: pl.DataFrame,
    sensors: Sequence[str],
    *,
    period: float,
    start: float | None = None,
    instants: int | None = None,
) -> pl.DataFrame:
    """Readings at instants ``t_k = start + k * period`` (FRAMES: slot, t, sensor, on), rows by
    slot then by the order of ``sensors``.

    ``on`` = the state after the sensor's last accepted edge at or before ``t_k`` (off before
    its first edge; of edges at the same stamp, the later row). ``start`` defaults to
    ``floor(first edge / period) * period``; ``instants`` to the count reaching the last edge;
    more than :data:`~onebit.core.config.MAX_FRAME_CELLS` rows is a :class:`ConfigError`.

    With numpy, linear in edges + cells: edge ``e`` first holds at instant
    ``k_e = min {k : t_k >= t_e}`` (``searchsorted`` on the instants' own stamps, computed as
    the table's ``t``); per sensor the state over instants is the value of its latest edge by
    ``k_e`` (the later row of a slot), held until its next edge's slot: one ``repeat`` of the
    values over the run lengths. :func:`onebit._testing.reader_oracles.proximity_frames_reference` (an ``as-of`` join of
    every instant to the edges) is its test oracle.
    """
    sensors = list(dict.fromkeys(sensors))
    ev = proximity.select("t", "sensor", "on").filter(pl.col("sensor").is_in(sensors))
    span = _frame_span(ev, sensors, period, start, instants)
    if span is None:
        return pl.DataFrame(schema=FRAMES)
    start, instants = span
    n_s = len(sensors)
    t_grid = float(start) + np.arange(instants, dtype=np.float64) * period
    code = ev["sensor"].cast(pl.Enum(sensors)).to_physical().to_numpy().astype(np.int64)
    te = ev["t"].to_numpy()
    on = ev["on"].to_numpy()
    if on.dtype != np.bool_:  # nulls: as the reference's fill, off
        on = ev["on"].fill_null(False).to_numpy()
    slot_e = np.searchsorted(t_grid, te, side="left")  # the first instant each edge holds at
    keep = slot_e < instants
    # per (sensor, slot), the edge that holds: the latest stamp, then the later row
    order = np.lexsort((np.arange(te.size)[keep], te[keep], slot_e[keep], code[keep]))
    c, k, v = code[keep][order], slot_e[keep][order], on[keep][order]
    last = np.ones(c.size, dtype=np.bool_)
    last[:-1] = (c[1:] != c[:-1]) | (k[1:] != k[:-1])
    c, k, v = c[last], k[last], v[last]
    states = np.zeros((instants, n_s), dtype=np.bool_)
    bounds = np.searchsorted(c, np.arange(n_s + 1), side="left")
    for s in range(n_s):  # per sensor: its values held over the run lengths between its edges
        lo, hi = bounds[s], bounds[s + 1]
        if lo == hi:
            continue
        ks = k[lo:hi]
        states[ks[0] :, s] = np.repeat(v[lo:hi], np.diff(np.append(ks, instants)))
    cells = instants * n_s
    return pl.DataFrame(
        {
            "slot": np.repeat(np.arange(instants, dtype=np.int64), n_s),
            "t": np.repeat(t_grid, n_s),
            "sensor": pl.Series(sensors, dtype=pl.String).gather(np.tile(np.arange(n_s, dtype=np.uint32), instants)),
            "on": states.reshape(cells),
            "fired": pl.repeat(None, cells, dtype=pl.Boolean, eager=True),
        },
        schema=FRAMES,
    )
