"""Row-level reading shared by every CSV/MCAP reader: raw string rows -> typed rows + rejects.

A reader first gets its rows as all-string columns with a ``line`` column and a ``raw``
column (CSV: the file's physical line number, header = line 1, and the line's text; MCAP:
the message's index in its channel and its JSON text), then types and checks them with
polars expressions. A row that fails any check goes to ``rejects`` with the first reason that
applies; nothing is dropped silently.

The CSV layer (:func:`read_csv_rows`) works on physical lines, so one bad byte, one stray
quote or one ragged line costs that line alone:

1. **Physical lines** (:func:`physical_lines`): the file's bytes are split at ``\\n`` (a
   trailing ``\\r`` is dropped, a UTF-8 byte-order mark at the start too); line ``k`` is what
   an editor shows as line ``k``. A line with bytes that are not UTF-8 is rejected naming
   the byte and its column; its raw text shows them as U+FFFD.
2. **Shape** (polars regular expressions over all lines at once): a line whose quotes do not
   pair up, or whose quote does not enclose a whole field (``"..."``, ``""`` for a quote
   inside), or whose number of fields differs from the header's, is rejected. A quoted field
   never spans lines: a quote left open is the line's fault, and the next line is read as a
   line of its own (onebit's logs hold numbers and names, never line breaks).
3. **Fields**: the lines that passed are split by polars' CSV parser. Each line carries its
   number into the parser as an extra first field, so a line number can never drift.

**Clean files** skip all three: :func:`read_clean_csv` types the whole file with one
``pl.read_csv`` (names and spellings as ``Enum`` columns) when it is UTF-8 without quotes,
carriage returns or a byte-order mark and every line after the header is one record whose
fields parse; its line numbers are then the row index + 2. The readers use it first and fall
back to the physical-line path, which names every bad line, when it returns ``None``;
``tests/readers/test_clean_path.py`` holds both paths to equal frames and rejects.

Blank lines (empty, or spaces and tabs only) are not rows: accepted + rejected (+ suppressed,
for toggle logs) = the non-blank lines after the header. The raw text and the reason of every
reject are cut to :data:`onebit.core.errors.MAX_QUOTE` characters with the full length stated.
"""

from __future__ import annotations

import codecs
import io
from contextvars import ContextVar
from dataclasses import dataclass
import math
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import MAX_QUOTE, InputError
from onebit.core.tables import REJECTS
from onebit.readers.timebase import MAX_GAP_S, TimeOrigin, column_origin, number_column_origin

EXTRA = "__extra__"
#: The field separator and the quote character of onebit's CSV logs.
SEPARATOR, QUOTE = ",", '"'
_QUOTED = r'"(?:[^"]|"")*"'
_FIELD = rf'(?:[^",]*|{_QUOTED})'
#: A line that is one well-formed CSV record: every quote opens or closes a whole field.
_RECORD = rf"^{_FIELD}(?:,{_FIELD})*$"
_BLANK = r"^[ \t]*$"


@dataclass(frozen=True)
class RawRows:
    """String rows of one source: ``frame`` has the wanted columns (String), ``line`` and ``raw``."""

    source: str
    frame: pl.DataFrame
    rejects: pl.DataFrame


# --------------------------------------------------------------------------- physical lines

_BAD_BYTES: ContextVar[list[int]] = ContextVar("onebit_bad_bytes")


def _note_bad_byte(exc: UnicodeError) -> tuple[str, int]:
    """Decoding error handler: note where the invalid sequence starts, put U+FFFD there."""
    _BAD_BYTES.get().append(exc.start)
    return "\ufffd", exc.end


codecs.register_error("onebit.note_bad_byte", _note_bad_byte)


