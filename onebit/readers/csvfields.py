"""String rows of a CSV log: the header, each line's shape and fields.

Steps 2 and 3 of the CSV layer (:mod:`onebit.readers.rows`): :func:`csv_header` reads the
header, :func:`rows_of_lines` rejects the lines whose quotes or number of fields are wrong
and splits the others with polars' CSV parser (each line carrying its number), giving
:class:`RawRows`: all-String columns with ``line`` and ``raw``. :func:`read_csv_rows` does it
for a whole file; :func:`read_clean_csv` types a clean file in one read.
"""

from __future__ import annotations

import codecs
import io
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.core.tables import REJECTS
from onebit.readers import lines as physical
from onebit.readers.lines import QUOTE, SEPARATOR, check_shapes, physical_lines, read_bytes
from onebit.readers.linetext import make_rejects

EXTRA = "__extra__"


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


def _first_record(data: bytes) -> pl.DataFrame:
    """The first non-blank physical line of ``data`` (``line``, ``text``, ``_reason``; empty when
    there is none), split out of the start of the file only (a line is at most
    :data:`~onebit.readers.lines.MAX_LINE_BYTES`), so a bad header costs nothing of the rest."""
    head = data[: physical.MAX_LINE_BYTES + 1]
    if len(head) < len(data):
        head = head[: head.rfind(b"\n") + 1] or head
    lines = physical_lines(head)
    lines = lines.filter(~pl.col("text").str.contains(_BLANK) | pl.col("_reason").is_not_null()).head(1)
    if lines.height == 0 and len(head) < len(data):  # megabytes of blank lines first
        lines = physical_lines(data)
        lines = lines.filter(~pl.col("text").str.contains(_BLANK) | pl.col("_reason").is_not_null()).head(1)
    return lines


def _header_of(path: Path, data: bytes) -> tuple[list[str], int]:
    """Names and line number of the header of ``data`` (the bytes of ``path``); see :func:`csv_header`."""
    head = _first_record(data)
    if head.height == 0:
        return [], 0
    head = head.with_columns(_quote_problem().alias("_reason"), _n_fields().alias("_n"))
    line, why, n = head.select("line", "_reason", "_n").row(0)
    if why is not None:
        raise InputError(f"cannot read the CSV header: {why}", file=path, line=line)
    if n > MAX_HEADER_FIELDS:
        raise InputError(
            f"cannot read the CSV header: {n} fields, more than the {MAX_HEADER_FIELDS} a sensor log can have "
            "(is this a CSV file?)",
            file=path,
            line=line,
        )
    return [str(v or "").strip() for v in _split_fields(head, n).drop("line").row(0)], line


def header_names(path: str | Path) -> tuple[list[str], int]:
    """The header of a CSV file (its field names, stripped, and its line number) as
    :func:`csv_header` reads it, without splitting the lines after it."""
    path = Path(path)
    return _header_of(path, read_bytes(path))


def csv_header(path: str | Path, columns: tuple[str, ...] = ()) -> tuple[list[str], int, pl.DataFrame]:
    """The header of a CSV file: its field names (stripped), its line number and the lines after it
    (``line``, ``text``, ``_reason``; blank lines left out).

    The header is the first non-blank line; a header that is not UTF-8 or not one well-formed
    record is an :class:`InputError` naming the file and the line, and so is a header without
    one of ``columns`` (or naming it twice). The header is checked before the rest of the file
    is split. An empty file gives ``[]``.
    """
    path = Path(path)
    data = read_bytes(path)
    names, line = _header_of(path, data)
    if not names:
        return [], 0, pl.DataFrame(schema={"line": pl.Int64, "text": pl.String, "_reason": pl.String})
    _check_columns(path, names, line, columns)
    if columns:
        check_shapes(data, path, len(names), line)
    lines = physical_lines(data)
    del data
    lines = lines.filter(
        (pl.col("line") > line) & (~pl.col("text").str.contains(_BLANK) | pl.col("_reason").is_not_null())
    )
    return names, line, lines


