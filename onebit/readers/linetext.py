"""The text of named lines of a file, for rejects: :class:`FileLines` (an index of where the
lines are, made once per file), :func:`line_texts`, :func:`raw_lines` and :func:`make_rejects`
(the REJECTS rows of bad rows, their raw text and reason cut to
:data:`~onebit.core.errors.MAX_QUOTE` characters). Part of the CSV layer
(:mod:`onebit.readers.rows`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import MAX_QUOTE, InputError, bounded
from onebit.core.tables import REJECTS
from onebit.readers.lines import _FEW_LINES, newlines, physical_lines, read_bytes


def _bounded(col: str, limit: int = MAX_QUOTE) -> pl.Expr:
    """``col`` cut to ``limit`` characters, stating the full length (:func:`onebit.core.errors.bounded`)."""
    n = pl.col(col).str.len_chars()
    return (
        pl.when(n > limit)
        .then(pl.format("{}... ({} characters)", pl.col(col).str.slice(0, limit), n))
        .otherwise(pl.col(col))
        .alias(col)
    )


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