def read_bytes(path: str | Path) -> bytes:
    """The bytes of a user file; an unreadable one is an :class:`InputError` naming it."""
    path = Path(path)
    try:
        return path.read_bytes()
    except IsADirectoryError:
        raise InputError("is a folder, not a file", file=path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", file=path) from None


def _decode(data: bytes) -> tuple[str, np.ndarray]:
    """Text of ``data`` (invalid UTF-8 as U+FFFD) and the byte offsets where invalid sequences start."""
    try:
        return data.decode("utf-8"), np.empty(0, dtype=np.int64)
    except UnicodeDecodeError:
        pass
    token = _BAD_BYTES.set([])
    try:  # the handler runs once per invalid sequence, not per line
        text = data.decode("utf-8", errors="onebit.note_bad_byte")
        return text, np.asarray(_BAD_BYTES.get(), dtype=np.int64)
    finally:
        _BAD_BYTES.reset(token)


def physical_lines(data: bytes) -> pl.DataFrame:
    """Every physical line of a text file's bytes: ``line`` (1-based), ``text`` (without its
    ``\\n`` / ``\\r\\n``) and ``_reason`` (why the line is not text, else null).

    A line holding bytes that are not UTF-8 gets ``_reason`` naming the first such byte and
    its column (1-based, in bytes); its ``text`` shows invalid sequences as U+FFFD.
    """
    text, bad = _decode(data)
    if text.startswith("\ufeff"):  # a UTF-8 byte-order mark (spreadsheet exports) is not data
        text = text[1:]
    if text == "":
        return pl.DataFrame(schema={"line": pl.Int64, "text": pl.String, "_reason": pl.String})
    parts = pl.Series("text", [text]).str.split("\n").explode()
    if text.endswith("\n"):
        parts = parts.slice(0, parts.len() - 1)
    lines = pl.DataFrame({"text": parts}).with_row_index("line", offset=1).select(
        pl.col("line").cast(pl.Int64), pl.col("text").str.strip_suffix("\r")
    )
    if bad.size == 0:
        return lines.with_columns(pl.lit(None, pl.String).alias("_reason"))
    newlines = np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == 0x0A)
    line_of = np.searchsorted(newlines, bad, side="left") + 1
    first_line, first = np.unique(line_of, return_index=True)
    at = bad[first]
    starts = np.r_[0, newlines + 1]
    column = at - starts[first_line - 1] + 1
    byte = np.frombuffer(data, dtype=np.uint8)[at]
    why = [f"not UTF-8 text: byte 0x{b:02X} at column {c}" for b, c in zip(byte.tolist(), column.tolist())]  # bad lines only
    reasons = pl.DataFrame({"line": first_line.astype(np.int64), "_reason": why}, schema={"line": pl.Int64, "_reason": pl.String})
    return lines.join(reasons, on="line", how="left")


def _bounded(col: str, limit: int = MAX_QUOTE) -> pl.Expr:
    """``col`` cut to ``limit`` characters, stating the full length (:func:`onebit.core.errors.bounded`)."""
    n = pl.col(col).str.len_chars()
    return (
        pl.when(n > limit)
        .then(pl.format("{}... ({} characters)", pl.col(col).str.slice(0, limit), n))
        .otherwise(pl.col(col))
        .alias(col)
    )


# --------------------------------------------------------------------------- CSV rows


def _split_fields(lines: pl.DataFrame, n: int) -> pl.DataFrame:
    """Split well-formed lines (``line``, ``text``; each exactly ``n`` fields) with polars' CSV
    parser; the line number rides along as a first field. Returns ``line`` + ``_f0.._f{n-1}``."""
    schema = {"line": pl.Int64, **{f"_f{i}": pl.String for i in range(n)}}
    if lines.height == 0:
        return pl.DataFrame(schema=schema)
    body = lines.select(pl.format("{},{}", pl.col("line"), pl.col("text")).str.join("\n")).item()
    return pl.read_csv(
        io.BytesIO(body.encode("utf-8")),
        has_header=False,
        schema=schema,
        quote_char=QUOTE,
        separator=SEPARATOR,
        comment_prefix=None,
        raise_if_empty=False,
    )


