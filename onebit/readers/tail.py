"""Incremental readers of a growing CSV log (``onebit follow``): each poll reads only the bytes
appended since the last one, and the rows they give are exactly the batch reader's rows on
the whole file, emitted in the batch reader's order as soon as they can no longer change.

:class:`CsvTail` cuts appended bytes into physical lines (a last line without its newline is
kept for the next feed, never rejected; :meth:`CsvTail.finish` takes it as the batch reader
does at the end of a file), finds the header once and numbers every line as the whole file
would (:func:`~onebit.readers.rows.physical_lines`, :func:`~onebit.readers.rows.rows_of_lines`
on the new lines only). :class:`ToggleTail` (``motion.csv``, ``proximity.csv``: the pipeline's
:func:`~onebit.readers.motion.read_motion_csv`) and :class:`BeamTail` (``beams.csv``:
:func:`~onebit.readers.beams.decode_beam_log`) type the new rows with the batch reader's own
parsers and carry the rest of its state across feeds:

* **duplicates**: the first line of every key seen (a dict; a row far back in time may still
  be a duplicate, and the batch reader names it so);
* **order**: the running maximum ``m`` of accepted stamps. A later row is accepted only if
  ``t >= m - tolerance``, so a row with ``t <= F = m - tolerance`` is in its final place (a
  later row with the same stamp sorts after it, by line): rows wait in a heap until ``F``
  passes them, then go through the state machines in the batch order ``(t, line)``;
* **state changes**: each sensor's (beam pair's) last state;
* **debounce** (:func:`~onebit.readers.kernels.debounce_masks` as a streaming machine):
  chatter drops an (off, on) pair of neighbours within ``chatter_window``; minimum on-time an
  (on, off) pair among the edges chatter left, sooner than ``min_on``. A chattering sensor has
  an unbounded chain of suppressed pairs, but each pair is final the moment its on edge
  arrives; what can still change is at most two edges per sensor -- its last off edge (until
  the next edge, or until ``F - t > chatter_window``: no later edge can be within the window)
  and its last kept on edge (until the next kept off edge, or until every later edge is at
  least ``min_on`` after it) -- the *unsettled tail*. Edges are emitted in ``(t, line)`` order
  up to the first unsettled one;
* **crossings** (``crossings.csv``, :class:`CrossingTail`): no state beyond the checks;
* **passes** (:func:`~onebit.readers.kernels.beam_passes`): each beam's open pass (its first
  edge's rank and pair); a crossing or start-and-return is emitted once no later close can
  share its stamp (``t < F``).

Rejects are emitted in line order up to the first line still waiting in the heap (it may yet
become a "no state change" reject). :attr:`ToggleTail.settled_until` is the log time before
which every row the batch reader gives has been emitted. File-level refusals of the batch
reader (a binary file, a line over 16 MiB, hundreds of malformed lines) are left to the batch
run at the end. ``tests/readers/test_tail.py`` splits random logs at random byte offsets and
checks that the concatenated output and rejects (with line numbers) equal one batch read.
"""

from __future__ import annotations

import heapq
import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError
from onebit.core.tables import ABORTED, BEAM_EVENTS, CROSSINGS, MOTION, REJECTS
from onebit.readers.beams import BEAM_COLUMNS, _beam_parsers
from onebit.readers.csvfields import _BLANK, _check_columns, _header_of
from onebit.readers.motion import (
    SUPPRESSED,
    TIME_EPS,
    TOGGLE_COLUMNS,
    DebounceRules,
    _toggle_parsers,
)
from onebit.readers.rows import (
    MAX_LINE_BYTES,
    REORDER_TOLERANCE_S,
    RawRows,
    backwards_reason,
    make_rejects,
    physical_lines,
    rows_of_lines,
)
from onebit.readers.tables_csv import _crossing_parsers
from onebit.readers.timebase import TimeOrigin


