"""CASAS smart-home event logs: the field's public formats, read into tables.

A CASAS log (Washington State University's smart-home testbeds; see the datasets' README
files) is one sensor event per line. The variants written in the field, all read here:

``2010-11-04 00:03:50.209589<TAB>M003<TAB>ON``
    date and time in two fields (tabs or spaces between any fields);
``2010-11-04T00:03:50.209589 M003 ON``
    date and time in one field (``T`` or ``_`` between them; a zone ``Z``/``+02:00`` may
    follow: the stamp is then converted to UTC);
``2008-11-10<TAB>14:28:17.986759<TAB>M22<TAB>ON 2 2`` / ``... M17 OFF 2 7 1 6``
    the value followed by resident/task annotation pairs, once or twice (the ADL
    multi-resident sessions: "the most likely resident that triggered the sensor event and
    the most likely task"); read into ``residents`` ("1", or "1;2" when two pairs name two
    residents: ids sorted as text and joined with ``;``) and ``tasks`` (in pair order);
``... M003 ON Sleeping begin`` / ``... M003 ON Meal_Preparation="end"``
    an activity label, read into ``activity`` and ``activity_edge`` (``begin``/``end``, else
    null) -- numbers before a label are resident/task pairs as above;
``2011-06-15 08:00:01.5 Bedroom Bedroom ON Sleep``
    a *named* sensor: the name once or twice before the value (``M021 Bedroom Bedroom ON``,
    an id then its location written twice, also reads: ``location`` = Bedroom);
``events.csv`` (pymrt / pyActLearn style, :func:`read_casas_csv`)
    ``time,sensor,message,residents,activity`` with the time zone in the stamp
    (``2009-06-10 03:20:59.087874-07:00``), residents separated by ``;``; a header naming
    the columns, or none (then in that order; the last two may be absent).

Kinds of sensor
---------------
A sensor's kind comes from, in order: the ``kinds`` mapping (a layout file; the only way a
contact becomes an entry/exit ``door``); a CASAS id (``M###``/``MA###`` motion, ``D###``
``contact`` -- cupboards, appliances and doors alike: the log cannot tell them apart --,
``T###`` temperature, ``I###`` item, ``L###`` light; any other ``X###`` id is ``other``);
for a named sensor (``Bedroom``) the values it takes: mostly ``ON``/``OFF`` motion,
``OPEN``/``CLOSE`` contact, ``PRESENT``/``ABSENT`` item, numbers ``analog``, else ``other``.
A motion, contact, door or item value that is none of the toggle spellings of
:data:`onebit.readers.motion.TOGGLE_VALUES` is a reject, never a silent reclassification.

Rejects
-------
:func:`read_casas` types every line at once with polars expressions (no loop over lines): a
line that is not an event (too few fields, a date or time that does not parse, a toggle
value that is not one), a lone time stamp far from the rest (:mod:`onebit.readers.timebase`),
an exact duplicate, or a line more than ``tolerance`` seconds earlier than an accepted line
before it goes to ``rejects`` with its line number, its reason and its text. CASAS logs are
up to 0.7 s out of order: lines less far back are sorted into place and counted
(``reordered``). Blank lines are skipped. ``events`` + ``rejects`` = the non-blank lines. An
event whose annotation cannot be read (``OFF 211``: an odd count of resident/task numbers) is
kept without residents, and the annotation is listed in ``annotation_problems`` with its
reason (the event itself is sound).

Lost OFFs
---------
:func:`repair_lost_offs` (used by ``onebit import casas``): CASAS logs lose edges; a
repeated ``ON`` (``OPEN``) means the ``OFF`` between was lost. Rule, per toggle sensor: its
*hold time* ``h`` is the median of its on-durations (``ON`` followed by ``OFF``), when it has
at least ``min_samples`` of them, else ``default_hold_s``. A repeated ON more than ``h``
after the previous ON gets an OFF inserted at ``t_prev + h`` (counted in ``repairs``); a
repeated ON within ``h`` is a re-trigger while on and is left alone (the motion reader
counts it as a repeat).

Examples
--------
>>> import tempfile, pathlib
>>> import polars as pl
>>> p = pathlib.Path(tempfile.mkdtemp()) / "log.txt"
>>> _ = p.write_text("2010-11-04 00:03:50.2\\tM003\\tON 1 4 2 7\\n2010-11-04 00:03:50\\tD001\\tOPEN\\nbad line\\n")
>>> log = read_casas(p)
>>> log.events.select(pl.col("t").round(6), "sensor", "kind", "on", "residents").rows(), log.reordered, log.rejects["line"].to_list()
([(0.0, 'D001', 'contact', True, None), (0.2, 'M003', 'motion', True, '1;2')], 1, [3])
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError
from onebit.core.tables import REJECTS
from onebit.readers.motion import TOGGLE_VALUES
from onebit.readers.rows import (
    MAX_MALFORMED_LINES,
    REORDER_TOLERANCE_S,
    RawRows,
    check_line_lengths,
    check_rows,
    check_text,
    csv_header,
    file_spans,
    parse_name,
    parse_time,
    physical_lines,
    rows_of_lines,
)
from onebit.readers.timebase import TimeOrigin, time_origin

#: Kinds of sensor by CASAS id: a regex on the id, in order; the first that matches wins.
KINDS: tuple[tuple[str, str], ...] = (
    ("motion", r"^MA?\d+$"),
    ("contact", r"^D\d+$"),
    ("temperature", r"^T\d+$"),
    ("item", r"^I\d+$"),
    ("light", r"^L[A-Z]?\d+$"),
)
#: A CASAS sensor id (letters then digits, an optional ``-X`` suffix: ``AD1-A``); ids that are
#: not are *named* sensors, whose kind comes from their values.
CASAS_ID = r"^[A-Z]{1,3}\d+(?:-[A-Za-z0-9]+)?$"
OTHER = "other"
#: Every kind a layout may name.
ALL_KINDS = ("motion", "contact", "door", "temperature", "item", "light", "analog", OTHER)
#: Kinds whose value is a toggle (on/off): checked against the toggle spellings.
VALUED_TOGGLES = ("motion", "contact", "door", "item")
#: Kinds written to ``motion.csv`` by the importer: the nodes of the sensor graph.
TOGGLE_KINDS = ("motion", "contact", "door")
#: Toggle spellings by family, for the kind of a named sensor.
_FAMILIES = {
    "motion": ("on", "off", "1", "0", "true", "false"),
    "contact": ("open", "close", "closed"),
    "item": ("present", "absent"),
}

#: The date and time, in one field or two, and the rest of the line.
DATETIME_RE = r"^\s*(\d{4}-\d{1,2}-\d{1,2})(?:[ \t]+|[Tt_])(\d{1,2}:\d{2}(?::\d{2}(?:\.\d+)?)?)((?:[Zz]|[+-]\d{2}:?\d{2})?)(?:[ \t]+(.*?))?\s*$"
_NUMBER_RE = r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$"
_PAIRS_RE = r"^((?:\d+\s+)*\d+)(?:\s+(.*))?$"
_LABEL_RE = r'^(.*?)(?:[ _=]+"?(?i:(begin|end))"?)$'

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
        "residents": pl.String,
        "tasks": pl.String,
        "activity": pl.String,
        "activity_edge": pl.String,
        "location": pl.String,
    }
)

#: Schema of :func:`repair_lost_offs`' ``repairs`` table.
REPAIRS = pl.Schema(
    {
        "sensor": pl.String,
        "t_on": pl.Float64,
        "t_off": pl.Float64,
        "t_next_on": pl.Float64,
        "hold_s": pl.Float64,
        "hold_from": pl.String,
        "line": pl.Int64,
    }
)


@dataclass(frozen=True)
class CasasLog:
    """What :func:`read_casas` made of a log.

    events : :data:`EVENTS`, sorted by ``t`` (file order within a stamp); ``on`` is the toggle
        value of motion, contact, door and item sensors (null for the others), ``stamp`` the
        text of the time.
    rejects : REJECTS rows (source, line, reason, raw text).
    origin : the time base (``t = 0``): the log's first second, or ``epoch``.
    reordered : events up to ``tolerance`` s out of order, sorted into place.
    lines : non-blank lines read (= events + rejects).
    annotation_problems : REJECTS rows of events kept whose annotation could not be read.
    """

    source: str
    events: pl.DataFrame
    rejects: pl.DataFrame
    origin: TimeOrigin
    reordered: int
    lines: int
    annotation_problems: pl.DataFrame = None  # type: ignore[assignment]

    def kind_counts(self) -> dict[str, int]:
        return dict(self.events.group_by("kind").len().sort("kind").iter_rows())


def kind_of(sensor: pl.Expr) -> pl.Expr:
    """The kind of a CASAS sensor id (:data:`KINDS`; ``other`` for another CASAS id; null for a
    named sensor, whose kind comes from its values)."""
    expr = pl.when(sensor.is_null()).then(pl.lit(None, pl.String))
    for kind, rx in KINDS:
        expr = expr.when(sensor.str.contains(rx)).then(pl.lit(kind))
    return expr.when(sensor.str.contains(CASAS_ID)).then(pl.lit(OTHER)).otherwise(pl.lit(None, pl.String))


def casas_lines(path: str | Path) -> pl.DataFrame:
    """``(line, text)`` of every non-blank line (1-based numbers; bytes that are not UTF-8 are
    replaced, so a damaged file still reads and its lines are rejected by their content)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read CASAS log: {exc.strerror}", file=path) from None
    check_line_lengths(data, path)  # bounded memory: no 200 MB line, no binary file split into lines
    check_text(data, path)
    count, first = undated_lines(data)
    if count > MAX_MALFORMED_LINES:  # each would be a reject holding its text
        raise InputError(
            f"{count} lines do not start with a date (this is the first), more than the "
            f"{MAX_MALFORMED_LINES} a log may have rejected: is this a CASAS log?",
            file=path,
            line=first,
        )
    # physical lines (split at \n only, as rows.physical_lines does for every log), so a stray
    # \r, form feed or U+2028 inside a line never shifts the line numbers of what follows
    df = physical_lines(data).select("line", pl.col("text").str.replace_all("\x00", "\ufffd", literal=True))
    del data
    return df.filter(pl.col("text").str.strip_chars() != "")


