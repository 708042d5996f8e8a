"""Plain references of the readers' fast paths, the tests' oracles (not used by a run):
:func:`proximity_frames_reference` of :func:`onebit.readers.proximity.proximity_frames`,
:func:`separators_per_line_reference` of :func:`onebit.readers.kernels.separators_per_line`,
:func:`line_texts_reference` of the ASCII path of :func:`onebit.readers.linetext.line_texts` and
:func:`block_newlines_reference` of :func:`onebit.readers.linetext.block_newlines`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import polars as pl

from onebit.core.tables import FRAMES, conform
from onebit.readers.lines import _bounds, newlines
from onebit.readers.linetext import _BLOCK
from onebit.readers.proximity import _frame_span


def proximity_frames_reference(
    proximity: pl.DataFrame,
    sensors: Sequence[str],
    *,
    period: float,
    start: float | None = None,
    instants: int | None = None,
) -> pl.DataFrame:
    """:func:`proximity_frames` by polars joins (every instant x sensor, an as-of join backward
    on ``t`` to the edges sorted by stamp in row order): its plain reference and test oracle."""
    sensors = list(dict.fromkeys(sensors))
    ev = (
        proximity.select("t", "sensor", pl.col("on").alias("state"))
        .filter(pl.col("sensor").is_in(sensors))
        .sort("t", maintain_order=True)
    )
    span = _frame_span(ev, sensors, period, start, instants)
    if span is None:
        return pl.DataFrame(schema=FRAMES)
    start, instants = span
    grid = (
        pl.DataFrame({"slot": pl.arange(0, instants, eager=True).cast(pl.Int64)})
        .join(
            pl.DataFrame(
                {"sensor": sensors, "_k": list(range(len(sensors)))}, schema={"sensor": pl.String, "_k": pl.Int64}
            ),
            how="cross",
        )
        .with_columns(t=pl.lit(float(start)) + pl.col("slot").cast(pl.Float64) * period)
        .sort("t")
    )
    out = grid.join_asof(ev, on="t", by="sensor", strategy="backward", check_sortedness=False, tolerance=None)
    out = out.with_columns(on=pl.col("state").fill_null(False)).sort(["slot", "_k"])
    return conform(out, FRAMES)


def separators_per_line_reference(buf: np.ndarray, sep: int) -> np.ndarray:
    """:func:`separators_per_line` with numpy (sorted positions, one ``searchsorted``): its test oracle."""
    nl = np.flatnonzero(buf == 10)
    at = np.flatnonzero(buf == sep)
    before = np.searchsorted(at, np.concatenate([nl, [buf.shape[0]]]), side="left")
    return np.diff(np.concatenate([[0], before])).astype(np.int64)


def line_texts_reference(data: bytes, lines) -> pl.DataFrame:
    """:func:`line_texts` one line at a time (its path for a few lines or text that is not
    ASCII): the test oracle of :func:`_ascii_line_texts`."""
    want = np.unique(np.asarray(lines, dtype=np.int64))
    nl = newlines(data)
    n_lines = nl.size + (len(data) > 0 and not data.endswith(b"\n"))
    want = want[(want >= 1) & (want <= n_lines)]
    starts, ends = _bounds(nl, len(data), want)
    rows = [
        (k, data[s:e].decode("utf-8", errors="replace").removesuffix("\r"))
        for k, s, e in zip(want.tolist(), starts, ends)
    ]
    return pl.DataFrame(
        {"line": [r[0] for r in rows], "text": [r[1] for r in rows], "_reason": [None] * len(rows)},
        schema={"line": pl.Int64, "text": pl.String, "_reason": pl.String},
    )


def block_newlines_reference(buf: np.ndarray) -> np.ndarray:
    """:func:`block_newlines` one block at a time: its test oracle."""
    return np.array(
        [np.count_nonzero(buf[lo : lo + _BLOCK] == 0x0A) for lo in range(0, buf.shape[0], _BLOCK)], dtype=np.uint8
    )