class CsvTail:
    """Appended bytes of one CSV log -> :class:`RawRows` of its new complete lines.

    ``source``: the name rejects carry (the file's name); ``columns``: the fields wanted.
    """

    def __init__(self, source: str, columns: tuple[str, ...], path: Path | None = None):
        self.source = source
        self.columns = columns
        self.path = Path(path) if path is not None else Path(source)
        self.partial = b""  # bytes after the last newline: a line being written
        self.lines = 0  # physical lines consumed so far
        self.head = b""  # the bytes read before the header was found
        self.header: list[str] | None = None
        self.header_line = 0
        self.ended = False

    def feed(self, data: bytes) -> RawRows:
        """The rows of the complete lines that ``data`` (appended bytes) ends."""
        if self.ended:
            raise InputError("bytes appended after the end of the log", file=self.path)
        buf = self.partial + data
        cut = buf.rfind(b"\n")
        if cut < 0:
            if len(buf) > MAX_LINE_BYTES:  # as the batch reader refuses such a file (and a bound on memory)
                raise InputError(
                    f"line longer than the {MAX_LINE_BYTES} bytes a log line may have (is this a CSV log?)",
                    file=self.path,
                    line=self.lines + 1,
                )
            self.partial = buf
            return self._rows(None)
        self.partial = buf[cut + 1 :]
        return self._rows(buf[: cut + 1])

    def finish(self) -> RawRows:
        """The end of the log: its last line, even without a newline."""
        rest, self.partial, self.ended = self.partial, b"", True
        return self._rows(rest if rest else None)

    def _rows(self, complete: bytes | None) -> RawRows:
        schema = {"line": pl.Int64, **dict.fromkeys(self.columns, pl.String), "raw": pl.String}
        empty = RawRows(self.source, pl.DataFrame(schema=schema), pl.DataFrame(schema=REJECTS))
        if not complete:
            return empty
        start = self.lines
        if start == 0:  # the start of the file (a byte-order mark there is not data)
            lines = physical_lines(complete)
        else:  # elsewhere a line's first bytes are data: split behind a newline, numbers shifted
            lines = physical_lines(b"\n" + complete).slice(1).with_columns(pl.col("line") - 1 + start)
        self.lines = start + lines.height
        if self.header is None:
            self.head += complete
            keep = lines.filter(~pl.col("text").str.contains(_BLANK) | pl.col("_reason").is_not_null())
            if keep.height == 0:
                return empty
            self.header, self.header_line = _header_of(self.path, self.head)
            self.head = b""
            _check_columns(self.path, self.header, self.header_line, self.columns)
        body = lines.filter(
            (pl.col("line") > self.header_line)
            & (~pl.col("text").str.contains(_BLANK) | pl.col("_reason").is_not_null())
        )
        if body.height == 0:
            return empty
        return rows_of_lines(body, self.header, self.columns, self.source)


def _typed(raw: RawRows, parsers: dict) -> tuple[pl.DataFrame, pl.DataFrame]:
    """The field step of :func:`~onebit.readers.rows.check_rows`: (rows whose fields parsed, rejects)."""
    typed = raw.frame.with_columns(pl.coalesce([r for _, r in parsers.values()]).alias("_reason")).with_columns(
        v.alias(c) for c, (v, _) in parsers.items()
    )
    bad = typed.filter(pl.col("_reason").is_not_null()).select("line", "raw", "_reason")
    rej = make_rejects(bad, raw.source, None)
    if raw.rejects.height:
        rej = pl.concat([raw.rejects, rej]).sort("line")
    return typed.filter(pl.col("_reason").is_null()), rej