def _n_fields() -> pl.Expr:
    """Fields of a line (``text``) with well-formed quotes: separators outside quoted fields, plus one."""
    text = pl.col("text")
    unquoted = pl.when(text.str.contains(QUOTE, literal=True)).then(text.str.replace_all(_QUOTED, "")).otherwise(text)
    return unquoted.str.count_matches(SEPARATOR, literal=True) + 1


def _quote_problem() -> pl.Expr:
    """The reason a line (``text``, ``_reason`` from decoding) is not text with well-formed quotes, else null."""
    text = pl.col("text")
    return (
        pl.when(pl.col("_reason").is_not_null())
        .then(pl.col("_reason"))
        .when(text.str.count_matches(QUOTE, literal=True) % 2 == 1)
        .then(pl.lit("unbalanced quote: a quoted field does not close on its line"))
        .when(text.str.contains(QUOTE, literal=True) & ~text.str.contains(_RECORD))
        .then(pl.lit('stray quote: a quote must enclose a whole field ("...", with "" for a quote inside)'))
        .otherwise(None)
    )


def _line_shape(n: int) -> pl.Expr:
    """The reason a line is not one record of ``n`` fields, else null (the first that applies)."""
    fields = _n_fields()
    return pl.coalesce(
        _quote_problem(),
        pl.when(fields > n).then(pl.format("too many fields ({} of {})", fields, pl.lit(n))),
        pl.when(fields < n).then(pl.format("too few fields ({} of {})", fields, pl.lit(n))),
    )


#: The most fields a CSV header may have: a header wider than this is not a sensor log's.
MAX_HEADER_FIELDS = 1000


def csv_header(path: str | Path) -> tuple[list[str], int, pl.DataFrame]:
    """The header of a CSV file: its field names (stripped), its line number and the lines after it
    (``line``, ``text``, ``_reason``; blank lines left out).

    The header is the first non-blank line; a header that is not UTF-8 or not one well-formed
    record is an :class:`InputError` naming the file and the line. An empty file gives ``[]``.
    """
    path = Path(path)
    lines = physical_lines(read_bytes(path))
    lines = lines.filter(~pl.col("text").str.contains(_BLANK) | pl.col("_reason").is_not_null())
    if lines.height == 0:
        return [], 0, lines
    head = lines.head(1).with_columns(_quote_problem().alias("_reason"), _n_fields().alias("_n"))
    line, why, n = head.select("line", "_reason", "_n").row(0)
    if why is not None:
        raise InputError(f"cannot read the CSV header: {why}", file=path, line=line)
    if n > MAX_HEADER_FIELDS:
        raise InputError(
            f"cannot read the CSV header: {n} fields, more than the {MAX_HEADER_FIELDS} a sensor log can have "
            "(is this a CSV file?)", file=path, line=line)
    names = [str(v or "").strip() for v in _split_fields(head, n).drop("line").row(0)]
    return names, line, lines.slice(1)


