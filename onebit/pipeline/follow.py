"""``onebit follow``: read a dataset's logs as they grow, publish each estimate with a bounded delay.

Two ways in:

* **live** -- the dataset's CSV logs (``motion.csv``, ``beams.csv``, ``crossings.csv``,
  ``proximity.csv``, ``truth.csv``, ``truth_crossings.csv``) are tailed: every poll reads the
  lines appended since the last one. A last line without its newline is being written: it is
  left for the next poll, never rejected (at the end, or when its file is rotated away or
  truncated, it is taken as a line, as the batch reader takes a file's last line). A log rotated,
  truncated or rewritten in place is followed into its new file (:func:`_read_live`). A growing
  ``.mcap`` (chunked, as loggers write them) is re-read when it grew, keeping every complete
  chunk (and the ``mcap_topics.toml`` map of ROS 2 topics). The *horizon* (the log time known
  so far) is the earliest of the sensor logs' latest stamps (a log that runs ahead does not
  make another's events final; ``truth.csv`` does not count).
* **replay** (``--replay 20x``) -- a finished log is played back at 20 times its own pace: a
  line is released when a virtual clock ``t0 + speed * (wall - wall0)`` passes its stamp; the
  horizon is that clock.

Released lines are appended to a snapshot of the dataset (a temporary folder with the dataset's
``*.toml``: what the final batch run of a live follow reads) and fed to the incremental readers
(:mod:`onebit.readers.tail`, :class:`_Tails`) of ``motion.csv``, ``proximity.csv``,
``beams.csv`` and ``crossings.csv``: each poll they read only the lines released since the last
one, carry the batch reader's state (duplicates, order, sensor and pair states, the debounce's
unsettled tail, open beam passes) and emit exactly the batch reader's rows and rejects on the
whole file once final. The other reader stages (``frames`` of a ceiling array's ``frames.csv``,
``correct``, MCAP channels) read the snapshot every poll (:func:`_read_prefix`). The time origin is fixed once (the whole log's in a replay;
when live, the first poll's, with its window of accepted stamps left open ahead, so a lone stamp
far in the future is rejected only by the final batch run).
``FollowConfig(incremental=False)`` re-reads the snapshot whole and re-runs ``beams`` and
``istate`` on the prefix at every poll (the earlier way; same tables).

Trackers online (:data:`ONLINE`):

* ``intruder`` -- per iteration, incrementally: :mod:`onebit.trackers.intruder.online` keeps the
  particle filter's posterior and steps it over each slot once it is final;
* ``beams`` -- per crossing, incrementally: :mod:`onebit.trackers.beams.online` feeds each final
  crossing to Algorithm 1 as a resumable pass; when the false-negative correction runs
  (``[correct]``) its input is the corrected string, chosen over the whole string, and it is
  re-run on the settled prefix instead;
* ``istate`` -- per stage, incrementally with ``latency_auto = false`` and without
  ``reliable_negatives`` (:mod:`onebit.trackers.istate.online`); otherwise re-run on the
  settled prefix;
* ``intruder-naive`` -- per iteration, re-run on the settled prefix of its input whenever a new
  settled event arrives; the rows up to that event not published before are published (a
  re-run could change an earlier row, which is never un-published: the final report says
  whether the published rows equal the batch's).

* ``findinghumo``, ``hmm1``, ``hmm2`` with ``decoding = "lagged"`` (their ``run.toml`` section)
  -- per block of ``tau`` slots, incrementally: :mod:`onebit.trackers.findinghumo.lagged` keeps
  the window decoder and the committed output, slots only the recent edges, and commits a block
  once ``decision_lag`` slots after it have arrived (the paper's bounded delay D'); the rows
  equal the batch run's with the same config. By default (``decoding = "batch"``) they are
  re-run on the settled prefix, and the published rows may differ from the final decoding.
* ``binpf`` -- per frame, incrementally: :mod:`onebit.trackers.binpf.online` keeps the particle
  filter's state and commits frame ``k`` once frame ``k + commit_lag`` is filtered (tracklets
  joined causally); equal to the batch run with the same ``[binpf] commit_lag`` (with the
  default 0 the batch run reports back to a track's birth and joins over the whole log; the
  follow then commits after ``DEFAULT_COMMIT_LAG`` frames and the report says where they differ).

Every other tracker is batch-only and runs at the end. An event at ``e`` is *settled* once the
horizon passes ``e + settle``, ``settle`` = the readers' look-ahead (1 s of reordering plus
the longest debounce window of the site's sensors), and once the incremental readers have
emitted it (:attr:`_Tails.until`).

Outputs, beside the run folder that the final batch run writes (``onebit run`` on the data
followed, so ``OUT/report.*``, ``OUT/tables``, ``OUT/rrd`` are the batch run's):

* ``OUT/live/tables/<table>/part-NNNNNN.parquet`` -- the published rows, one part per poll,
  each written to a temp file and renamed, so a crash leaves every table readable
  (``pl.read_parquet("OUT/live/tables/intruder_tracks/*.parquet")``): ``<tracker>_tracks``,
  ``intruder_iterations``, ``intruder_camera`` (the pan-tilt-zoom command of every iteration,
  with ``[intruder] camera_position``) and ``delays`` (tracker, t, delay_s);
* ``OUT/live/rrd/follow.rrd`` -- the Rerun stream as it grows (plus ``--connect`` /
  ``--serve-web``);
* ``OUT/live/report.csv`` / ``.parquet`` -- per online tracker: estimates published, delay p50 /
  p99 / max (s, wall clock, from the moment the log reached the estimate's time to its
  publication) and whether the published rows equal the batch run's.

The follow loop owns the clock (``clock`` / ``sleep`` can be injected: tests replay with a
simulated clock); trackers never read it.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import shutil
import tempfile
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
import polars as pl

from onebit.core import writers as outputs
from onebit.core.config import config_from_mapping
from onebit.core.errors import ConfigError, InputError, OnebitError
from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.core.tables import REJECTS
from onebit.models.graph_hmm.decoding import build_eatg
from onebit.pipeline.context import RunContext, dataset_run_config
from onebit.pipeline.runner import RunResult, check_dataset, check_out, check_sections, run_pipeline
from onebit.pipeline.stages import (
    LOOKS,
    TIME_SOURCES,
    TRACKERS,
    run_time_origin,
    stages,
    tracker_config,
    without_ignored,
)
from onebit.readers.mcap_io import load_topic_map, read_mcap
from onebit.readers.motion import MotionConfig, site_rules
from onebit.readers.proximity import ProximityConfig, proximity_frames
from onebit.readers.rows import REORDER_TOLERANCE_S, RawRows
from onebit.readers.tail import BeamTail, CrossingTail, ToggleTail
from onebit.readers.timebase import MAX_GAP_S, TimeOrigin
from onebit.trackers.base import ARTIFACTS, PROGRESS
from onebit.trackers.beams import online as beams_online
from onebit.trackers.binpf import online as binpf_online
from onebit.trackers.binpf import stage as binpf_stage
from onebit.trackers.findinghumo import lagged as hmm_online
from onebit.trackers.findinghumo.stage import FindingHumoConfig
from onebit.trackers.intruder import online as intruder_online
from onebit.trackers.istate import online as istate_online
from onebit.viz import live as viz_live
from onebit.viz.families import Look

#: Trackers that run while the log grows, and how often they publish.
ONLINE: dict[str, str] = {
    "intruder": "per iteration (incremental particle filter)",
    "intruder-naive": "per iteration",
    "beams": "per crossing (incremental; re-run on the settled prefix when [correct] runs)",
    "istate": "per stage (incremental with latency_auto = false; else re-run on the settled prefix)",
    "findinghumo": "per window (re-run on the settled prefix)",
    "hmm1": "per window (re-run on the settled prefix)",
    "hmm2": "per window (re-run on the settled prefix)",
    "binpf": "per frame, committed after [binpf] commit_lag frames (incremental particle filter)",
}
#: The HMM trackers, online incrementally with ``decoding = "lagged"`` (their window decoder mode).
_LAGGED_MODES = {"findinghumo": "adaptive", "hmm1": "full1", "hmm2": "full2"}
#: How they publish then.
LAGGED = "per block of tau slots, final D' slots after it (decoding = 'lagged', incremental)"
#: The input table whose settled events close the rows of a re-run-on-prefix tracker.
_PREFIX_EVENTS = {
    "intruder-naive": ("motion",),
    "beams": ("corrected_crossings", "crossings"),
    "istate": ("motion", "proximity", "crossings"),
    "findinghumo": ("motion",),
    "hmm1": ("motion",),
    "hmm2": ("motion",),
}
#: Reader stages run on every poll (truth and camera only at the end, by the batch run).
_READER_STAGES = ("frames", "crossings", "motion", "proximity", "correct")
#: Logs that are ground truth, not sensor input: they do not hold the live horizon back.
_TRUTH_LOGS = ("truth", "truth_crossings")
#: Subfolder of OUT with the live outputs (kept by later runs into OUT).
LIVE = "live"


@dataclass(frozen=True, kw_only=True)
class FollowConfig:
    """How ``onebit follow`` reads and publishes.

    replay : speed factor of a replay (``--replay 20x`` -> 20.0); ``None`` = follow growing logs.
    poll : seconds between polls: the publication cadence (a bound on the delay added by the loop).
    idle : seconds without a new line that end a live run.
    settle : seconds an event must be in the past before it is final; ``None`` = the readers'
        look-ahead (1 s reordering + the longest debounce window).
    incremental : read the CSV logs incrementally and run ``beams`` crossing by crossing;
        ``False`` re-reads the whole snapshot and re-runs ``beams`` on the prefix at every poll
        (the earlier way, same tables: for comparisons, ``benchmarks/bench_follow.py``).
    """

    replay: float | None = None
    poll: float = 0.25
    idle: float = 10.0
    settle: float | None = None
    incremental: bool = True

    def __post_init__(self) -> None:
        if self.replay is not None and not (
            isinstance(self.replay, (int, float)) and math.isfinite(self.replay) and self.replay > 0
        ):
            raise ConfigError(f"FollowConfig.replay = {self.replay!r}; a speed factor > 0 (e.g. 20 for --replay 20x)")
        if not isinstance(self.incremental, bool):
            raise ConfigError(f"FollowConfig.incremental = {self.incremental!r}; must be true or false")
        for name, lo in (("poll", 1e-4), ("idle", 0.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < lo:
                raise ConfigError(f"FollowConfig.{name} = {v!r}; allowed range: [{lo}, inf) seconds")
        if self.settle is not None and (
            not isinstance(self.settle, (int, float)) or not math.isfinite(self.settle) or self.settle < 0
        ):
            raise ConfigError(f"FollowConfig.settle = {self.settle!r}; allowed range: [0, inf) seconds")


def parse_speed(text: str) -> float:
    """``"20x"`` / ``"20"`` / ``"0.5x"`` -> the speed factor; anything else is a :class:`ConfigError`."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*[xX]?\s*", str(text))
    if not m or not float(m.group(1)) > 0:
        raise ConfigError(f"--replay {text!r}: expected a speed such as 20x (20 times real time)")
    return float(m.group(1))


