"""Row-level reading shared by every CSV/MCAP reader: raw string rows -> typed rows + rejects.

A reader first gets its rows as all-string columns with a ``line`` column and a ``raw``
column (CSV: the file's physical line number, header = line 1, and the line's text; MCAP:
the message's index in its channel and its JSON text), then types and checks them with
polars expressions. A row that fails any check goes to ``rejects`` with the first reason that
applies; nothing is dropped silently.

The CSV layer (:func:`read_csv_rows`) works on physical lines, so one bad byte, one stray
quote or one ragged line costs that line alone:

1. **Physical lines** (:func:`physical_lines`): the file's bytes are split at ``\n`` (a
   trailing ``\r`` is dropped, a UTF-8 byte-order mark at the start too); line ``k`` is what
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

This module is the CSV layer's one front door: its steps live in their own modules and every
name of them is importable from here.

* :mod:`onebit.readers.lines` -- physical lines: the bytes checked, lines and their shapes;
* :mod:`onebit.readers.csvfields` -- the header, each line's shape and fields: :class:`RawRows`;
* :mod:`onebit.readers.typedread` -- the typed read of a large file and its split;
* :mod:`onebit.readers.rowchecks` -- typing and checking rows: parsers, duplicates, order;
* :mod:`onebit.readers.linetext` -- the raw text of named lines, for rejects.
"""

from __future__ import annotations

from onebit.readers.csvfields import (
    EXTRA,
    MAX_HEADER_FIELDS,
    RawRows,
    csv_header,
    header_names,
    read_clean_csv,
    read_csv_rows,
    rows_of_lines,
)
from onebit.readers.lines import (
    MAX_LINE_BYTES,
    MAX_MALFORMED_LINES,
    MIN_BINARY_LINES,
    QUOTE,
    SEPARATOR,
    TEXT_PROBE_BYTES,
    check_line_lengths,
    check_shapes,
    check_text,
    file_spans,
    malformed_lines,
    newlines,
    physical_lines,
    read_bytes,
)
from onebit.readers.linetext import (
    FileLines,
    block_newlines,
    line_texts,
    make_rejects,
    raw_lines,
)
from onebit.readers.rowchecks import (
    REORDER_TOLERANCE_S,
    TypedRows,
    backwards_reason,
    by_time,
    check_rows,
    duplicate_of,
    duplicate_rows,
    in_time_order,
    mark_in_order,
    order_checks,
    parse_choice,
    parse_float,
    parse_name,
    parse_time,
    type_rows,
)
from onebit.readers.typedread import (
    TypedSplit,
    check_split,
    clean_time,
    kept_rows,
    minus_constant,
    numpy_column,
    one_buffer,
    read_csv_column,
    read_typed_csv,
)

__all__ = [
    "EXTRA",
    "FileLines",
    "MAX_HEADER_FIELDS",
    "MAX_LINE_BYTES",
    "MAX_MALFORMED_LINES",
    "MIN_BINARY_LINES",
    "QUOTE",
    "REORDER_TOLERANCE_S",
    "RawRows",
    "SEPARATOR",
    "TEXT_PROBE_BYTES",
    "TypedRows",
    "TypedSplit",
    "backwards_reason",
    "block_newlines",
    "by_time",
    "check_line_lengths",
    "check_rows",
    "check_shapes",
    "check_split",
    "check_text",
    "clean_time",
    "csv_header",
    "duplicate_of",
    "duplicate_rows",
    "file_spans",
    "header_names",
    "in_time_order",
    "kept_rows",
    "line_texts",
    "make_rejects",
    "malformed_lines",
    "mark_in_order",
    "minus_constant",
    "newlines",
    "numpy_column",
    "one_buffer",
    "order_checks",
    "parse_choice",
    "parse_float",
    "parse_name",
    "parse_time",
    "physical_lines",
    "raw_lines",
    "read_bytes",
    "read_clean_csv",
    "read_csv_column",
    "read_csv_rows",
    "read_typed_csv",
    "rows_of_lines",
    "type_rows",
]