class _Seen:
    """The first line of every distinct key seen (the duplicate check), in bounded-size parts:
    keys at or after ``top - tolerance`` in a dict; older keys (only a row going backwards can
    repeat one: every later accepted row is at or after that time) moved to sorted numpy
    arrays (``t``, a code of the other fields, line), about 20 bytes a key instead of ~200,
    merged two by two like a binary counter (O(log n) moves per key)."""

    def __init__(self) -> None:
        self.recent: dict = {}
        self.order: deque = deque()  # the recent keys in insertion order (stamps roughly increasing)
        self.codes: dict = {}  # the fields other than t -> int code
        self.parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (t, code, line), sorted by (t, code)

    def get(self, key: tuple, old: bool):
        """The first line of ``key`` (``old``: its ``t`` is before the recent window, look in the archive too)."""
        first = self.recent.get(key)
        if first is not None or not old:
            return first
        code = self.codes.get(key[1:])
        if code is None:
            return None
        t = key[0]
        for ts, cs, ls in self.parts:
            lo, hi = np.searchsorted(ts, t, side="left"), np.searchsorted(ts, t, side="right")
            hit = np.flatnonzero(cs[lo:hi] == code)
            if hit.size:
                return int(ls[lo + hit[0]])
        return None

    def add(self, key: tuple, line: int) -> None:
        self.recent[key] = line
        self.order.append(key)

    def archive(self, before: float) -> None:
        """Move the keys with ``t < before`` (from the front of the insertion order) out of the dict."""
        moved = []
        order, recent = self.order, self.recent
        while order and order[0][0] < before:
            k = order.popleft()
            moved.append((k[0], self.codes.setdefault(k[1:], len(self.codes)), recent.pop(k)))
        if not moved:
            return
        a = np.array(moved, dtype=np.float64)
        part = (a[:, 0].copy(), a[:, 1].astype(np.int64), a[:, 2].astype(np.int64))
        self.parts.append(self._sorted(*part))
        while len(self.parts) > 1 and len(self.parts[-2][0]) <= 2 * len(self.parts[-1][0]):
            b, c = self.parts.pop(), self.parts.pop()
            self.parts.append(self._sorted(*(np.concatenate([x, y]) for x, y in zip(c, b))))

    @staticmethod
    def _sorted(t, code, line):
        o = np.lexsort((code, t))
        return t[o], code[o], line[o]

    def __len__(self) -> int:
        return len(self.recent) + sum(len(p[0]) for p in self.parts)


@dataclass
class _Ordered:
    """Duplicates and order across feeds (:func:`~onebit.readers.rows.order_checks` as a stream)."""

    key: tuple[str, ...]
    tolerance: float
    source: str
    seen: _Seen = field(default_factory=_Seen)  # key -> first line
    top: float = -math.inf  # running maximum of accepted stamps
    heap: list = field(default_factory=list)  # (t, line, row) waiting for their final place
    reordered: int = 0

    @property
    def frontier(self) -> float:
        """Every row still to come has ``t >= frontier``."""
        return self.top - self.tolerance

    def push(self, ok: pl.DataFrame, cols: tuple[str, ...]) -> pl.DataFrame:
        """Check ``ok`` (line order); queue the accepted rows; return the rejects made."""
        dups, backs = [], []
        tol = self.tolerance
        seen = self.seen
        for row in ok.select("line", *cols, "raw").iter_rows():
            line, t = row[0], row[1]
            k = row[1 : 1 + len(cols)]
            prev = self.top
            first = seen.get(k, t < prev - tol)
            if first is not None:
                dups.append((line, row[-1], first))
                continue
            seen.add(k, line)
            if t < prev - tol:
                backs.append((line, row[-1], t, prev))
                continue
            if t < prev:
                self.reordered += 1
            else:
                self.top = t
            heapq.heappush(self.heap, (t, line, row))
        seen.archive(self.top - tol)
        parts = []
        if dups:
            same = " and ".join(", ".join(self.key).rsplit(", ", 1))
            d = pl.DataFrame(dups, schema={"line": pl.Int64, "raw": pl.String, "_dup": pl.Int64}, orient="row")
            parts.append(
                d.select(
                    "line",
                    "raw",
                    pl.format("duplicate of line {} (same {})", pl.col("_dup"), pl.lit(same)).alias("_reason"),
                )
            )
        if backs:
            b = pl.DataFrame(
                backs, schema={"line": pl.Int64, "raw": pl.String, "t": pl.Float64, "_prev": pl.Float64}, orient="row"
            )
            why = backwards_reason(tol)
            parts.append(b.select("line", "raw", why.alias("_reason")))
        if not parts:
            return pl.DataFrame(schema=REJECTS)
        return make_rejects(pl.concat(parts).sort("line"), self.source, None)

    def pop(self, until: float):
        """The queued rows with ``t <= until``, in ``(t, line)`` order."""
        h = self.heap
        while h and h[0][0] <= until:
            yield heapq.heappop(h)[2]

    def first_waiting_line(self) -> float:
        return min((x[1] for x in self.heap), default=math.inf)


