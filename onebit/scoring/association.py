"""The one truth-to-track association of every scorer (docs/architecture.md, "Scores and reports").

Two small steps, used by the ``intruder``, ``clustertrack``, ``findinghumo``/``hmm1``/``hmm2``
and ``beams`` scorers alike (each with its own per-sample cost, in the paper's unit):

* :func:`pair_samples` -- every track sample with each target's truth sample nearest in time
  (within a tolerance): a long table ``(track, target, t, ...)``, one row per pair of samples.
* :func:`associate` -- tracks matched one-to-one to targets by minimum total cost over the
  whole run (``scipy.optimize.linear_sum_assignment``), with a gate so a track or a target may
  stay unmatched.

Formulation
-----------
Let :math:`S_{kg}` be the samples at which track :math:`k` and target :math:`g` are paired
and :math:`c_s` the cost of sample :math:`s` (a distance, a hop count, minus one per shared
crossing). The cost of the pair is the sum or the mean over the run,

.. math::

    C_{kg} = \\sum_{s \\in S_{kg}} c_s  \\quad\\text{or}\\quad
    C_{kg} = \\frac{1}{|S_{kg}|} \\sum_{s \\in S_{kg}} c_s ,
    \\qquad C_{kg} = +\\infty \\text{ if } S_{kg} = \\emptyset .

The association is the one-to-one matching :math:`x_{kg} \\in \\{0, 1\\}`,
:math:`\\sum_g x_{kg} \\le 1`, :math:`\\sum_k x_{kg} \\le 1`, that solves

.. math::

    \\min_x \\sum_{k, g} x_{kg} \\, (C_{kg} - \\gamma)
    \\;=\\; \\min_x \\Big[ \\sum_{k, g} x_{kg} C_{kg}
    + \\tfrac{\\gamma}{2} \\big(\\#\\text{unmatched tracks} + \\#\\text{unmatched targets}\\big) \\Big]
    - \\tfrac{\\gamma}{2} (K + G)

with the gate :math:`\\gamma`: leaving a track and a target unmatched costs :math:`\\gamma/2`
each, so a pair is matched only if :math:`C_{kg} \\le \\gamma`. It is solved exactly by one
``linear_sum_assignment`` on the rectangular matrix :math:`\\min(C_{kg}, \\gamma)` (a pair
charged :math:`\\gamma` is "left unmatched"; any partial matching extends to a full one at
that charge). Without a gate (:math:`\\gamma = \\infty`) every track that can be matched is:
maximum cardinality first, then minimum :math:`\\sum C_{kg}`.

Sum or mean. ``mean`` when tracks and targets overlap for different lengths of time (point
tracks, the paper's "mean error over the instants"): a track is not preferred merely for
being short. ``sum`` when every pair covers the same samples (the HMM slots, where a slot the
track misses is charged the graph diameter) or when the cost counts events (beams: minus the
crossings a track and a target share, so the matching maximises the crossings attributed to
the right agent).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import polars as pl

from onebit.core.errors import OnebitError
from onebit.core.lazy import lazy_module

_optimize = lazy_module("scipy.optimize")

#: Columns of :func:`associate`'s result.
ASSOCIATION = pl.Schema({"track": pl.String, "target": pl.String, "cost": pl.Float64, "samples": pl.UInt32})


def truth_at(
    times: pl.Series | np.ndarray,
    truth: pl.DataFrame,
    *,
    tolerance: float | None,
    columns: tuple[str, ...] = ("x", "y"),
) -> pl.DataFrame:
    """Each target's truth sample nearest to every time in ``times``.

    Parameters
    ----------
    times : (T,) times (s); duplicates are kept.
    truth : TRUTH-like table with ``t``, ``target`` and ``columns``.
    tolerance : largest ``|t - t_truth|`` (s); ``None`` takes the nearest sample however far.
    columns : truth columns to carry, renamed ``true_<column>``.

    Returns
    -------
    ``(t, target, t_truth, true_<column>...)``, one row per (time, target) with a truth sample
    within ``tolerance``, sorted by ``t`` then ``target``.
    """
    frames = pl.DataFrame({"t": pl.Series(times, dtype=pl.Float64)}).sort("t")
    sel = [pl.col("t").alias("t_truth"), *(pl.col(c).alias(f"true_{c}") for c in columns)]
    schema = {"t": pl.Float64, "target": pl.String, "t_truth": pl.Float64} | {
        f"true_{c}": truth.schema[c] for c in columns
    }
    targets = truth["target"].unique().sort().to_list() if truth.height else []
    parts = []
    for g in targets:  # one as-of join per target (a handful), each vectorised over the times
        tg = truth.filter(pl.col("target") == g).select("t", *sel).sort("t")
        j = frames.join_asof(
            tg, left_on="t", right_on="t", strategy="nearest", tolerance=tolerance, check_sortedness=False
        )
        parts.append(j.drop_nulls("t_truth").with_columns(target=pl.lit(g, dtype=pl.String)))
    if not parts:
        return pl.DataFrame(schema=schema)
    return pl.concat(parts).select(list(schema)).sort(["t", "target"], maintain_order=True)


def pair_samples(
    tracks: pl.DataFrame,
    truth: pl.DataFrame,
    *,
    tolerance: float | None,
    columns: tuple[str, ...] = ("x", "y"),
    truth_columns: tuple[str, ...] = ("x", "y"),
    complete: bool = False,
) -> pl.DataFrame:
    """Every track sample paired with each target's truth sample nearest in time.

    Parameters
    ----------
    tracks : TRACKS-like table with ``track``, ``t`` and ``columns`` (rows with a null in
        ``columns`` are the caller's to drop first).
    truth : TRUTH-like table with ``t``, ``target`` and ``truth_columns``.
    tolerance : largest ``|t - t_truth|`` (s) of a pair; ``None``: the nearest, however far.
    columns, truth_columns : columns carried from the track and (as ``true_<c>``) the truth.
    complete : also a row for every (frame, target present, track) where the track has no
        sample at the frame (its ``columns`` null); the frames are the tracks' sample times.
        The HMM scorer charges such a slot the graph diameter.

    Returns
    -------
    ``(track, target, t, t_truth, <columns>, true_<truth_columns>)`` with ``t`` the track's
    sample time, sorted by ``t``, ``track``, ``target``.
    """
    keep = ["track", "t", *columns]
    tr = tracks.select(keep)
    true = truth_at(tr["t"].unique(), truth, tolerance=tolerance, columns=truth_columns)
    if complete:
        names = pl.DataFrame({"track": tr["track"].unique().sort()})
        pairs = true.join(names, how="cross").join(tr, on=["t", "track"], how="left")
    else:
        pairs = tr.join(true, on="t", how="inner")
    order = ["track", "target", "t", "t_truth", *columns, *(f"true_{c}" for c in truth_columns)]
    return pairs.select(order).sort(["t", "track", "target"], maintain_order=True)


def cost_table(pairs: pl.DataFrame, *, cost: str = "cost", reduce: Literal["sum", "mean"] = "mean") -> pl.DataFrame:
    """:math:`C_{kg}`: the sum or mean of ``cost`` over the samples of every (track, target).

    Returns ``(track, target, cost, samples)`` sorted by ``track``, ``target``.
    """
    if reduce not in ("sum", "mean"):
        raise OnebitError(f"associate: reduce={reduce!r}; expected 'sum' or 'mean'")
    if cost not in pairs.columns:
        raise OnebitError(f"associate: the pairs have no cost column {cost!r} (columns: {pairs.columns})")
    agg = pl.col(cost).cast(pl.Float64)
    return (
        pairs.group_by("track", "target")
        .agg(cost=agg.sum() if reduce == "sum" else agg.mean(), samples=pl.len())
        .sort(["track", "target"])
        .cast(dict(ASSOCIATION))
    )


def associate(
    pairs: pl.DataFrame, *, cost: str = "cost", reduce: Literal["sum", "mean"] = "mean", gate: float | None = None
) -> pl.DataFrame:
    """Tracks matched one-to-one to targets by minimum total cost over the whole run.

    Solves :math:`\\min_x \\sum_{kg} x_{kg} (C_{kg} - \\gamma)` (module docstring) with
    :math:`C` from :func:`cost_table` and :math:`\\gamma` = ``gate``.

    Parameters
    ----------
    pairs : long table with ``track``, ``target`` and the per-sample ``cost`` (one row per
        paired sample, e.g. from :func:`pair_samples`).
    cost : name of the per-sample cost column.
    reduce : ``"sum"`` or ``"mean"`` over the run (module docstring says which when).
    gate : largest :math:`C_{kg}` of a matched pair (inclusive); ``None``: no gate, every
        track that can be matched is.

    Returns
    -------
    ``(track, target, cost, samples)`` (:data:`ASSOCIATION`) of the matched pairs, sorted by track.
    """
    if gate is not None and not np.isfinite(gate):
        raise OnebitError(f"associate: gate={gate!r}; expected a finite number or None")
    C_long = cost_table(pairs, cost=cost, reduce=reduce)
    if C_long.height == 0:
        return pl.DataFrame(schema=ASSOCIATION)
    tracks = C_long["track"].unique().sort().to_frame().with_row_index("k")
    targets = C_long["target"].unique().sort().to_frame().with_row_index("g")
    idx = C_long.join(tracks, on="track").join(targets, on="target")
    C = np.full((tracks.height, targets.height), np.inf)
    C[idx["k"].to_numpy(), idx["g"].to_numpy()] = idx["cost"].to_numpy()
    finite = np.isfinite(C)
    if gate is None:
        # "leaving unmatched" outweighs any finite total: maximum cardinality, then minimum cost
        big = (np.abs(C[finite]).max() + 1.0) * (2 * min(C.shape) + 1) if finite.any() else 1.0
        W = np.where(finite, C, big)
        ok = finite
    else:
        ok = finite & (C <= gate)
        W = np.where(ok, C, gate)
    r, c = _optimize.linear_sum_assignment(W)
    m = ok[r, c]
    out = pl.DataFrame({"track": tracks["track"].gather(r[m]), "target": targets["target"].gather(c[m])})
    return out.join(C_long, on=["track", "target"], how="left").select(list(ASSOCIATION)).sort("track")


def matched_pairs(pairs: pl.DataFrame, matching: pl.DataFrame) -> pl.DataFrame:
    """The rows of ``pairs`` whose (track, target) is in ``matching`` (order kept)."""
    return pairs.join(matching.select("track", "target"), on=["track", "target"], how="semi")