def read_csv_rows(path: str | Path, columns: tuple[str, ...]) -> RawRows:
    """Read a CSV whose header names at least ``columns`` (any order, extra columns ignored).

    Returns the rows whose line is one well-formed record with as many fields as the header,
    as String columns ``columns`` plus ``line`` (physical line number) and ``raw`` (its
    text); every other non-blank line is in ``rejects`` (module docstring). A file that
    cannot be read, a bad header or a missing column is an :class:`InputError`.
    """
    path = Path(path)
    header, _, body = csv_header(path, columns)
    if not header:
        return RawRows(path.name, _empty_rows(columns), pl.DataFrame(schema=REJECTS))
    return rows_of_lines(body, header, columns, path.name)


def _check_columns(path: Path, header: list[str], header_line: int, columns) -> None:
    for col in columns:
        if col not in header:
            raise InputError(f"missing column; the header has {header}", file=path, line=header_line, field=col)
        if header.count(col) > 1:
            raise InputError("column named twice in the header", file=path, line=header_line, field=col)


def rows_of_lines(body: pl.DataFrame, header: list[str], columns: tuple[str, ...], source: str) -> RawRows:
    """Steps 2 and 3 of the CSV layer (module docstring) on non-blank lines after the header
    (``line``, ``text``, ``_reason``): the :class:`RawRows` of the well-formed ones, every
    other line a reject. :func:`read_csv_rows` runs it on every line of a file,
    :func:`read_typed_csv` on the lines its typed read could not take."""
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
    split = plain.select(
        pl.col("text")
        .str.split_exact(SEPARATOR, width - 1)
        .struct.rename_fields([f"_f{i}" for i in range(width)])
        .struct.unnest()
    )
    frame = plain.select("line", pl.col("text").alias("raw")).hstack(
        split.select([f"_f{header.index(c)}" for c in columns])
    )
    frame = frame.rename({f"_f{header.index(c)}": c for c in columns})
    quoted_lines = quoted_lines.filter(pl.col("_reason").is_null())
    if quoted_lines.height:  # lines with quoted fields: polars' CSV parser splits them
        parsed = _split_fields(quoted_lines, n).select(
            "line", *[pl.col(f"_f{header.index(c)}").fill_null("").alias(c) for c in columns]
        )
        both = quoted_lines.select("line", pl.col("text").alias("raw")).join(parsed, on="line", how="left")
        lost = both.filter(~pl.col("line").is_in(parsed["line"].implode()))
        if lost.height:  # the parser did not return the line: never dropped silently
            bad = pl.concat(
                [bad, lost.select("line", "raw", pl.lit("cannot be split into fields").alias("_reason"))],
                how="diagonal_relaxed",
            )
        frame = pl.concat(
            [frame, both.filter(pl.col("line").is_in(parsed["line"].implode()))], how="diagonal_relaxed"
        ).sort("line")
    frame = frame.select("line", *columns, "raw")
    bad = bad.rename({"text": "raw"}, strict=False).select("line", "raw", "_reason").sort("line")
    return RawRows(source, frame, make_rejects(bad, source, None))


def read_clean_csv(path: str | Path, dtypes: dict[str, pl.DataType]) -> pl.DataFrame | None:
    """The strict test of a clean CSV: one typed ``pl.read_csv`` of the whole file, or ``None``
    when the file is not clean (the readers use :func:`read_typed_csv`, which also takes a
    file with bad lines; this is the narrower check of ``clean_beam_events`` / ``clean_toggle_rows``).

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
            data,
            has_header=False,
            skip_rows=1,
            schema=schema,
            columns=[header.index(c) for c in dtypes],
            separator=SEPARATOR,
            quote_char=None,
            comment_prefix=None,
            raise_if_empty=False,
            truncate_ragged_lines=False,
        )
    except (pl.exceptions.ComputeError, pl.exceptions.PolarsError):
        return None
    if frame.height != n_lines or frame.null_count().sum_horizontal().item():
        return None
    frame = frame.rename({f"_f{header.index(c)}": c for c in dtypes}).select(*dtypes)
    return frame.with_columns(pl.int_range(2, frame.height + 2, dtype=pl.Int64).alias("line")).select("line", *dtypes)


def _empty_rows(columns) -> pl.DataFrame:
    return pl.DataFrame(schema={"line": pl.Int64, **{c: pl.String for c in columns}, "raw": pl.String})