class _Rejects:
    """Rejects held until no earlier line can be rejected any more, then emitted in line order."""

    def __init__(self):
        self.parts: list[pl.DataFrame] = []

    def add(self, df: pl.DataFrame) -> None:
        if df.height:
            self.parts.append(df)

    def take(self, below: float) -> pl.DataFrame:
        if not self.parts:
            return pl.DataFrame(schema=REJECTS)
        allr = pl.concat(self.parts).sort("line")
        out = allr.filter(pl.col("line") < below) if math.isfinite(below) else allr
        rest = allr.filter(pl.col("line") >= below) if math.isfinite(below) else allr.clear()
        self.parts = [rest] if rest.height else []
        return out


@dataclass
class ToggleChunk:
    """What one feed of a toggle log gave: the next rows of the batch reader's tables."""

    motion: pl.DataFrame  # MOTION
    suppressed: pl.DataFrame  # SUPPRESSED
    rejects: pl.DataFrame  # REJECTS
    held: int = 0
    reordered: int = 0


class _Sensor:
    __slots__ = ("w", "mo", "held", "state", "last", "kept")

    def __init__(self, w: float, mo: float, held: bool):
        self.w, self.mo, self.held = w, mo, held
        self.state = False  # every sensor starts off
        self.last: list | None = None  # the last edge (unfed: its chatter fate still open)
        self.kept: list | None = None  # the last edge chatter left, fed to the minimum on-time rule


# an edge: [t, line, sensor, on, status, fed]; status None = unsettled, else "kept" / "chatter" / "min_on"
_T, _LINE, _S, _ON, _STATUS, _FED = range(6)


