"""Tailing the logs of ``onebit follow``: the CSV logs and the ``.mcap`` recordings as they
grow (or as a replay releases them), and the incremental readers fed with what they gained.

* :class:`LogSource` -- one CSV log followed: what was released into the snapshot so far. Live,
  every poll reads the lines appended since the last one (:func:`read_live`): a last line
  without its newline is being written and waits for the next poll (at the end, or when its
  file is rotated away or truncated, it is taken as a line, as the batch reader takes a file's
  last line); a log rotated, truncated or rewritten in place is followed into its new file.
  In a replay, its lines are released when the virtual clock passes their stamps.
* :class:`McapSource` -- one ``.mcap``: re-read when it grew, keeping every complete chunk.
* :class:`Tails` -- the incremental readers (:mod:`onebit.readers.tail`) of ``motion.csv``,
  ``proximity.csv``, ``beams.csv`` and ``crossings.csv``: each poll they read only the lines
  released since the last one and emit exactly the batch reader's rows and rejects on the
  whole file once final.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np
import polars as pl

from onebit.core.config import config_from_mapping
from onebit.core.errors import InputError, OnebitError
from onebit.core.tables import REJECTS
from onebit.pipeline.context import RunContext
from onebit.readers.mcap_io import read_mcap
from onebit.readers.motion import MotionConfig, site_rules
from onebit.readers.proximity import ProximityConfig, proximity_frames
from onebit.readers.rows import RawRows
from onebit.readers.tail import BeamTail, CrossingTail, ToggleTail
from onebit.readers.timebase import TimeOrigin


@dataclass
class LogSource:
    """One CSV log being followed: what was released into the snapshot so far."""

    stem: str
    path: Path
    snapshot: Path
    header: bytes | None = None
    t_col: int = 0
    offset: int = 0  # live: bytes of the original consumed (complete lines only)
    lines: list[bytes] = field(default_factory=list)  # replay: every data line
    release: np.ndarray = field(default_factory=lambda: np.zeros(0))  # replay: log time each line is released at
    released: int = 0
    last_t: float = -math.inf  # latest stamp released (live horizon)
    fh: BinaryIO | None = None  # live: the file being read, kept open (a rotated file is read to its end)
    ident: tuple[int, int] | None = None  # live: (device, inode) of ``fh``
    at_start: bool = True  # live: the next complete line is the first of a file (its header)
    last_line: bytes = b""  # live: the last complete line consumed (to see a rewrite in place)
    partial: bytes = b""  # live: the bytes after the last newline, as seen at the last poll
    restarts: int = 0  # live: times the log was rotated, truncated or rewritten while followed

    def close(self) -> None:
        if self.fh is not None:
            self.fh.close()
            self.fh = None

    def write(self, lines: list[bytes]) -> None:
        if not lines:
            return
        with open(self.snapshot, "ab") as fh:
            if fh.tell() == 0:
                fh.write(self.header if self.header.endswith(b"\n") else self.header + b"\n")
            for ln in lines:
                fh.write(ln if ln.endswith(b"\n") else ln + b"\n")


def header_t_column(header: bytes, path: Path) -> int:
    names = [c.strip().strip('"') for c in header.decode("utf-8", errors="replace").rstrip("\r\n").split(",")]
    if "t" not in names:
        raise InputError(f"no 't' column in the header {names}", file=path, line=1)
    return names.index("t")


def stamps(lines: list[bytes], col: int, origin: TimeOrigin) -> np.ndarray:
    """``t`` (run seconds) of each line's field ``col``; NaN where it does not parse."""
    if not lines:
        return np.zeros(0)
    fields = []
    for ln in lines:
        parts = ln.decode("utf-8", errors="replace").rstrip("\r\n").split(",")
        fields.append(parts[col].strip().strip('"') if col < len(parts) else None)
    t = pl.DataFrame({"t": fields}, schema={"t": pl.String}).select(origin.t_expr("t").alias("t"))["t"]
    return t.cast(pl.Float64).fill_null(float("nan")).to_numpy()


def _complete_lines(data: bytes) -> tuple[list[bytes], int]:
    """The complete lines of ``data`` and the bytes they take (a line without its newline is left)."""
    end = data.rfind(b"\n")
    if end < 0:
        return [], 0
    return data[: end + 1].splitlines(keepends=True), end + 1


def _fields(line: bytes) -> list[str]:
    return [c.strip().strip('"') for c in line.decode("utf-8", errors="replace").rstrip("\r\n").split(",")]


