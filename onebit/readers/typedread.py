"""The typed read of a large CSV log: the whole file by one ``pl.read_csv``, only the lines
that read cannot take by the row-by-row path (:mod:`onebit.readers.rows`, "Large files").

:func:`read_typed_csv` gives a :class:`TypedSplit` (the good rows typed, the other lines as
:class:`~onebit.readers.csvfields.RawRows`); :func:`check_split` types those row by row on the
origin the whole file gives and checks duplicates and order over both, as
:func:`~onebit.readers.rowchecks.check_rows` would on the whole file. :func:`read_csv_column`
reads one column fast (the run's time origin).
"""

from __future__ import annotations

import codecs
import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.compiled import numba_loaded
from onebit.core.errors import InputError
from onebit.core.tables import REJECTS
from onebit.readers import kernels
from onebit.readers.csvfields import _BLANK, MAX_HEADER_FIELDS, RawRows, _empty_rows, read_csv_rows, rows_of_lines
from onebit.readers.lines import _FEW_LINES, SEPARATOR, _bounds, check_shapes, read_bytes
from onebit.readers.linetext import FileLines
from onebit.readers.rowchecks import TypedRows, in_time_order, mark_in_order, order_checks
from onebit.readers.timebase import (
    TimeOrigin,
    number_column_origin,
    parts_origin,
)


def read_csv_column(path: str | Path, col: str) -> pl.DataFrame:
    """``line`` and the String field ``col`` of every well-formed record of a CSV -- the rows
    :func:`read_csv_rows` gives for ``(col,)``, without its rejects -- by one typed read when it
    can (:func:`read_typed_csv`: the lines that read cannot take go row by row), else by
    :func:`read_csv_rows`. For what needs one column of a long log fast (the run's time origin)."""
    split = read_typed_csv(path, {col: pl.String})
    if split is None:
        return read_csv_rows(path, (col,)).frame.select("line", col)
    return pl.concat([split.good.select("line", col), split.rest.frame.select("line", col)]).sort("line")


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
    plain_header = _plain_header(data, dtypes)
    if plain_header is None:
        return None
    header, head_text = plain_header
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


def _plain_header(data: bytes, dtypes: dict[str, pl.DataType]) -> tuple[list[str], str] | None:
    """(the header's names, its text) when the file's first line is a plain header naming each
    wanted column once (UTF-8, no quote, no carriage return but its line end, no byte-order
    mark), with a data line after it; else ``None``."""
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
    return header, head_text


def _line_numbers(n: int) -> pl.Series:
    """``line`` of the ``n`` rows of a typed read: 2, 3, ... (the header is line 1), as numpy
    makes it (half the time of polars' ``int_range`` in a fresh process), flagged sorted (the
    checks of line order read the flag)."""
    return pl.Series("line", np.arange(2, n + 2, dtype=np.int64)).set_sorted()


def _widths_hold(data: bytes, header: list[str], dtypes: dict[str, pl.DataType], n_lines: int) -> bool:
    """Whether no line can be longer than the header: the strict read raises on a long line
    only when it reads every column, so when some are not read the separators are counted
    (every line of the header's width holds ``n - 1``; fewer is caught by the read). A last line
    without its newline is counted in every case: the strict read takes ``1,a,b,1,`` there as
    the header's four fields."""
    n = len(header)
    if not data.endswith(b"\n") and data[data.rfind(b"\n") + 1 :].count(SEPARATOR.encode()) != n - 1:
        return False
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