def read_csv_rows(path: str | Path, columns: tuple[str, ...]) -> RawRows:
    """Read a CSV whose header names at least ``columns`` (any order, extra columns ignored).

    Returns the rows whose line is one well-formed record with as many fields as the header,
    as String columns ``columns`` plus ``line`` (physical line number) and ``raw`` (its
    text); every other non-blank line is in ``rejects`` (module docstring). A file that
    cannot be read, a bad header or a missing column is an :class:`InputError`.
    """
    path = Path(path)
    source = path.name
    header, header_line, body = csv_header(path)
    if not header:
        return RawRows(source, _empty_rows(columns), pl.DataFrame(schema=REJECTS))
    for col in columns:
        if col not in header:
            raise InputError(f"missing column; the header has {header}", file=path, line=header_line, field=col)
        if header.count(col) > 1:
            raise InputError("column named twice in the header", file=path, line=header_line, field=col)
    n = len(header)
    quoted = pl.col("text").str.contains(QUOTE, literal=True)
    body = body.with_columns(quoted.alias("_quoted"))
    # quote-free lines (nearly all): the shape is the separator count, the split a plain split
    plain = body.filter(~pl.col("_quoted"))
    fields = pl.col("text").str.count_matches(SEPARATOR, literal=True) + 1
    plain = plain.with_columns(
        pl.coalesce(
            "_reason",
            pl.when(fields > n).then(pl.format("too many fields ({} of {})", fields, pl.lit(n))),
            pl.when(fields < n).then(pl.format("too few fields ({} of {})", fields, pl.lit(n))),
        ).alias("_reason")
    )
    quoted_lines = body.filter(pl.col("_quoted")).with_columns(_line_shape(n).alias("_reason"))
    bad = pl.concat([plain, quoted_lines]).filter(pl.col("_reason").is_not_null())
    plain = plain.filter(pl.col("_reason").is_null())
    width = max(header.index(c) for c in columns) + 1  # split only as far as the last wanted field
    split = plain.select(pl.col("text").str.split_exact(SEPARATOR, width - 1).struct.rename_fields([f"_f{i}" for i in range(width)]).struct.unnest())
    frame = plain.select("line", pl.col("text").alias("raw")).hstack(split.select([f"_f{header.index(c)}" for c in columns]))
    frame = frame.rename({f"_f{header.index(c)}": c for c in columns})
    quoted_lines = quoted_lines.filter(pl.col("_reason").is_null())
    if quoted_lines.height:  # lines with quoted fields: polars' CSV parser splits them
        parsed = _split_fields(quoted_lines, n).select("line", *[pl.col(f"_f{header.index(c)}").fill_null("").alias(c) for c in columns])
        both = quoted_lines.select("line", pl.col("text").alias("raw")).join(parsed, on="line", how="left")
        lost = both.filter(~pl.col("line").is_in(parsed["line"].implode()))
        if lost.height:  # the parser did not return the line: never dropped silently
            bad = pl.concat([bad, lost.select("line", "raw", pl.lit("cannot be split into fields").alias("_reason"))], how="diagonal_relaxed")
        frame = pl.concat([frame, both.filter(pl.col("line").is_in(parsed["line"].implode()))], how="diagonal_relaxed").sort("line")
    frame = frame.select("line", *columns, "raw")
    bad = bad.rename({"text": "raw"}, strict=False).select("line", "raw", "_reason").sort("line")
    return RawRows(source, frame, make_rejects(bad, source, None))


def read_clean_csv(path: str | Path, dtypes: dict[str, pl.DataType]) -> pl.DataFrame | None:
    """The fast path of a clean CSV: one typed ``pl.read_csv`` of the whole file, or ``None``
    when the file is not clean and :func:`read_csv_rows` must name its bad lines.

    ``dtypes`` maps each wanted column to the type its every field must parse as (an ``Enum``
    for names and spellings: a value outside it fails the read). The file is clean when it is
    UTF-8 without a byte-order mark, quotes or carriage returns, its first line is the header
    (at most :data:`MAX_HEADER_FIELDS` names, each wanted column once), and every later line
    is one record whose wanted fields parse and are not empty. Then the typed read has exactly
    one row per line after the header (a blank or short line gives a null, a long line fails
    the read), and line numbers are the row index + 2. Returns ``line`` + the wanted columns.
    """
    try:
        data = read_bytes(path)
    except InputError:
        return None
    if not data or b'"' in data or b"\r" in data or data.startswith(codecs.BOM_UTF8):
        return None
    if not data.isascii():
        try:
            data.decode("utf-8")
        except UnicodeDecodeError:
            return None
    end = data.find(b"\n")
    if end <= 0:  # no data line, or a blank first line
        return None
    header = [name.strip() for name in data[:end].decode("utf-8").split(SEPARATOR)]
    if len(header) > MAX_HEADER_FIELDS or any(header.count(c) != 1 for c in dtypes):
        return None
    n_lines = data.count(b"\n") + (not data.endswith(b"\n")) - 1
    schema = {f"_f{i}": dtypes.get(name, pl.String) for i, name in enumerate(header)}
    try:
        frame = pl.read_csv(
            data, has_header=False, skip_rows=1, schema=schema, columns=[header.index(c) for c in dtypes],
            separator=SEPARATOR, quote_char=None, comment_prefix=None, raise_if_empty=False, truncate_ragged_lines=False,
        )  # fmt: skip
    except (pl.exceptions.ComputeError, pl.exceptions.PolarsError):
        return None
    if frame.height != n_lines or frame.null_count().sum_horizontal().item():
        return None
    frame = frame.rename({f"_f{header.index(c)}": c for c in dtypes}).select(*dtypes)
    return frame.with_columns(pl.int_range(2, frame.height + 2, dtype=pl.Int64).alias("line")).select("line", *dtypes)