def _read_appended(src: LogSource) -> list[bytes]:
    """The complete lines appended to ``src``'s open file since the last read (the first file's
    header is taken as the log's header; a later file's first line is dropped when it is that
    header again); the bytes of a line still being written are kept in ``src.partial``."""
    size = os.fstat(src.fh.fileno()).st_size
    if size <= src.offset:
        src.partial = b""
        return []
    src.fh.seek(src.offset)
    chunk = src.fh.read(size - src.offset)
    lines, used = _complete_lines(chunk)
    src.partial = chunk[used:]
    if not lines:
        return []
    src.offset += used
    src.last_line = lines[-1]
    if src.at_start:
        src.at_start = False
        if src.header is None:
            src.header, lines = lines[0], lines[1:]
            src.t_col = header_t_column(src.header, src.path)
            src.snapshot.write_bytes(src.header if src.header.endswith(b"\n") else src.header + b"\n")
        elif _fields(lines[0]) == _fields(src.header):
            lines = lines[1:]
    return lines


def _rewritten(src: LogSource) -> bool:
    """Whether the open file was truncated (shorter than what was read) or rewritten in place
    (the last line read is no longer where it was): a logger that restarted on the same file."""
    size = os.fstat(src.fh.fileno()).st_size
    if size < src.offset:
        return True
    n = len(src.last_line)
    return n > 0 and os.pread(src.fh.fileno(), n, src.offset - n) != src.last_line


def _rotated(src: LogSource) -> bool:
    """Whether the log's path now names another file than the one open (renamed and a new one
    started); a path with no file yet (between the rename and the new file) is not."""
    try:
        st = os.stat(src.path)
    except FileNotFoundError:
        return False
    return (st.st_dev, st.st_ino) != src.ident


def _unfinished_line(src: LogSource) -> list[bytes]:
    """The line the old file ends with that never got its newline, as a complete line (the
    batch reader takes a file's last line so), unless it is only the start of a header."""
    rest, src.partial = src.partial, b""
    if not rest.strip() or src.header is None or (src.at_start and src.header.startswith(rest.rstrip(b"\r"))):
        return []
    return [rest + b"\n"]


def _open_log(src: LogSource) -> bool:
    """Open the file at the log's path (a new one is read from its start)."""
    try:
        src.fh = open(src.path, "rb")  # noqa: SIM115 - kept open across polls, closed by close()
    except OSError:
        return False
    st = os.fstat(src.fh.fileno())
    src.ident, src.offset, src.last_line, src.at_start = (st.st_dev, st.st_ino), 0, b"", True
    return True


def read_live(src: LogSource) -> tuple[list[bytes], list[str]]:
    """The complete lines a followed log gained since the last poll, and what happened to it.

    * rewritten in place (truncated, or its bytes changed under the last line read: a logger
      that restarted on the same file): its unfinished last line is taken, then the file is
      read again from its start as a new file of the log;
    * rotated (its path names a new file): the old file is read to its end (its unfinished last
      line taken), then the new one from its start.

    A new file's lines are appended to the log followed, after the old ones (its header, when
    it repeats the log's, dropped); rows earlier than those accepted are then the readers'
    "goes backwards" rejects, as in a batch run on the concatenated log.
    """
    notes: list[str] = []
    if src.fh is None and not _open_log(src):
        return [], notes
    lines: list[bytes] = []
    if src.offset and _rewritten(src):
        lines += _unfinished_line(src)
        src.offset, src.last_line, src.at_start, src.restarts = 0, b"", True, src.restarts + 1
        notes.append(f"{src.path}: truncated or rewritten while followed; read again from its start")
    lines += _read_appended(src)
    if _rotated(src):
        lines += _read_appended(src)  # what the logger wrote before it moved to the new file
        lines += _unfinished_line(src)
        src.close()
        src.restarts += 1
        notes.append(f"{src.path}: rotated (a new file at its path); the old one read to its end")
        if _open_log(src):
            lines += _read_appended(src)
    return lines, notes


def take_unfinished(sources: dict[str, LogSource]) -> None:
    """The end of a live follow: a last line that never got its newline is taken as the batch
    reader takes a file's last line (a row if it parses, else a reject naming its line)."""
    for src in sources.values():
        if src.fh is None:
            continue
        last = _unfinished_line(src)
        if last:
            src.write(last)
            src.lines.extend(last)
            src.released = len(src.lines)


