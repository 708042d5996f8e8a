"""Frame-sampled binary logs (``frames.csv``) -> the ``levels`` of every sensor at every frame.

A frame log samples every sensor at each frame (a ceiling array read at 2 Hz, a camera-like
occupancy grid), where a toggle log (``motion.csv``) lists state changes only. Three layouts,
told apart by the header:

* **list** -- ``t, active``: one row per frame, ``active`` the ids of the sensors on in that
  frame, separated by spaces, ``;`` or ``|`` (empty: none on)::

      t,active
      0.0,5 6
      0.5,""

* **long** -- ``t, sensor, value``: one row per frame and sensor, ``value`` any toggle
  spelling (``1``/``0``, ``on``/``off``, ...); a sensor not listed in a frame is off in it
  (counted, ``unlisted``);
* **wide** -- ``t, S1, S2, ...``: one row per frame, one 0/1 column per sensor; a sensor of
  the site without a column is off throughout (counted, ``unlisted``).

A frame is one accepted row (list, wide) or one distinct ``t`` (long). Every row goes through
the typed row checks of :mod:`onebit.readers.rows`: a malformed ``t`` or value, an unknown
sensor id (list: the whole frame's row is rejected, never half taken), a duplicate frame (the
same ``t`` twice; long: the same ``t`` and sensor twice) and a row earlier than an accepted
one before it go to ``rejects`` with file, line and reason. A wide header naming an unknown
sensor is an :class:`~onebit.core.errors.InputError` naming the column.

The result is the FRAMES table (``slot, t, sensor, on, fired``) over every frame and every
sensor: ``slot`` the frame's index in time order, ``on`` its reading, ``fired`` a rising edge
(off in the previous frame, or the first frame, and on now). For level sensors (a sensor held
on is presence: :data:`onebit.core.site.SIGNALS`) ``on`` is the reading to use; for edge
sensors ``fired``. :func:`edges_of_levels` turns the levels into the toggle edges (MOTION)
the edge-based trackers read.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError
from onebit.core.tables import FRAMES, MOTION, REJECTS
from onebit.readers.logs import Log, csv_path
from onebit.readers.motion import TOGGLE_VALUES
from onebit.readers.rows import RawRows, check_rows, header_names, parse_choice, parse_time, read_csv_rows
from onebit.readers.timebase import TimeOrigin

LAYOUTS = ("list", "long", "wide")
#: Column of the list layout (``active``; ``sensors`` is read as the same).
LIST_COLUMNS = ("active", "sensors")
#: Separators of the ids in a list layout's ``active`` field.
ID_SEPARATORS = r"[\s;|]+"


@dataclass(frozen=True)
class FrameLog:
    """What :func:`read_frames_csv` / :func:`read_frame_rows` made of a frame log."""

    levels: pl.DataFrame  # FRAMES: every frame x every sensor
    rejects: pl.DataFrame  # REJECTS
    layout: str  # one of LAYOUTS
    frames: int  # accepted frames
    unlisted: int = 0  # (frame, sensor) cells the log did not give, taken as off (long, wide)

    @property
    def period(self) -> float | None:
        """The median gap between consecutive frames (s), ``None`` with fewer than two."""
        t = self.levels["t"].unique().sort()
        return float(t.diff().drop_nulls().median()) if t.len() > 1 else None


def frame_log_layout(header: Sequence[str], *, file: str | Path = "frames.csv", line: int | None = 1) -> str:
    """The layout a header names (module docstring); an :class:`InputError` when it has no ``t``."""
    cols = [c.strip() for c in header]
    if "t" not in cols:
        raise InputError(f"a frame log needs a 't' column; the header has {cols}", file=file, line=line, field="t")
    rest = [c for c in cols if c != "t"]
    if any(c in LIST_COLUMNS for c in rest):
        return "list"
    if "sensor" in rest and "value" in rest:
        return "long"
    return "wide"


def read_frames(log: Log, sensors: Sequence[str], *, epoch: str | TimeOrigin | None = None) -> FrameLog:
    """The frame-log reader: ``frames.csv`` in any layout (:func:`read_frames_csv`) or an MCAP
    ``/frames`` channel's rows, in the list layout (``t``, ``active``)."""
    if isinstance(log, RawRows):
        return read_frame_rows(log, sensors, layout="list", epoch=epoch)
    return read_frames_csv(csv_path(log), sensors, epoch=epoch)


def read_frames_csv(path: str | Path, sensors: Sequence[str], *, epoch: str | TimeOrigin | None = None) -> FrameLog:
    """Read ``frames.csv`` in any layout (module docstring); ``sensors`` are the known ids."""
    path = Path(path)
    header, line = header_names(path)
    if not header:
        return FrameLog(pl.DataFrame(schema=FRAMES), pl.DataFrame(schema=REJECTS), "list", 0)
    layout = frame_log_layout(header, file=path, line=line)
    sensors = tuple(dict.fromkeys(sensors))
    if layout == "list":
        col = next(c for c in header if c.strip() in LIST_COLUMNS)
        raw = read_csv_rows(path, ("t", col))
        if col != "active":
            raw = RawRows(raw.source, raw.frame.rename({col: "active"}), raw.rejects)
        columns: tuple[str, ...] = ()
    elif layout == "long":
        raw = read_csv_rows(path, ("t", "sensor", "value"))
        columns = ()
    else:
        columns = tuple(c for c in header if c.strip() != "t")
        unknown = [c for c in columns if c.strip() not in sensors]
        if unknown:
            raise InputError(
                f"column {unknown[0]!r} is not a sensor of the site (known: {len(sensors)} sensors)",
                file=path,
                line=line,
                field=unknown[0],
            )
        raw = read_csv_rows(path, ("t", *columns))
    return read_frame_rows(raw, sensors, layout=layout, epoch=epoch, path=path, columns=columns)