def undated_lines(data: bytes) -> tuple[int, int | None]:
    """Lines of a CASAS log that surely do not start with a date: their first byte is not a
    space, a tab or a line end, and they do not start ``dddd-``. Returns their count and the
    first one's number; scans the bytes a span at a time (numpy, bounded temporaries)."""
    count, first, line0 = 0, None, 1
    for lo, hi in file_spans(data):
        block = np.frombuffer(data, dtype=np.uint8, count=hi - lo, offset=lo)
        nl = np.flatnonzero(block == 0x0A)
        starts = np.r_[0, nl + 1]
        starts = starts[starts < block.size]
        padded = np.concatenate([block, np.zeros(5, dtype=np.uint8)])
        head = padded[starts[:, None] + np.arange(5)]
        digits = (head[:, :4] >= ord("0")) & (head[:, :4] <= ord("9"))
        dated = digits.all(axis=1) & (head[:, 4] == ord("-"))
        blank_or_indented = np.isin(head[:, 0], np.array([0x20, 0x09, 0x0D, 0x0A], dtype=np.uint8))
        bad = np.flatnonzero(~dated & ~blank_or_indented)
        if bad.size:
            count += int(bad.size)
            first = first if first is not None else line0 + int(bad[0])
        line0 += int(nl.size)
    return count, first


