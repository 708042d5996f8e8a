"""Queries on the observation string (Bobadilla et al., section IV-F-1), as polars tables.

The paper's four questions, each a small vectorised function of the assignment table
(one row per crossing: ``t, source, region`` -- the region left and the region entered --
and ``track``; rows with a null ``track`` are unexplained crossings and are left out):

1. *Which region was the most visited?* :func:`visits_per_region` -- the number of crossings
   whose edge enters the region ("count the characters representing incoming edges": for r4
   of Fig. 2, the occurrences of ``d``, ``f``, ``g^-1``), most visited first.
2. *Which areas had the most traffic in a certain period?* :func:`traffic_per_region` --
   entries and exits per region per time bucket ``[k b, (k + 1) b)``.
3. *What was the count of bodies in a given period?* :func:`occupancy` --
   ``n_r(t) = n_r(0) + entries_r(<= t) - exits_r(<= t)`` after every crossing.
4. *Were there more than N agents in any region?* :func:`intervals_over_threshold` -- the
   maximal intervals in which ``n_r(t) > N``.
"""

from __future__ import annotations

import polars as pl

_EMPTY_INTERVALS = {
    "region": pl.String,
    "t_start": pl.Float64,
    "t_end": pl.Float64,
    "duration_s": pl.Float64,
    "peak": pl.Int64,
}


def _explained(assignment: pl.DataFrame) -> pl.DataFrame:
    return assignment.filter(pl.col("track").is_not_null()) if "track" in assignment.columns else assignment


def visits_per_region(assignment: pl.DataFrame, regions: list[str] | tuple[str, ...]) -> pl.DataFrame:
    """``region, visits``: crossings entering each region, most visited first (ties by name).

    Examples
    --------
    >>> a = pl.DataFrame({"t": [0.0, 1.0, 2.0], "source": ["r1", "r2", "r1"], "region": ["r2", "r1", "r2"]})
    >>> visits_per_region(a, ["r1", "r2", "r3"])["visits"].to_list()
    [2, 1, 0]
    """
    counts = _explained(assignment).group_by("region").agg(visits=pl.len().cast(pl.Int64))
    return (
        pl.DataFrame({"region": list(regions)}, schema={"region": pl.String})
        .join(counts, on="region", how="left")
        .with_columns(pl.col("visits").fill_null(0))
        .sort(["visits", "region"], descending=[True, False])
    )


def traffic_per_region(assignment: pl.DataFrame, bucket_s: float) -> pl.DataFrame:
    """``bucket, t_start, region, entries, exits, traffic``: crossings per region per time bucket.

    Bucket ``k`` is ``[k * bucket_s, (k + 1) * bucket_s)``; ``traffic = entries + exits``. Only
    (bucket, region) pairs with at least one crossing appear; sorted by bucket then traffic.
    """
    if bucket_s <= 0:
        raise ValueError(f"bucket_s must be > 0, got {bucket_s}")
    a = _explained(assignment)
    bucket = (pl.col("t") / bucket_s).floor().cast(pl.Int64).alias("bucket")
    moves = pl.concat(
        [
            a.select(bucket, region="region", entries=pl.lit(1, pl.Int64), exits=pl.lit(0, pl.Int64)),
            a.select(bucket, region="source", entries=pl.lit(0, pl.Int64), exits=pl.lit(1, pl.Int64)),
        ]
    )
    return (
        moves.group_by("bucket", "region")
        .agg(pl.col("entries").sum(), pl.col("exits").sum())
        .with_columns(t_start=pl.col("bucket").cast(pl.Float64) * bucket_s, traffic=pl.col("entries") + pl.col("exits"))
        .select("bucket", "t_start", "region", "entries", "exits", "traffic")
        .sort(["bucket", "traffic", "region"], descending=[False, True, False])
    )


def occupancy(assignment: pl.DataFrame, starts: pl.DataFrame, regions: list[str] | tuple[str, ...]) -> pl.DataFrame:
    """``t, region, count``: agents per region at the first time, then after each crossing.

    ``starts`` holds one row per agent with its initial ``region`` and the start time ``t``.
    ``count_r(t) = n_r(0) + entries_r(<= t) - exits_r(<= t)``; one row per region at the
    start and one per (crossing, endpoint region), computed with cumulative sums per region.
    """
    a = _explained(assignment)
    t0 = starts["t"].min() if starts.height else (a["t"].min() if a.height else 0.0)
    init = (
        pl.DataFrame({"region": list(regions)}, schema={"region": pl.String})
        .join(starts.group_by("region").agg(delta=pl.len().cast(pl.Int64)), on="region", how="left")
        .with_columns(t=pl.lit(t0, pl.Float64), delta=pl.col("delta").fill_null(0), order=pl.lit(0))
    )
    moves = pl.concat(
        [
            a.select("t", region="source", delta=pl.lit(-1, pl.Int64)).with_row_index("order", offset=1),
            a.select("t", region="region", delta=pl.lit(1, pl.Int64)).with_row_index("order", offset=1),
        ]
    ).select("t", "region", "delta", pl.col("order").cast(pl.Int32))
    allm = pl.concat([init.select("t", "region", "delta", pl.col("order").cast(pl.Int32)), moves])
    return (
        allm.sort(["order", "delta"])
        .with_columns(count=pl.col("delta").cum_sum().over("region"))
        .select("t", "region", "count")
    )


def intervals_over_threshold(occ: pl.DataFrame, threshold: int, *, t_end: float | None = None) -> pl.DataFrame:
    """``region, t_start, t_end, duration_s, peak``: maximal intervals with ``count > threshold``.

    An interval starts at the row where the count of the region first exceeds ``threshold`` and
    ends at the region's next row where it does not (``t_end`` -- default the last time in
    ``occ`` -- when it never drops back). Run-length ids per region, no row loop.

    Examples
    --------
    >>> occ = pl.DataFrame({"t": [0.0, 1.0, 2.0, 3.0], "region": ["r1"] * 4, "count": [1, 3, 4, 1]})
    >>> intervals_over_threshold(occ, 2).select("t_start", "t_end", "peak").rows()
    [(1.0, 3.0, 4)]
    """
    if occ.height == 0:
        return pl.DataFrame(schema=_EMPTY_INTERVALS)
    end = float(occ["t"].max()) if t_end is None else float(t_end)
    o = occ.with_row_index("i").sort(["region", "i"]).with_columns(over=pl.col("count") > threshold)
    o = o.with_columns(
        run=pl.col("over").rle_id().over("region"),
        t_next_run=pl.col("t").shift(-1).over("region"),
    )
    runs = (
        o.group_by("region", "run")
        .agg(
            over=pl.col("over").first(),
            t_start=pl.col("t").first(),
            t_end=pl.col("t_next_run").last(),
            peak=pl.col("count").max().cast(pl.Int64),
        )
        .filter(pl.col("over"))
        .with_columns(pl.col("t_end").fill_null(end))
    )
    return (
        runs.with_columns(duration_s=pl.col("t_end") - pl.col("t_start"))
        .select("region", "t_start", "t_end", "duration_s", "peak")
        .sort(["t_start", "region"])
    )
