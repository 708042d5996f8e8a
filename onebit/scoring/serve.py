"""When a tracker cannot serve the data: say so in the report instead of printing a number.

A tracker built for one target (the intruder filter) run on a recording of several people,
or an I-state over ``n`` targets on a recording with more of them at once, produces numbers
that mean nothing. Its scorer raises :class:`CannotServe` with the reason; the scores stage
records ``<tracker>/cannot_serve = 1`` in the report and the reason as the status
``scores/<tracker>``, and prints no error metric for it.

``targets`` (``site.toml``) has one meaning for every tracker: **the most targets present in
the site at any one time** (people, agents, robots), when known; a recording where people
come and go has more distinct ids than that.
"""

from __future__ import annotations

import polars as pl

from onebit.core.errors import OnebitError


class CannotServe(OnebitError):
    """The tracker's model does not fit the data (the message says why)."""


def targets_at_once(truth: pl.DataFrame, *, period: float | None = None) -> int:
    """The most targets present at one time in ``truth`` (t, target): distinct targets per time
    bucket of ``period`` seconds (default: the median interval between a target's samples)."""
    if truth.height == 0:
        return 0
    if period is None:
        d = truth.sort("target", "t").select(pl.col("t").diff().over("target")).to_series().drop_nulls()
        d = d.filter(d > 0)
        period = float(d.median()) if d.len() else 1.0
    bucket = (pl.col("t") / max(period, 1e-9)).floor().cast(pl.Int64)
    return int(truth.group_by(bucket.alias("_b")).agg(pl.col("target").n_unique().alias("n"))["n"].max())