@dataclass
class McapSource:
    """One ``.mcap`` of the dataset being followed: its raw channels as read so far.

    Replay: the whole file is read once and each channel's rows are released by their stamps.
    Live: the file is re-read when it grew; :func:`onebit.readers.mcap_io.read_mcap` keeps
    every complete chunk of a file still being written (its missing footer is not a reject
    here: the final batch run reads the file as it is then).
    """

    path: Path
    topic_map: dict | None
    frames: dict[str, pl.DataFrame] = field(default_factory=dict)
    release: dict[str, np.ndarray] = field(default_factory=dict)
    released: dict[str, int] = field(default_factory=dict)
    size: int = 0
    last_t: float = -math.inf

    def load_all(self, origin: TimeOrigin) -> None:
        self.frames = read_mcap(self.path, topic_map=self.topic_map).channels
        for topic, frame in self.frames.items():
            t = frame.select(origin.t_expr("t").alias("t"))["t"].cast(pl.Float64).fill_nan(None)
            filled = t.fill_null(strategy="forward").fill_null(-math.inf).to_numpy()
            self.release[topic] = np.maximum.accumulate(filled) if len(filled) else filled
            self.released[topic] = 0

    def replay(self, horizon: float) -> bool:
        new = False
        for topic, rel in self.release.items():
            n = int(np.searchsorted(rel, horizon, side="right"))
            if n > self.released[topic]:
                self.released[topic], new = n, True
        return new

    def done(self) -> bool:
        return all(self.released[t] == len(r) for t, r in self.release.items())

    def poll(self) -> bool:
        try:
            size = self.path.stat().st_size
        except OSError:
            return False
        if size < self.size:
            raise InputError(f"the recording shrank from {self.size} to {size} bytes while followed", file=self.path)
        if size == self.size:
            return False
        try:
            frames = read_mcap(self.path, topic_map=self.topic_map).channels
        except InputError:  # not even the magic yet: an empty file being created
            return False
        self.size = size
        grew = any(f.height > self.released.get(t, 0) for t, f in frames.items())
        self.frames = frames
        self.released = {t: f.height for t, f in frames.items()}
        return grew

    def stamps(self, origin: TimeOrigin) -> None:
        for _topic, frame in self.frames.items():
            if frame.height:
                t = frame.select(origin.t_expr("t").alias("t"))["t"].cast(pl.Float64).fill_nan(None).max()
                if t is not None and math.isfinite(t):
                    self.last_t = max(self.last_t, float(t))

    def rows(self) -> dict[str, RawRows]:
        empty = pl.DataFrame(schema=REJECTS)
        return {
            topic: RawRows(f"{self.path.name}:{topic}", f.head(self.released.get(topic, 0)), empty)
            for topic, f in self.frames.items()
        }


def channels(mcaps: list[McapSource]) -> dict[str, RawRows]:
    """Topic -> rows released so far; the first file holding a topic wins (as in ``onebit run``)."""
    out: dict[str, RawRows] = {}
    for m in mcaps:
        for topic, rows in m.rows().items():
            out.setdefault(topic, rows)
    return out


# --------------------------------------------------------------------------- incremental readers

#: The CSV logs read incrementally (:mod:`onebit.readers.tail`), by the reader stage they replace.
_TAILED = {"motion": "motion", "proximity": "proximity", "beams": "crossings", "crossings": "crossings"}
#: Rechunk an accumulated table once it holds this many chunks (one per poll otherwise).
_MAX_CHUNKS = 64


