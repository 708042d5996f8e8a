"""The stages of "how many are home": the count's truth and profile, the count model, the scores.

    truth_count    truth_count.csv    -> truth_count (people in, as intervals: t, end, count)
    count_profile  count_profile.csv  -> count_profile (the count model learned from labelled days)
    occupancy      motion (+ count_profile) -> occupancy_bins, occupancy_people
                   (the home's count model, :mod:`onebit.models.occupancy`; the ``residents``
                   tracker reads its count)

And what every multi-person tracker's ``<tracker>_people`` is when the tracker does not write its
own (:func:`people_from_tracks`), and its score against ``truth_count``
(:func:`count_metric`, :mod:`onebit.scoring.count`).
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.config import config_from_mapping
from onebit.core.units import config_in_site_units
from onebit.models.occupancy import PEOPLE, OccupancyConfig, estimate
from onebit.pipeline.context import ReportRow, RunContext
from onebit.readers.tables_csv import read_count_profile_csv, read_truth_count_csv
from onebit.readers.timebase import TimeOrigin
from onebit.scoring.count import baseline_rows, count_scores


def truth_count_available(ctx: RunContext) -> str | None:
    return None if (ctx.dataset / "truth_count.csv").exists() else "no truth_count.csv in the dataset"


def truth_count_work(ctx: RunContext, origin: TimeOrigin) -> dict[str, pl.DataFrame]:
    """``truth_count.csv`` (t, end, count): how many people were in (``onebit import aras``
    writes it from the residents' Going Out labels); ``origin``: the run's time origin."""
    tc, rej = read_truth_count_csv(ctx.dataset / "truth_count.csv", epoch=origin)
    ctx.add_rejects(rej)
    span = float((tc["end"] - tc["t"]).sum()) if tc.height else 0.0
    ctx.report += [
        ("truth_count", "intervals", float(tc.height), "intervals"),
        ("truth_count", "hours", span / 3600.0, "h"),
    ]
    return {"truth_count": tc}


def count_profile_available(ctx: RunContext) -> str | None:
    return None if (ctx.dataset / "count_profile.csv").exists() else "no count_profile.csv in the dataset"


def count_profile_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    """``count_profile.csv`` (learned by ``onebit learn residents`` from days with
    ``truth_count.csv``): the count model's statistics."""
    prof, rej = read_count_profile_csv(ctx.dataset / "count_profile.csv")
    ctx.add_rejects(rej)
    bins = prof.filter(pl.col("term") == "bins")["count"].sum() if prof.height else 0.0
    ctx.report.append(("count_profile", "labelled_hours", float(bins) * 60.0 / 3600.0, "h"))
    return {"count_profile": prof}


def occupancy_available(ctx: RunContext) -> str | None:
    if "motion" not in ctx.tables:
        return "input table 'motion' not produced by an earlier stage"
    return None if ctx.site.tracked.motion_sensors else "site has no motion sensors"


def occupancy_work(ctx: RunContext, motion: pl.DataFrame) -> dict[str, pl.DataFrame]:
    """The home's count (:func:`onebit.models.occupancy.estimate`) over ``motion`` (the run's,
    without the ignored sensors' rows), on the sensors the trackers see."""
    cfg = config_from_mapping(OccupancyConfig, ctx.section("occupancy"), section="occupancy")
    ctx.record("occupancy", cfg)
    cfg = config_in_site_units(cfg, ctx.site)
    bins, people = estimate(motion, ctx.site.tracked, cfg, ctx.tables.get("count_profile"))
    n = bins["present"].to_numpy() if bins.height else np.zeros(0)
    ctx.report += [
        ("occupancy", "bins", float(bins.height), "bins"),
        ("occupancy", "mean_present", float(n.mean()) if n.size else 0.0, "people"),
        ("occupancy", "max_present", float(n.max()) if n.size else 0.0, "people"),
        ("occupancy", "learned", float("count_profile" in ctx.tables and cfg.profile), "flag"),
        *[("occupancy", f"share_{k}", float((n == k).mean()) if n.size else 0.0, "fraction of bins") for k in range(3)],
        ("occupancy", "share_3plus", float((n >= 3).mean()) if n.size else 0.0, "fraction of bins"),
    ]
    return {"occupancy_bins": bins, "occupancy_people": people}


def people_from_tracks(tracks: pl.DataFrame | None) -> pl.DataFrame:
    """``(t, present)`` of a tracker's tracks: each track present over its runs of rows (rows
    at most 1.5 x the tracks' usual step apart), until one step after its last row of a run;
    the count at every change. An empty table says nobody (one row: 0 people)."""
    if tracks is None or tracks.height == 0:
        return pl.DataFrame({"t": [0.0], "present": [0]}, schema=PEOPLE)
    tr = tracks.select("track", "t").drop_nulls().unique().sort("track", "t")
    ts = np.unique(tr["t"].to_numpy())
    step = float(np.median(np.diff(ts))) if ts.size > 1 else 1.0
    step = step if step > 0 else 1.0
    t = tr["t"].to_numpy()
    same = np.r_[False, tr["track"].to_numpy()[1:] == tr["track"].to_numpy()[:-1]]
    gap = np.r_[np.inf, np.diff(t)]
    start = ~same | (gap > 1.5 * step)
    end = np.r_[start[1:], True]
    times = np.r_[t[start], t[end] + step]
    delta = np.r_[np.ones(int(start.sum()), np.int64), -np.ones(int(end.sum()), np.int64)]
    order = np.argsort(times, kind="stable")
    times, delta = times[order], delta[order]
    uniq, first = np.unique(times, return_index=True)
    level = np.cumsum(delta)[np.r_[first[1:] - 1, len(delta) - 1]]
    keep = np.r_[True, level[1:] != level[:-1]]
    return pl.DataFrame({"t": uniq[keep], "present": level[keep].astype(np.int64)}, schema=PEOPLE)


def count_metric(tracker: str, tables: dict[str, pl.DataFrame], site, region_graph) -> list[ReportRow]:
    """Per-minute count scores of ``<tracker>_people`` when the dataset has ``truth_count``."""
    tc = tables.get("truth_count")
    people = tables.get(f"{tracker}_people")
    if tc is None or not tc.height or people is None:
        return []
    return count_scores(tc, people).rows(tracker)


def count_rows(tables: dict[str, pl.DataFrame]) -> list[ReportRow]:
    """The count model's own scores and both baselines', when the dataset has ``truth_count``."""
    tc = tables.get("truth_count")
    if tc is None or not tc.height:
        return []
    rows: list[ReportRow] = []
    if "occupancy_people" in tables:
        rows += count_scores(tc, tables["occupancy_people"]).rows("occupancy")
    return rows + baseline_rows(tc, tables.get("motion"))
