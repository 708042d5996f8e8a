"""Physical lines of a log file: its bytes checked, split at ``\\n``, their shapes counted.

Step 1 of the CSV layer (:mod:`onebit.readers.rows`): a file is refused whole when it is
surely not a log (a line longer than :data:`MAX_LINE_BYTES`, binary bytes, more than
:data:`MAX_MALFORMED_LINES` lines that are not records); otherwise every physical line is a
row of its own (:func:`physical_lines`), the bad bytes of a line named by line and column.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError
from onebit.readers.filebytes import read_file

#: The field separator and the quote character of onebit's CSV logs.
SEPARATOR, QUOTE = ",", '"'


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
