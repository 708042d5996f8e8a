"""CASAS smart-home event logs (``*.txt``): the field's public format, read into tables.

A CASAS log (Washington State University's smart-home testbeds; see the datasets' README
files) is one sensor event per line::

    2010-11-04 00:03:50.209589<TAB>M003<TAB>ON[<TAB>annotation]

date, time (microseconds optional), sensor id, value and an optional annotation (an
activity label such as ``Sleeping begin``); the fields are separated by tabs or spaces. Ids
say the sensor's kind: ``M###`` (and ``MA###``, area sensors) motion (``ON``/``OFF``),
``D###`` doors (``OPEN``/``CLOSE``), ``T###`` temperature (a number), anything else (lights
``L###``, items ``I###``, analog ``AD1-A``, ...) is ``other``. Times are the home's wall clock
without a zone.

:func:`read_casas` types every line, all at once with polars expressions (no loop over
lines): a line that is not an event (too few fields, a date or time that does not parse, a
motion or door value that is none of the toggle spellings of
:data:`onebit.readers.motion.TOGGLE_VALUES`), a lone time stamp far from the rest
(:mod:`onebit.readers.timebase`), an exact duplicate, or a line more than ``tolerance``
seconds earlier than an accepted line before it goes to ``rejects`` with its line number, its
reason and its text. CASAS logs are up to 0.7 s out of order (sensor clocks, the gateway's
queue): lines less far back are sorted into place and counted (``reordered``). Blank lines
are skipped. Nothing else is dropped: ``events`` + ``rejects`` = the non-blank lines.

Examples
--------
>>> import tempfile, pathlib
>>> import polars as pl
>>> p = pathlib.Path(tempfile.mkdtemp()) / "log.txt"
>>> _ = p.write_text("2010-11-04 00:03:50.2\\tM003\\tON\\tWalk begin\\n2010-11-04 00:03:50\\tD001\\tOPEN\\nbad line\\n")
>>> log = read_casas(p)
>>> log.events.select(pl.col("t").round(6), "sensor", "kind", "on").rows(), log.reordered, log.rejects["line"].to_list()
([(0.0, 'D001', 'door', True), (0.2, 'M003', 'motion', True)], 1, [3])
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.core.tables import REJECTS
from onebit.readers.motion import TOGGLE_VALUES
from onebit.readers.rows import REORDER_TOLERANCE_S, RawRows, check_rows, parse_name, parse_time, physical_lines
from onebit.readers.timebase import TimeOrigin, time_origin

#: Kinds of sensor by id: a regex on the id, in order; the first that matches wins.
KINDS: tuple[tuple[str, str], ...] = (
    ("motion", r"^MA?\d+$"),
    ("door", r"^D\d+$"),
    ("temperature", r"^T\d+$"),
)
OTHER = "other"
#: Kinds whose value is a toggle (written to ``motion.csv`` by the importer).
TOGGLE_KINDS = ("motion", "door")

#: One event line: date, time, sensor, value, optional annotation (tabs or spaces between).
LINE_RE = r"^\s*(\S+)[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)(?:[ \t]+(.*?))?\s*$"
DATE_RE = r"^\d{4}-\d{1,2}-\d{1,2}$"
TIME_RE = r"^\d{1,2}:\d{2}(:\d{2}(\.\d+)?)?$"

#: Schema of :attr:`CasasLog.events`.
EVENTS = pl.Schema(
    {
        "line": pl.Int64,
        "t": pl.Float64,
        "stamp": pl.String,
        "sensor": pl.String,
        "kind": pl.String,
        "value": pl.String,
        "on": pl.Boolean,
        "annotation": pl.String,
    }
)


@dataclass(frozen=True)
class CasasLog:
    """What :func:`read_casas` made of a log.

    events : :data:`EVENTS`, sorted by ``t`` (file order within a stamp); ``on`` is the toggle
        value of motion and door sensors (null for the others), ``stamp`` the text of the time.
    rejects : REJECTS rows (source, line, reason, raw text).
    origin : the time base (``t = 0``): the log's first second, or ``epoch``.
    reordered : events up to ``tolerance`` s out of order, sorted into place.
    lines : non-blank lines read (= events + rejects).
    """

    source: str
    events: pl.DataFrame
    rejects: pl.DataFrame
    origin: TimeOrigin
    reordered: int
    lines: int

    def kind_counts(self) -> dict[str, int]:
        return dict(self.events.group_by("kind").len().sort("kind").iter_rows())


def kind_of(sensor: pl.Expr) -> pl.Expr:
    """The kind of a sensor id (:data:`KINDS`, else ``other``)."""
    expr = pl.when(sensor.is_null()).then(pl.lit(None, pl.String))
    for kind, rx in KINDS:
        expr = expr.when(sensor.str.contains(rx)).then(pl.lit(kind))
    return expr.otherwise(pl.lit(OTHER))


def casas_lines(path: str | Path) -> pl.DataFrame:
    """``(line, text)`` of every non-blank line (1-based numbers; bytes that are not UTF-8 are
    replaced, so a damaged file still reads and its lines are rejected by their content)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read CASAS log: {exc.strerror}", file=path) from None
    # physical lines (split at \n only, as rows.physical_lines does for every log), so a stray
    # \r, form feed or U+2028 inside a line never shifts the line numbers of what follows
    df = physical_lines(data).select("line", pl.col("text").str.replace_all("\x00", "\ufffd", literal=True))
    return df.filter(pl.col("text").str.strip_chars() != "")


