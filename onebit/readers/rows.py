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

**Large files** go through all three only where they must: :func:`read_typed_csv` types the
whole file with one ``pl.read_csv`` (names and spellings as ``Enum`` columns, numbers as
``Float64``) and hands to the physical-line path only the lines that read cannot take: a line
with a field that does not parse, a quote, a stray carriage return, bytes that are not UTF-8,
too few fields (the header's last column is null) or too many (found by counting separators,
on every line only when their total disagrees). A clean file is one strict read; a file with a
few bad lines costs one more (tolerant) read and the bad lines alone. Its good rows' line
numbers are the row index + 2 (a line taken out is blanked, not removed, so it stays a row).
:func:`check_split` then types the other lines row by row, with the time origin the whole
file gives (:func:`~onebit.readers.timebase.parts_origin`), and checks duplicates and order
over both. ``tests/readers/test_typed_split.py`` and ``test_clean_path.py`` hold it to the
row-by-row path's frames and rejects on messy files.

Blank lines (empty, or spaces and tabs only) are not rows: accepted + rejected (+ suppressed,
for toggle logs) = the non-blank lines after the header. The raw text and the reason of every
reject are cut to :data:`onebit.core.errors.MAX_QUOTE` characters with the full length stated.
"""

from __future__ import annotations

import codecs
import dataclasses
import io
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.compiled import numba_loaded
from onebit.core.errors import MAX_QUOTE, InputError, bounded
from onebit.core.tables import REJECTS
from onebit.readers import kernels
from onebit.readers.filebytes import read_file
from onebit.readers.timebase import (
    MAX_GAP_S,
    TimeOrigin,
    column_origin,
    number_column_origin,
    parts_origin,
)

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

#: The longest physical line (bytes, without its ``\\n``) a log may hold: no sensor log line comes
#: near it (a ``frames.csv`` line of :data:`MAX_HEADER_FIELDS` sensors is a few kB; a shorter bad
#: line is one reject), so a longer line means the file is not a log (one 200 MB line of garbage):
#: the file is refused, naming the line, before any of it is split.
MAX_LINE_BYTES = 1 << 24
#: The first this many bytes of a file are looked at to tell a text file from a binary one.
TEXT_PROBE_BYTES = 1 << 16
#: A file whose first :data:`TEXT_PROBE_BYTES` hold at least this many lines that are not UTF-8
#: text, and more such lines than good ones, is refused as not a text file (random bytes, a
#: compressed or binary file under a log's name) instead of being rejected line by line. A log
#: with a few bad bytes (a flipped bit, a crash's NUL run) keeps the line-by-line rejects.
MIN_BINARY_LINES = 8
#: Bytes looked at per step when a whole file is scanned for its newlines (bounded temporaries).
_SCAN_BYTES = 1 << 24


def _line_starts_ends(data: bytes, lo: int, hi: int) -> np.ndarray:
    """Offsets of the ``\\n`` bytes of ``data[lo:hi]`` (absolute)."""
    return np.flatnonzero(np.frombuffer(data, dtype=np.uint8, count=hi - lo, offset=lo) == 0x0A) + lo


def check_line_lengths(data: bytes, path: str | Path) -> None:
    """Refuse ``data`` (the bytes of ``path``) when a physical line is longer than
    :data:`MAX_LINE_BYTES`: an :class:`InputError` naming the file and the line. Scans the file
    in steps of 16 MiB, so the check itself costs bounded memory.

    A line longer than ``M`` = :data:`MAX_LINE_BYTES` holds a whole block ``[k M/2, (k+1) M/2)``
    without a newline, so a file whose every such block holds one (one ``bytes.find`` each,
    stopping at the block's first newline) has no long line and is not scanned further: a log
    of short lines costs microseconds, not a pass over all its newlines."""
    if len(data) <= MAX_LINE_BYTES:
        return
    half = max(1, MAX_LINE_BYTES // 2)
    if all(data.find(b"\n", lo, lo + half) >= 0 for lo in range(0, len(data) - half + 1, half)):
        return
    start, lines_before = 0, 0  # start of the current line; newlines before this step
    for lo in range(0, len(data), _SCAN_BYTES):
        hi = min(len(data), lo + _SCAN_BYTES)
        nl = _line_starts_ends(data, lo, hi)
        ends = np.r_[nl, hi] if hi == len(data) else nl
        lengths = ends - np.r_[start, nl[: ends.size - 1] + 1] if ends.size else ends
        over = np.flatnonzero(lengths > MAX_LINE_BYTES)
        if over.size or (nl.size == 0 and hi - start > MAX_LINE_BYTES):
            raise InputError(
                f"line longer than the {MAX_LINE_BYTES} bytes a log line may have (is this a CSV log?)",
                file=path,
                line=lines_before + (int(over[0]) if over.size else 0) + 1,
            )
        if nl.size:
            start = int(nl[-1]) + 1
        lines_before += int(nl.size)


def check_text(data: bytes, path: str | Path) -> None:
    """Refuse ``data`` (the bytes of ``path``) when its first :data:`TEXT_PROBE_BYTES` look binary:
    at least :data:`MIN_BINARY_LINES` lines that are not UTF-8, more than the lines that are.
    An :class:`InputError` naming the file, the first bad line and byte."""
    probe = data[:TEXT_PROBE_BYTES]
    if probe.isascii():
        return
    if len(data) > TEXT_PROBE_BYTES:  # the last line of the probe may be cut mid-character
        probe = probe[: probe.rfind(b"\n") + 1] or probe
    bad, good, first = 0, 0, None
    for k, line in enumerate(probe.split(b"\n"), start=1):
        try:
            line.decode("utf-8")
            good += 1
        except UnicodeDecodeError as exc:
            bad += 1
            first = first or (k, line[exc.start], exc.start + 1)
    if bad >= MIN_BINARY_LINES and bad > good:
        k, byte, col = first
        raise InputError(
            f"not a text file: {bad} of the first {bad + good} lines are not UTF-8 text "
            f"(the first: byte 0x{byte:02X} at column {col}); a log is UTF-8 text",
            file=path,
            line=k,
        )


def read_bytes(path: str | Path) -> bytes:
    """The bytes of a user log file; an unreadable one is an :class:`InputError` naming it, and so is
    a file with a line longer than :data:`MAX_LINE_BYTES` (:func:`check_line_lengths`) or one that
    is not text (:func:`check_text`): the readers then never hold more than a few copies of a
    file's bytes, whatever is in it."""
    path = Path(path)
    try:
        data = read_file(path)  # (a large file into memory advised for huge pages: fewer page faults)
    except IsADirectoryError:
        raise InputError("is a folder, not a file", file=path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", file=path) from None
    check_line_lengths(data, path)
    check_text(data, path)
    return data


#: The most lines of the wrong shape (no quote, not blank, not as many fields as the header) a
#: CSV log may hold: a file with more is refused before it is split (:func:`check_shapes`), since
#: each would be a reject holding its text -- 200 MB of text that is not the log (garbage, the
#: wrong file) would otherwise cost gigabytes of rejects. Fewer are rejected line by line.
MAX_MALFORMED_LINES = 100_000
#: Bytes per step of :func:`check_shapes` (cut at a newline): its temporaries are a few times this.
_SHAPE_BYTES = 1 << 22


def _per_line(ends: np.ndarray, at: np.ndarray) -> np.ndarray:
    """How many of the byte offsets ``at`` fall on each line (line ``k`` ends at ``ends[k]``)."""
    return np.bincount(np.searchsorted(ends, at), minlength=ends.size)[: ends.size]


def malformed_lines(data: bytes, n_fields: int, after_line: int) -> tuple[int, int | None]:
    """Lines after ``after_line`` of ``data`` that are surely not one record of ``n_fields``:
    quote-free, not blank, and with another number of separators. Returns their count and the
    first one's number. Scans ``data`` :data:`_SHAPE_BYTES` at a time (bounded temporaries):
    separators are counted per line from their offsets; only the lines with a wrong count are
    looked at for quotes and blanks."""
    count, first, line0 = 0, None, 1
    for lo, hi in file_spans(data, _SHAPE_BYTES):
        block = np.frombuffer(data, dtype=np.uint8, count=hi - lo, offset=lo)
        ends = np.flatnonzero(block == 0x0A)
        n_nl = int(ends.size)
        if hi == len(data) and (ends.size == 0 or ends[-1] != block.size - 1):
            ends = np.r_[ends, block.size]
        if ends.size:
            seps = _per_line(ends, np.flatnonzero(block == ord(SEPARATOR)))
            numbers = np.arange(line0, line0 + ends.size)
            odd = np.flatnonzero((seps != n_fields - 1) & (numbers > after_line))
            if odd.size:
                quoted = _per_line(ends, np.flatnonzero(block == ord(QUOTE)))[odd] > 0
                texty = (block != 0x20) & (block != 0x09) & (block != 0x0D) & (block != 0x0A)
                blank = _per_line(ends, np.flatnonzero(texty))[odd] == 0
                bad = odd[~quoted & ~blank]
                if bad.size:
                    count += int(bad.size)
                    first = first if first is not None else int(numbers[bad[0]])
        line0 += n_nl
    return count, first


def check_shapes(data: bytes, path: str | Path, n_fields: int, header_line: int) -> None:
    """Refuse ``data`` (the bytes of ``path``, whose header of ``n_fields`` names is line
    ``header_line``) when more than :data:`MAX_MALFORMED_LINES` of its lines are surely not
    records of the header's width (:func:`malformed_lines`): an :class:`InputError` naming the
    file and the first such line."""
    if len(data) < MAX_MALFORMED_LINES:  # too short to hold that many lines
        return
    count, first = malformed_lines(data, n_fields, header_line)
    if count > MAX_MALFORMED_LINES:
        raise InputError(
            f"{count} lines are not records of the header's {n_fields} fields (this is the first), more than "
            f"the {MAX_MALFORMED_LINES} a log may have rejected: is this the right file?",
            file=path,
            line=first,
        )


def _bad_lines(data: bytes) -> tuple[np.ndarray, list[str]]:
    """The 1-based lines of ``data`` holding bytes that are not UTF-8, and for each the reason
    naming its first such byte and column. Lines with a byte >= 0x80 are found 16 MiB at a time
    (numpy), then each of them alone is decoded: bounded memory, no per-byte Python call."""
    candidates = []
    lines_before = 0
    for lo in range(0, len(data), _SCAN_BYTES):
        hi = min(len(data), lo + _SCAN_BYTES)
        block = np.frombuffer(data, dtype=np.uint8, count=hi - lo, offset=lo)
        nl = np.flatnonzero(block == 0x0A)
        high = np.flatnonzero(block >= 0x80)
        if high.size:
            candidates.append(np.unique(np.searchsorted(nl, high)) + lines_before + 1)
        lines_before += int(nl.size)
    if not candidates:
        return np.empty(0, dtype=np.int64), []
    lines = np.unique(np.concatenate(candidates))
    nl = newlines(data)
    starts, ends = _bounds(nl, len(data), lines)
    keep, why = [], []
    for k, s, e in zip(lines.tolist(), starts, ends):
        raw = data[s:e]
        try:
            raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            keep.append(k)
            why.append(f"not UTF-8 text: byte 0x{raw[exc.start]:02X} at column {exc.start + 1}")
    return np.asarray(keep, dtype=np.int64), why


def physical_lines(data: bytes) -> pl.DataFrame:
    """Every physical line of a text file's bytes: ``line`` (1-based), ``text`` (without its
    ``\\n`` / ``\\r\\n``) and ``_reason`` (why the line is not text, else null).

    A line holding bytes that are not UTF-8 gets ``_reason`` naming the first such byte and
    its column (1-based, in bytes); its ``text`` shows invalid sequences as U+FFFD.
    """
    blocks = [_block_lines(data, lo, hi) for lo, hi in file_spans(data)]  # one span of the file at a time
    if not any(len(parts) for parts, _ in blocks):
        return pl.DataFrame(schema={"line": pl.Int64, "text": pl.String, "_reason": pl.String})
    parts = pl.concat([parts for parts, _ in blocks], rechunk=True)
    bad = _bad_lines(data) if any(not utf8 for _, utf8 in blocks) else None
    del blocks
    lines = (
        pl.DataFrame({"text": parts})
        .with_row_index("line", offset=1)
        .select(pl.col("line").cast(pl.Int64), pl.col("text").str.strip_suffix("\r"))
    )
    if bad is None:
        return lines.with_columns(pl.lit(None, pl.String).alias("_reason"))
    reasons = pl.DataFrame({"line": bad[0], "_reason": bad[1]}, schema={"line": pl.Int64, "_reason": pl.String})
    return lines.join(reasons, on="line", how="left")


def file_spans(data: bytes, step: int | None = None) -> list[tuple[int, int]]:
    """``data`` cut into spans of about ``step`` bytes (:data:`_SCAN_BYTES`), each ending just
    after a newline (the last at the end of the data): the steps a whole file is scanned or
    split in, one at a time (:func:`physical_lines`, :func:`malformed_lines`)."""
    spans, pos, size = [], 0, len(data)
    step = step or _SCAN_BYTES
    while pos < size:
        hi = min(size, pos + step)
        if hi < size:
            cut = data.rfind(b"\n", pos, hi)
            cut = cut if cut >= pos else data.find(b"\n", hi)
            hi = size if cut == -1 else cut + 1
        spans.append((pos, hi))
        pos = hi
    return spans


def _block_lines(data: bytes, lo: int, hi: int) -> tuple[pl.Series, bool]:
    """The lines of ``data[lo:hi]`` (a span of :func:`file_spans`) as text, invalid UTF-8 as U+FFFD
    (a byte-order mark at the start of the file is not data), and whether the span is UTF-8."""
    raw = data[lo:hi]
    try:
        text, utf8 = raw.decode("utf-8"), True
    except UnicodeDecodeError:
        text, utf8 = raw.decode("utf-8", errors="replace"), False
    del raw
    if lo == 0 and text.startswith("\ufeff"):
        text = text[1:]
    if not text:
        return pl.Series("text", [], dtype=pl.String), utf8
    if hi == len(data) and not text.endswith("\n"):
        text += "\n"  # the last line has no newline: the same split as one that has
    parts = pl.Series("text", [text]).str.split("\n").explode()
    return parts.slice(0, parts.len() - 1), utf8  # the empty part after the span's last newline


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


def _first_record(data: bytes) -> pl.DataFrame:
    """The first non-blank physical line of ``data`` (``line``, ``text``, ``_reason``; empty when
    there is none), split out of the start of the file only (a line is at most
    :data:`MAX_LINE_BYTES`), so a bad header costs nothing of the rest."""
    head = data[: MAX_LINE_BYTES + 1]
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


def read_csv_column(path: str | Path, col: str) -> pl.DataFrame:
    """``line`` and the String field ``col`` of every well-formed record of a CSV -- the rows
    :func:`read_csv_rows` gives for ``(col,)``, without its rejects -- by one typed read when it
    can (:func:`read_typed_csv`: the lines that read cannot take go row by row), else by
    :func:`read_csv_rows`. For what needs one column of a long log fast (the run's time origin)."""
    split = read_typed_csv(path, {col: pl.String})
    if split is None:
        return read_csv_rows(path, (col,)).frame.select("line", col)
    return pl.concat([split.good.select("line", col), split.rest.frame.select("line", col)]).sort("line")


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


@dataclass(frozen=True)
class TypedSplit:
    """A CSV file cut in two by :func:`read_typed_csv`.

    good : ``line`` + the wanted columns, typed by one ``pl.read_csv`` (the read's dtypes:
        ``Enum`` names, finite ``Float64`` numbers): rows whose line is one plain record of
        the header's width and whose every wanted field parsed as written.
    rest : the :class:`RawRows` of every other non-blank line after the header (string rows of
        the well-formed ones, a reject for each of the others): what the row-by-row path types.
    file : the file's :class:`FileLines` (the text of a line, to name it).
    """

    good: pl.DataFrame
    rest: RawRows
    header: list[str]
    file: FileLines

    def demote(self, lines: pl.Series) -> TypedSplit:
        """The split with the good rows of ``lines`` moved to ``rest`` (as string rows), for a
        check the typed read cannot make (a time stamp outside the accepted window)."""
        if lines.len() == 0:
            return self
        columns = tuple(self.rest.frame.columns[1:-1])
        moved = rows_of_lines(self.file.lines(lines.to_numpy()), self.header, columns, self.rest.source)
        frame = pl.concat([self.rest.frame, moved.frame]).sort("line")
        rejects = pl.concat([self.rest.rejects, moved.rejects]).sort("line")
        good = self.good.filter(~pl.col("line").is_in(lines.implode()))
        return TypedSplit(good, RawRows(self.rest.source, frame, rejects), self.header, self.file)


def _typed_read(data: bytes, header: list[str], dtypes: dict[str, pl.DataType], *, tolerant: bool) -> pl.DataFrame:
    """One ``pl.read_csv`` of the lines after the header (quotes taken as data): the wanted
    columns typed (``tolerant``: names read as strings and cast, a field that does not parse
    is null, a long line is cut) and, when not wanted, the header's last column as ``_last``
    (a line too short to reach it has a null there). May raise a polars error (not tolerant:
    any field that does not parse, or a long line)."""
    n = len(header)
    cols = sorted({header.index(c) for c in dtypes} | {n - 1})
    read_as = {c: (pl.String if tolerant and isinstance(d, pl.Enum) else d) for c, d in dtypes.items()}
    schema = {f"_f{i}": read_as.get(name, pl.String) for i, name in enumerate(header)}
    # polars takes the file's width from its first line: the tolerant read starts at the header
    # (as wide as the schema) and drops it, since a first data line may be short or long
    frame = pl.read_csv(
        data,
        has_header=False,
        skip_rows=0 if tolerant else 1,
        schema=schema,
        columns=cols,
        separator=SEPARATOR,
        quote_char=None,
        comment_prefix=None,
        raise_if_empty=False,
        truncate_ragged_lines=tolerant,
        ignore_errors=tolerant,
    )
    if tolerant:
        frame = frame.slice(1)
    frame = frame.rename({f"_f{i}": (header[i] if header[i] in dtypes else "_last") for i in cols})
    if tolerant:
        frame = frame.with_columns(pl.col(c).cast(d, strict=False) for c, d in dtypes.items() if isinstance(d, pl.Enum))
    return frame


#: Bytes from which :func:`numpy_column` copies a column through numpy: numpy asks the kernel
#: for transparent huge pages for its arrays of 4 MiB and more (``madvise``), polars' allocator
#: does not, so a 10^6-row float column first touched by numpy costs ~420 page faults, not ~2 000.
_NUMPY_COPY_BYTES = 1 << 22


def numpy_column(name: str, values: np.ndarray) -> pl.Series:
    """A Series over ``values`` (1-d, numeric, C-contiguous): polars takes numpy's buffer
    without copying it, so a large column made in numpy (huge pages, see
    :data:`_NUMPY_COPY_BYTES`) stays in numpy's memory."""
    return pl.Series(name, values)


def _wide_numbers(s: pl.Series) -> bool:
    """Whether ``s`` is a ``Float64`` or ``Int64`` column without nulls of at least
    :data:`_NUMPY_COPY_BYTES` (its numpy copy holds the same values: a null would become NaN)."""
    return s.dtype in (pl.Float64, pl.Int64) and s.len() * 8 >= _NUMPY_COPY_BYTES and s.null_count() == 0


def minus_constant(s: pl.Series, c: float) -> pl.Series:
    """``s - c`` (the same IEEE-754 differences as polars'), made in numpy for a large
    ``Float64`` column without nulls (:func:`numpy_column`)."""
    if s.dtype == pl.Float64 and _wide_numbers(s):
        with np.errstate(over="ignore", invalid="ignore"):  # (inf and NaN as polars makes them, silently)
            return numpy_column(s.name, s.to_numpy() - c)
    return s - c


def kept_rows(s: pl.Series, keep: np.ndarray | None) -> pl.Series:
    """``s.filter(keep)`` (a boolean mask; ``None``: all of ``s``) with its sorted flag, the rows
    of a large ``Float64`` / ``Int64`` column without nulls taken in numpy (:func:`numpy_column`)."""
    if keep is None:
        return s
    if not _wide_numbers(s):
        return s.filter(pl.Series(keep))
    out = numpy_column(s.name, s.to_numpy()[keep])
    if s.flags.get("SORTED_ASC") or s.flags.get("SORTED_DESC"):  # a subsequence keeps the order
        out = out.set_sorted(descending=bool(s.flags.get("SORTED_DESC")))
    return out


def one_buffer(frame: pl.DataFrame) -> pl.DataFrame:
    """``frame`` with every column in one buffer (``rechunk``), a large ``Float64`` / ``Int64``
    column without nulls copied through numpy (:func:`numpy_column`: a fifth of the page faults
    of polars' own copy); the same values, dtypes and sorted flags."""
    cols = []
    for s in frame.iter_columns():
        if s.n_chunks() > 1 and _wide_numbers(s):
            one = numpy_column(s.name, np.concatenate([c.to_numpy() for c in s.get_chunks()]))
            if s.flags.get("SORTED_ASC") or s.flags.get("SORTED_DESC"):
                one = one.set_sorted(descending=bool(s.flags.get("SORTED_DESC")))
            cols.append(one)
        else:
            cols.append(s.rechunk())
    return pl.DataFrame(cols)


def _parsed(frame: pl.DataFrame, dtypes: dict[str, pl.DataType]) -> pl.Expr:
    """Rows whose every wanted field parsed (not null; numbers finite; free names without
    surrounding blanks, as the row-by-row path strips them) and that reach the last column."""
    ok = [pl.col(c).is_not_null() for c in dtypes] + [pl.col(c).is_finite() for c, d in dtypes.items() if d.is_float()]
    ok += [pl.col(c).str.strip_chars() == pl.col(c) for c, d in dtypes.items() if d == pl.String]  # names as written
    if "_last" in frame.columns:
        ok.append(pl.col("_last").is_not_null())
    return pl.all_horizontal(ok)


def _all_parsed(frame: pl.DataFrame, dtypes: dict[str, pl.DataType]) -> bool:
    """Whether every row is :func:`_parsed` (nulls from the columns' counts, no row scan)."""
    if sum(frame.null_count().row(0)):
        return False
    for c, d in dtypes.items():  # finite: the min and max are (NaN and inf show there), no mask
        if d.is_float() and frame.height:
            a = frame[c].to_numpy()
            if not (np.isfinite(a.min()) and np.isfinite(a.max())):
                return False
    strings = [c for c, d in dtypes.items() if d == pl.String]
    return not strings or frame.select(_parsed(frame.select(strings), {c: pl.String for c in strings}).all()).item()


def _odd_lines(work: bytes, nl: np.ndarray) -> np.ndarray:
    """The 1-based numbers of the lines of ``work`` (``\\r\\n`` line ends already made ``\\n``;
    ``nl``: its newlines) that hold a quote, a carriage return or, when ``work`` is not UTF-8,
    any byte that is not ASCII: the row-by-row path reads them."""
    arr = np.frombuffer(work, dtype=np.uint8)
    at = []
    if b"\r" in work:
        at.append(np.flatnonzero(arr == 0x0D))
    if b'"' in work:
        at.append(np.flatnonzero(arr == 0x22))
    if not work.isascii():
        try:
            work.decode("utf-8")
        except UnicodeDecodeError:
            at.append(np.flatnonzero(arr >= 0x80))
    if not at:
        return np.empty(0, dtype=np.int64)
    return np.unique(np.searchsorted(nl, np.concatenate(at), side="left") + 1)


def _emptied(work: bytes, nl: np.ndarray, lines: np.ndarray) -> bytes:
    """``work`` with each of the given lines made one space (same lines, same numbers: a last
    line without a newline stays a line; the typed read sees a blank line)."""
    starts, ends = _bounds(nl, len(work), lines)
    parts, pos = [], 0
    for s, e in zip(starts, ends):
        parts.append(work[pos:s])
        parts.append(b" ")
        pos = e
    parts.append(work[pos:])
    return b"".join(parts)


def _commas(work: bytes, nl: np.ndarray, lines: np.ndarray) -> int:
    """Separators on the given 1-based lines of ``work``, in all."""
    if lines.size > _FEW_LINES:
        return int(_separators_per_line(work, nl.size + 1)[lines - 1].sum())
    starts, ends = _bounds(nl, len(work), lines)
    sep = SEPARATOR.encode()
    return sum(work.count(sep, s, e) for s, e in zip(starts, ends))


def _separators_per_line(work: bytes, n_lines: int) -> np.ndarray:
    """Separators on every line of ``work``: compiled from :data:`~onebit.readers.kernels.MIN_ROWS`
    lines on when numba is loaded already (:func:`~onebit.core.compiled.numba_loaded`), else
    with numpy (:func:`~onebit.readers.kernels.separators_per_line_vectorised`): a reader never
    pays numba's load (0.3-0.5 s) for a messy file."""
    buf = np.frombuffer(work, dtype=np.uint8)
    if n_lines >= kernels.MIN_ROWS and numba_loaded():
        return kernels.separators_per_line(buf, ord(SEPARATOR))
    return kernels.separators_per_line_vectorised(buf, ord(SEPARATOR))


def read_typed_csv(path: str | Path, dtypes: dict[str, pl.DataType]) -> TypedSplit | None:
    """Read a CSV by one typed ``pl.read_csv``, leaving to the row-by-row path only the lines it
    cannot take (:class:`TypedSplit`); ``None`` when the header is not a plain first line naming
    each wanted column once (then :func:`read_csv_rows` reads the file, or names its fault).

    ``dtypes`` maps each wanted column to the type its fields parse as when the row is good
    (an ``Enum`` for names and spellings). A clean file (UTF-8, no quotes or carriage
    returns, every line one record whose fields parse: the usual log) is typed by one strict
    read. Any other file is read once more, tolerantly: a field that does not parse is null
    and marks its line, and so does a line holding a quote, a carriage return (but in a
    ``\\r\\n`` line end) or, in a file that is not UTF-8, a byte that is not ASCII (such
    lines are blanked for the read), and a line too short to reach the header's last column.
    Lines with too many fields are found by counting separators: on every line
    (:func:`~onebit.readers.kernels.separators_per_line`) when the total of the unmarked lines
    is more than their width allows, else never. Each marked line is then cut out of the file
    and goes through :func:`rows_of_lines`, which names its fault or splits its fields (blank
    lines are not rows). A row's line number is its row index + 2 (an emptied or blank line
    is a null row of the read).
    """
    path = Path(path)
    try:
        data = read_bytes(path)
    except InputError:
        return None
    if not data or data.startswith(codecs.BOM_UTF8):
        return None
    end = data.find(b"\n")
    if end <= 0:  # no data line, or a blank first line
        return None
    head = data[:end].removesuffix(b"\r")
    if b'"' in head or b"\r" in head:
        return None
    try:
        head_text = head.decode("utf-8")
    except UnicodeDecodeError:
        return None
    header = [name.strip() for name in head_text.split(SEPARATOR)]
    if len(header) > MAX_HEADER_FIELDS or any(header.count(c) != 1 for c in dtypes) or not head_text.strip(" \t"):
        return None
    n = len(header)
    file = FileLines(data)  # its newlines counted once: the lines, and where a named line is
    n_lines = file.n_lines - 1
    columns = tuple(dtypes)
    empty_rest = RawRows(path.name, _empty_rows(columns), pl.DataFrame(schema=REJECTS))
    plain = b'"' not in data and b"\r" not in data
    if plain and (data.isascii() or _utf8(data)):
        try:
            frame = _typed_read(data, header, dtypes, tolerant=False)
        except pl.exceptions.PolarsError:
            frame = None
        # one buffer per column (the parse gives one per thread's piece): every later numpy
        # view of a column is free, not a copy each time (the checks, time origin, decoder)
        frame = one_buffer(frame) if frame is not None and frame.height == n_lines else None
        if frame is not None and _all_parsed(frame, dtypes) and _widths_hold(data, header, dtypes, n_lines):
            frame = frame.select(columns).insert_column(0, _line_numbers(frame.height))
            if "t" in frame.columns and frame.schema["t"].is_float() and in_time_order(frame["t"]):
                frame = mark_in_order(frame, "t")  # found once: the time origin and the checks read the flag
            return TypedSplit(frame, empty_rest, header, file)
    check_shapes(data, path, n, 1)  # not clean: refused before the tolerant read if it is not this log
    work = data.replace(b"\r\n", b"\n") if b"\r" in data else data
    wfile = file if work is data else FileLines(work)
    odd = _odd_lines(work, wfile.nl) if not plain or not work.isascii() else np.empty(0, dtype=np.int64)
    if odd.size and odd[0] == 1:
        return None
    try:
        frame = _typed_read(_emptied(work, wfile.nl, odd) if odd.size else work, header, dtypes, tolerant=True)
    except pl.exceptions.PolarsError:
        return None
    if frame.height != n_lines:  # never guess which row is which line
        return None
    frame = frame.with_columns(
        pl.int_range(2, frame.height + 2, dtype=pl.Int64).alias("line"), _parsed(frame, dtypes).alias("_ok")
    )
    marked = frame.filter(~pl.col("_ok"))["line"].to_numpy()
    total = int(np.count_nonzero(np.frombuffer(work, dtype=np.uint8) == ord(SEPARATOR))) - head_text.count(SEPARATOR)
    if total - _commas(work, wfile.nl, marked) != (n - 1) * (
        frame.height - marked.size
    ):  # a good-looking line is too long
        per_line = _separators_per_line(work, n_lines)[1 : n_lines + 1]
        frame = frame.with_columns(pl.col("_ok") & pl.Series(per_line == n - 1))
        marked = frame.filter(~pl.col("_ok"))["line"].to_numpy()
    good = frame.filter(pl.col("_ok")).select("line", *columns)
    if marked.size == 0:
        return TypedSplit(good, empty_rest, header, file)
    lines = file.lines(marked)
    lines = lines.filter(~pl.col("text").str.contains(_BLANK) | pl.col("_reason").is_not_null())
    return TypedSplit(good, rows_of_lines(lines, header, columns, path.name), header, file)


def _line_numbers(n: int) -> pl.Series:
    """``line`` of the ``n`` rows of a typed read: 2, 3, ... (the header is line 1), as numpy
    makes it (half the time of polars' ``int_range`` in a fresh process), flagged sorted (the
    checks of line order read the flag)."""
    return pl.Series("line", np.arange(2, n + 2, dtype=np.int64)).set_sorted()


def _widths_hold(data: bytes, header: list[str], dtypes: dict[str, pl.DataType], n_lines: int) -> bool:
    """Whether no line can be longer than the header: the strict read raises on a long line
    only when it reads every column, so when some are not read the separators are counted
    (every line of the header's width holds ``n - 1``; fewer is caught by the read)."""
    n = len(header)
    if len({header.index(c) for c in dtypes} | {n - 1}) == n:
        return True
    return int(np.count_nonzero(np.frombuffer(data, dtype=np.uint8) == ord(SEPARATOR))) == (n - 1) * (n_lines + 1)


def _utf8(data: bytes) -> bool:
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


def clean_time(t: pl.Series, epoch: str | TimeOrigin | None) -> pl.Series | None:
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


def newlines(data: bytes) -> np.ndarray:
    """Byte offsets of every ``\\n`` of ``data``: line ``k`` (1-based) runs from just after the
    ``(k-1)``-th to the ``k``-th (or to the end of the data)."""
    return np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == 0x0A)


#: Above this many lines :func:`line_texts` splits the whole file (:func:`physical_lines`)
#: instead of cutting the lines out one by one.
_FEW_LINES = 20_000


def _bounds(nl: np.ndarray, size: int, lines: np.ndarray) -> tuple[list[int], list[int]]:
    """Start and end byte offsets of the given 1-based lines (``nl``: :func:`newlines`; ``size``: bytes)."""
    if nl.size == 0:
        return [0] * lines.size, [size] * lines.size
    starts = np.where(lines > 1, nl[np.clip(lines - 2, 0, nl.size - 1)] + 1, 0)
    ends = np.where(lines - 1 < nl.size, nl[np.clip(lines - 1, 0, nl.size - 1)], size)
    return starts.tolist(), ends.tolist()


def line_texts(data: bytes, lines, nl: np.ndarray | None = None) -> pl.DataFrame:
    """The rows of :func:`physical_lines` (``line``, ``text``, ``_reason``) for the given 1-based
    line numbers only (each once, in order; numbers past the end are left out), cut out of
    ``data`` at its newlines (``nl``: :func:`newlines`, when already known): what naming a few
    bad lines of a large file costs, instead of splitting all of it (:meth:`FileLines.lines`)."""
    file = FileLines(data)
    if nl is not None:
        file._nl = nl
    return file.lines(lines)


def _ascii_line_texts(data: bytes, want: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> pl.DataFrame:
    """:func:`line_texts` of ASCII ``data`` (the lines ``want``, 1-based, ascending, each in the
    file, from byte ``starts`` to ``ends``) without a Python step per line: their bytes gathered
    with their line ends into one string, split at the newlines; a ``\r`` before a newline is
    dropped, as there."""
    buf = np.frombuffer(data, dtype=np.uint8)
    span = ends - starts + 1  # each line and its newline
    first = np.cumsum(span) - span
    at = np.repeat(starts - first, span) + np.arange(int(span.sum()), dtype=np.int64)
    np.minimum(at, buf.size - 1, out=at)  # (a last line without a newline: its end is past the data)
    cut = buf[at]
    cut[first + span - 1] = 0x0A  # every line ends with a newline (the file is not copied to give it one)
    text = pl.Series([cut.tobytes().decode("ascii")]).str.split("\n").explode().slice(0, want.size)
    return pl.DataFrame(
        {"line": want, "text": text.str.strip_suffix("\r"), "_reason": pl.Series([None] * want.size, dtype=pl.String)},
        schema={"line": pl.Int64, "text": pl.String, "_reason": pl.String},
    )


def _line_texts_reference(data: bytes, lines) -> pl.DataFrame:
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


#: Bytes per step of :class:`FileLines`' newline count (its index of where the lines are).
_LINE_STEP = 1 << 20
#: Bytes per block of :class:`FileLines`' index of where a named line is (a newline count per
#: block): a line is found among the 64 bytes of its block, not among its step's.
_BLOCK = 64
_BYTE_SUM = np.uint64(0x0101010101010101)


def block_newlines(buf: np.ndarray, step: int = _LINE_STEP) -> np.ndarray:
    """How many newlines each :data:`_BLOCK` bytes of ``buf`` (uint8) hold (the last block may be
    shorter), found ``step`` bytes at a time (bounded temporaries). In a block the 0/1 bytes of
    its newline mask are summed as eight uint64 words, then the eight byte lanes of that sum
    (each at most 8) by one multiplication: no per-block reduction call."""
    n = buf.shape[0]
    full = n // _BLOCK * _BLOCK
    out = np.empty(-(-n // _BLOCK), dtype=np.uint8)
    step = max(_BLOCK, step // _BLOCK * _BLOCK)
    for lo in range(0, full, step):
        hi = min(full, lo + step)
        words = (buf[lo:hi] == 0x0A).view(np.uint64).reshape(-1, _BLOCK // 8)
        s = words[:, 0] + words[:, 1]
        for j in range(2, _BLOCK // 8):
            s += words[:, j]
        s *= _BYTE_SUM  # the top byte of the product is the sum of the eight byte lanes
        s >>= np.uint64(56)
        out[lo // _BLOCK : hi // _BLOCK] = s
    if full < n:
        out[-1] = np.count_nonzero(buf[full:] == 0x0A)
    return out


def block_newlines_reference(buf: np.ndarray) -> np.ndarray:
    """:func:`block_newlines` one block at a time: its test oracle."""
    return np.array(
        [np.count_nonzero(buf[lo : lo + _BLOCK] == 0x0A) for lo in range(0, buf.shape[0], _BLOCK)], dtype=np.uint8
    )


class FileLines:
    """A file's bytes and, once needed, where its lines are: the text of any line by number.

    Naming a few lines of a large file does not list all its newlines (:attr:`nl`, 8 bytes per
    line): the newlines of every ``step`` bytes (:data:`_LINE_STEP`) are counted once (:meth:`step_newlines`,
    the pass that also gives the number of lines), and a line's bounds are found in its step
    alone."""

    def __init__(self, data: bytes, step: int = _LINE_STEP) -> None:
        self.data = data
        self.step = step
        self._nl: np.ndarray | None = None
        self._steps: np.ndarray | None = None
        self._blocks: np.ndarray | None = None
        self._ascii: bool | None = None

    @property
    def nl(self) -> np.ndarray:
        """Byte offsets of every newline (:func:`newlines`)."""
        if self._nl is None:
            self._nl = newlines(self.data)
        return self._nl

    def step_newlines(self) -> np.ndarray:
        """How many newlines each :attr:`step` bytes of the file hold (counted once)."""
        if self._steps is None:
            buf, step = np.frombuffer(self.data, dtype=np.uint8), self.step
            self._steps = np.array(
                [np.count_nonzero(buf[lo : lo + step] == 0x0A) for lo in range(0, buf.size, step)],
                dtype=np.int64,
            )
        return self._steps

    @property
    def n_newlines(self) -> int:
        return int(self._nl.size) if self._nl is not None else int(self.step_newlines().sum())

    @property
    def n_lines(self) -> int:
        """Physical lines: one per newline, and the text after the last one if any."""
        return self.n_newlines + (len(self.data) > 0 and not self.data.endswith(b"\n"))

    def is_ascii(self) -> bool:
        if self._ascii is None:
            self._ascii = self.data.isascii()
        return self._ascii

    def block_ends(self) -> np.ndarray:
        """Newlines up to the end of each :data:`_BLOCK` bytes of the file (cumulative; counted
        once, when a line is first named): where a named line is, to its block."""
        if self._blocks is None:
            self._blocks = np.cumsum(
                block_newlines(np.frombuffer(self.data, dtype=np.uint8), self.step), dtype=np.int64
            )
        return self._blocks

    def newline_offsets(self, k: np.ndarray) -> np.ndarray:
        """Byte offsets of the newlines ``k`` (0-based, each below :attr:`n_newlines`): from
        :attr:`nl` when listed, else each one found in its block of :data:`_BLOCK` bytes
        (:meth:`block_ends`: the block holding it, then its rank among the block's newlines)."""
        k = np.asarray(k, dtype=np.int64)
        if self._nl is not None:
            return self._nl[k]
        if k.size == 0:
            return np.empty(0, dtype=np.int64)
        ends = self.block_ends()
        block = np.searchsorted(ends, k, side="right")
        rank = k - np.where(block > 0, ends[block - 1], 0)  # newlines of the block before this one
        count = ends[block] - (k - rank)  # newlines in each one's block
        buf = np.frombuffer(self.data, dtype=np.uint8)
        full = buf.size // _BLOCK
        rows = np.empty((k.size, _BLOCK), dtype=np.uint8)
        inside = block < full
        rows[inside] = buf[: full * _BLOCK].reshape(full, _BLOCK)[block[inside]]
        if not inside.all():  # the file's last block, shorter: padded with a byte that is not a newline
            tail = np.zeros(_BLOCK, dtype=np.uint8)
            tail[: buf.size - full * _BLOCK] = buf[full * _BLOCK :]
            rows[~inside] = tail
        at = np.flatnonzero(rows == 0x0A)  # the blocks' newlines, block after block (each block's count)
        first = np.cumsum(count) - count
        return block * _BLOCK + at[first + rank] - np.arange(k.size, dtype=np.int64) * _BLOCK

    def bounds(self, want: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Start and end byte offsets of the lines ``want`` (1-based, each in the file)."""
        n_nl = self.n_newlines
        starts = np.zeros(want.size, dtype=np.int64)
        ends = np.full(want.size, len(self.data), dtype=np.int64)
        after = np.flatnonzero(want > 1)  # lines after the first start past the newline before them
        closed = np.flatnonzero(want - 1 < n_nl)  # lines that end at a newline
        at = self.newline_offsets(np.concatenate([want[after] - 2, want[closed] - 1]))  # one look-up for both
        starts[after] = at[: after.size] + 1
        ends[closed] = at[after.size :]
        return starts, ends

    def lines(self, lines) -> pl.DataFrame:
        """The rows of :func:`physical_lines` (``line``, ``text``, ``_reason``) of these 1-based
        line numbers (each once, in order; numbers past the end left out)."""
        data = self.data
        want = np.unique(np.asarray(lines, dtype=np.int64))
        schema = {"line": pl.Int64, "text": pl.String, "_reason": pl.String}
        if want.size > _FEW_LINES:
            return physical_lines(data).filter(pl.col("line").is_in(pl.Series(want).implode()))
        want = want[(want >= 1) & (want <= self.n_lines)]
        starts, ends = self.bounds(want)
        if want.size > 64 and self.is_ascii():  # no decoding to fail: cut out in one go
            return _ascii_line_texts(data, want, starts, ends)
        texts, reasons = [], []
        for k, s, e in zip(want.tolist(), starts.tolist(), ends.tolist()):  # the named lines only
            raw = data[s:e]
            try:
                text, why = raw.decode("utf-8"), None
            except UnicodeDecodeError as exc:  # as physical_lines: U+FFFD per invalid sequence, the first one named
                text = raw.decode("utf-8", errors="replace")
                why = f"not UTF-8 text: byte 0x{raw[exc.start]:02X} at column {exc.start + 1}"
            if k == 1 and text.startswith("\ufeff"):
                text = text[1:]
            texts.append(text.removesuffix("\r"))
            reasons.append(why)
        return pl.DataFrame({"line": want, "text": texts, "_reason": reasons}, schema=schema)

    def texts(self, lines, *, limit: int | None = MAX_QUOTE) -> dict[int, str]:
        """The text of each of these lines, cut to ``limit`` characters (``None``: whole)."""
        if len(lines) == 0:
            return {}
        want = np.unique(np.asarray(lines, dtype=np.int64))
        if want.size <= _FEW_LINES and self.is_ascii():  # nothing to decode: cut out one by one, no table
            want = want[(want >= 1) & (want <= self.n_lines)]
            starts, ends = self.bounds(want)
            buf, data = np.frombuffer(self.data, dtype=np.uint8), self.data
            if want.size:  # a line's "\r" before its newline is not text (as physical_lines)
                ends -= (ends > starts) & (buf[np.maximum(ends - 1, 0)] == 0x0D)
            text = [data[s:e].decode("ascii") for s, e in zip(starts.tolist(), ends.tolist())]
            if limit is not None:  # only the lines longer than the limit are cut (ASCII: a byte a character)
                for i in np.flatnonzero(ends - starts > limit).tolist():
                    text[i] = bounded(text[i], limit)
            return dict(zip(want.tolist(), text))
        found = self.lines(lines)
        return dict(found.select("line", "text" if limit is None else _bounded("text", limit)).iter_rows())


def raw_lines(
    path: Path, lines: list[int], *, limit: int | None = MAX_QUOTE, data: FileLines | None = None
) -> dict[int, str]:
    """The text of the given 1-based physical line numbers, each cut to ``limit`` characters
    (:data:`~onebit.core.errors.MAX_QUOTE`; ``None``: whole) (read only when there are rejects;
    ``data``: the file's :class:`FileLines`, when already read)."""
    if not lines:
        return {}
    if data is None:
        try:
            data = FileLines(read_bytes(path))
        except InputError:
            return {}
    return data.texts(lines, limit=limit)


def make_rejects(bad: pl.DataFrame, source: str, path: Path | None, file: FileLines | None = None) -> pl.DataFrame:
    """Build ``rejects`` rows from a frame with ``line``, ``_reason`` and optionally ``raw``;
    the raw text and the reason are cut to :data:`~onebit.core.errors.MAX_QUOTE` characters
    (``file``: the CSV's :class:`FileLines`, when already read)."""
    if bad.height == 0:
        return pl.DataFrame(schema=REJECTS)
    if "raw" in bad.columns and bad["raw"].null_count() < bad.height:
        raw = bad["raw"]
    elif path is not None and path.suffix.lower() == ".csv":
        text = raw_lines(path, bad["line"].to_list(), data=file)
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


def parse_time(col: str, epoch: str | TimeOrigin | None, frame: pl.DataFrame | None = None) -> tuple[pl.Expr, pl.Expr]:
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
                pl.lit(col),
                s,
                pl.lit(round(lo, 6)),
                pl.lit(round(hi, 6)),
                pl.lit(MAX_GAP_S / 86400),
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
        reason = reason.when(~s.is_in(list(known))).then(
            pl.format("field '{}': unknown {} '{}'", pl.lit(col), pl.lit(what), s)
        )
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
    within the tolerance and sorted into place (``reordered``); ``file``: the CSV's
    :class:`FileLines` when read whole (to name more lines)."""

    accepted: pl.DataFrame
    rejects: pl.DataFrame
    reordered: int = 0
    file: FileLines | None = None


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
    return order_checks(
        ok,
        key=key,
        tolerance=tolerance,
        field_bad=typed.filter(pl.col("_reason").is_not_null()),
        prior=raw.rejects,
        source=raw.source,
        path=path,
        columns=tuple(parsers),
    )


def in_time_order(t: pl.Series) -> bool:
    """Whether ``t`` never decreases (one pass in numpy; nulls and NaN are never in order); a
    column polars knows to be sorted (its flag: :func:`mark_in_order`), without nulls or NaN,
    needs no pass over its values."""
    if t.flags.get("SORTED_ASC") and t.null_count() == 0 and not (t.dtype.is_float() and t.len() and math.isnan(t[-1])):
        return True  # (polars sorts NaN last: a sorted column holds one only if its last value is NaN)
    v = t.to_numpy()
    return bool(v.size < 2 or (v[1:] >= v[:-1]).all())


def mark_in_order(rows: pl.DataFrame, *columns: str) -> pl.DataFrame:
    """``rows`` with ``columns`` flagged as sorted ascending for polars, once found in order
    (:func:`in_time_order`): later checks of the same rows read the flag instead of the values."""
    return rows.with_columns(pl.col(c).set_sorted() for c in columns)


def by_time(rows: pl.DataFrame) -> pl.DataFrame:
    """``rows`` sorted by ``t``, then ``line`` (file order within a stamp); no sort when both
    already increase (the accepted rows of a log written in time order)."""
    if in_time_order(rows["t"]) and in_time_order(rows["line"]):
        return rows
    return rows.sort(["t", "line"])


def duplicate_of(ok: pl.DataFrame, key: tuple[str, ...]) -> pl.Series:
    """For every row of ``ok`` (``line`` + the ``key`` columns, ``t`` among them), the first
    ``line`` of an earlier row with the same ``key`` (nulls equal), else null
    (:func:`duplicate_rows`, as a column)."""
    out = pl.Series("_dup", [], dtype=pl.Int64).extend_constant(None, ok.height)
    dup = duplicate_rows(ok, key)
    return out.scatter(dup["_i"], dup["_first"]) if dup.height else out


def duplicate_rows(ok: pl.DataFrame, key: tuple[str, ...], *, in_order: bool | None = None) -> pl.DataFrame:
    """The rows of ``ok`` (``line`` + the ``key`` columns, ``t`` among them) identical in ``key``
    to an earlier row (nulls equal): their index ``_i`` and the ``line`` of the first such
    row, ``_first``. Found by one sort on the key and a comparison of neighbours (no window
    over the key). Rows whose ``t`` no other row has cannot be duplicates; when ``t`` never
    decreases in file order (the usual log; ``in_order``: already known) only the runs of
    equal ``t`` are sorted, and a log without two equal stamps costs one comparison."""
    none = pl.DataFrame(schema={"_i": pl.Int64, "_first": pl.Int64})
    v = ok["t"].to_numpy() if "t" in ok.columns else None  # a time-free table: every row a candidate
    if v is not None and (in_order if in_order is not None else in_time_order(ok["t"])):
        eq = v[1:] == v[:-1]
        if not eq.any():  # no two rows share a stamp: no duplicate
            return none
        first = np.flatnonzero(eq)  # rows whose stamp the next row has
        at = np.unique(np.concatenate([first, first + 1]))  # only the rows in a run of equal stamps
        cand = ok[at].select(pl.Series("_i", at, dtype=pl.Int64), "line", *key)
        found = _duplicates_numpy(cand, key)  # (a few rows: numpy's sort beats a polars query)
        return found if found is not None else _duplicates_polars(cand, key)
    cand = ok.select(pl.int_range(pl.len(), dtype=pl.Int64).alias("_i"), "line", *key)
    return _duplicates_polars(cand, key)


def _duplicates_polars(cand: pl.DataFrame, key: tuple[str, ...]) -> pl.DataFrame:
    """:func:`duplicate_rows` of candidate rows (``_i``, ``line``, the ``key`` columns): one sort
    on the key and line, each row compared with the one before (nulls equal)."""
    cand = cand.sort([*key, "line"])
    same = pl.all_horizontal([pl.col(k).eq_missing(pl.col(k).shift(1)) for k in key]).fill_null(False)
    cand = cand.with_columns(pl.when(same).then(None).otherwise(pl.col("line")).forward_fill().alias("_first"))
    return cand.filter(pl.col("_first") != pl.col("line")).select("_i", "_first")


def _key_values(s: pl.Series) -> np.ndarray | None:
    """The values of a key column as numpy compares them the way polars' ``eq_missing`` does
    (enum codes, booleans, integers, finite floats without a negative zero, no nulls), else
    ``None``."""
    if s.null_count():
        return None
    if isinstance(s.dtype, pl.Enum):
        return s.to_physical().to_numpy()
    if s.dtype == pl.Boolean or s.dtype.is_integer():
        return s.to_numpy()
    if s.dtype.is_float():
        a = s.to_numpy()
        return a if np.isfinite(a).all() and not (np.signbit(a) & (a == 0)).any() else None
    return None


def _duplicates_numpy(cand: pl.DataFrame, key: tuple[str, ...]) -> pl.DataFrame | None:
    """:func:`_duplicates_polars` in numpy (one ``lexsort`` on the key and line, neighbours
    compared), for key columns numpy compares as polars does (:func:`_key_values`); ``None``
    for others (text, nulls, NaN). Equal to it (tests)."""
    values = [_key_values(cand[k]) for k in key]
    if cand.height == 0 or any(v is None for v in values):
        return None
    line = cand["line"].to_numpy()
    order = np.lexsort((line, *values[::-1]))  # by the key (its first column first), then line
    same = np.ones(max(line.size - 1, 0), dtype=np.bool_)
    for v in values:
        vs = v[order]
        same &= vs[1:] == vs[:-1]
    start = np.ones(line.size, dtype=np.bool_)  # a row that starts its group of equal keys
    start[1:] = ~same
    first = line[order][np.maximum.accumulate(np.where(start, np.arange(line.size), 0))]
    dup = np.flatnonzero(~start)
    return pl.DataFrame(
        {"_i": cand["_i"].to_numpy()[order][dup], "_first": first[dup]},
        schema={"_i": pl.Int64, "_first": pl.Int64},
    )


def backwards_reason(tolerance: float) -> pl.Expr:
    """The reject reason of a row whose ``t`` is earlier than ``_prev`` (the latest time before
    it) by more than ``tolerance`` seconds."""
    if tolerance <= 0:
        return pl.format("timestamp goes backwards ({} after {})", pl.col("t"), pl.col("_prev"))
    return pl.format(
        "timestamp goes backwards ({} after {}, more than {} s)", pl.col("t"), pl.col("_prev"), pl.lit(tolerance)
    )


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
    data: FileLines | None = None,
) -> TypedRows:
    """The ordering checks of :func:`check_rows` on rows whose fields all parsed (``ok``: ``line``
    + typed ``columns``, in file order): duplicates (:func:`duplicate_of`), then rows going
    backwards by more than ``tolerance``. ``field_bad`` (rows rejected by their fields, with
    ``_reason``) and ``prior`` (rejects already made) join the rejects. Reasons are formatted
    for the rejected rows only; rows without ``raw`` get their line's text from ``path``
    (``data``: its :class:`FileLines`, when already read)."""
    parts = [field_bad] if field_bad is not None and field_bad.height else []
    in_order = "t" in ok.columns and in_time_order(ok["t"])  # (dropping rows keeps the order)
    dups = duplicate_rows(ok, key, in_order=in_order)
    if dups.height:
        same = " and ".join(", ".join(key).rsplit(", ", 1))  # ("t", "target") -> "t and target"
        dup_of = (
            pl.Series("_dup", [], dtype=pl.Int64).extend_constant(None, ok.height).scatter(dups["_i"], dups["_first"])
        )
        ok = ok.with_columns(dup_of)
        dup = ok.filter(pl.col("_dup").is_not_null()).rechunk()
        parts.append(
            dup.with_columns(pl.format("duplicate of line {} (same {})", pl.col("_dup"), pl.lit(same)).alias("_reason"))
        )
        ok = ok.filter(pl.col("_dup").is_null()).drop("_dup")
    reordered = 0
    if "t" in ok.columns and not in_order:  # some row is earlier than a row before it (time-free tables: no order)
        ok = ok.sort("line").with_columns(pl.col("t").cum_max().shift(1).alias("_prev"))
        back = (pl.col("t") < pl.col("_prev") - tolerance).fill_null(False)
        late = ok.filter(back).rechunk()  # (polars 2.1 panics formatting a filtered frame's floats otherwise)
        if late.height:
            why = backwards_reason(tolerance)
            parts.append(late.with_columns(why.alias("_reason")))
            ok = ok.filter(~back)
        reordered = int(ok.select((pl.col("t") < pl.col("_prev")).fill_null(False).sum()).item())
        ok = ok.drop("_prev")
    if parts:
        with_raw = all("raw" in p.columns for p in parts)
        bad = pl.concat([p.select("line", "_reason", *(["raw"] if with_raw else [])) for p in parts]).sort("line")
        if path is not None and not with_raw:  # rows of the typed read: their text read back
            text = raw_lines(path, bad["line"].to_list(), limit=None, data=data)
            bad = bad.with_columns(pl.Series("raw", [text.get(i) for i in bad["line"].to_list()], dtype=pl.String))
        made = make_rejects(bad, source, path)
    else:
        made = pl.DataFrame(schema=REJECTS)
    rejects = made if prior is None else pl.concat([prior, made]).sort("line")
    accepted = ok.select("line", *columns)
    if "t" in accepted.columns and not in_order and (reordered or not in_time_order(accepted["t"])):
        accepted = accepted.sort(["t", "line"])
    elif in_order:  # the finite stamps of parsed rows, in order: flagged so, for the reader's next checks
        accepted = mark_in_order(accepted, "t")
    return TypedRows(accepted, rejects, reordered)


def check_split(
    split: TypedSplit,
    good: pl.DataFrame,
    parsers: Callable[[TimeOrigin, pl.DataFrame], dict[str, tuple[pl.Expr, pl.Expr]]],
    *,
    epoch: str | TimeOrigin | None,
    key: tuple[str, ...],
    tolerance: float,
    path: Path,
) -> TypedRows:
    """:func:`check_rows` of a file read by :func:`read_typed_csv`: ``good`` (the split's good
    rows with numeric ``t`` as written, the other columns in the types the readers decode) and
    the rest typed row by row by ``parsers(origin, frame)``, whose values are cast to ``good``'s
    types; then the ordering checks over both. The time origin is the one the row-by-row path
    finds over all the rows (:func:`~onebit.readers.timebase.parts_origin`); good rows whose
    stamp falls outside its window go to the row-by-row side, which names them."""
    origin = epoch if isinstance(epoch, TimeOrigin) else parts_origin(good["t"], split.rest.frame["t"], epoch)
    if (math.isfinite(origin.lo) or math.isfinite(origin.hi)) and good.height:
        lo, hi = good["t"].min() - origin.numeric, good["t"].max() - origin.numeric  # no mask when none is out
        t = good["t"] - origin.numeric if lo < origin.lo - 1e-3 or hi > origin.hi + 1e-3 else None
        lone = (t < origin.lo - 1e-3) | (t > origin.hi + 1e-3) if t is not None else None
        if lone is not None and lone.any():
            out = good.filter(lone)["line"]
            split = split.demote(out)
            good = good.filter(~lone)
    if origin.numeric:  # (a constant taken off keeps the order: rounding is monotone)
        in_order = bool(good["t"].flags.get("SORTED_ASC"))
        good = good.with_columns(minus_constant(good["t"], origin.numeric))
        good = mark_in_order(good, "t") if in_order else good
    rest = split.rest
    columns = tuple(good.columns[1:])
    if rest.frame.height == 0:
        res = order_checks(
            good,
            key=key,
            tolerance=tolerance,
            columns=columns,
            source=rest.source,
            path=path,
            prior=rest.rejects if rest.rejects.height else None,
            data=split.file,
        )
    else:
        p = parsers(origin, rest.frame)
        typed = (
            rest.frame.drop("raw")
            .with_columns(pl.coalesce([r for _, r in p.values()]).alias("_reason"))
            .with_columns(v.alias(c) for c, (v, _) in p.items())
        )
        fine = typed.filter(pl.col("_reason").is_null()).select(
            "line", *[pl.col(c).cast(good.schema[c]) for c in columns]
        )
        ok = pl.concat([good, fine]).sort("line") if fine.height else good
        res = order_checks(
            ok,
            key=key,
            tolerance=tolerance,
            columns=columns,
            source=rest.source,
            path=path,
            field_bad=typed.filter(pl.col("_reason").is_not_null()),
            prior=rest.rejects,
            data=split.file,
        )
    return dataclasses.replace(res, file=split.file)


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