def split_lines(lines: pl.DataFrame) -> pl.DataFrame:
    """Fields of each text line: date, time, zone, sensor, location, value, annotation (strings;
    null if absent), ``n_fields`` (whitespace-separated tokens of the line) and
    ``datetime_ok`` (the line starts with a date and time)."""
    g = pl.col("text").str.extract_groups(DATETIME_RE)
    tokens = pl.col("text").str.strip_chars().str.replace_all(r"[ \t]+", " ")
    out = lines.with_columns(
        g.alias("_g"), tokens.str.split(" ").list.len().cast(pl.Int64).alias("n_fields")
    ).with_columns(
        date=pl.col("_g").struct.field("1"),
        time=pl.col("_g").struct.field("2"),
        zone=pl.col("_g").struct.field("3"),
        _rest=pl.col("_g").struct.field("4").str.replace_all(r"[ \t]+", " ").str.split(" "),
    )
    tok = pl.col("_rest")
    t0, t1, t2 = (tok.list.get(i, null_on_oob=True) for i in range(3))
    value_like = t1.str.to_lowercase().is_in(list(TOGGLE_VALUES)) | t1.str.contains(_NUMBER_RE)
    # the value's index in the rest: after the name written twice, or an id and its location twice
    at = pl.when(t1 == t0).then(2).when((t1 == t2) & ~value_like).then(3).otherwise(1)
    out = out.with_columns(_at=at).with_columns(
        sensor=t0,
        location=pl.when(pl.col("_at") == 3).then(t1),
        value=tok.list.get(pl.col("_at"), null_on_oob=True),
        annotation=tok.list.slice(pl.col("_at") + 1).list.join(" ").replace("", None),
    )
    return out.drop("_g", "_rest", "_at")


