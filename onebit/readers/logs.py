"""A raw log of a dataset as every reader takes it: its CSV file (a :class:`CsvLog`, or a
plain path), or the string rows of its MCAP channel (:class:`~onebit.readers.rows.RawRows`).

Each log format has one reader, ``read_<format>(log, ...)`` (``read_beams``,
``read_crossings``, ``read_motion``, ``read_frames``, ...), which chooses its path itself: a
CSV file is typed in one read where it can and only the lines that read cannot take go line by
line (:func:`~onebit.readers.rows.read_typed_csv`); an MCAP channel's rows go line by line.
Each log also has one time-origin step, :func:`log_stamps` (or its format's typed version,
:func:`typed_stamps`): its ``t`` stamps, for :func:`~onebit.readers.timebase.time_origin`.

**One read per log.** A run's CSV log is one :class:`CsvLog` (``RunContext.log(stem)``
gives the same object all run long), which owns its typed read: the time-origin step reads the
file in its reader's types (:meth:`CsvLog.typed`) and the log keeps that read; the reader then
takes it (:func:`typed_read` -> :meth:`CsvLog.take`), and the log drops it, so its memory
goes with the stage. A kept read is served only for the same types and only while the file's
size and modification time are those it was read at (``onebit follow`` re-reads growing logs):
otherwise, or when nothing was kept (a plain path: tests, users), the reader reads the file
itself. The MCAP rows are in memory already and are taken as they are.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeAlias

import polars as pl

from onebit.core.errors import InputError
from onebit.readers.rows import RawRows, TypedSplit, read_csv_column, read_typed_csv

#: The stamps of one log for the time origin: a frame of ``line`` and String ``t``, or the
#: frames of a typed read (its good rows' numeric ``t``, its other rows' strings).
Stamps: TypeAlias = pl.DataFrame | list[pl.DataFrame]


def _file_state(path: Path) -> tuple[int, int] | None:
    """``(size, mtime_ns)`` of the file, ``None`` when it cannot be looked at."""
    try:
        st = path.stat()
    except OSError:
        return None
    return st.st_size, st.st_mtime_ns


@dataclass(eq=False)
class CsvLog:
    """A dataset's CSV log for one run: its path and, between the time-origin step and its
    reader, the one typed read of it (module docstring, "One read per log"). It is a path
    (``os.PathLike``: ``Path(log)``, ``open(log)``); ``name`` is the file's name."""

    path: Path
    #: the kept read: (its types, the file's (size, mtime_ns) before it, the read); ``None``: none kept
    _kept: tuple[dict[str, pl.DataType], tuple[int, int] | None, TypedSplit | None] | None = field(
        default=None, repr=False
    )

    def __post_init__(self) -> None:
        self.path = Path(self.path)

    @property
    def name(self) -> str:
        return self.path.name

    def __fspath__(self) -> str:
        return os.fspath(self.path)

    def typed(self, dtypes: dict[str, pl.DataType]) -> TypedSplit | None:
        """:func:`~onebit.readers.rows.read_typed_csv` of the file in ``dtypes``, kept for its
        reader (:meth:`take`). The file's state is taken before the read: a file that grows
        during it no longer matches, and its reader reads it anew."""
        state = _file_state(self.path)
        split = read_typed_csv(self.path, dtypes)
        self._kept = (dict(dtypes), state, split)
        return split

    def take(self, dtypes: dict[str, pl.DataType]) -> TypedSplit | None:
        """The typed read of the file in ``dtypes``: the kept one when it was made in these
        types and the file is as it was then, else a new read. Nothing is kept after it."""
        kept, self._kept = self._kept, None
        if kept is not None:
            types, state, split = kept
            if state is not None and types == dtypes and _file_state(self.path) == state:
                return split
        return read_typed_csv(self.path, dtypes)

    @property
    def holds_read(self) -> bool:
        """Whether a typed read is kept (for :meth:`take`)."""
        return self._kept is not None


#: A raw log: its CSV file (a :class:`CsvLog`, or a plain path), or the string rows of its MCAP channel.
Log: TypeAlias = CsvLog | Path | RawRows


def csv_path(log: CsvLog | str | Path) -> Path:
    """The path of a CSV log (a :class:`CsvLog` or a path)."""
    return log.path if isinstance(log, CsvLog) else Path(log)


def typed_read(log: CsvLog | str | Path, dtypes: dict[str, pl.DataType]) -> TypedSplit | None:
    """A reader's typed read of its CSV log: the one its :class:`CsvLog` kept from the time-origin
    step (:meth:`CsvLog.take`), else :func:`~onebit.readers.rows.read_typed_csv` of the file."""
    if isinstance(log, CsvLog):
        return log.take(dtypes)
    return read_typed_csv(log, dtypes)


def log_name(log: Log) -> str:
    """The log's name in the time origin and in rejects: ``motion.csv``, ``rec.mcap:/motion``."""
    return log.source if isinstance(log, RawRows) else csv_path(log).name


def log_stamps(log: Log) -> pl.DataFrame | None:
    """``line`` + String ``t`` of every well-formed row of the log (a CSV typed in one read when
    it can, :func:`~onebit.readers.rows.read_csv_column`; an MCAP channel's rows as they are);
    ``None`` when the CSV's header cannot be read (its reader reports it)."""
    if isinstance(log, RawRows):
        return log.frame
    try:
        return read_csv_column(csv_path(log), "t")
    except InputError:
        return None


def typed_stamps(log: Log, dtypes: dict[str, pl.DataType] | None, *, keep: bool = True) -> Stamps | None:
    """The stamps of a CSV log by the typed read its reader makes (``dtypes``; ``None``: its
    reader will not read it, the stamps alone), so that a log's stamps and its rows agree on
    what a number is; :func:`log_stamps` when that read cannot take the file, or for an MCAP
    channel. A :class:`CsvLog` keeps the read for its reader (:meth:`CsvLog.typed`) unless
    ``keep`` is false (its reader will not run). An :class:`~onebit.core.errors.InputError` of
    that read is raised."""
    if not isinstance(log, RawRows) and dtypes:
        split = log.typed(dtypes) if keep and isinstance(log, CsvLog) else read_typed_csv(csv_path(log), dtypes)
        if split is not None:
            return [split.good.select("line", "t"), split.rest.frame.select("line", "t")]
    return log_stamps(log)