def clean_time(t: pl.Series, epoch: "str | TimeOrigin | None") -> pl.Series | None:
    """``t`` of a clean numeric column (Float64 stamps) as :func:`parse_time` computes it, or
    ``None`` when a stamp would be rejected (not finite, or a lone stamp outside the window)."""
    if not t.is_finite().all():
        return None
    origin = number_column_origin(t, epoch)
    out = t - origin.numeric
    if (math.isfinite(origin.lo) or math.isfinite(origin.hi)) and (
        (out < origin.lo - 1e-3) | (out > origin.hi + 1e-3)
    ).any():
        return None
    return out.alias("t")


def _empty_rows(columns) -> pl.DataFrame:
    return pl.DataFrame(schema={"line": pl.Int64, **{c: pl.String for c in columns}, "raw": pl.String})


def raw_lines(path: Path, lines: list[int], *, limit: int | None = MAX_QUOTE) -> dict[int, str]:
    """The text of the given 1-based physical line numbers, each cut to ``limit`` characters
    (:data:`~onebit.core.errors.MAX_QUOTE`; ``None``: whole) (read only when there are rejects)."""
    if not lines:
        return {}
    try:
        data = read_bytes(path)
    except InputError:
        return {}
    found = physical_lines(data).filter(pl.col("line").is_in(list(set(lines))))
    found = found.select("line", "text" if limit is None else _bounded("text", limit))
    return dict(found.iter_rows())


def make_rejects(bad: pl.DataFrame, source: str, path: Path | None) -> pl.DataFrame:
    """Build ``rejects`` rows from a frame with ``line``, ``_reason`` and optionally ``raw``;
    the raw text and the reason are cut to :data:`~onebit.core.errors.MAX_QUOTE` characters."""
    if bad.height == 0:
        return pl.DataFrame(schema=REJECTS)
    if "raw" in bad.columns and bad["raw"].null_count() < bad.height:
        raw = bad["raw"]
    elif path is not None and path.suffix.lower() == ".csv":
        text = raw_lines(path, bad["line"].to_list())
        raw = pl.Series([text.get(i) for i in bad["line"].to_list()], dtype=pl.String)
    else:
        raw = pl.Series([None] * bad.height, dtype=pl.String)
    return pl.DataFrame(
        {
            "source": pl.Series([source] * bad.height, dtype=pl.String),
            "line": bad["line"].cast(pl.Int64),
            "reason": bad["_reason"].cast(pl.String),
            "raw": raw.cast(pl.String),
        },
        schema=REJECTS,
    ).with_columns(_bounded("reason"), _bounded("raw"))


# --------------------------------------------------------------------------- typing rows