def _annotation_fields(frame: pl.DataFrame) -> pl.DataFrame:
    """``residents``, ``tasks``, ``activity``, ``activity_edge`` and ``_note_reason`` from
    ``annotation`` (module docstring); ``residents_in`` (pymrt's column), when present, wins."""
    ann = pl.col("annotation").str.strip_chars()
    pairs = ann.str.extract_groups(_PAIRS_RE)
    out = frame.with_columns(_p=pairs).with_columns(
        _nums=pl.col("_p").struct.field("1").str.split(" "),
        _label=pl.when(pl.col("_p").struct.field("1").is_null())
        .then(ann)
        .otherwise(pl.col("_p").struct.field("2"))
        .str.strip_chars()
        .replace("", None),
    )
    n = pl.col("_nums").list.len()
    odd = pl.col("_nums").is_not_null() & (n % 2 == 1)
    res = pl.col("_nums").list.gather_every(2).list.unique().list.sort().list.join(";")
    tasks = pl.col("_nums").list.gather_every(2, offset=1).list.join(";")
    lab = pl.col("_label").str.extract_groups(_LABEL_RE)
    out = out.with_columns(
        residents=pl.when(~odd).then(res),
        tasks=pl.when(~odd).then(tasks),
        _note_reason=pl.when(odd).then(
            pl.format(
                "annotation '{}': {} number(s), not resident/task pairs; the event is kept without residents", ann, n
            )
        ),
        activity=pl.coalesce(lab.struct.field("1").str.strip_chars().replace("", None), pl.col("_label")),
        activity_edge=lab.struct.field("2").str.to_lowercase(),
    )
    if "residents_in" in out.columns:
        given = (
            pl.col("residents_in")
            .str.strip_chars()
            .str.split(";")
            .list.eval(pl.element().str.strip_chars())
            .list.filter(pl.element() != "")
        )
        joined = given.list.unique().list.sort().list.join(";").replace("", None)
        out = out.with_columns(residents=pl.coalesce(joined, "residents"))
    return out.drop("_p", "_nums", "_label")