class ToggleTail:
    """:func:`~onebit.readers.motion.read_motion_csv` of a growing toggle log, one feed at a time
    (module docstring). ``origin``: the run's fixed :class:`TimeOrigin`."""

    def __init__(
        self,
        source: str,
        sensors: Sequence[str],
        *,
        origin: TimeOrigin,
        rules: DebounceRules | Mapping[str, DebounceRules] | None = None,
        held: frozenset[str] | set[str] = frozenset(),
        tolerance: float = REORDER_TOLERANCE_S,
        path: Path | None = None,
    ):
        self.sensors = tuple(sensors)
        self.origin = origin
        self.csv = CsvTail(source, TOGGLE_COLUMNS, path)
        self.order = _Ordered(TOGGLE_COLUMNS, tolerance, source)
        self.rejects = _Rejects()
        per = rules if isinstance(rules, Mapping) else {}
        one = rules if isinstance(rules, DebounceRules) else DebounceRules()
        self.state = {}
        for s in self.sensors:
            r = per.get(s, DebounceRules()) if per else one
            self.state[s] = _Sensor(r.chatter_window, r.min_on, s in held)
        self.edges: list[list] = []  # in (t, line) order, from the first unsettled one
        self.n_held = 0
        self.done = False

    # ---- feeding
    def feed(self, data: bytes) -> ToggleChunk:
        """Read ``data`` (bytes appended to the log); return the rows settled by it."""
        return self._step(self.csv.feed(data), final=False)

    def finish(self) -> ToggleChunk:
        """The log has ended: every row left, as the batch reader gives them at the end of a file."""
        return self._step(self.csv.finish(), final=True)

    @property
    def settled_until(self) -> float:
        """Every row of the batch read with ``t`` below this has been emitted."""
        if self.done:
            return math.inf
        w = self.order.frontier
        if self.edges:
            w = min(w, self.edges[0][_T])
        return w

    def _step(self, raw: RawRows, *, final: bool) -> ToggleChunk:
        before_held, before_re = self.n_held, self.order.reordered
        if raw.frame.height or raw.rejects.height:
            ok, rej = _typed(raw, _toggle_parsers(self.sensors, self.origin, raw.frame))
            self.rejects.add(rej)
            self.rejects.add(self.order.push(ok, TOGGLE_COLUMNS))
        frontier = math.inf if final else self.order.frontier
        repeats = []
        for row in self.order.pop(frontier):
            _, t, sensor, on, text = row
            st = self.state[sensor]
            if on == st.state:
                if st.held:
                    self.n_held += 1
                else:
                    repeats.append((row[0], text, f"no state change: sensor {sensor} already {'on' if on else 'off'}"))
                continue
            st.state = on
            self._edge(st, [t, row[0], sensor, on, None, False])
        if repeats:
            self.rejects.add(
                make_rejects(
                    pl.DataFrame(
                        repeats, schema={"line": pl.Int64, "raw": pl.String, "_reason": pl.String}, orient="row"
                    ),
                    self.csv.source,
                    None,
                )
            )
        if final:
            for st in self.state.values():
                x = st.last
                if x is not None and not x[_FED] and x[_STATUS] is None:
                    self._feed_rule(st, x)
                if st.kept is not None and st.kept[_STATUS] is None:
                    st.kept[_STATUS] = "kept"
            self.done = True
        else:
            self._settle(frontier)
        motion, suppressed = self._emit()
        rejects = self.rejects.take(math.inf if final else self.order.first_waiting_line())
        reordered = self.order.reordered - before_re
        return ToggleChunk(motion, suppressed, rejects, self.n_held - before_held, reordered)

    # ---- the debounce as a stream (kernels.debounce_masks)
    def _edge(self, st: _Sensor, k: list) -> None:
        self.edges.append(k)
        j, st.last = st.last, k
        if j is not None:
            if st.w > 0 and k[_ON] and not j[_ON] and k[_T] - j[_T] <= st.w + TIME_EPS:
                j[_STATUS] = k[_STATUS] = "chatter"
            elif not j[_FED] and j[_STATUS] is None:
                self._feed_rule(st, j)
        # an on edge's chatter fate is known on arrival; an off edge's too without a window
        if k[_STATUS] is None and (k[_ON] or st.w <= 0):
            self._feed_rule(st, k)

    @staticmethod
    def _feed_rule(st: _Sensor, x: list) -> None:
        """Give ``x`` (chatter left it) to the minimum on-time rule."""
        x[_FED] = True
        i, st.kept = st.kept, x
        if i is not None and i[_STATUS] is None:  # i: an on edge waiting for its off edge
            if st.mo > 0 and i[_ON] and not x[_ON] and x[_T] - i[_T] < st.mo - TIME_EPS:
                i[_STATUS] = x[_STATUS] = "min_on"
                return
            i[_STATUS] = "kept"
        if not x[_ON] or st.mo <= 0:  # only an on edge can still be shortened
            x[_STATUS] = "kept"

    def _settle(self, frontier: float) -> None:
        """Settle by time: no edge to come has ``t < frontier``."""
        for st in self.state.values():
            x = st.last
            if x is not None and not x[_FED] and x[_STATUS] is None and frontier - x[_T] > st.w + TIME_EPS:
                self._feed_rule(st, x)  # no later on edge can be within the chatter window
            i = st.kept
            if i is not None and i[_STATUS] is None:
                x = st.last
                low = x[_T] if (x is not None and not x[_FED] and x[_STATUS] is None) else frontier
                if low - i[_T] >= st.mo - TIME_EPS:  # no later off edge can be sooner than min_on
                    i[_STATUS] = "kept"

    def _emit(self) -> tuple[pl.DataFrame, pl.DataFrame]:
        n = 0
        for e in self.edges:
            if e[_STATUS] is None:
                break
            n += 1
        out, self.edges = self.edges[:n], self.edges[n:]
        kept = [e for e in out if e[_STATUS] == "kept"]
        gone = [e for e in out if e[_STATUS] != "kept"]
        motion = pl.DataFrame(
            {"t": [e[_T] for e in kept], "sensor": [e[_S] for e in kept], "on": [e[_ON] for e in kept]}, schema=MOTION
        )
        suppressed = pl.DataFrame(
            {
                "t": [e[_T] for e in gone],
                "sensor": [e[_S] for e in gone],
                "on": [e[_ON] for e in gone],
                "rule": [e[_STATUS] for e in gone],
                "line": [e[_LINE] for e in gone],
            },
            schema=SUPPRESSED,
        )
        return motion, suppressed


