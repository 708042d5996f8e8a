"""Canonical table schemas (see docs/architecture.md, "Canonical tables").

Every table carries ``t: Float64`` = seconds since the dataset epoch, sorted by ``t``.
Readers normalise to these schemas; stages call :func:`check_schema` on entry.
"""

from __future__ import annotations

import polars as pl

from onebit.core.errors import OnebitError

#: Raw directional-beam events: one row per edge of one emitter-detector pair.
BEAM_EVENTS = pl.Schema({"t": pl.Float64, "beam": pl.String, "pair": pl.String, "blocked": pl.Boolean})

#: Decoded beam crossings (+1 forward, -1 backward).
CROSSINGS = pl.Schema({"t": pl.Float64, "beam": pl.String, "direction": pl.Int8})

#: Crossings with the agent that produced them (simulator ground truth, ``truth_crossings.csv``).
TRUE_CROSSINGS = pl.Schema({"t": pl.Float64, "beam": pl.String, "direction": pl.Int8, "target": pl.String})

#: Start-and-return passes the beam state machine recognised (no crossing emitted).
ABORTED = pl.Schema({"t": pl.Float64, "beam": pl.String, "side": pl.Int8})

#: Motion sensors after debounce: one row per accepted edge.
MOTION = pl.Schema({"t": pl.Float64, "sensor": pl.String, "on": pl.Boolean})

#: Motion sampled at a period T for slot-based trackers: ``t`` = slot start, ``on`` = the sensor
#: was on at some time in the slot, ``fired`` = a rising edge (0 -> 1) of the sensor in the slot.
FRAMES = pl.Schema({"slot": pl.Int64, "t": pl.Float64, "sensor": pl.String, "on": pl.Boolean, "fired": pl.Boolean})

#: Binary proximity readings.
PROXIMITY = pl.Schema({"t": pl.Float64, "sensor": pl.String, "on": pl.Boolean})

#: Ground-truth positions; ``region`` / ``node`` filled where the site has them.
TRUTH = pl.Schema(
    {"t": pl.Float64, "target": pl.String, "x": pl.Float64, "y": pl.Float64, "region": pl.String, "node": pl.String}
)

#: Per-event identity truth (CASAS resident annotations, ``truth_events.csv``): which
#: resident(s) caused each firing (ON/OPEN) of a graph sensor; ``residents`` = resident ids
#: sorted as text and joined with ``;`` ("1", "1;2"). ``t`` on the run's time base (as motion).
TRUTH_EVENTS = pl.Schema({"t": pl.Float64, "sensor": pl.String, "residents": pl.String})

#: A residents profile (``residents_profile.csv``, learned by ``onebit learn residents`` from
#: datasets with ``truth_events``): per resident, ``count`` of their consecutive labelled events
#: ``from`` -> ``to`` (sensors); a row with ``from`` null counts the resident's events at ``to``
#: (their habit); a habit row with a ``bin`` (``"session 3/10"``, ``"day 14/24"``) counts them
#: in that part of the session or of the day only (the profile's clock). Read by the
#: ``residents`` tracker (docs/residents.md, "Known residents").
RESIDENTS_PROFILE = pl.Schema(
    {"resident": pl.String, "from": pl.String, "to": pl.String, "count": pl.Float64, "bin": pl.String}
)

#: ``count_profile``: the count model's sufficient statistics from labelled days
#: (:func:`onebit.models.occupancy.stats`): counts per term, count state and key.
COUNT_PROFILE = pl.Schema({"term": pl.String, "state": pl.Int64, "key": pl.String, "count": pl.Float64})

#: ``truth_count``: how many people are in, as intervals [t, end).
TRUTH_COUNT = pl.Schema({"t": pl.Float64, "end": pl.Float64, "count": pl.Int64})

#: ``<tracker>_events``: the track each motion firing (ON edge) was attributed to (null: none).
TRACKER_EVENTS = pl.Schema({"t": pl.Float64, "sensor": pl.String, "track": pl.String})

#: Estimated tracks of every tracker.
TRACKS = pl.Schema(
    {
        "tracker": pl.String,
        "track": pl.String,
        "t": pl.Float64,
        "x": pl.Float64,
        "y": pl.Float64,
        "region": pl.String,
        "node": pl.String,
    }
)

#: Per-sample localisation error of a track against its matched target.
SCORES = pl.Schema(
    {
        "tracker": pl.String,
        "track": pl.String,
        "target": pl.String,
        "t": pl.Float64,
        "error": pl.Float64,
        "hop_error": pl.Int64,
    }
)

#: Every input row a reader did not accept.
REJECTS = pl.Schema({"source": pl.String, "line": pl.Int64, "reason": pl.String, "raw": pl.String})

#: The long-form run report.
REPORT = pl.Schema({"stage": pl.String, "metric": pl.String, "value": pl.Float64, "unit": pl.String})


def empty(schema: pl.Schema) -> pl.DataFrame:
    """An empty frame of ``schema``."""
    return pl.DataFrame(schema=schema)


def conform(df: pl.DataFrame, schema: pl.Schema) -> pl.DataFrame:
    """Select and cast ``df`` to ``schema``, adding absent nullable columns as nulls."""
    exprs = [
        (pl.col(name) if name in df.columns else pl.lit(None)).cast(dtype).alias(name) for name, dtype in schema.items()
    ]
    return df.select(exprs)


def check_schema(df: pl.DataFrame, schema: pl.Schema, *, name: str) -> pl.DataFrame:
    """Raise if ``df`` lacks a column of ``schema`` or has it with another dtype; return ``df``."""
    problems = []
    for col, dtype in schema.items():
        if col not in df.schema:
            problems.append(f"missing column '{col}' ({dtype})")
        elif df.schema[col] != dtype:
            problems.append(f"column '{col}' is {df.schema[col]}, expected {dtype}")
    if problems:
        raise OnebitError(f"table '{name}': " + "; ".join(problems))
    return df


def rejects_frame(rows: list[tuple[str, int | None, str, str | None]]) -> pl.DataFrame:
    """Build a ``rejects`` frame from ``(source, line, reason, raw)`` tuples."""
    return pl.DataFrame(rows, schema=REJECTS, orient="row")
