"""A raw log of a dataset as every reader takes it: its CSV file, or the string rows of its
MCAP channel (:class:`~onebit.readers.rows.RawRows`).

Each log format has one reader, ``read_<format>(log, ...)`` (``read_beams``,
``read_crossings``, ``read_motion``, ``read_frames``, ...), which chooses its path itself: a
CSV file is typed in one read where it can and only the lines that read cannot take go line by
line (:func:`~onebit.readers.rows.read_typed_csv`); an MCAP channel's rows go line by line.
Each log also has one time-origin step, :func:`log_stamps` (or its format's typed version,
:func:`typed_stamps`): its ``t`` stamps, for :func:`~onebit.readers.timebase.time_origin`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TypeAlias

import polars as pl

from onebit.core.errors import InputError
from onebit.readers.rows import RawRows, read_csv_column, read_typed_csv

#: A raw log: the path of its CSV file, or the string rows of its MCAP channel.
Log: TypeAlias = Path | RawRows
#: The stamps of one log for the time origin: a frame of ``line`` and String ``t``, or the
#: frames of a typed read (its good rows' numeric ``t``, its other rows' strings).
Stamps: TypeAlias = pl.DataFrame | list[pl.DataFrame]


def log_name(log: Log) -> str:
    """The log's name in the time origin and in rejects: ``motion.csv``, ``rec.mcap:/motion``."""
    return log.name if isinstance(log, Path) else log.source


def log_stamps(log: Log) -> pl.DataFrame | None:
    """``line`` + String ``t`` of every well-formed row of the log (a CSV typed in one read when
    it can, :func:`~onebit.readers.rows.read_csv_column`; an MCAP channel's rows as they are);
    ``None`` when the CSV's header cannot be read (its reader reports it)."""
    if isinstance(log, RawRows):
        return log.frame
    try:
        return read_csv_column(log, "t")
    except InputError:
        return None


def typed_stamps(log: Log, dtypes: dict[str, pl.DataType] | None) -> Stamps | None:
    """The stamps of a CSV log by the typed read its reader makes (``dtypes``; ``None``: its
    reader will not read it, the stamps alone), so that a log's stamps and its rows agree on
    what a number is; :func:`log_stamps` when that read cannot take the file, or for an MCAP
    channel. An :class:`~onebit.core.errors.InputError` of that read is raised."""
    if isinstance(log, Path) and dtypes:
        split = read_typed_csv(log, dtypes)
        if split is not None:
            return [split.good.select("line", "t"), split.rest.frame.select("line", "t")]
    return log_stamps(log)