def _named_kinds(frame: pl.DataFrame) -> pl.DataFrame:
    """``sensor -> kind`` of the named sensors (kind null) from the values they take: the family
    (:data:`_FAMILIES`, or numbers: ``analog``) most of their values belong to, else ``other``."""
    named = frame.filter(pl.col("kind").is_null() & pl.col("sensor").is_not_null() & pl.col("value").is_not_null())
    if named.height == 0:
        return pl.DataFrame(schema={"sensor": pl.String, "_named": pl.String})
    v = pl.col("value").str.strip_chars().str.to_lowercase()
    fam = pl.lit(None, pl.String)
    expr = pl.when(v.str.contains(_NUMBER_RE) & ~v.is_in(["0", "1"])).then(pl.lit("analog"))
    for kind, spellings in _FAMILIES.items():
        expr = expr.when(v.is_in(list(spellings))).then(pl.lit(kind))
    fam = expr.otherwise(pl.lit(OTHER))
    counts = named.group_by("sensor", fam.alias("_named")).len()
    best = (
        counts.sort(["sensor", "len", "_named"], descending=[False, True, False])
        .group_by("sensor", maintain_order=True)
        .first()
    )
    return best.select("sensor", "_named")


def _type_events(
    frame: pl.DataFrame,
    source: str,
    *,
    epoch: str | TimeOrigin | None,
    tolerance: float,
    kinds: dict[str, str] | None,
    shape: pl.Expr,
    n_lines: int,
) -> CasasLog:
    """Kinds, values, annotations, time; then :func:`check_rows` (shared by both formats).
    ``frame``: line, raw, date, time, zone, sensor, location, value, annotation[, residents_in];
    ``shape``: the reason a line is not an event (null where it is one)."""
    stamp = pl.when(pl.col("date").is_not_null() & pl.col("time").is_not_null()).then(
        pl.concat_str([pl.col("date"), pl.lit(" "), pl.col("time"), pl.col("zone").fill_null("")])
    )
    frame = frame.with_columns(t=stamp, kind=kind_of(pl.col("sensor")), _shape=shape)
    named = _named_kinds(frame)
    frame = frame.join(named, on="sensor", how="left").with_columns(kind=pl.coalesce("kind", "_named")).drop("_named")
    if kinds:
        k = pl.DataFrame(
            {"sensor": list(kinds), "_layout": list(kinds.values())}, schema={"sensor": pl.String, "_layout": pl.String}
        )
        frame = frame.join(k, on="sensor", how="left").with_columns(kind=pl.coalesce("_layout", "kind")).drop("_layout")
    frame = _annotation_fields(frame.with_columns(pl.col("kind").fill_null(OTHER)))
    if isinstance(epoch, TimeOrigin):
        origin = epoch
    else:
        origin = time_origin({source: frame.filter(pl.col("_shape").is_null()).select("line", "t")}, epoch=epoch)
    t_expr, t_reason = parse_time("t", origin, frame)
    key = pl.col("value").str.strip_chars().str.to_lowercase()
    on = key.replace_strict(list(TOGGLE_VALUES), list(TOGGLE_VALUES.values()), default=None, return_dtype=pl.Boolean)
    toggle = pl.col("kind").is_in(list(VALUED_TOGGLES))
    value_reason = (
        pl.when(pl.col("value").is_null())
        .then(pl.lit("field 'value': missing"))
        .when(toggle & on.is_null())
        .then(
            pl.format(
                "field 'value': '{}' is not a {} value (one of {})",
                pl.col("value"),
                pl.col("kind"),
                pl.lit("|".join(TOGGLE_VALUES)),
            )
        )
    )
    parsers = {
        "t": (t_expr, pl.coalesce(pl.col("_shape"), t_reason)),
        "stamp": (pl.col("t"), pl.lit(None, pl.String)),
        "sensor": parse_name("sensor", None, "sensor"),
        "kind": (pl.col("kind"), pl.lit(None, pl.String)),
        "value": (pl.col("value"), value_reason.otherwise(None)),
        "on": (pl.when(toggle).then(on), pl.lit(None, pl.String)),
        **{
            c: (pl.col(c), pl.lit(None, pl.String))
            for c in (
                "annotation",
                "residents",
                "tasks",
                "activity",
                "activity_edge",
                "location",
                "_note_reason",
                "raw",
            )
        },
    }
    keep = [
        "line",
        "t",
        "date",
        "time",
        "sensor",
        "kind",
        "value",
        "annotation",
        "residents",
        "tasks",
        "activity",
        "activity_edge",
        "location",
        "_note_reason",
        "_shape",
        "raw",
    ]
    raw = RawRows(source, frame.select(keep), pl.DataFrame(schema=REJECTS))
    typed = check_rows(raw, parsers, key=("t", "sensor", "value", "annotation"), path=None, tolerance=tolerance)
    acc = typed.accepted
    notes = acc.filter(pl.col("_note_reason").is_not_null())
    problems = notes.select(pl.lit(source).alias("source"), "line", pl.col("_note_reason").alias("reason"), "raw")
    events = acc.select(list(EVENTS)).cast(dict(EVENTS))
    rejects = typed.rejects.select(REJECTS.names()).cast(dict(REJECTS))
    return CasasLog(source, events, rejects, origin, typed.reordered, n_lines, problems.cast(dict(REJECTS)))


