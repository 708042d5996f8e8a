"""Rerun logging of the ``occupancy`` stage: how many people are home, against the truth.

Entity paths::

    occupancy/present     the count model's people present (a step series over the whole run)
    occupancy/truth       the true count (``truth_count``), when the dataset has it (a step series)
    occupancy/doors       a point at 0 at every bin with a door event

Each series is one ``send_columns``; the styles are static.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import paths

rr = lazy_module("rerun")

ROOT = "occupancy"


def log_step_series(rec, entity: str, t: np.ndarray, v: np.ndarray, *, name: str, rgb, width: float = 2.0) -> None:
    """A step series (held until the next value) in one call, styled once."""
    if t.size == 0:
        return
    rec.log(
        entity,
        rr.SeriesLines(
            colors=[rgb], names=[name], widths=[width], interpolation_mode=rr.components.InterpolationMode.StepAfter
        ),
        static=True,
    )
    rec.send_columns(
        entity,
        indexes=[paths.time_column(np.asarray(t, dtype=np.float64))],
        columns=rr.Scalars.columns(scalars=np.asarray(v, dtype=np.float64)),
    )


def truth_steps(truth_count: pl.DataFrame | None) -> tuple[np.ndarray, np.ndarray]:
    """The truth's step corners: each interval's start at its count, a 0 where a gap starts."""
    if truth_count is None or truth_count.height == 0:
        return np.zeros(0), np.zeros(0)
    tc = truth_count.sort("t")
    t, end, c = tc["t"].to_numpy(), tc["end"].to_numpy(), tc["count"].to_numpy().astype(float)
    gap = np.r_[t[1:] > end[:-1] + 1e-9, True]
    ts = np.r_[t, end[gap]]
    vs = np.r_[c, np.zeros(int(gap.sum()))]
    order = np.argsort(ts, kind="stable")
    return ts[order], vs[order]


def log_occupancy(rec, ctx, made: dict) -> None:
    """The count, the truth and the door events (module docstring)."""
    people = made.get("occupancy_people")
    if people is not None and people.height:
        t, v = people["t"].to_numpy(), people["present"].to_numpy()
        bins = made.get("occupancy_bins")
        if bins is not None and bins.height:  # hold the last value to the end of the last bin
            t, v = (
                np.r_[t, bins["t"].max() + float(np.diff(bins["t"].to_numpy()[:2])[0] if bins.height > 1 else 60.0)],
                np.r_[v, v[-1]],
            )
        log_step_series(rec, paths.join(ROOT, "present"), t, v, name="people home (model)", rgb=(255, 140, 120))
    ts, vs = truth_steps(ctx.tables.get("truth_count"))
    log_step_series(rec, paths.join(ROOT, "truth"), ts, vs, name="people home (truth)", rgb=(120, 220, 120))
    bins = made.get("occupancy_bins")
    if bins is not None and bins.height and bins["door"].any():
        d = bins.filter("door")
        entity = paths.join(ROOT, "doors")
        rec.log(entity, rr.SeriesPoints(colors=[(80, 160, 255)], names=["door event"], markers=["cross"]), static=True)
        rec.send_columns(
            entity,
            indexes=[paths.time_column(d["t"].to_numpy())],
            columns=rr.Scalars.columns(scalars=np.zeros(d.height)),
        )