@dataclass
class FollowResult:
    """What :func:`follow` did: the final batch run, the follow report and the live folder."""

    run: RunResult
    report: pl.DataFrame
    live: Path
    batch_only: list[str] = field(default_factory=list)


# --------------------------------------------------------------------------- sources


@dataclass
class _Source:
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


def _header_t_column(header: bytes, path: Path) -> int:
    names = [c.strip().strip('"') for c in header.decode("utf-8", errors="replace").rstrip("\r\n").split(",")]
    if "t" not in names:
        raise InputError(f"no 't' column in the header {names}", file=path, line=1)
    return names.index("t")


def _stamps(lines: list[bytes], col: int, origin: TimeOrigin) -> np.ndarray:
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


def _read_appended(src: _Source) -> list[bytes]:
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
            src.t_col = _header_t_column(src.header, src.path)
            src.snapshot.write_bytes(src.header if src.header.endswith(b"\n") else src.header + b"\n")
        elif _fields(lines[0]) == _fields(src.header):
            lines = lines[1:]
    return lines


def _rewritten(src: _Source) -> bool:
    """Whether the open file was truncated (shorter than what was read) or rewritten in place
    (the last line read is no longer where it was): a logger that restarted on the same file."""
    size = os.fstat(src.fh.fileno()).st_size
    if size < src.offset:
        return True
    n = len(src.last_line)
    return n > 0 and os.pread(src.fh.fileno(), n, src.offset - n) != src.last_line