class Tails:
    """The incremental readers of the followed CSV logs (``motion.csv``, ``proximity.csv``,
    ``beams.csv``, ``crossings.csv`` when there is no raw beam log) and the tables they have
    emitted so far: each poll feeds them only the lines released since the last one; their
    rows are the batch reader stage's rows on the whole log, emitted once final
    (:mod:`onebit.readers.tail`). A reader that fails (a bad header, a log that is not text)
    leaves its stage's tables out, as a failed stage does; the final batch run reports the
    error."""

    def __init__(self) -> None:
        self.readers: dict[str, ToggleTail | BeamTail | CrossingTail] = {}
        self.fed: dict[str, int] = {}
        self.failed: dict[str, str] = {}
        self.tables: dict[str, pl.DataFrame] = {}
        self.prox: tuple[list[str], ProximityConfig] | None = None

    @property
    def stages(self) -> set[str]:
        """The reader stages these readers stand in for."""
        return {_TAILED[k] for k in (*self.readers, *self.failed)}

    def start(self, src: LogSource, ctx: RunContext, stage_list, origin: TimeOrigin) -> None:
        """Open the reader of ``src`` if its stage reads that CSV (and has not been opened)."""
        stem = src.stem
        if stem not in _TAILED or stem in self.readers or stem in self.failed or src.header is None:
            return
        stage = next((st for st in stage_list if st.name == _TAILED[stem]), None)
        if stage is None or stage.available(ctx) is not None:
            return
        if stem == "crossings" and ctx.has_source("beams"):  # the stage decodes the raw beams instead
            return
        site = ctx.site
        try:
            if stem == "motion":
                cfg = config_from_mapping(MotionConfig, ctx.section("motion"), section="motion")
                ids = [m.id for m in site.motion_sensors]
                reader = ToggleTail(
                    src.path.name,
                    ids,
                    origin=origin,
                    rules=site_rules(site, cfg),
                    held=site.level_sensors,
                    path=src.path,
                )
            elif stem == "proximity":
                cfg = config_from_mapping(ProximityConfig, ctx.section("proximity"), section="proximity")
                ids = [p.id for p in site.proximity_sensors]
                self.prox = (ids, cfg)
                reader = ToggleTail(
                    src.path.name, ids, origin=origin, rules=cfg.rules, held=site.level_sensors, path=src.path
                )
            elif stem == "beams":
                reader = BeamTail(src.path.name, site.beam_ids, origin=origin, path=src.path)
            else:
                reader = CrossingTail(src.path.name, site.beam_ids, origin=origin, path=src.path)
            self.readers[stem] = reader
            self.fed[stem] = 0
            self._add(stem, reader.feed(src.header))
        except OnebitError as exc:
            self._fail(stem, exc)

    def poll(self, sources: dict[str, LogSource], final: bool) -> None:
        """Feed every reader the lines released since the last poll (and end them when ``final``)."""
        for stem, reader in list(self.readers.items()):
            src = sources[stem]
            try:
                lines = src.lines[self.fed[stem] : src.released]
                self.fed[stem] = src.released
                if lines:
                    self._add(stem, reader.feed(b"".join(lines)))
                if final:
                    self._add(stem, reader.finish())
            except OnebitError as exc:
                self._fail(stem, exc)

    @property
    def until(self) -> float:
        """Every row the batch readers give with ``t`` below this is in :attr:`tables`."""
        return min((r.settled_until for r in self.readers.values()), default=math.inf)

    def preset(self) -> dict[str, pl.DataFrame]:
        """The tables so far (with ``proximity_frames`` made from the proximity edges, as the stage makes them)."""
        out = dict(self.tables)
        if "proximity" in out and self.prox is not None:
            ids, cfg = self.prox
            out["proximity_frames"] = proximity_frames(
                out["proximity"],
                ids,
                period=cfg.period,
                start=None if cfg.start < 0 else cfg.start,
                instants=cfg.instants or None,
            )
        return out

    def _fail(self, stem: str, exc: OnebitError) -> None:
        self.readers.pop(stem, None)
        self.failed[stem] = str(exc)
        for name in (
            ("motion", "motion_suppressed")
            if stem == "motion"
            else (
                ("proximity", "proximity_suppressed")
                if stem == "proximity"
                else ("crossings", "aborted", "beam_events")
            )
        ):
            self.tables.pop(name, None)

    def _add(self, stem: str, chunk) -> None:
        if stem == "beams":
            parts = {"crossings": chunk.crossings, "aborted": chunk.aborted, "beam_events": chunk.events}
        elif stem == "crossings":
            parts = {"crossings": chunk.crossings}
        else:
            parts = {stem: chunk.motion, f"{stem}_suppressed": chunk.suppressed}
        parts["rejects"] = chunk.rejects
        for name, df in parts.items():
            old = self.tables.get(name)
            if old is None:
                self.tables[name] = df
            elif df.height:  # a new frame sharing the old chunks (a tracker may hold the old one)
                new = pl.concat([old, df], rechunk=False)
                self.tables[name] = new.rechunk() if new.n_chunks() > _MAX_CHUNKS else new


BACKWARDS = "timestamp goes backwards"


def say_clock_steps(tails: Tails, warned: set[str], echo: Callable[[str], None]) -> None:
    """Say once per log when its clock stepped back: the readers' first "goes backwards" reject."""
    rejects = tails.tables.get("rejects")
    if rejects is None or rejects.height == 0:
        return
    back = rejects.filter(pl.col("reason").str.starts_with(BACKWARDS) & ~pl.col("source").is_in(list(warned)))
    for source, line, reason in (
        back.unique("source", keep="first", maintain_order=True).select("source", "line", "reason").iter_rows()
    ):
        warned.add(source)
        echo(
            f"  {source}:{line}: the logger's clock stepped back ({reason}); its rows are rejected "
            "(OUT/tables/rejects.parquet) until its clock passes the latest time accepted"
        )