def split_lines(lines: pl.DataFrame) -> pl.DataFrame:
    """Fields of each line: date, time, sensor, value, annotation (strings; null if absent)."""
    g = pl.col("text").str.extract_groups(LINE_RE)
    out = lines.with_columns(g.alias("_g")).with_columns(
        date=pl.col("_g").struct.field("1"),
        time=pl.col("_g").struct.field("2"),
        sensor=pl.col("_g").struct.field("3"),
        value=pl.col("_g").struct.field("4"),
        annotation=pl.col("_g").struct.field("5").replace("", None),
        n_fields=pl.col("text").str.strip_chars().str.replace_all(r"\s+", " ").str.split(" ").list.len().cast(pl.Int64),
    )
    return out.drop("_g")


def read_casas(
    path: str | Path,
    *,
    epoch: str | TimeOrigin | None = None,
    tolerance: float = REORDER_TOLERANCE_S,
) -> CasasLog:
    """Read a CASAS log (module docstring). ``epoch``: a run's time origin, an ISO epoch, or
    ``None`` = the log's own first second (floored)."""
    path = Path(path)
    source = path.name
    lines = split_lines(casas_lines(path))
    n_lines = lines.height
    stamp = pl.when(pl.col("date").str.contains(DATE_RE) & pl.col("time").str.contains(TIME_RE)).then(
        pl.concat_str([pl.col("date"), pl.col("time")], separator=" ")
    )
    frame = lines.with_columns(t=stamp, kind=kind_of(pl.col("sensor")), raw=pl.col("text"))
    if isinstance(epoch, TimeOrigin):
        origin = epoch
    else:
        origin = time_origin({source: frame.select("line", "t")}, epoch=epoch)
    t_expr, t_reason = parse_time("t", origin, frame)
    shape = (
        pl.when(pl.col("n_fields") < 4)
        .then(pl.format("too few fields ({} of 4: date, time, sensor, value)", pl.col("n_fields")))
        .when(pl.col("t").is_null())
        .then(pl.format("field 'time': not a date and time YYYY-MM-DD HH:MM:SS[.ffffff]: '{} {}'", pl.col("date"), pl.col("time")))
    )
    key = pl.col("value").str.strip_chars().str.to_lowercase()
    on = key.replace_strict(list(TOGGLE_VALUES), list(TOGGLE_VALUES.values()), default=None, return_dtype=pl.Boolean)
    toggle = pl.col("kind").is_in(list(TOGGLE_KINDS))
    value_reason = pl.when(toggle & on.is_null()).then(
        pl.format("field 'value': '{}' is not a {} value (one of {})", pl.col("value"), pl.col("kind"), pl.lit("|".join(TOGGLE_VALUES)))
    )
    parsers = {
        "t": (t_expr, shape.otherwise(t_reason)),
        "stamp": (pl.col("t"), pl.lit(None, pl.String)),
        "sensor": parse_name("sensor", None, "sensor"),
        "kind": (pl.col("kind"), pl.lit(None, pl.String)),
        "value": (pl.col("value"), value_reason.otherwise(None)),
        "on": (pl.when(toggle).then(on), pl.lit(None, pl.String)),
        "annotation": (pl.col("annotation"), pl.lit(None, pl.String)),
    }
    raw = RawRows(source, frame.select("line", "t", "date", "time", "n_fields", "sensor", "kind", "value", "annotation", "raw"), pl.DataFrame(schema=REJECTS))
    typed = check_rows(raw, parsers, key=("t", "sensor", "value", "annotation"), path=None, tolerance=tolerance)
    events = typed.accepted.select(list(EVENTS)).cast(dict(EVENTS))
    rejects = typed.rejects.select(REJECTS.names()).cast(dict(REJECTS))
    return CasasLog(source, events, rejects, origin, typed.reordered, n_lines)
