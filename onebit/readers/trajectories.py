"""Trajectory exports of people counters and indoor-positioning systems -> the ``truth`` table.

Such exports are delimited text with one position per row: a time, a track id, x and y,
under many names and units. :class:`TrajectoryFormat` says how to read one:

* ``delimiter``: ``,`` ``;`` tab ``|`` or a space; ``None`` = the one of these that splits the
  header into the most columns;
* column names ``time``, ``track``, ``x``, ``y`` -- each ``None`` = the first header name found
  among common spellings (:data:`ALIASES`: ``t``/``time``/``timestamp``, ``id``/``track_id``/
  ``person_id``, ``x``/``pos_x``, ...), compared without letter case;
* ``time_unit``: ``s``, ``ms``, ``us``, ``iso`` or ``auto`` (ISO strings are ISO; numbers are
  ``ms`` when their median is above 1e11 -- Unix milliseconds -- else seconds);
* positions: ``x_site = sx * x + ox``, ``y_site = sy * y + oy`` with ``sx = scale`` (``-scale``
  with ``flip_x``), likewise y, and ``swap_xy`` first -- e.g. ``scale = 0.001`` for millimetres
  on a site in metres, ``flip_y`` for image-like axes;
* ``join``: groups of track ids a user knows are one person (a tracker re-identified them
  after an occlusion); every id of a group becomes its first.

:func:`read_trajectories` types every row with polars expressions (no loop over rows). A row
with a missing or unreadable time, id, x or y, or a second position of the same track at
the same time (after joining) goes to ``rejects`` with its line, reason and text. Rows need
not be in time order (exports are often grouped by track): the accepted rows are sorted by
``t``, nothing else is reordered. ``t`` is seconds since the time origin (the data's first
second, or the ``epoch`` given; :mod:`onebit.readers.timebase`); a lone stamp far from the
rest is rejected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from onebit.core.errors import ConfigError, InputError
from onebit.core.tables import REJECTS, TRUTH, conform
from onebit.readers.rows import RawRows, check_rows, make_rejects, parse_float, parse_name, parse_time, raw_lines
from onebit.readers.timebase import TimeOrigin, number, time_origin

#: Header spellings tried for each column (lower case), in order.
ALIASES: dict[str, tuple[str, ...]] = {
    "time": (
        "t",
        "time",
        "timestamp",
        "ts",
        "time_ms",
        "timestamp_ms",
        "datetime",
        "date_time",
        "frame_time",
        "unix_time",
    ),
    "track": (
        "track",
        "target",
        "id",
        "track_id",
        "trackid",
        "person_id",
        "person",
        "object_id",
        "objectid",
        "tid",
        "pid",
        "tag",
    ),
    "x": ("x", "pos_x", "x_m", "x_mm", "position_x", "px"),
    "y": ("y", "pos_y", "y_m", "y_mm", "position_y", "py"),
}
DELIMITERS = (",", ";", "\t", "|", " ")
TIME_UNITS = ("auto", "s", "ms", "us", "iso")
_EXTRA = "__extra__"


@dataclass(frozen=True, kw_only=True)
class TrajectoryFormat:
    """How to read a trajectory export (module docstring); every field has a default."""

    delimiter: str | None = None
    time: str | None = None
    track: str | None = None
    x: str | None = None
    y: str | None = None
    time_unit: str = "auto"
    scale: float = 1.0
    offset: tuple[float, float] = (0.0, 0.0)
    flip_x: bool = False
    flip_y: bool = False
    swap_xy: bool = False
    join: tuple[tuple[str, ...], ...] = ()

    def __post_init__(self) -> None:
        if self.delimiter is not None and (not isinstance(self.delimiter, str) or len(self.delimiter) != 1):
            raise ConfigError(
                f"TrajectoryFormat.delimiter = {self.delimiter!r}; must be one character (',', ';', '\\t', '|', ' ')"
            )
        if self.time_unit not in TIME_UNITS:
            raise ConfigError(f"TrajectoryFormat.time_unit = {self.time_unit!r}; allowed values: {list(TIME_UNITS)}")
        if (
            isinstance(self.scale, bool)
            or not isinstance(self.scale, (int, float))
            or not math.isfinite(self.scale)
            or self.scale == 0
        ):
            raise ConfigError(f"TrajectoryFormat.scale = {self.scale!r}; must be a finite non-zero number")
        off = self.offset
        if not (
            isinstance(off, (list, tuple))
            and len(off) == 2
            and all(isinstance(v, (int, float)) and math.isfinite(v) for v in off)
        ):
            raise ConfigError(f"TrajectoryFormat.offset = {off!r}; must be [dx, dy] (two finite numbers)")
        seen: set[str] = set()
        for group in self.join:
            if len(group) < 2 or not all(isinstance(g, str) and g for g in group):
                raise ConfigError(
                    f"TrajectoryFormat.join: {group!r}; each group needs two or more track ids (e.g. --join a,b)"
                )
            if seen & set(group):
                raise ConfigError(f"TrajectoryFormat.join: id(s) {sorted(seen & set(group))} in two groups")
            seen |= set(group)


@dataclass(frozen=True)
class TrajectoryRead:
    """``truth`` (TRUTH schema, sorted by t), ``rejects``, the time origin and the columns used."""

    truth: pl.DataFrame
    rejects: pl.DataFrame
    origin: TimeOrigin
    columns: dict[str, str]
    time_unit: str
    joined: int  # rows whose id was replaced by --join


def _read_strings(path: Path, delimiter: str | None) -> tuple[list[str], str, pl.DataFrame, pl.DataFrame]:
    """(header, delimiter, rows with ``line``, malformed-row rejects): every field a string."""
    try:
        first = path.read_bytes()[:65536].decode("utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise InputError(f"cannot read trajectory file: {exc.strerror}", file=path) from None
    head = next((ln for ln in first if ln.strip()), None)
    if head is None:
        raise InputError("empty file: no header line", file=path, line=1)
    if delimiter is None:
        delimiter = max(DELIMITERS, key=lambda d: len(head.split(d)) if d != " " else len(head.split()))
    try:
        header = pl.read_csv(path, n_rows=0, infer_schema=False, separator=delimiter, encoding="utf8-lossy").columns
    except (pl.exceptions.PolarsError, OSError) as exc:
        raise InputError(f"cannot read the header: {exc}", file=path, line=1) from None
    header = [h.strip() for h in header]
    names = [f"c{i}" for i in range(len(header))] + [_EXTRA]
    try:
        df = pl.read_csv(
            path,
            has_header=False,
            skip_rows=1,
            separator=delimiter,
            schema={n: pl.String for n in names},
            missing_columns="insert",
            truncate_ragged_lines=True,
            encoding="utf8-lossy",
            quote_char='"',
        )
    except (pl.exceptions.PolarsError, OSError) as exc:
        raise InputError(f"cannot parse the file with delimiter {delimiter!r}: {exc}", file=path) from None
    df = df.with_row_index("line", offset=2).with_columns(pl.col("line").cast(pl.Int64))
    fields = names[:-1]
    df = df.filter(~pl.all_horizontal([pl.col(n).is_null() for n in names]))
    n_fields = pl.sum_horizontal([pl.col(n).is_not_null().cast(pl.Int32) for n in fields])
    reason = (
        pl.when(pl.col(_EXTRA).is_not_null())
        .then(pl.lit(f"too many fields (expected {len(fields)})"))
        .when(pl.col(fields[-1]).is_null() & (n_fields < len(fields)))
        .then(pl.format("too few fields ({} of {})", n_fields, pl.lit(len(fields))))
    )
    df = df.with_columns(reason.alias("_reason"))
    bad = make_rejects(df.filter(pl.col("_reason").is_not_null()), path.name, path)
    good = df.filter(pl.col("_reason").is_null()).drop("_reason", _EXTRA)
    return header, delimiter, good, bad


def _column(header: list[str], wanted: str | None, role: str, path: Path) -> int:
    """Index of the column playing ``role`` (its name, else the first alias present)."""
    low: dict[str, int] = {}
    for i, h in enumerate(header):
        low.setdefault(h.lower(), i)
    if wanted is not None:
        if wanted in header:
            return header.index(wanted)
        if wanted.lower() in low:
            return low[wanted.lower()]
        raise InputError(f"no column {wanted!r}; the header has {header}", file=path, line=1, field=role)
    for a in ALIASES[role]:
        if a in low:
            return low[a]
    raise InputError(
        f"no {role} column among {header}; name it with --{role}-column (tried {list(ALIASES[role])})",
        file=path,
        line=1,
        field=role,
    )


def read_trajectories(
    path: str | Path, fmt: TrajectoryFormat | None = None, *, epoch: str | TimeOrigin | None = None
) -> TrajectoryRead:
    """Read a trajectory export into the ``truth`` table (module docstring)."""
    path = Path(path)
    fmt = fmt or TrajectoryFormat()
    header, _, rows, malformed = _read_strings(path, fmt.delimiter)
    idx = {role: _column(header, getattr(fmt, role), role, path) for role in ("time", "track", "x", "y")}
    cols = {role: header[i] for role, i in idx.items()}
    if len(set(idx.values())) < 4:
        raise InputError(f"one column serves two roles: {cols}", file=path, line=1)
    frame = rows.select(
        "line",
        pl.col(f"c{idx['time']}").alias("t"),
        pl.col(f"c{idx['track']}").alias("target"),
        pl.col(f"c{idx['x']}").alias("x"),
        pl.col(f"c{idx['y']}").alias("y"),
    ).with_columns(raw=pl.lit(None, pl.String))
    unit = fmt.time_unit
    if unit == "auto":
        is_num = frame.select(number(pl.col("t")).is_not_null().sum()).item()
        if is_num * 2 < frame.height:
            unit = "iso"
        else:
            med = frame.select(number(pl.col("t")).median()).item()
            unit = "ms" if med is not None and abs(med) > 1e11 else "s"
    if unit in ("ms", "us"):  # numbers in seconds, as strings: the time base reads them
        div = 1e3 if unit == "ms" else 1e6
        frame = frame.with_columns(
            pl.when(number(pl.col("t")).is_not_null())
            .then((number(pl.col("t")) / div).cast(pl.String))
            .otherwise(pl.col("t"))
            .alias("t")
        )
    origin = (
        epoch if isinstance(epoch, TimeOrigin) else time_origin({path.name: frame.select("line", "t")}, epoch=epoch)
    )
    joined = 0
    if fmt.join:
        mapping = {old: g[0] for g in fmt.join for old in g[1:]}
        tid = pl.col("target").str.strip_chars()
        joined = frame.select(tid.is_in(list(mapping)).sum()).item()
        frame = frame.with_columns(tid.replace(mapping).alias("target"))
    x, xr = parse_float("x")
    y, yr = parse_float("y")
    if fmt.swap_xy:
        x, xr, y, yr = y, yr, x, xr
    sx = -fmt.scale if fmt.flip_x else fmt.scale
    sy = -fmt.scale if fmt.flip_y else fmt.scale
    parsers = {
        "t": parse_time("t", origin, frame),
        "target": parse_name("target", None, "track"),
        "x": (x * sx + fmt.offset[0], xr),
        "y": (y * sy + fmt.offset[1], yr),
    }
    raw = RawRows(path.name, frame, malformed)
    typed = check_rows(raw, parsers, key=("t", "target"), path=path, tolerance=math.inf)
    truth = conform(typed.accepted.sort(["t", "target"], maintain_order=True), TRUTH)
    rejects = typed.rejects.select(REJECTS.names()).cast(dict(REJECTS))
    if rejects.height and rejects["raw"].null_count():  # the text of each rejected line, whatever the suffix
        text = raw_lines(path, rejects["line"].drop_nulls().to_list())
        rejects = rejects.with_columns(
            pl.coalesce(pl.col("raw"), pl.col("line").replace_strict(text, default=None, return_dtype=pl.String)).alias(
                "raw"
            )
        )
    return TrajectoryRead(truth, rejects, origin, cols, unit, joined)