def _rotated(src: _Source) -> bool:
    """Whether the log's path now names another file than the one open (renamed and a new one
    started); a path with no file yet (between the rename and the new file) is not."""
    try:
        st = os.stat(src.path)
    except FileNotFoundError:
        return False
    return (st.st_dev, st.st_ino) != src.ident


def _unfinished_line(src: _Source) -> list[bytes]:
    """The line the old file ends with that never got its newline, as a complete line (the
    batch reader takes a file's last line so), unless it is only the start of a header."""
    rest, src.partial = src.partial, b""
    if not rest.strip() or src.header is None or (src.at_start and src.header.startswith(rest.rstrip(b"\r"))):
        return []
    return [rest + b"\n"]


def _open_log(src: _Source) -> bool:
    """Open the file at the log's path (a new one is read from its start)."""
    try:
        src.fh = open(src.path, "rb")  # noqa: SIM115 - kept open across polls, closed by close()
    except OSError:
        return False
    st = os.fstat(src.fh.fileno())
    src.ident, src.offset, src.last_line, src.at_start = (st.st_dev, st.st_ino), 0, b"", True
    return True


def _read_live(src: _Source) -> tuple[list[bytes], list[str]]:
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


def _take_unfinished(sources: dict[str, _Source]) -> None:
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
class _McapSource:
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


def _channels(mcaps: list[_McapSource]) -> dict[str, RawRows]:
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


class _Tails:
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

    def start(self, src: _Source, ctx: RunContext, stage_list, origin: TimeOrigin) -> None:
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

    def poll(self, sources: dict[str, _Source], final: bool) -> None:
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


# --------------------------------------------------------------------------- the loop