@dataclass
class BeamChunk:
    """What one feed of a beam log gave: the next rows of :class:`~onebit.readers.beams.BeamDecode`'s tables
    (``unfinished``: the passes still open, at :meth:`BeamTail.finish` only)."""

    events: pl.DataFrame
    crossings: pl.DataFrame
    aborted: pl.DataFrame
    rejects: pl.DataFrame
    unfinished: pl.DataFrame | None = None


class BeamTail:
    """:func:`~onebit.readers.beams.decode_beam_log` of a growing ``beams.csv``, one feed at a
    time (module docstring): the pass machine of :func:`~onebit.readers.kernels.beam_passes`
    with its state (pair states, each beam's open pass) carried between feeds."""

    def __init__(self, source: str, beam_ids: Sequence[str], *, origin: TimeOrigin, path: Path | None = None):
        self.beam_ids = tuple(beam_ids)
        self.origin = origin
        self.csv = CsvTail(source, BEAM_COLUMNS, path)
        self.order = _Ordered(BEAM_COLUMNS, 0.0, source)
        self.rejects = _Rejects()
        self.pairs: dict[tuple[str, str], bool] = {}
        self.open: dict[str, tuple[int, str]] = {}  # beam -> (rank of the pass's first edge, its pair)
        self.last_t: dict[str, float] = {}  # beam -> t of its last accepted edge
        self.rank = 0  # accepted edges so far
        self.closed: list[tuple] = []  # (t, beam, crossing?, opener pair, rank of the first edge), not emitted
        self.done = False

    def feed(self, data: bytes) -> BeamChunk:
        return self._step(self.csv.feed(data), final=False)

    def finish(self) -> BeamChunk:
        return self._step(self.csv.finish(), final=True)

    @property
    def settled_until(self) -> float:
        return math.inf if self.done else self.order.frontier

    def _step(self, raw: RawRows, *, final: bool) -> BeamChunk:
        if raw.frame.height or raw.rejects.height:
            ok, rej = _typed(raw, _beam_parsers(self.beam_ids, self.origin, raw.frame))
            self.rejects.add(rej)
            self.rejects.add(self.order.push(ok, BEAM_COLUMNS))
        frontier = math.inf if final else self.order.frontier
        events, same = [], []
        for row in self.order.pop(frontier):
            line, t, beam, pair, blocked, text = row
            key = (beam, pair)
            if self.pairs.get(key, False) == blocked:
                what = "blocked" if blocked else "clear"
                same.append((line, text, f"pair {pair} of beam {beam} already {what} (no state change)"))
                continue
            self.pairs[key] = blocked
            events.append((t, beam, pair, blocked))
            self.last_t[beam] = t
            if beam not in self.open:
                self.open[beam] = (self.rank, pair)
            self.rank += 1
            if not (self.pairs.get((beam, "a"), False) or self.pairs.get((beam, "b"), False)):
                first, opener = self.open.pop(beam)
                self.closed.append((t, beam, opener != pair, opener, first))
        if same:
            self.rejects.add(
                make_rejects(
                    pl.DataFrame(same, schema={"line": pl.Int64, "raw": pl.String, "_reason": pl.String}, orient="row"),
                    self.csv.source,
                    None,
                )
            )
        # a pass closed at t is emitted once no later close can have that stamp
        ready = [c for c in self.closed if final or c[0] < frontier]
        self.closed = [c for c in self.closed if not (final or c[0] < frontier)]
        cross = sorted((c for c in ready if c[2]), key=lambda c: (c[0], c[1]))
        ab = sorted((c for c in ready if not c[2]), key=lambda c: (c[0], c[4]))
        crossings = pl.DataFrame(
            {
                "t": [c[0] for c in cross],
                "beam": [c[1] for c in cross],
                "direction": [1 if c[3] == "a" else -1 for c in cross],
            },
            schema=CROSSINGS,
        )
        aborted = pl.DataFrame(
            {"t": [c[0] for c in ab], "beam": [c[1] for c in ab], "side": [-1 if c[3] == "a" else 1 for c in ab]},
            schema=ABORTED,
        )
        ev = pl.DataFrame(events, schema=BEAM_EVENTS, orient="row")
        unfinished = None
        if final:
            self.done = True
            op = sorted(self.open.items(), key=lambda kv: kv[1][0])
            unfinished = pl.DataFrame(
                {"t": [self.last_t[b] for b, _ in op], "beam": [b for b, _ in op]},
                schema={"t": pl.Float64, "beam": pl.String},
            )
        rejects = self.rejects.take(math.inf if final else self.order.first_waiting_line())
        return BeamChunk(ev, crossings, aborted, rejects, unfinished)