def read_casas(
    path: str | Path,
    *,
    epoch: str | TimeOrigin | None = None,
    tolerance: float = REORDER_TOLERANCE_S,
    kinds: dict[str, str] | None = None,
) -> CasasLog:
    """Read a CASAS log (module docstring): the text format, or a pymrt ``events.csv`` (a
    ``.csv`` file: :func:`read_casas_csv`). ``epoch``: a run's time origin, an ISO epoch, or
    ``None`` = the log's own first second (floored). ``kinds``: sensor id -> kind (a layout's),
    overriding the kinds found from ids and values."""
    path = Path(path)
    if path.suffix.lower() == ".csv":
        return read_casas_csv(path, epoch=epoch, tolerance=tolerance, kinds=kinds)
    lines = split_lines(casas_lines(path))
    frame = lines.with_columns(raw=pl.col("text"))
    shape = (
        pl.when(pl.col("date").is_null())
        .then(
            pl.when(pl.col("n_fields") < 3)
            .then(pl.format("too few fields ({} of at least 3: date and time, sensor, value)", pl.col("n_fields")))
            .otherwise(pl.lit("field 'time': not a date and time YYYY-MM-DD HH:MM:SS[.ffffff] (one field or two)"))
        )
        .when(pl.col("sensor").is_null() | pl.col("value").is_null())
        .then(pl.lit("too few fields: a sensor and its value must follow the date and time"))
    )
    return _type_events(
        frame, path.name, epoch=epoch, tolerance=tolerance, kinds=kinds, shape=shape, n_lines=lines.height
    )


#: Header names of a pymrt ``events.csv`` column (lower case), by the column they fill.
CSV_COLUMNS = {
    "time": ("time", "datetime", "timestamp", "date_time", "stamp"),
    "sensor": ("sensor", "sensor_id", "id"),
    "message": ("message", "value", "state", "msg"),
    "residents": ("residents", "resident", "resident_id"),
    "activity": ("activity", "activities", "label"),
}


