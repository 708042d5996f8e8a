"""Which track each motion event went to: the ``<tracker>_events`` table of the graph trackers.

A slot tracker decodes users at nodes per slot; the identity scores
(:mod:`onebit.scoring.identity`) need, per *event*, the track it was attributed to. The rule,
for a firing (ON edge) of sensor ``s`` at time ``t``, in slot ``k = floor((t - t0) / T)``:

1. a track decoded at ``s`` in slot ``k`` (several: the first by track name);
2. else the track decoded nearest to ``s`` on the sensor graph in slot ``k`` (fewest hops;
   ties: the first by track name);
3. else (no track in slot ``k``, none reachable from ``s``, or ``s`` not a node) none: ``track``
   is null.

It reads the tracker's own ``tracks`` table (after its user cap and the empty-room rule), so
what is scored is what the tracker reports. Vectorised over events: a (users, events) gather
of the decoded nodes and one ``argmin`` of the hop distances.
"""

from __future__ import annotations

import re

import numpy as np
import polars as pl

from onebit.core.tables import TRACKER_EVENTS


def _natural(s: str):
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", s)]


def attribute_events(
    motion: pl.DataFrame, tracks: pl.DataFrame, nodes: tuple[str, ...], hops: np.ndarray, *, t0: float, period: float
) -> pl.DataFrame:
    """``<tracker>_events`` (:data:`~onebit.core.tables.TRACKER_EVENTS`): one row per ON edge of
    ``motion`` (t, sensor, on), in time order, with the track it went to (module docstring).

    ``tracks``: the tracker's TRACKS rows (``t`` at slot mid times ``t0 + (k + 1/2) T``,
    ``node``); ``hops``: (N, N) hop counts of ``nodes`` (> N: unreachable)."""
    ev = motion.filter(pl.col("on")).select("t", "sensor").sort("t", maintain_order=True)
    if ev.height == 0:
        return pl.DataFrame(schema=TRACKER_EVENTS)
    n = len(nodes)
    idx = {s: i for i, s in enumerate(nodes)}
    j = ev["sensor"].replace_strict(idx, default=-1, return_dtype=pl.Int64).to_numpy()
    k_ev = np.floor((ev["t"].to_numpy() - t0) / period).astype(np.int64)
    tr = tracks.filter(pl.col("node").is_not_null() & pl.col("track").is_not_null())
    names = sorted(tr["track"].unique().to_list(), key=_natural)
    track_col = np.full(ev.height, None, dtype=object)
    if names and n:
        u = tr["track"].replace_strict({t: i for i, t in enumerate(names)}, return_dtype=pl.Int64).to_numpy()
        k_tr = np.round((tr["t"].to_numpy() - t0) / period - 0.5).astype(np.int64)
        node = tr["node"].replace_strict(idx, default=-1, return_dtype=pl.Int64).to_numpy()
        d = int(max(k_tr.max(initial=0), k_ev.max(initial=0))) + 1
        paths = np.full((len(names), d), -1, dtype=np.int64)
        ok = (node >= 0) & (k_tr >= 0)
        paths[u[ok], k_tr[ok]] = node[ok]
        inside = (k_ev >= 0) & (j >= 0)
        cand = paths[:, np.clip(k_ev, 0, d - 1)]  # (U, E) node of each user in the event's slot
        far = n + 1
        dist = np.where(cand >= 0, hops[np.clip(j, 0, n - 1)[None, :], np.clip(cand, 0, n - 1)], far)
        dist = np.where(dist > n, far, dist)  # unreachable: never the nearest
        best = np.argmin(dist, axis=0)  # first user by name on ties
        hit = inside & (dist[best, np.arange(ev.height)] < far)
        track_col[hit] = np.asarray(names, dtype=object)[best[hit]]
    return ev.with_columns(track=pl.Series("track", track_col.tolist(), dtype=pl.String)).select(list(TRACKER_EVENTS))