def parse_time(col: str, epoch: "str | TimeOrigin | None", frame: pl.DataFrame | None = None) -> tuple[pl.Expr, pl.Expr]:
    """Expression for ``t`` (seconds since the time origin) from numbers or ISO wall-clock strings.

    Returns ``(t, reason)``; ``reason`` is null where the value parsed. ``epoch`` is the run's
    :class:`~onebit.readers.timebase.TimeOrigin` (the pipeline's: one origin for every
    table) or, for a reader used on its own, the site's ``epoch`` string or ``None``: then
    numbers are taken as they are and ISO strings are measured from the epoch, else from the
    column's own first stamp (floored to a second) -- never from midnight. A stamp outside the
    origin's window (a lone stamp far from the rest, :mod:`onebit.readers.timebase`) is rejected.
    """
    origin = epoch if isinstance(epoch, TimeOrigin) else column_origin(frame, col, epoch)
    s = pl.col(col).str.strip_chars()
    numbers_only = (
        frame is not None
        and frame.height > 0
        and not frame.select((s.cast(pl.Float64, strict=False).is_null() & pl.col(col).is_not_null()).any()).item()
    )
    t = origin.t_expr(col, numbers_only=numbers_only)
    reason = (
        pl.when(pl.col(col).is_null() | (s == ""))
        .then(pl.lit(f"field '{col}': missing"))
        .when(t.is_null())
        .then(pl.format("field '{}': not a number or ISO time: '{}'", pl.lit(col), s))
        .when(~t.is_finite())
        .then(pl.format("field '{}': not finite: '{}'", pl.lit(col), s))
    )
    if math.isfinite(origin.lo) or math.isfinite(origin.hi):
        lo, hi = origin.lo, origin.hi  # the window was found in float Unix seconds: 1 ms slack
        reason = reason.when((t < lo - 1e-3) | (t > hi + 1e-3)).then(
            pl.format(
                "field '{}': '{}' is a lone time stamp far from the rest of the data (accepted span {} .. {} s "
                "after the time origin; gaps over {} days cut it off)",
                pl.lit(col), s, pl.lit(round(lo, 6)), pl.lit(round(hi, 6)), pl.lit(MAX_GAP_S / 86400),
            )
        )
    return t, reason.otherwise(None)


def parse_float(col: str) -> tuple[pl.Expr, pl.Expr]:
    s = pl.col(col).str.strip_chars()
    v = s.cast(pl.Float64, strict=False)
    reason = (
        pl.when(pl.col(col).is_null() | (s == ""))
        .then(pl.lit(f"field '{col}': missing"))
        .when(v.is_null() | ~v.is_finite())
        .then(pl.format("field '{}': not a finite number: '{}'", pl.lit(col), s))
        .otherwise(None)
    )
    return v, reason


def parse_choice(
    col: str, mapping: dict[str, object], dtype: pl.DataType, *, case_insensitive: bool = False
) -> tuple[pl.Expr, pl.Expr]:
    """Map string values through ``mapping``; anything else is rejected naming the allowed values.

    With ``case_insensitive`` the value is lower-cased first (``mapping``'s keys are lower case).
    """
    s = pl.col(col).str.strip_chars()
    key = s.str.to_lowercase() if case_insensitive else s
    v = key.replace_strict(list(mapping), list(mapping.values()), default=None, return_dtype=dtype)
    allowed = "|".join(mapping)
    reason = (
        pl.when(pl.col(col).is_null() | (s == ""))
        .then(pl.lit(f"field '{col}': missing"))
        .when(v.is_null())
        .then(pl.format("field '{}': '{}' is not one of {}", pl.lit(col), s, pl.lit(allowed)))
        .otherwise(None)
    )
    return v, reason


def parse_name(col: str, known: tuple[str, ...] | None, what: str) -> tuple[pl.Expr, pl.Expr]:
    """A sensor/target name; when ``known`` is given, unknown names are rejected."""
    s = pl.col(col).str.strip_chars()
    reason = pl.when(pl.col(col).is_null() | (s == "")).then(pl.lit(f"field '{col}': missing"))
    if known is not None:
        reason = reason.when(~s.is_in(list(known))).then(pl.format("field '{}': unknown {} '{}'", pl.lit(col), pl.lit(what), s))
    return s, reason.otherwise(None)