def read_casas_csv(
    path: str | Path,
    *,
    epoch: str | TimeOrigin | None = None,
    tolerance: float = REORDER_TOLERANCE_S,
    kinds: dict[str, str] | None = None,
) -> CasasLog:
    """A pymrt / pyActLearn ``events.csv`` (module docstring): ``time`` (ISO, with a zone:
    converted to UTC), ``sensor``, ``message``, ``residents`` (``R1;R2``), ``activity``.
    With a header its names pick the columns (:data:`CSV_COLUMNS`, any case, any order); a
    file whose first line starts with a date and time has none: the columns are positional."""
    path = Path(path)
    header, header_line, body = csv_header(path)
    source = path.name
    if not header:
        empty = pl.DataFrame(schema={"line": pl.Int64, "text": pl.String, "_reason": pl.String})
        body = empty
    headerless = bool(header) and bool(pl.Series([header[0]]).str.contains(r"^\d{4}-\d{1,2}-\d{1,2}[ Tt_]\d").item())
    if headerless:
        names = ["time", "sensor", "message", "residents", "activity"][: max(3, min(5, len(header)))]
        head_row = physical_lines(path.read_bytes()).filter(pl.col("line") == header_line)
        body = pl.concat([head_row.select("line", "text", "_reason"), body.select("line", "text", "_reason")])
        header = names
        columns = tuple(names)
    else:
        low = [h.lower() for h in header]
        rename = {}
        for col, spellings in CSV_COLUMNS.items():
            hit = next((header[low.index(s)] for s in spellings if s in low), None)
            if hit is not None:
                rename[hit] = col
        for need in ("time", "sensor", "message"):
            if need not in rename.values():
                raise InputError(
                    f"no '{need}' column; the header has {header} (expected names: {list(CSV_COLUMNS[need])})",
                    file=path,
                    line=header_line,
                )
        header = [rename.get(h, f"_unused{i}") for i, h in enumerate(header)]
        columns = tuple(c for c in CSV_COLUMNS if c in header)
    rows = (
        rows_of_lines(body, header, columns, source)
        if body.height
        else RawRows(
            source, pl.DataFrame(schema={c: pl.String for c in ("line", *columns, "raw")}), pl.DataFrame(schema=REJECTS)
        )
    )
    f = rows.frame.with_columns(pl.col("line").cast(pl.Int64))
    dt = (
        pl.col("time")
        .str.strip_chars()
        .str.extract_groups(
            r"^(\d{4}-\d{1,2}-\d{1,2})[ Tt_](\d{1,2}:\d{2}(?::\d{2}(?:\.\d+)?)?)((?:[Zz]|[+-]\d{2}:?\d{2})?)$"
        )
    )
    frame = (
        f.with_columns(_g=dt)
        .with_columns(
            date=pl.col("_g").struct.field("1"),
            time=pl.col("_g").struct.field("2"),
            zone=pl.col("_g").struct.field("3"),
            sensor=pl.col("sensor").str.strip_chars().replace("", None),
            location=pl.lit(None, pl.String),
            value=pl.col("message").str.strip_chars().replace("", None),
            annotation=(
                pl.col("activity").str.strip_chars().replace("", None)
                if "activity" in columns
                else pl.lit(None, pl.String)
            ),
            residents_in=(pl.col("residents") if "residents" in columns else pl.lit(None, pl.String)),
            _time_text=pl.col("time"),
        )
        .drop("_g")
    )
    shape = (
        pl.when(pl.col("date").is_null())
        .then(
            pl.format(
                "field 'time': not a date and time YYYY-MM-DD HH:MM:SS[.ffffff][+HH:MM]: '{}'", pl.col("_time_text")
            )
        )
        .when(pl.col("sensor").is_null())
        .then(pl.lit("field 'sensor': missing"))
    )
    log = _type_events(frame, source, epoch=epoch, tolerance=tolerance, kinds=kinds, shape=shape, n_lines=body.height)
    if rows.rejects.height:
        rej = pl.concat([log.rejects, rows.rejects.select(REJECTS.names()).cast(dict(REJECTS))]).sort("line")
        log = CasasLog(log.source, log.events, rej, log.origin, log.reordered, log.lines, log.annotation_problems)
    return log


# --------------------------------------------------------------------------- lost OFFs

#: Hold time (s) of a toggle sensor with too few on-durations to learn its own.
DEFAULT_HOLD_S = 5.0
#: On-durations a sensor needs for its own hold time.
MIN_HOLD_SAMPLES = 5


def hold_times(
    events: pl.DataFrame, *, default_hold_s: float = DEFAULT_HOLD_S, min_samples: int = MIN_HOLD_SAMPLES
) -> pl.DataFrame:
    """``sensor, hold_s, samples, hold_from`` of every sensor of ``events`` (t, sensor, on;
    toggles only): the median on-duration (``ON`` then ``OFF``) of the sensor when it has at
    least ``min_samples``, else ``default_hold_s`` (``hold_from`` says which)."""
    ev = events.filter(pl.col("on").is_not_null()).sort("sensor", "t", maintain_order=True)
    prev_on = pl.col("on").shift(1).over("sensor")
    dur = ev.with_columns(d=(pl.col("t") - pl.col("t").shift(1).over("sensor"))).filter(
        ~pl.col("on") & prev_on.fill_null(False)
    )
    stats = dur.group_by("sensor").agg(samples=pl.len().cast(pl.Int64), med=pl.col("d").median())
    sensors = ev.select("sensor").unique()
    out = sensors.join(stats, on="sensor", how="left").with_columns(pl.col("samples").fill_null(0))
    own = pl.col("samples") >= min_samples
    return out.select(
        "sensor",
        pl.when(own).then(pl.col("med")).otherwise(pl.lit(float(default_hold_s))).alias("hold_s"),
        "samples",
        pl.when(own).then(pl.lit("median on-duration")).otherwise(pl.lit("default")).alias("hold_from"),
    ).sort("sensor")