@dataclass
class CrossingChunk:
    """What one feed of ``crossings.csv`` gave: the next crossings (CROSSINGS) and rejects."""

    crossings: pl.DataFrame
    rejects: pl.DataFrame


class CrossingTail:
    """:func:`~onebit.readers.tables_csv.read_crossings_csv` of a growing ``crossings.csv`` (a log
    of decoded crossings: t, beam, direction), one feed at a time: the field, duplicate and order
    checks of the batch read (no reordering tolerance), a crossing emitted once no later row can
    sort before it."""

    def __init__(self, source: str, beam_ids: Sequence[str], *, origin: TimeOrigin, path: Path | None = None):
        self.beam_ids = tuple(beam_ids)
        self.origin = origin
        self.csv = CsvTail(source, ("t", "beam", "direction"), path)
        self.order = _Ordered(("t", "beam", "direction"), 0.0, source)
        self.rejects = _Rejects()
        self.done = False

    def feed(self, data: bytes) -> CrossingChunk:
        return self._step(self.csv.feed(data), final=False)

    def finish(self) -> CrossingChunk:
        return self._step(self.csv.finish(), final=True)

    @property
    def settled_until(self) -> float:
        return math.inf if self.done else self.order.frontier

    def _step(self, raw: RawRows, *, final: bool) -> CrossingChunk:
        cols = ("t", "beam", "direction")
        if raw.frame.height or raw.rejects.height:
            ok, rej = _typed(raw, _crossing_parsers(self.beam_ids, self.origin, raw.frame))
            self.rejects.add(rej)
            self.rejects.add(self.order.push(ok, cols))
        rows = [r[1:4] for r in self.order.pop(math.inf if final else self.order.frontier)]
        self.done = self.done or final
        out = pl.DataFrame(rows, schema=CROSSINGS, orient="row")
        return CrossingChunk(out, self.rejects.take(math.inf if final else self.order.first_waiting_line()))