#: Toggle logs (motion, proximity, CASAS): rows up to this many seconds earlier than an
#: accepted row before them are sorted into place, not rejected (CASAS logs are up to 0.7 s
#: out of order: sensors' clocks and the gateway's queue); a row further back is rejected as
#: going backwards. Raw beam events, crossings and truth keep a strict order (tolerance 0):
#: a beam pass takes a tenth of a second, so a reordered edge would change the decoding.
REORDER_TOLERANCE_S = 1.0


@dataclass(frozen=True)
class TypedRows:
    """What :func:`check_rows` made of string rows: ``accepted`` (sorted by ``t``, file order
    within a stamp, with ``line``), ``rejects`` and how many accepted rows were out of order
    within the tolerance and sorted into place (``reordered``)."""

    accepted: pl.DataFrame
    rejects: pl.DataFrame
    reordered: int = 0


def check_rows(
    raw: RawRows,
    parsers: dict[str, tuple[pl.Expr, pl.Expr]],
    *,
    key: tuple[str, ...],
    path: Path | None = None,
    tolerance: float = 0.0,
) -> TypedRows:
    """Apply ``parsers`` (column -> (value, reason)), then the ordering checks, and split.

    Checks, in order: each field's own reason; a row identical in ``key`` to an earlier row
    is a duplicate; a row whose ``t`` is more than ``tolerance`` seconds earlier than an
    accepted row before it goes backwards. Rows less far back are accepted, sorted into
    place and counted (``reordered``).
    """
    df = raw.frame
    value_exprs = [v.alias(c) for c, (v, _) in parsers.items()]
    reasons = [r for _, r in parsers.values()]
    typed = df.with_columns(pl.coalesce(reasons).alias("_reason")).with_columns(value_exprs)
    ok = typed.filter(pl.col("_reason").is_null())
    return order_checks(ok, key=key, tolerance=tolerance, field_bad=typed.filter(pl.col("_reason").is_not_null()),
                        prior=raw.rejects, source=raw.source, path=path, columns=tuple(parsers))  # fmt: skip


def in_time_order(t: pl.Series) -> bool:
    """Whether ``t`` never decreases (one pass in numpy; nulls and NaN are never in order)."""
    v = t.to_numpy()
    return bool(v.size < 2 or (v[1:] >= v[:-1]).all())


def by_time(rows: pl.DataFrame) -> pl.DataFrame:
    """``rows`` sorted by ``t``, then ``line`` (file order within a stamp); no sort when both
    already increase (the accepted rows of a log written in time order)."""
    if in_time_order(rows["t"]) and in_time_order(rows["line"]):
        return rows
    return rows.sort(["t", "line"])


def duplicate_of(ok: pl.DataFrame, key: tuple[str, ...]) -> pl.Series:
    """For every row of ``ok`` (``line`` + the ``key`` columns, ``t`` among them), the first
    ``line`` of an earlier row with the same ``key``, else null: found by one sort on the key and
    a comparison of neighbours (no window over the key). Rows whose ``t`` no other row has
    cannot be duplicates; when ``t`` never decreases in file order (the usual log) only the
    runs of equal ``t`` are sorted."""
    idx = pl.int_range(pl.len(), dtype=pl.Int64).alias("_i")
    cand = ok.select(idx, "line", *key)
    t = ok["t"]
    if in_time_order(t):
        tie = (t == t.shift(1)).fill_null(False) | (t == t.shift(-1)).fill_null(False)
        cand = cand.filter(tie)
    cand = cand.sort([*key, "line"])
    same = pl.all_horizontal([pl.col(k).eq_missing(pl.col(k).shift(1)) for k in key]).fill_null(False)
    cand = cand.with_columns(pl.when(same).then(None).otherwise(pl.col("line")).forward_fill().alias("_first"))
    cand = cand.filter(pl.col("_first") != pl.col("line"))
    out = pl.Series("_dup", [], dtype=pl.Int64).extend_constant(None, ok.height)
    if cand.height:
        out = out.scatter(cand["_i"], cand["_first"])
    return out