def read_frame_rows(
    raw: RawRows,
    sensors: Sequence[str],
    *,
    layout: str,
    epoch: str | TimeOrigin | None = None,
    path: Path | None = None,
    columns: tuple[str, ...] = (),
) -> FrameLog:
    """Type and check the string rows of a frame log of ``layout`` (``columns``: a wide log's
    sensor columns) into a :class:`FrameLog`."""
    if layout not in LAYOUTS:
        raise InputError(f"layout {layout!r} is not one of {list(LAYOUTS)}", field="layout")
    sensors = tuple(dict.fromkeys(sensors))
    t_parser = parse_time("t", epoch, raw.frame)
    if layout == "list":
        frame = raw.frame.with_columns(
            _ids=pl.col("active")
            .fill_null("")
            .str.strip_chars()
            .str.replace_all(ID_SEPARATORS, " ")
            .str.split(" ")
            .list.eval(pl.element().filter(pl.element() != ""))
        )
        unknown = pl.col("_ids").list.eval(pl.element().filter(~pl.element().is_in(list(sensors)))).list.first()
        reason = (
            pl.when(unknown.is_not_null())
            .then(pl.format("field 'active': unknown sensor '{}'", unknown))
            .otherwise(None)
        )
        typed = check_rows(
            RawRows(raw.source, frame, raw.rejects),
            {"t": t_parser, "_ids": (pl.col("_ids"), reason)},
            key=("t",),
            path=path,
        )
        ok = typed.accepted
        times = ok.select("t").unique(maintain_order=True)
        on = ok.select("t", pl.col("_ids").alias("sensor")).explode("sensor").drop_nulls("sensor").unique()
        unlisted = 0
    elif layout == "long":
        parsers = {
            "t": t_parser,
            "sensor": _name_parser(sensors),
            "value": parse_choice("value", TOGGLE_VALUES, pl.Boolean, case_insensitive=True),
        }
        typed = check_rows(raw, parsers, key=("t", "sensor"), path=path)
        ok = typed.accepted
        times = ok.select("t").unique(maintain_order=True)
        on = ok.filter("value").select("t", "sensor")
        unlisted = times.height * len(sensors) - ok.height
    else:
        parsers = {"t": t_parser} | {
            c: parse_choice(c, TOGGLE_VALUES, pl.Boolean, case_insensitive=True) for c in columns
        }
        typed = check_rows(raw, parsers, key=("t",), path=path)
        ok = typed.accepted
        times = ok.select("t")
        on = (
            ok.unpivot(index="t", on=list(columns), variable_name="sensor", value_name="value")
            .filter("value")
            .select("t", pl.col("sensor").str.strip_chars())
            if columns
            else pl.DataFrame(schema={"t": pl.Float64, "sensor": pl.String})
        )
        unlisted = times.height * len(set(sensors) - {c.strip() for c in columns})
    levels = levels_table(times["t"], on, sensors)
    return FrameLog(
        levels, typed.rejects.select(REJECTS.names()).cast(dict(REJECTS)), layout, times.height, int(unlisted)
    )


def _name_parser(sensors: tuple[str, ...]) -> tuple[pl.Expr, pl.Expr]:
    s = pl.col("sensor").str.strip_chars()
    reason = (
        pl.when(pl.col("sensor").is_null() | (s == ""))
        .then(pl.lit("field 'sensor': missing"))
        .when(~s.is_in(list(sensors)))
        .then(pl.format("field 'sensor': unknown sensor '{}'", s))
        .otherwise(None)
    )
    return s, reason


def levels_table(times: pl.Series, on: pl.DataFrame, sensors: Sequence[str]) -> pl.DataFrame:
    """FRAMES over the frames at ``times`` x ``sensors`` from the (t, sensor) pairs that are on:
    ``slot`` = the frame's index in time order, ``fired`` = on now and off in the previous
    frame (or the first frame)."""
    sensors = list(dict.fromkeys(sensors))
    t = np.unique(times.cast(pl.Float64).to_numpy())
    n, m = len(t), len(sensors)
    if n == 0 or m == 0:
        return pl.DataFrame(schema=FRAMES)
    grid = np.zeros((n, m), dtype=bool)
    if on.height:
        k = np.searchsorted(t, on["t"].cast(pl.Float64).to_numpy())
        idx = {s: i for i, s in enumerate(sensors)}
        j = np.array([idx[s] for s in on["sensor"].to_list()], dtype=np.int64)
        grid[k, j] = True
    fired = grid & ~np.vstack([np.zeros((1, m), bool), grid[:-1]])
    return pl.DataFrame(
        {
            "slot": np.repeat(np.arange(n, dtype=np.int64), m),
            "t": np.repeat(t, m),
            "sensor": np.tile(np.array(sensors, dtype=object), n).astype(str),
            "on": grid.ravel(),
            "fired": fired.ravel(),
        },
        schema=FRAMES,
    )


def edges_of_levels(levels: pl.DataFrame, sensors: Sequence[str] | None = None) -> pl.DataFrame:
    """The toggle edges (MOTION: t, sensor, on) of FRAMES levels: an on edge at the first frame
    a sensor is on after being off (or at the first frame), an off edge at the first frame it
    is off again; ``sensors`` (default all) picks the sensors. Sorted by ``t``, then sensor order."""
    lv = levels if sensors is None else levels.filter(pl.col("sensor").is_in(list(sensors)))
    prev = pl.col("on").shift(1).over("sensor", order_by="slot").fill_null(False)
    return lv.filter(pl.col("on") != prev).select("t", "sensor", "on").sort("t", maintain_order=True).cast(dict(MOTION))