class _Publisher:
    """Appends published rows as parquet parts, logs them to the stream, measures delays."""

    def __init__(self, live: Path, rec, wall_at: Callable[[float], float], clock: Callable[[], float]):
        self.tables = live / "tables"
        self.rec = rec
        self.wall_at = wall_at
        self.clock = clock
        self.parts: dict[str, int] = {}
        self.delays: list[pl.DataFrame] = []
        self.counts: dict[str, int] = {}

    def table(self, name: str, df: pl.DataFrame) -> None:
        if df is None or df.height == 0:
            return
        k = self.parts.get(name, 0)
        self.parts[name] = k + 1
        outputs.write_parquet(df, self.tables / name / f"part-{k:06d}.parquet")

    def estimates(self, tracker: str, tracks: pl.DataFrame) -> None:
        if tracks is None or tracks.height == 0:
            return
        now = self.clock()
        t = tracks["t"].to_numpy()
        delay = np.array([max(0.0, now - self.wall_at(float(x))) for x in t])
        self.table(f"{tracker}_tracks", tracks)
        d = pl.DataFrame(
            {"tracker": [tracker] * len(t), "t": t, "delay_s": delay},
            schema={"tracker": pl.String, "t": pl.Float64, "delay_s": pl.Float64},
        )
        self.table("delays", d)
        self.delays.append(d)
        self.counts[tracker] = self.counts.get(tracker, 0) + len(t)
        if self.rec is not None:
            viz_live.log_estimates(self.rec, tracker, tracks, rgb=LOOKS.get(tracker, Look()).rgb)
            viz_live.log_delays(self.rec, tracker, t, delay)


def _lagged(entry, data: Path, scratch: Path, site, rg, sections: dict, trackers) -> bool:
    """Whether an HMM tracker's config (``--config``, else the dataset's ``run.toml``) asks for
    ``decoding = "lagged"``."""
    ctx = RunContext(
        data, scratch, site, rg, {k: dict(v) for k, v in sections.items() if isinstance(v, dict)}, trackers=trackers
    )
    return getattr(tracker_config(entry, ctx), "decoding", "batch") == "lagged"


def _settle(site, sections: dict) -> float:
    """The readers' look-ahead: reordering tolerance + the longest debounce window."""
    cfg = config_from_mapping(MotionConfig, sections.get("motion", {}), section="motion")
    windows = [0.0]
    if site.motion_sensors:
        for r in site_rules(site, cfg).values():
            windows += [r.chatter_window, r.min_on]
    return REORDER_TOLERANCE_S + max(windows)


def _read_prefix(
    snapshot: Path,
    scratch: Path,
    site,
    rg,
    sections: dict,
    trackers: tuple[str, ...],
    origin: TimeOrigin | None,
    stage_list,
    mcap_channels: dict[str, RawRows],
    tails: _Tails | None = None,
) -> RunContext:
    """The reader stages on the snapshot (and the MCAP rows released): a context whose
    ``tables`` hold what they made. The stages that ``tails`` stands in for are not run: their
    tables are the incremental readers' (read from the bytes appended since the last poll)."""
    ctx = _context(snapshot, scratch, site, rg, sections, trackers, mcap_channels)
    if origin is not None:
        ctx.time_origin = origin
    skip = set()
    if tails is not None:
        ctx.tables.update(tails.preset())
        skip = tails.stages
    for st in stage_list:
        if st.name not in _READER_STAGES or st.name in skip:
            continue
        if any(n not in ctx.tables for n in st.needs) or st.available(ctx) is not None:
            continue
        try:
            made = st.work(ctx)
        except OnebitError as exc:
            ctx.status[st.name] = f"failed: {exc}"
            continue
        ctx.tables.update({k: v for k, v in made.items() if k != ARTIFACTS})
    return ctx


def _context(data: Path, scratch: Path, site, rg, sections: dict, trackers, mcap_channels) -> RunContext:
    ctx = RunContext(
        data, scratch, site, rg, {k: dict(v) for k, v in sections.items() if isinstance(v, dict)}, trackers=trackers
    )
    ctx.mcap_channels = dict(mcap_channels)
    return ctx


def _inputs(
    entry, tables: dict, region_graph, *, until: float | None, ignored: frozenset[str] = frozenset()
) -> dict[str, Any] | None:
    """A tracker's inputs from ``tables``, each cut at ``t <= until`` (``None``: whole), without
    the rows of the ``ignored`` sensors (:func:`onebit.pipeline.stages.without_ignored`)."""
    inputs: dict[str, Any] = {}
    for key in entry.spec.needs:
        src = next((s for s in entry.inputs.get(key, (key,)) if s in tables), None)
        if src is None:
            return None
        df = without_ignored(src, tables[src], ignored)
        inputs[key] = df if until is None or "t" not in df.columns else df.filter(pl.col("t") <= until)
    for k in entry.spec.wants:
        if k in tables:
            df = without_ignored(k, tables[k], ignored)
            inputs[k] = df if until is None or "t" not in df.columns else df.filter(pl.col("t") <= until)
    inputs["region_graph"] = region_graph
    inputs[PROGRESS] = lambda done, total: None
    return inputs