def order_checks(
    ok: pl.DataFrame,
    *,
    key: tuple[str, ...],
    tolerance: float,
    columns: tuple[str, ...],
    source: str,
    path: Path | None,
    field_bad: pl.DataFrame | None = None,
    prior: pl.DataFrame | None = None,
) -> TypedRows:
    """The ordering checks of :func:`check_rows` on rows whose fields all parsed (``ok``: ``line``
    + typed ``columns``, in file order): duplicates (:func:`duplicate_of`), then rows going
    backwards by more than ``tolerance``. ``field_bad`` (rows rejected by their fields, with
    ``_reason``) and ``prior`` (rejects already made) join the rejects."""
    ok = ok.with_columns(duplicate_of(ok, key).alias("_dup"))
    same = " and ".join(", ".join(key).rsplit(", ", 1))  # ("t", "target") -> "t and target"
    ok = ok.with_columns(
        pl.when(pl.col("_dup").is_not_null()).then(pl.format("duplicate of line {} (same {})", pl.col("_dup"), pl.lit(same))).alias("_reason")
    )
    ok = ok.drop("_dup")
    dup = ok.filter(pl.col("_reason").is_not_null())
    ok = ok.filter(pl.col("_reason").is_null())
    if in_time_order(ok["t"]):  # never earlier than a row before it
        back = ok.clear()
        reordered = 0
    else:
        ok = ok.sort("line")
        prev_max = pl.col("t").cum_max().shift(1)
        ok = ok.with_columns(
            pl.when(pl.col("t") < prev_max - tolerance)
            .then(
                pl.format("timestamp goes backwards ({} after {})", pl.col("t"), prev_max)
                if tolerance <= 0
                else pl.format("timestamp goes backwards ({} after {}, more than {} s)", pl.col("t"), prev_max, pl.lit(tolerance))
            )
            .otherwise(None)
            .alias("_reason"),
            (pl.col("t") < prev_max).fill_null(False).alias("_late"),
        )
        back = ok.filter(pl.col("_reason").is_not_null()).drop("_late")
        ok = ok.filter(pl.col("_reason").is_null())
        reordered = int(ok["_late"].sum()) if ok.height else 0
    parts = [p for p in (field_bad, dup, back) if p is not None and p.height]
    if parts:
        bad = pl.concat(parts, how="vertical_relaxed").sort("line")
        if path is not None and "raw" not in bad.columns:  # rows of the fast path: their text read back
            text = raw_lines(path, bad["line"].to_list(), limit=None)
            bad = bad.with_columns(pl.Series("raw", [text.get(i) for i in bad["line"].to_list()], dtype=pl.String))
        made = make_rejects(bad, source, path)
    else:
        made = pl.DataFrame(schema=REJECTS)
    rejects = made if prior is None else pl.concat([prior, made]).sort("line")
    accepted = ok.select("line", *columns)
    if reordered or not in_time_order(accepted["t"]):
        accepted = accepted.sort(["t", "line"])
    return TypedRows(accepted, rejects, reordered)


def type_rows(
    raw: RawRows,
    parsers: dict[str, tuple[pl.Expr, pl.Expr]],
    *,
    key: tuple[str, ...],
    path: Path | None = None,
    tolerance: float = 0.0,
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """:func:`check_rows` as ``(accepted, rejects)``."""
    res = check_rows(raw, parsers, key=key, path=path, tolerance=tolerance)
    return res.accepted, res.rejects
