"""Readers of already-canonical logs: ``crossings.csv``, ``truth.csv``, ``truth_crossings.csv``."""

from __future__ import annotations

from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.readers.rows import RawRows, csv_header, parse_choice, parse_float, parse_name, parse_time, read_csv_rows, type_rows
from onebit.core.tables import CROSSINGS, TRUE_CROSSINGS, TRUTH, conform

_FLAG = {"0": False, "1": True, "false": False, "true": True}
_DIRECTION = {"1": 1, "+1": 1, "-1": -1, "f": 1, "b": -1, "forward": 1, "backward": -1}


def crossings_from_rows(raw: RawRows, beam_ids, *, epoch=None, path: Path | None = None):
    """Type crossing rows: t, known beam, direction +1|-1. Returns ``(crossings, rejects)``."""
    parsers = {
        "t": parse_time("t", epoch, raw.frame),
        "beam": parse_name("beam", tuple(beam_ids), "beam"),
        "direction": parse_choice("direction", _DIRECTION, pl.Int8),
    }
    ok, rej = type_rows(raw, parsers, key=("t", "beam", "direction"), path=path)
    return conform(ok, CROSSINGS), rej


def true_crossings_from_rows(raw: RawRows, beam_ids, *, epoch=None, path: Path | None = None):
    """Type true-crossing rows; a ``dropped`` column (simulator flag 0|1), when read, is kept."""
    parsers = {
        "t": parse_time("t", epoch, raw.frame),
        "beam": parse_name("beam", tuple(beam_ids), "beam"),
        "direction": parse_choice("direction", _DIRECTION, pl.Int8),
        "target": parse_name("target", None, "target"),
    }
    if "dropped" in raw.frame.columns:
        parsers["dropped"] = parse_choice("dropped", _FLAG, pl.Boolean)
    ok, rej = type_rows(raw, parsers, key=("t", "beam", "direction", "target"), path=path)
    out = conform(ok, TRUE_CROSSINGS)
    return (out.with_columns(ok["dropped"]) if "dropped" in parsers else out), rej


def true_crossings_columns(path: Path) -> tuple[str, ...]:
    """Columns to read from ``truth_crossings.csv``: TRUE_CROSSINGS, plus ``dropped`` if the header has it."""
    base = tuple(TRUE_CROSSINGS.names())
    try:
        header = csv_header(path)[0]
    except InputError:
        return base  # absent or unreadable: read_csv_rows reports it
    return base + ("dropped",) if "dropped" in header else base


def truth_from_rows(raw: RawRows, *, epoch=None, path: Path | None = None):
    """Type truth rows: t, target, x, y (world units). Returns ``(truth, rejects)``.

    Time order is checked per file; a target may appear at most once per time stamp.
    """
    parsers = {
        "t": parse_time("t", epoch, raw.frame),
        "target": parse_name("target", None, "target"),
        "x": parse_float("x"),
        "y": parse_float("y"),
    }
    ok, rej = type_rows(raw, parsers, key=("t", "target"), path=path)
    return conform(ok, TRUTH), rej


def read_crossings_csv(path, beam_ids, *, epoch=None):
    path = Path(path)
    return crossings_from_rows(read_csv_rows(path, ("t", "beam", "direction")), beam_ids, epoch=epoch, path=path)


def read_true_crossings_csv(path, beam_ids, *, epoch=None):
    path = Path(path)
    return true_crossings_from_rows(read_csv_rows(path, ("t", "beam", "direction", "target")), beam_ids, epoch=epoch, path=path)


def read_truth_csv(path, *, epoch=None):
    path = Path(path)
    return truth_from_rows(read_csv_rows(path, ("t", "target", "x", "y")), epoch=epoch, path=path)