def follow(
    dataset: str | Path,
    out: str | Path,
    *,
    trackers: tuple[str, ...] | None = None,
    config: dict[str, Any] | None = None,
    options: FollowConfig = FollowConfig(),
    connect: str | None = None,
    serve_web: bool | viz_live.WebServe = False,
    echo: Callable[[str], None] | None = None,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> FollowResult:
    """Follow ``dataset`` (module docstring) and end with the batch run into ``out``.

    ``serve_web``: ``True`` serves the web viewer on :class:`~onebit.viz.live.WebServe`'s
    defaults (127.0.0.1 only, ports 9090 and 9876), a ``WebServe`` where it says.

    Raises :class:`OnebitError` for bad input found before anything is followed (dataset,
    ``OUT``, site, config, tracker names, no CSV log to follow, a port in use).
    """
    dataset, out = Path(dataset), Path(out)
    echo = echo or (lambda s: None)
    check_dataset(dataset)
    check_out(out, dataset)
    site = load_site(dataset / "site.toml")
    rg = build_region_graph(site)
    stage_list = stages(TRACKERS)
    sections = dict(config or {})
    check_sections(sections, stage_list, source="--config")
    dataset_sections = dataset_run_config(dataset)
    check_sections(dataset_sections, stage_list, source=dataset / "run.toml")
    merged = {**dataset_sections, **sections}
    known = [e.name for e in TRACKERS]
    for tr in trackers or ():
        if tr not in known:
            raise ConfigError(f"--trackers: unknown tracker {tr!r}; known: {sorted(known)}")
    chosen = tuple(trackers) if trackers else tuple(known)
    logs = [stem for stem in TIME_SOURCES if (dataset / f"{stem}.csv").is_file()]
    topics = dataset / "mcap_topics.toml"
    topic_map = load_topic_map(topics) if topics.is_file() else None
    mcaps = [_McapSource(p, topic_map) for p in sorted(dataset.glob("*.mcap"))]
    if not logs and not mcaps:
        raise InputError(
            "no log to follow (motion.csv, beams.csv, crossings.csv, proximity.csv, truth.csv or an .mcap)",
            file=dataset,
        )
    settle = options.settle if options.settle is not None else _settle(site, merged)
    serve = viz_live.WebServe() if serve_web is True else (serve_web or None)
    if serve is not None:
        viz_live.check_ports(serve)  # a port in use stops the follow before it replaces OUT/live

    live = out / LIVE
    shutil.rmtree(live, ignore_errors=True)  # a previous follow's live outputs
    live.mkdir(parents=True)
    snapshot = Path(tempfile.mkdtemp(prefix="onebit-follow-"))
    served: viz_live.ServedViewer | None = None
    scratch = snapshot / ".scratch"
    data = snapshot / "data"
    data.mkdir()
    scratch.mkdir()
    sources: dict[str, _Source] = {}
    try:
        for p in dataset.glob("*.toml"):
            shutil.copy(p, data / p.name)
        sources = {stem: _Source(stem, dataset / f"{stem}.csv", data / f"{stem}.csv") for stem in logs}
        origin: TimeOrigin | None = None
        if options.replay is not None:  # the whole log is known: its origin, every line's release time
            full = RunContext(dataset, scratch, site, rg, {}, trackers=chosen)
            for m in mcaps:
                for topic, frame in read_mcap(m.path, topic_map=topic_map).channels.items():
                    full.mcap_channels.setdefault(
                        topic, RawRows(f"{m.path.name}:{topic}", frame, pl.DataFrame(schema=REJECTS))
                    )
            origin = run_time_origin(full)
            for m in mcaps:
                m.load_all(origin)
            for src in sources.values():
                raw = src.path.read_bytes()
                head, _, body = raw.partition(b"\n")
                src.header = head + b"\n"
                src.t_col = _header_t_column(src.header, src.path)
                src.lines = body.splitlines(keepends=True)
                t = _stamps(src.lines, src.t_col, origin)
                # in file order: a line without a readable stamp goes with the line before it
                filled = pl.Series(t).fill_nan(None).fill_null(strategy="forward").fill_null(-math.inf).to_numpy()
                src.release = np.maximum.accumulate(filled) if len(filled) else filled
        starts = [s.release[0] for s in sources.values() if len(s.release) and math.isfinite(s.release[0])]
        starts += [r[0] for m in mcaps for r in m.release.values() if len(r) and math.isfinite(r[0])]
        t0 = min(starts) if starts else 0.0
        wall0 = clock()
        history: list[tuple[float, float]] = []  # live: (horizon, wall) at each poll

        def wall_at(t: float) -> float:
            if options.replay is not None:
                return wall0 + (t - t0) / options.replay
            i = next((w for h, w in history if h >= t), None)
            return i if i is not None else clock()

        recording_id = str(uuid.uuid4())
        rec, served = viz_live.open_live(
            live / "rrd" / "follow.rrd", recording_id=recording_id, connect=connect, serve_web=serve
        )
        for line in served.describe() if served else ():
            echo(f"  {line}")
        viz_live.log_live_site(rec, site, rg)
        pub = _Publisher(live, rec, wall_at, clock)

        entries = {e.name: e for e in TRACKERS}
        online = [
            n
            for n in ONLINE
            if n in chosen and (entries[n].spec.available is None or entries[n].spec.available(site.tracked) is None)
        ]
        viz_live.send_live_blueprint(rec, online)
        batch_only = [n for n in chosen if n not in online]
        if batch_only:
            echo(f"  batch-only (run at the end): {', '.join(batch_only)}")
        intruder_state = None
        tails = _Tails()
        beams_state: beams_online.OnlineBeams | None = None
        istate_state: istate_online.OnlineIState | bool | None = None  # False: not online with its config
        hmm_states: dict[str, hmm_online.OnlineHmm] = {}
        binpf_state: binpf_online.FollowBinPF | None = None
        lagged = [
            n for n in online if n in _LAGGED_MODES and _lagged(entries[n], data, scratch, site, rg, merged, chosen)
        ]
        for n in online:
            echo(f"  {n}: online, {LAGGED if n in lagged else ONLINE[n]}")
        published: dict[str, float] = {n: -math.inf for n in online}
        warned: set[str] = set()  # logs whose clock was said to have stepped back
        sent: dict[str, pl.DataFrame] = {}
        logged_edges = 0
        last_growth = clock()
        polls = 0
        horizon = -math.inf
        final = False
        while True:
            now = clock()
            new = False
            if options.replay is not None:
                horizon = t0 + (now - wall0) * options.replay
                for src in sources.values():
                    n = int(np.searchsorted(src.release, horizon, side="right"))
                    if n > src.released:
                        src.write(src.lines[src.released : n])
                        src.released, new = n, True
                for m in mcaps:
                    new = m.replay(horizon) or new
                final = all(s.released == len(s.lines) for s in sources.values()) and all(m.done() for m in mcaps)
                if final:
                    horizon = max([horizon, *(s.release[-1] for s in sources.values() if len(s.release))])
                    horizon = max([horizon, *(r[-1] for m in mcaps for r in m.release.values() if len(r))])
            else:
                for src in sources.values():
                    lines, notes = _read_live(src)  # a line being written waits for its newline
                    for note in notes:
                        echo(f"  {note}")
                    if lines:
                        src.write(lines)
                        src.lines.extend(lines)
                        new = True
                for m in mcaps:
                    new = m.poll() or new
                if new:
                    last_growth = now
                    if origin is None:  # the first lines fix t = 0; the window of accepted stamps stays open ahead
                        first_ctx = RunContext(data, scratch, site, rg, {}, trackers=chosen)
                        first_ctx.mcap_channels = _channels(mcaps)
                        first = run_time_origin(first_ctx)
                        lo = first.lo - MAX_GAP_S if math.isfinite(first.lo) else first.lo
                        origin = dataclasses.replace(first, lo=lo, hi=math.inf)
                    for src in sources.values():
                        fresh = src.lines[src.released :]
                        if fresh:
                            t = _stamps(fresh, src.t_col, origin)
                            t = t[np.isfinite(t)]
                            if len(t):
                                src.last_t = max(src.last_t, float(t.max()))
                            src.released = len(src.lines)
                    for m in mcaps:
                        m.stamps(origin)
                    # every sensor log must have passed a time before it is known: the horizon is
                    # the earliest of their latest stamps (ground truth logs do not hold it back)
                    known = [s.last_t for k, s in sources.items() if k not in _TRUTH_LOGS and math.isfinite(s.last_t)]
                    known += [m.last_t for m in mcaps if math.isfinite(m.last_t)]
                    if not known:
                        known = [s.last_t for s in sources.values()]
                    horizon = min(known) if known else -math.inf
                    history.append((horizon, now))
                final = now - last_growth >= options.idle
                if final:
                    _take_unfinished(sources)
            polls += 1
            if new or final:
                if origin is not None and options.incremental:  # only the lines released since the last poll
                    here = _context(data, scratch, site, rg, merged, chosen, _channels(mcaps))
                    for src in sources.values():
                        tails.start(src, here, stage_list, origin)
                    tails.poll(sources, final)
                    _say_clock_steps(tails, warned, echo)
                ctx = _read_prefix(data, scratch, site, rg, merged, chosen, origin, stage_list, _channels(mcaps), tails)
                tables = ctx.tables
                # final: an event at most this late (the readers' look-ahead, and what they emitted)
                read_until = tails.until
                until_t = math.inf if final else min(horizon - settle, math.nextafter(read_until, -math.inf))
                if "motion" in tables:
                    settled = tables["motion"].filter(pl.col("t") <= until_t) if not final else tables["motion"]
                    if settled.height > logged_edges:
                        viz_live.log_states(rec, settled.slice(logged_edges))
                        logged_edges = settled.height
                for name in online:
                    entry = entries[name]
                    if name == "intruder":
                        if "motion" not in tables:
                            continue
                        if intruder_state is None:
                            intruder_state = intruder_online.start(site, tracker_config(entry, ctx))
                        rows = intruder_online.advance(
                            intruder_state,
                            tables["motion"],
                            horizon=min(horizon, until_t + settle),
                            settle=settle,
                            final=final,
                        )
                        pub.estimates(name, rows["tracks"])
                        pub.table(f"{name}_iterations", rows["iterations"])
                        if "camera" in rows:
                            pub.table(f"{name}_camera", rows["camera"])
                        continue
                    if (
                        name == "beams"
                        and options.incremental
                        and "corrected_crossings" not in tables
                        and "crossings" in tables
                    ):
                        # Algorithm 1 crossing by crossing (its input is the reader's, not the correction's)
                        if beams_state is None:
                            beams_state = beams_online.start(site, tracker_config(entry, ctx), rg)
                        cr = tables["crossings"]
                        rows = beams_online.advance(
                            beams_state, cr if final else cr.filter(pl.col("t") <= until_t), final=final
                        )
                        pub.estimates(name, rows)
                        continue
                    if name == "istate" and options.incremental and istate_state is not False:
                        # O'Kane's filter stage by stage (when its config lets the batch run be sequential)
                        if istate_state is None:
                            cfg = tracker_config(entry, ctx)
                            istate_state = (
                                istate_online.start(site, cfg) if istate_online.supported(cfg) is None else False
                            )
                        if istate_state is not False:
                            rows = istate_online.advance(
                                istate_state,
                                {k: tables[k] for k in ("motion", "proximity", "crossings") if k in tables},
                                until=until_t,
                                final=final,
                            )
                            pub.estimates(name, rows)
                            continue
                    if name == "binpf":
                        if "proximity_frames" in tables:
                            if binpf_state is None:
                                binpf_state = binpf_stage.start_follow(site.tracked, tracker_config(entry, ctx))
                            frames = tables["proximity_frames"]
                            pub.estimates(name, binpf_online.advance(binpf_state, frames, until=until_t, final=final))
                        continue
                    if name in lagged:
                        if "motion" not in tables:
                            continue
                        if name not in hmm_states:
                            cfg = tracker_config(entry, ctx)
                            eatg = build_eatg(site, np.zeros((0, len(site.sensor_graph.nodes)), bool), cfg)
                            hmm_states[name] = hmm_online.start(
                                name,
                                _LAGGED_MODES[name],
                                site,
                                cfg,
                                eatg,
                                cpda_windows=cfg.c_windows if isinstance(cfg, FindingHumoConfig) else None,
                            )
                        rows = hmm_online.advance(
                            hmm_states[name], tables["motion"], settled_until=until_t, final=final
                        )
                        pub.estimates(name, rows)
                        continue
                    events = next((tables[k] for k in _PREFIX_EVENTS[name] if k in tables), None)
                    if events is None or events.height == 0:
                        continue
                    until = None if final else until_t
                    ev = events if until is None else events.filter(pl.col("t") <= until)
                    if ev.height == 0:
                        continue
                    last = math.inf if final else float(ev["t"].max())
                    if last <= published[name]:
                        continue
                    inputs = _inputs(entry, tables, rg, until=until, ignored=site.ignored)
                    if inputs is None:
                        continue
                    res = entry.spec.run(inputs, site.tracked, tracker_config(entry, ctx))
                    upto = res["tracks"].filter(pl.col("t") <= last)
                    # rows not published yet (a re-run may add rows dated earlier: beams gives an agent
                    # created at a later crossing its initial region at the first crossing's time)
                    # an estimate is published once: a later re-run's value for the same
                    # (track, t, region, node) is not re-published (the final report compares)
                    seen = sent.get(name)
                    key = [c for c in upto.columns if c not in ("x", "y")]
                    rows = upto if seen is None else upto.join(seen.select(key), on=key, how="anti", nulls_equal=True)
                    sent[name] = upto if seen is None else pl.concat([seen, rows])
                    published[name] = last
                    pub.estimates(name, rows)
            if final:
                break
            sleep(options.poll)
        viz_live.close_live(rec, served)
        echo(f"  followed {polls} polls; final batch run")
        final_data = dataset if options.replay is not None else data
        for m in mcaps if options.replay is None else ():  # the recordings as they are now
            shutil.copy(m.path, data / m.path.name)
        run = run_pipeline(final_data, out, trackers=trackers, config=config, progress=False, echo=echo)
        report = pl.concat([_follow_report(out, live, online, pub, polls, batch_only), _fault_rows(out, sources)])
        outputs.write_parquet(report, live / "report.parquet")
        outputs.write_csv(report, live / "report.csv")
        return FollowResult(run=run, report=report, live=live, batch_only=batch_only)
    finally:
        for src in sources.values():
            src.close()
        if served is not None:  # an error or an interrupt: the page's server ends with the follow
            served.stop()
        shutil.rmtree(snapshot, ignore_errors=True)


#: The reason the readers give a row more than the reordering tolerance behind the latest accepted one.
_BACKWARDS = "timestamp goes backwards"


def _say_clock_steps(tails: _Tails, warned: set[str], echo: Callable[[str], None]) -> None:
    """Say once per log when its clock stepped back: the readers' first "goes backwards" reject."""
    rejects = tails.tables.get("rejects")
    if rejects is None or rejects.height == 0:
        return
    back = rejects.filter(pl.col("reason").str.starts_with(_BACKWARDS) & ~pl.col("source").is_in(list(warned)))
    for source, line, reason in (
        back.unique("source", keep="first", maintain_order=True).select("source", "line", "reason").iter_rows()
    ):
        warned.add(source)
        echo(
            f"  {source}:{line}: the logger's clock stepped back ({reason}); its rows are rejected "
            "(OUT/tables/rejects.parquet) until its clock passes the latest time accepted"
        )


def _fault_rows(out: Path, sources: dict[str, _Source]) -> pl.DataFrame:
    """The follow report's rows on faults of the logs: files restarted (rotated, truncated,
    rewritten) and rows rejected because the logger's clock stepped back (the final run's rejects)."""
    rows = [("follow", "log_restarts", float(sum(s.restarts for s in sources.values())), "files")]
    path = out / "tables" / "rejects.parquet"
    back = pl.read_parquet(path).filter(pl.col("reason").str.starts_with(_BACKWARDS)) if path.is_file() else None
    rows.append(("follow", "rows_rejected_backwards", float(back.height if back is not None else 0), "rows"))
    return pl.DataFrame(
        rows, schema={"stage": pl.String, "metric": pl.String, "value": pl.Float64, "unit": pl.String}, orient="row"
    )


def read_live_table(live: str | Path, name: str) -> pl.DataFrame | None:
    """Every part of ``OUT/live/tables/<name>/`` in order (``None`` when nothing was published)."""
    parts = sorted((Path(live) / "tables" / name).glob("part-*.parquet"))
    return pl.concat([pl.read_parquet(p) for p in parts]) if parts else None


def _follow_report(
    out: Path, live: Path, online: list[str], pub: _Publisher, polls: int, batch_only: list[str]
) -> pl.DataFrame:
    rows: list[tuple[str, str, float, str]] = [
        ("follow", "polls", float(polls), "polls"),
        ("follow", "batch_only_trackers", float(len(batch_only)), "trackers"),
    ]
    delays = (
        pl.concat(pub.delays)
        if pub.delays
        else pl.DataFrame(schema={"tracker": pl.String, "t": pl.Float64, "delay_s": pl.Float64})
    )
    for name in online:
        got = read_live_table(live, f"{name}_tracks")
        batch_path = out / "tables" / f"{name}_tracks.parquet"
        batch = pl.read_parquet(batch_path) if batch_path.is_file() else None
        if got is None and batch is None:  # its inputs never appeared (a site without beams, say)
            continue
        rows.append((name, "online_estimates", float(got.height if got is not None else 0), "rows"))
        if batch is not None:
            a = got if got is not None else batch.clear()
            cols = batch.columns
            same = (
                a.select(cols)
                .sort(["track", "t"], maintain_order=True)
                .equals(batch.sort(["track", "t"], maintain_order=True))
            )
            rows.append((name, "online_equals_batch", 1.0 if same else 0.0, "flag"))
            if not same:  # how far apart: rows only one side has, and positions of the rows both have
                key = [c for c in cols if c not in ("x", "y")]
                rows.append(
                    (
                        name,
                        "online_rows_not_in_batch",
                        float(a.join(batch, on=key, how="anti", nulls_equal=True).height),
                        "rows",
                    )
                )
                rows.append(
                    (
                        name,
                        "batch_rows_not_online",
                        float(batch.join(a, on=key, how="anti", nulls_equal=True).height),
                        "rows",
                    )
                )
                both = a.join(batch, on=key, how="inner", nulls_equal=True, suffix="_batch")
                if both.height and "x" in cols:
                    gap = ((pl.col("x") - pl.col("x_batch")) ** 2 + (pl.col("y") - pl.col("y_batch")) ** 2).sqrt()
                    rows.append(
                        (name, "max_position_difference", float(both.select(gap.max()).item() or 0.0), "site units")
                    )
        d = delays.filter(pl.col("tracker") == name)["delay_s"].to_numpy()
        if len(d):
            rows += [
                (name, "delay_p50", float(np.percentile(d, 50)), "s"),
                (name, "delay_p99", float(np.percentile(d, 99)), "s"),
                (name, "delay_max", float(d.max()), "s"),
            ]
    return pl.DataFrame(
        rows, schema={"stage": pl.String, "metric": pl.String, "value": pl.Float64, "unit": pl.String}, orient="row"
    )
