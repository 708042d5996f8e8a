"""How many people are in: the per-minute count scores (docs/metrics.md, "People count").

Truth: ``truth_count`` (t, end, count: people in over ``[t, end)``). Estimate: a tracker's
``<tracker>_people`` (t, present): a step function, ``present`` from its ``t`` to the next row's,
the last row to the end of the scored span, ``0`` before the first row (a tracker that says
nothing says nobody is in, and scores its misses).

Minutes: ``[t0 + 60 k, t0 + 60 (k + 1))`` from the truth's first ``t`` (floored to a minute)
to its last ``end``; a minute is scored when the truth covers at least half of it. In each, the
truth ``n_k`` and the estimate ``m_k`` are the step functions' time averages over the minute,
rounded (half up). Over the scored minutes ``M``::

    count_error        = (1/M) sum_k |m_k - n_k|
    count_accuracy     = (1/M) sum_k [m_k = n_k]
    occupancy_accuracy = (1/M) sum_k [(m_k >= 1) = (n_k >= 1)]

Baselines, scored by the same function (:func:`baseline_rows`):

* ``count-commonest`` -- every minute the commonest true count (the majority class: what a
  user who knows the home guesses);
* ``count-recent-60min`` -- home if a sensor changed in the last 60 minutes: in each minute
  the commonest non-zero true count when a motion row of the run falls in the 60 minutes
  before the minute's end, else 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

MINUTE_S = 60.0
RECENT_S = 3600.0


@dataclass(frozen=True)
class CountScores:
    count_error: float
    count_accuracy: float
    occupancy_accuracy: float
    minutes: int

    def rows(self, stage: str) -> list[tuple[str, str, float, str]]:
        return [
            (stage, "count_error", self.count_error, "people/minute"),
            (stage, "count_accuracy", self.count_accuracy, "fraction of minutes"),
            (stage, "occupancy_accuracy", self.occupancy_accuracy, "fraction of minutes"),
            (stage, "count_minutes", float(self.minutes), "minutes"),
        ]


def minute_grid(truth_count: pl.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Minute starts over the truth's span and the truth's rounded time average in each
    (``-1`` where it covers less than half of the minute)."""
    t, end, c = (truth_count[k].to_numpy().astype(float) for k in ("t", "end", "count"))
    if t.size == 0:
        return np.zeros(0), np.zeros(0, dtype=np.int64)
    t0 = np.floor(t.min() / MINUTE_S) * MINUTE_S
    minutes = t0 + MINUTE_S * np.arange(int(np.ceil((end.max() - t0) / MINUTE_S)))
    lo = np.clip(t[None, :], minutes[:, None], minutes[:, None] + MINUTE_S)
    hi = np.clip(end[None, :], minutes[:, None], minutes[:, None] + MINUTE_S)
    w = np.maximum(hi - lo, 0.0) if t.size * minutes.size <= 50_000_000 else None
    if w is None:  # long truths: interval by interval
        cover, total = np.zeros(minutes.size), np.zeros(minutes.size)
        for a, e, n in zip(t, end, c):
            ww = np.maximum(np.minimum(e, minutes + MINUTE_S) - np.maximum(a, minutes), 0.0)
            cover += ww
            total += ww * n
    else:
        cover, total = w.sum(axis=1), (w * c[None, :]).sum(axis=1)
    out = np.full(minutes.size, -1, dtype=np.int64)
    ok = cover >= MINUTE_S / 2
    out[ok] = np.floor(total[ok] / cover[ok] + 0.5).astype(np.int64)
    return minutes, out


def step_average(people: pl.DataFrame | None, minutes: np.ndarray) -> np.ndarray:
    """The rounded time average of a ``(t, present)`` step function over each minute."""
    if people is None or people.height == 0 or minutes.size == 0:
        return np.zeros(minutes.size, dtype=np.int64)
    p = people.sort("t")
    ts, v = p["t"].to_numpy().astype(float), p["present"].to_numpy().astype(float)
    edges = np.r_[minutes, minutes[-1] + MINUTE_S]
    # integral of the step function from -inf (0 before the first row) to each edge
    knots = np.r_[ts, max(edges[-1], ts[-1])]
    area = np.r_[0.0, np.cumsum(v * np.diff(knots))]
    k = np.searchsorted(ts, edges, side="right") - 1
    at = np.where(k >= 0, area[np.maximum(k, 0)] + v[np.maximum(k, 0)] * (edges - ts[np.maximum(k, 0)]), 0.0)
    avg = np.diff(at) / MINUTE_S
    return np.floor(avg + 0.5 + 1e-9).astype(np.int64)


def score_minutes(est: np.ndarray, true: np.ndarray) -> CountScores:
    """The three scores (module docstring) over the minutes with a truth (``true >= 0``)."""
    ok = true >= 0
    m, n = est[ok], true[ok]
    if m.size == 0:
        return CountScores(float("nan"), float("nan"), float("nan"), 0)
    return CountScores(
        float(np.abs(m - n).mean()),
        float((m == n).mean()),
        float(((m >= 1) == (n >= 1)).mean()),
        int(m.size),
    )


def count_scores(truth_count: pl.DataFrame, people: pl.DataFrame | None) -> CountScores:
    """A tracker's ``people`` against ``truth_count`` (module docstring)."""
    minutes, true = minute_grid(truth_count)
    return score_minutes(step_average(people, minutes), true)


def baseline_counts(truth_count: pl.DataFrame, motion: pl.DataFrame | None) -> dict[str, np.ndarray]:
    """The baselines' per-minute counts (module docstring), on the truth's minutes."""
    minutes, true = minute_grid(truth_count)
    known = true[true >= 0]
    if known.size == 0:
        return {}
    common = int(np.bincount(known).argmax())
    nonzero = known[known > 0]
    home = int(np.bincount(nonzero).argmax()) if nonzero.size else 1
    t = motion["t"].to_numpy().astype(float) if motion is not None and motion.height else np.zeros(0)
    t = np.sort(t)
    end = minutes + MINUTE_S
    recent = np.searchsorted(t, end, side="left") - np.searchsorted(t, end - RECENT_S, side="left") > 0
    return {
        "count-commonest": np.full(minutes.size, common, dtype=np.int64),
        "count-recent-60min": np.where(recent, home, 0).astype(np.int64),
    }


def baseline_rows(truth_count: pl.DataFrame, motion: pl.DataFrame | None) -> list[tuple[str, str, float, str]]:
    """Report rows of both baselines."""
    _, true = minute_grid(truth_count)
    rows = []
    for name, est in baseline_counts(truth_count, motion).items():
        rows += score_minutes(est, true).rows(name)
    return rows
