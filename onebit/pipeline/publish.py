"""What ``onebit follow`` publishes: ``OUT/live/tables/<table>/part-NNNNNN.parquet`` (one part per
poll, each written atomically), the live Rerun stream, and the follow report
(``OUT/live/report.*``: estimates, delays, whether the published rows equal the batch run's,
faults of the logs)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core import writers as outputs
from onebit.pipeline.tail import BACKWARDS, LogSource
from onebit.viz import live as viz_live
from onebit.viz.families import Look


class Publisher:
    """Appends published rows as parquet parts, logs them to the stream, measures delays."""

    def __init__(
        self,
        live: Path,
        rec,
        wall_at: Callable[[float], float],
        clock: Callable[[], float],
        looks: dict[str, Look] | None = None,
    ):
        self.tables = live / "tables"
        self.looks = looks or {}
        self.rec = rec
        self.wall_at = wall_at
        self.clock = clock
        self.parts: dict[str, int] = {}
        self.delays: list[pl.DataFrame] = []
        self.counts: dict[str, int] = {}

    def table(self, name: str, df: pl.DataFrame) -> None:
        if df is None or df.height == 0:
            return
        k = self.parts.get(name, 0)
        self.parts[name] = k + 1
        outputs.write_parquet(df, self.tables / name / f"part-{k:06d}.parquet")

    def rows(self, tracker: str, rows: dict[str, pl.DataFrame]) -> None:
        """An online tracker's rows of one poll: its estimates (``tracks``), then every other
        table it publishes (``<tracker>_<table>``)."""
        self.estimates(tracker, rows["tracks"])
        for name, df in rows.items():
            if name != "tracks":
                self.table(f"{tracker}_{name}", df)

    def estimates(self, tracker: str, tracks: pl.DataFrame) -> None:
        if tracks is None or tracks.height == 0:
            return
        now = self.clock()
        t = tracks["t"].to_numpy()
        delay = np.array([max(0.0, now - self.wall_at(float(x))) for x in t])
        self.table(f"{tracker}_tracks", tracks)
        d = pl.DataFrame(
            {"tracker": [tracker] * len(t), "t": t, "delay_s": delay},
            schema={"tracker": pl.String, "t": pl.Float64, "delay_s": pl.Float64},
        )
        self.table("delays", d)
        self.delays.append(d)
        self.counts[tracker] = self.counts.get(tracker, 0) + len(t)
        if self.rec is not None:
            viz_live.log_estimates(self.rec, tracker, tracks, rgb=self.looks.get(tracker, Look()).rgb)
            viz_live.log_delays(self.rec, tracker, t, delay)


def fault_rows(out: Path, sources: dict[str, LogSource]) -> pl.DataFrame:
    """The follow report's rows on faults of the logs: files restarted (rotated, truncated,
    rewritten) and rows rejected because the logger's clock stepped back (the final run's rejects)."""
    rows = [("follow", "log_restarts", float(sum(s.restarts for s in sources.values())), "files")]
    path = out / "tables" / "rejects.parquet"
    back = pl.read_parquet(path).filter(pl.col("reason").str.starts_with(BACKWARDS)) if path.is_file() else None
    rows.append(("follow", "rows_rejected_backwards", float(back.height if back is not None else 0), "rows"))
    return pl.DataFrame(
        rows, schema={"stage": pl.String, "metric": pl.String, "value": pl.Float64, "unit": pl.String}, orient="row"
    )


def read_live_table(live: str | Path, name: str) -> pl.DataFrame | None:
    """Every part of ``OUT/live/tables/<name>/`` in order (``None`` when nothing was published)."""
    parts = sorted((Path(live) / "tables" / name).glob("part-*.parquet"))
    return pl.concat([pl.read_parquet(p) for p in parts]) if parts else None


def follow_report(
    out: Path, live: Path, online: list[str], pub: Publisher, polls: int, batch_only: list[str]
) -> pl.DataFrame:
    rows: list[tuple[str, str, float, str]] = [
        ("follow", "polls", float(polls), "polls"),
        ("follow", "batch_only_trackers", float(len(batch_only)), "trackers"),
    ]
    delays = (
        pl.concat(pub.delays)
        if pub.delays
        else pl.DataFrame(schema={"tracker": pl.String, "t": pl.Float64, "delay_s": pl.Float64})
    )
    for name in online:
        got = read_live_table(live, f"{name}_tracks")
        batch_path = out / "tables" / f"{name}_tracks.parquet"
        batch = pl.read_parquet(batch_path) if batch_path.is_file() else None
        if got is None and batch is None:  # its inputs never appeared (a site without beams, say)
            continue
        rows.append((name, "online_estimates", float(got.height if got is not None else 0), "rows"))
        if batch is not None:
            a = got if got is not None else batch.clear()
            cols = batch.columns
            same = (
                a.select(cols)
                .sort(["track", "t"], maintain_order=True)
                .equals(batch.sort(["track", "t"], maintain_order=True))
            )
            rows.append((name, "online_equals_batch", 1.0 if same else 0.0, "flag"))
            if not same:  # how far apart: rows only one side has, and positions of the rows both have
                key = [c for c in cols if c not in ("x", "y")]
                rows.append(
                    (
                        name,
                        "online_rows_not_in_batch",
                        float(a.join(batch, on=key, how="anti", nulls_equal=True).height),
                        "rows",
                    )
                )
                rows.append(
                    (
                        name,
                        "batch_rows_not_online",
                        float(batch.join(a, on=key, how="anti", nulls_equal=True).height),
                        "rows",
                    )
                )
                both = a.join(batch, on=key, how="inner", nulls_equal=True, suffix="_batch")
                if both.height and "x" in cols:
                    gap = ((pl.col("x") - pl.col("x_batch")) ** 2 + (pl.col("y") - pl.col("y_batch")) ** 2).sqrt()
                    rows.append(
                        (name, "max_position_difference", float(both.select(gap.max()).item() or 0.0), "site units")
                    )
        d = delays.filter(pl.col("tracker") == name)["delay_s"].to_numpy()
        if len(d):
            rows += [
                (name, "delay_p50", float(np.percentile(d, 50)), "s"),
                (name, "delay_p99", float(np.percentile(d, 99)), "s"),
                (name, "delay_max", float(d.max()), "s"),
            ]
    return pl.DataFrame(
        rows, schema={"stage": pl.String, "metric": pl.String, "value": pl.Float64, "unit": pl.String}, orient="row"
    )