def repair_lost_offs(
    events: pl.DataFrame, *, default_hold_s: float = DEFAULT_HOLD_S, min_samples: int = MIN_HOLD_SAMPLES
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """Insert the OFFs a log lost (module docstring, "Lost OFFs").

    ``events``: at least t, sensor, on (toggle sensors; others pass through untouched), sorted
    by t. Returns ``(events with the inserted OFF rows, repairs)``; an inserted row has
    ``on = False``, ``value = "OFF"`` (``"CLOSE"`` for a contact or door), ``line`` null,
    ``repaired = True`` (False on every logged row) and every other column copied from the
    ON it closes (annotations null); ``repairs`` (:data:`REPAIRS`) lists them.
    """
    if not (default_hold_s > 0):
        raise InputError(f"default hold time must be > 0 s, got {default_hold_s!r}", field="hold_s")
    tog = events.filter(pl.col("on").is_not_null())
    if tog.height == 0:
        return events.with_columns(repaired=pl.lit(False)), pl.DataFrame(schema=REPAIRS)
    holds = hold_times(tog, default_hold_s=default_hold_s, min_samples=min_samples)
    seq = (
        tog.with_row_index("_i")
        .sort("sensor", "t", "_i")
        .join(holds.select("sensor", "hold_s", "hold_from"), on="sensor", how="left")
    )
    nxt_on = pl.col("on").shift(-1).over("sensor")
    nxt_t = pl.col("t").shift(-1).over("sensor")
    lost = seq.with_columns(_nt=nxt_t, _non=nxt_on).filter(
        pl.col("on") & (pl.col("_non") == True) & (pl.col("_nt") - pl.col("t") > pl.col("hold_s"))  # noqa: E712
    )
    repairs = lost.select(
        "sensor",
        pl.col("t").alias("t_on"),
        (pl.col("t") + pl.col("hold_s")).alias("t_off"),
        pl.col("_nt").alias("t_next_on"),
        "hold_s",
        "hold_from",
        pl.col("line").cast(pl.Int64) if "line" in lost.columns else pl.lit(None, pl.Int64).alias("line"),
    ).cast(dict(REPAIRS))
    if lost.height == 0:
        return events.with_columns(repaired=pl.lit(False)), repairs
    value = (
        pl.when(pl.col("value").str.to_lowercase().is_in(["open", "close", "closed"]))
        .then(pl.lit("CLOSE"))
        .otherwise(pl.lit("OFF"))
        if "value" in events.columns
        else None
    )
    ins = lost.drop("_i", "_nt", "_non", "hold_s", "hold_from").with_columns(
        t=pl.col("t") + lost["hold_s"], on=pl.lit(False)
    )
    if value is not None:
        ins = ins.with_columns(value=value)
    if "line" in ins.columns:
        ins = ins.with_columns(pl.lit(None, pl.Int64).alias("line"))
    for col in ("annotation", "residents", "tasks", "activity", "activity_edge", "stamp"):
        if col in ins.columns:
            ins = ins.with_columns(pl.lit(None, events.schema[col]).alias(col))
    out = pl.concat(
        [events.with_columns(_rep=pl.lit(False)), ins.select(events.columns).with_columns(_rep=pl.lit(True))]
    )
    out = out.with_row_index("_k").sort("t", "_k").drop("_k").rename({"_rep": "repaired"})
    return out, repairs.sort("t_on")
