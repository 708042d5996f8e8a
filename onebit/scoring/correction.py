"""Scoring of the false-negative correction in simulation (Bobadilla et al. V): which dropped
crossings the inserted ones restore."""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module

_optimize = lazy_module("scipy.optimize")


def recovered_matches(corrected: pl.DataFrame, sim_crossings: pl.DataFrame) -> pl.DataFrame:
    """Dropped true crossings matched one-to-one to inserted crossings.

    A dropped crossing of target ``X`` (``sim_crossings.dropped``) at time ``t_d`` is
    *restored* by an inserted crossing with the same beam and direction whose time lies
    strictly between ``X``'s previous and next true crossings -- its position within the
    neighbouring crossings of the same agent. The matching maximises the number restored
    (``linear_sum_assignment``; ties go to the smaller time difference).

    Returns the dropped crossings with ``inserted_row`` (row of ``corrected``, null if not restored).
    """
    sim = sim_crossings.sort(["target", "t"]).with_columns(
        t_prev=pl.col("t").shift(1).over("target").fill_null(-np.inf),
        t_next=pl.col("t").shift(-1).over("target").fill_null(np.inf),
    )
    drops = sim.filter(pl.col("dropped")).sort("t").with_row_index("drop_id")
    ins = corrected.with_row_index("row").filter(pl.col("inserted"))
    empty = drops.select("t", "beam", "direction", "target", pl.lit(None, pl.Int64).alias("inserted_row"))
    if drops.height == 0 or ins.height == 0:
        return empty
    pairs = drops.join(ins.select("row", "beam", "direction", t_ins="t"), on=["beam", "direction"]).filter(
        (pl.col("t_ins") > pl.col("t_prev")) & (pl.col("t_ins") < pl.col("t_next"))
    )
    if pairs.height == 0:
        return empty
    d_ids = pairs["drop_id"].unique().sort().to_numpy()
    r_ids = pairs["row"].unique().sort().to_numpy()
    di = np.searchsorted(d_ids, pairs["drop_id"].to_numpy())
    ri = np.searchsorted(r_ids, pairs["row"].to_numpy())
    dt = np.abs(pairs["t_ins"].to_numpy() - pairs["t"].to_numpy())
    w = np.zeros((len(d_ids), len(r_ids)))
    w[di, ri] = 1.0 + 1.0 / (1.0 + dt)  # one restored crossing outweighs any time difference
    a, b = _optimize.linear_sum_assignment(w, maximize=True)
    ok = w[a, b] > 0
    got = pl.DataFrame({"drop_id": d_ids[a[ok]].astype(np.uint32), "inserted_row": r_ids[b[ok]].astype(np.int64)})
    return drops.join(got, on="drop_id", how="left").select("t", "beam", "direction", "target", "inserted_row")


def corrected_targets(
    corrected: pl.DataFrame, observed_matches: pl.DataFrame, recovered: pl.DataFrame | None
) -> pl.DataFrame:
    """Per corrected crossing (in order) the true target: observed rows from ``observed_matches``
    (the matching of ``crossings`` to the true crossings), inserted rows from ``recovered``."""
    tgt = pl.Series("target", dtype=pl.String).extend_constant(None, corrected.height)
    obs_rows = np.flatnonzero(~corrected["inserted"].to_numpy())
    if obs_rows.size:
        tgt = tgt.scatter(obs_rows, observed_matches["target"].cast(pl.String))
    if recovered is not None and recovered.height:
        r = recovered.drop_nulls("inserted_row")
        if r.height:
            tgt = tgt.scatter(r["inserted_row"].to_numpy(), r["target"].cast(pl.String))
    return tgt.to_frame()


def score_correction(tables: dict, observed_matches: pl.DataFrame):
    """Report rows, tables and per-corrected-crossing targets for the ``scores`` stage.

    ``observed_matches``: the observed crossings matched to the true ones (``target`` column).
    In simulation (``sim_crossings`` with ``dropped``): ``correct/dropped`` and
    ``correct/recovered`` = restored / dropped (:func:`recovered_matches`), table
    ``correct_recovered``. The returned targets give inserted crossings the target of the
    dropped crossing they restored, so assignment accuracy counts them too.
    """
    corrected = tables["corrected_crossings"]
    sim = tables.get("sim_crossings")
    rows: list[tuple[str, str, float, str]] = []
    out: dict[str, pl.DataFrame] = {}
    rec = None
    if sim is not None and "dropped" in sim.columns:
        rec = recovered_matches(corrected, sim)
        n_drop = rec.height
        n_ok = rec["inserted_row"].drop_nulls().len()
        rows += [
            ("correct", "dropped", float(n_drop), "crossings"),
            ("correct", "restored", float(n_ok), "crossings"),
            ("correct", "recovered", n_ok / n_drop if n_drop else 1.0, "fraction"),
        ]
        out["correct_recovered"] = rec
    return rows, out, corrected_targets(corrected, observed_matches, rec)
