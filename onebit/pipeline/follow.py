"""``onebit follow``: read a dataset's logs as they grow, publish each estimate with a bounded delay.

Two ways in:

* **live** -- the dataset's CSV logs (``motion.csv``, ``beams.csv``, ``crossings.csv``,
  ``proximity.csv``, ``truth.csv``, ``truth_crossings.csv``) are tailed: every poll reads the
  lines appended since the last one (:mod:`onebit.pipeline.tail`: a line being written waits
  for its newline; a log rotated, truncated or rewritten in place is followed into its new
  file). A growing ``.mcap`` is re-read when it grew, keeping every complete chunk. The
  *horizon* (the log time known so far) is the earliest of the sensor logs' latest stamps (a
  log that runs ahead does not make another's events final; ``truth.csv`` does not count).
* **replay** (``--replay 20x``) -- a finished log is played back at 20 times its own pace: a
  line is released when a virtual clock ``t0 + speed * (wall - wall0)`` passes its stamp; the
  horizon is that clock.

A follow is a :class:`Follow` whose steps repeat until the logs end:

* :meth:`~Follow.poll` -- read what the logs gained (or what the replay released) into a
  snapshot of the dataset (a temporary folder with the dataset's ``*.toml``);
* :meth:`~Follow.read` -- the stages declared ``polled`` (the readers of the sensor logs,
  :mod:`onebit.pipeline.stages`) on what was released, each through the runner's one
  :func:`~onebit.pipeline.runner.run_stage`; the CSV logs are read incrementally
  (:class:`~onebit.pipeline.tail.Tails`: only the lines released since the last poll, emitting
  exactly the batch reader's rows once final) and their stages are not re-run;
* :meth:`~Follow.settle` -- how far the events are final: an event at ``e`` is *settled* once
  the horizon passes ``e + settle`` (``settle`` = the readers' look-ahead: 1 s of reordering
  plus the longest debounce window of the site's sensors) and the incremental readers have
  emitted it;
* :meth:`~Follow.publish` -- every tracker that runs live, as its entry declares
  (``TrackerEntry.live``, :mod:`onebit.pipeline.online`: stepped online, lagged, or re-run on
  the settled prefix); the others are batch-only;
* :meth:`~Follow.finish` -- the final batch run (:func:`~onebit.pipeline.runner.run_pipeline`
  on the data followed) and the follow report.

The time origin is fixed once (the whole log's in a replay; when live, the first poll's, with
its window of accepted stamps left open ahead, so a lone stamp far in the future is rejected
only by the final batch run). ``FollowConfig(incremental=False)`` re-reads the snapshot whole
and re-runs ``beams`` and ``istate`` on the prefix at every poll (the earlier way; same tables).

Outputs, beside the run folder that the final batch run writes (so ``OUT/report.*``,
``OUT/tables``, ``OUT/rrd`` are the batch run's), in ``OUT/live`` (:mod:`onebit.pipeline.publish`):

* ``tables/<table>/part-NNNNNN.parquet`` -- the published rows, one part per poll, each
  written to a temp file and renamed, so a crash leaves every table readable
  (``pl.read_parquet("OUT/live/tables/intruder_tracks/*.parquet")``): ``<tracker>_tracks``,
  the other tables an online tracker publishes (``intruder_iterations``, ``intruder_camera``)
  and ``delays`` (tracker, t, delay_s);
* ``rrd/follow.rrd`` -- the Rerun stream as it grows (plus ``--connect`` / ``--serve-web``);
* ``report.csv`` / ``.parquet`` -- per live tracker: estimates published, delay p50 / p99 /
  max (s, wall clock, from the moment the log reached the estimate's time to its
  publication) and whether the published rows equal the batch run's.

The follow owns the clock (``clock`` / ``sleep`` can be injected: tests replay with a
simulated clock); trackers never read it.
"""

from __future__ import annotations

import dataclasses
import math
import re
import shutil
import tempfile
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from onebit.core import writers as outputs
from onebit.core.config import config_from_mapping
from onebit.core.errors import ConfigError, InputError
from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.core.tables import REJECTS
from onebit.pipeline import stages as declaration
from onebit.pipeline.context import RunContext
from onebit.pipeline.online import BATCH, Poll
from onebit.pipeline.publish import Publisher, fault_rows, follow_report, read_live_table
from onebit.pipeline.runner import (
    RunResult,
    check_dataset,
    check_out,
    check_tracker_names,
    checked_sections,
    run_pipeline,
    run_stage,
    skip_reason,
)
from onebit.pipeline.stages import TIME_SOURCES, TRACKERS, TrackerEntry, run_time_origin
from onebit.pipeline.tail import (
    LogSource,
    McapSource,
    Tails,
    channels,
    header_t_column,
    read_live,
    say_clock_steps,
    stamps,
    take_unfinished,
)
from onebit.pipeline.tracking import tracker_config, tracker_inputs
from onebit.readers.mcap_io import load_topic_map, read_mcap
from onebit.readers.motion import MotionConfig, site_rules
from onebit.readers.rows import REORDER_TOLERANCE_S, RawRows
from onebit.readers.timebase import MAX_GAP_S, TimeOrigin
from onebit.trackers.base import ARTIFACTS
from onebit.viz import live as viz_live

__all__ = ["LIVE", "FollowConfig", "FollowResult", "Follow", "follow", "parse_speed", "read_live_table"]

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


@dataclass
class _LiveTracker:
    """One tracker running live: its entry, its config (built once), its stepper's state, and
    what a prefix re-run published so far."""

    entry: TrackerEntry
    config: Any
    state: Any = None
    published: float = -math.inf
    sent: pl.DataFrame | None = None


def _settle(site, sections: dict) -> float:
    """The readers' look-ahead: reordering tolerance + the longest debounce window."""
    cfg = config_from_mapping(MotionConfig, sections.get("motion", {}), section="motion")
    windows = [0.0]
    if site.motion_sensors:
        for r in site_rules(site, cfg).values():
            windows += [r.chatter_window, r.min_on]
    return REORDER_TOLERANCE_S + max(windows)


class Follow:
    """One follow of a dataset (module docstring): checked when made, then :meth:`start`, then
    :meth:`poll`, :meth:`read`, :meth:`settle` and :meth:`publish` until the logs end, then
    :meth:`finish`; :meth:`close` in any case. :func:`follow` runs them in that order."""

    def __init__(
        self,
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
        tracker_entries: tuple[TrackerEntry, ...] = TRACKERS,
    ) -> None:
        self.dataset, self.out = Path(dataset), Path(out)
        self.entries = tracker_entries
        self.trackers, self.config, self.options, self.connect = trackers, config, options, connect
        self.echo = echo or (lambda s: None)
        self.clock, self.sleep = clock, sleep
        check_dataset(self.dataset)
        check_out(self.out, self.dataset)
        self.site = load_site(self.dataset / "site.toml")
        self.rg = build_region_graph(self.site)
        self.stage_list = declaration.stages(tracker_entries)  # the run's own declaration, read at run time
        sections, dataset_sections = checked_sections(self.dataset, config, self.stage_list)
        self.merged = {**dataset_sections, **sections}
        known = [e.name for e in tracker_entries]
        check_tracker_names(tuple(trackers or ()), known, where="--trackers")
        self.chosen = tuple(trackers) if trackers else tuple(known)
        self.logs = [stem for stem in TIME_SOURCES if (self.dataset / f"{stem}.csv").is_file()]
        topics = self.dataset / "mcap_topics.toml"
        self.topic_map = load_topic_map(topics) if topics.is_file() else None
        self.mcaps = [McapSource(p, self.topic_map) for p in sorted(self.dataset.glob("*.mcap"))]
        if not self.logs and not self.mcaps:
            raise InputError(
                "no log to follow (motion.csv, beams.csv, crossings.csv, proximity.csv, truth.csv or an .mcap)",
                file=self.dataset,
            )
        self.settle_s = options.settle if options.settle is not None else _settle(self.site, self.merged)
        self.serve = viz_live.WebServe() if serve_web is True else (serve_web or None)
        if self.serve is not None:
            viz_live.check_ports(self.serve)  # a port in use stops the follow before it replaces OUT/live
        self.live = self.out / LIVE
        self.snapshot: Path | None = None
        self.sources: dict[str, LogSource] = {}
        self.served: viz_live.ServedViewer | None = None
        self.origin: TimeOrigin | None = None
        self.tails = Tails()
        self.horizon = -math.inf
        self.history: list[tuple[float, float]] = []  # live: (horizon, wall) at each poll
        self.polls = 0
        self.warned: set[str] = set()  # logs whose clock was said to have stepped back
        self.logged_edges = 0

    # ----------------------------------------------------------------------- start

    def start(self) -> None:
        """The live folder (a previous follow's replaced), the snapshot, the sources, the stream
        and the trackers that run live."""
        shutil.rmtree(self.live, ignore_errors=True)  # a previous follow's live outputs
        self.live.mkdir(parents=True)
        self.snapshot = Path(tempfile.mkdtemp(prefix="onebit-follow-"))
        self.scratch, self.data = self.snapshot / ".scratch", self.snapshot / "data"
        self.data.mkdir()
        self.scratch.mkdir()
        for p in self.dataset.glob("*.toml"):
            shutil.copy(p, self.data / p.name)
        self.sources = {
            stem: LogSource(stem, self.dataset / f"{stem}.csv", self.data / f"{stem}.csv") for stem in self.logs
        }
        if self.options.replay is not None:
            self._load_replay()
        starts = [s.release[0] for s in self.sources.values() if len(s.release) and math.isfinite(s.release[0])]
        starts += [r[0] for m in self.mcaps for r in m.release.values() if len(r) and math.isfinite(r[0])]
        self.t0 = min(starts) if starts else 0.0
        self.wall0 = self.clock()
        self.rec, self.served = viz_live.open_live(
            self.live / "rrd" / "follow.rrd", recording_id=str(uuid.uuid4()), connect=self.connect, serve_web=self.serve
        )
        for line in self.served.describe() if self.served else ():
            self.echo(f"  {line}")
        viz_live.log_live_site(self.rec, self.site, self.rg)
        self.pub = Publisher(self.live, self.rec, self.wall_at, self.clock, {e.name: e.drawn for e in self.entries})
        self._start_trackers()
        self.last_growth = self.clock()

    def _load_replay(self) -> None:
        """A replay knows the whole log: its time origin and every line's release time."""
        full = RunContext(self.dataset, self.scratch, self.site, self.rg, {}, trackers=self.chosen)
        for m in self.mcaps:
            for topic, frame in read_mcap(m.path, topic_map=self.topic_map).channels.items():
                full.mcap_channels.setdefault(
                    topic, RawRows(f"{m.path.name}:{topic}", frame, pl.DataFrame(schema=REJECTS))
                )
        self.origin = run_time_origin(full)
        for m in self.mcaps:
            m.load_all(self.origin)
        for src in self.sources.values():
            head, _, body = src.path.read_bytes().partition(b"\n")
            src.header = head + b"\n"
            src.t_col = header_t_column(src.header, src.path)
            src.lines = body.splitlines(keepends=True)
            t = stamps(src.lines, src.t_col, self.origin)
            # in file order: a line without a readable stamp goes with the line before it
            filled = pl.Series(t).fill_nan(None).fill_null(strategy="forward").fill_null(-math.inf).to_numpy()
            src.release = np.maximum.accumulate(filled) if len(filled) else filled

    def _start_trackers(self) -> None:
        """The chosen trackers that run live (``TrackerEntry.live``) and can serve the site, each
        with its config built once; the others are batch-only."""
        ctx = self._context()
        self.runs = [
            _LiveTracker(e, tracker_config(e, ctx))
            for e in self.entries
            if e.live.mode != BATCH
            and e.name in self.chosen
            and (e.spec.available is None or e.spec.available(self.site.tracked) is None)
        ]
        self.online = [r.entry.name for r in self.runs]
        viz_live.send_live_blueprint(self.rec, self.online)
        self.batch_only = [n for n in self.chosen if n not in self.online]
        if self.batch_only:
            self.echo(f"  batch-only (run at the end): {', '.join(self.batch_only)}")
        for r in self.runs:
            self.echo(f"  {r.entry.name}: online, {r.entry.live.says(r.config)}")

    def wall_at(self, t: float) -> float:
        """The wall clock at which the log reached time ``t`` (what a delay is measured from)."""
        if self.options.replay is not None:
            return self.wall0 + (t - self.t0) / self.options.replay
        i = next((w for h, w in self.history if h >= t), None)
        return i if i is not None else self.clock()

    def _context(self) -> RunContext:
        """A run context on the snapshot, with the MCAP rows released so far."""
        sections = {k: dict(v) for k, v in self.merged.items() if isinstance(v, dict)}
        ctx = RunContext(self.data, self.scratch, self.site, self.rg, sections, trackers=self.chosen)
        ctx.mcap_channels = dict(channels(self.mcaps))
        return ctx

    # ----------------------------------------------------------------------- poll

    def poll(self) -> tuple[bool, bool]:
        """Read what the logs gained since the last poll (or what the replay released) into the
        snapshot: (anything new, the logs ended)."""
        now = self.clock()
        new, final = self._replay(now) if self.options.replay is not None else self._tail(now)
        self.polls += 1
        return new, final

    def _replay(self, now: float) -> tuple[bool, bool]:
        horizon = self.t0 + (now - self.wall0) * self.options.replay
        new = False
        for src in self.sources.values():
            n = int(np.searchsorted(src.release, horizon, side="right"))
            if n > src.released:
                src.write(src.lines[src.released : n])
                src.released, new = n, True
        for m in self.mcaps:
            new = m.replay(horizon) or new
        final = all(s.released == len(s.lines) for s in self.sources.values()) and all(m.done() for m in self.mcaps)
        if final:
            horizon = max([horizon, *(s.release[-1] for s in self.sources.values() if len(s.release))])
            horizon = max([horizon, *(r[-1] for m in self.mcaps for r in m.release.values() if len(r))])
        self.horizon = horizon
        return new, final

    def _tail(self, now: float) -> tuple[bool, bool]:
        new = False
        for src in self.sources.values():
            lines, notes = read_live(src)  # a line being written waits for its newline
            for note in notes:
                self.echo(f"  {note}")
            if lines:
                src.write(lines)
                src.lines.extend(lines)
                new = True
        for m in self.mcaps:
            new = m.poll() or new
        if new:
            self.last_growth = now
            if self.origin is None:  # the first lines fix t = 0; the window of accepted stamps stays open ahead
                first_ctx = RunContext(self.data, self.scratch, self.site, self.rg, {}, trackers=self.chosen)
                first_ctx.mcap_channels = channels(self.mcaps)
                first = run_time_origin(first_ctx)
                lo = first.lo - MAX_GAP_S if math.isfinite(first.lo) else first.lo
                self.origin = dataclasses.replace(first, lo=lo, hi=math.inf)
            self._live_horizon(now)
        final = now - self.last_growth >= self.options.idle
        if final:
            take_unfinished(self.sources)
        return new, final

    def _live_horizon(self, now: float) -> None:
        """Every sensor log must have passed a time before it is known: the horizon is the
        earliest of their latest stamps (ground truth logs do not hold it back)."""
        for src in self.sources.values():
            fresh = src.lines[src.released :]
            if fresh:
                t = stamps(fresh, src.t_col, self.origin)
                t = t[np.isfinite(t)]
                if len(t):
                    src.last_t = max(src.last_t, float(t.max()))
                src.released = len(src.lines)
        for m in self.mcaps:
            m.stamps(self.origin)
        known = [s.last_t for k, s in self.sources.items() if k not in _TRUTH_LOGS and math.isfinite(s.last_t)]
        known += [m.last_t for m in self.mcaps if math.isfinite(m.last_t)]
        if not known:
            known = [s.last_t for s in self.sources.values()]
        self.horizon = min(known) if known else -math.inf
        self.history.append((self.horizon, now))

    # ----------------------------------------------------------------------- read, settle

    def read(self, final: bool) -> RunContext:
        """The polled stages on what was released: a context whose ``tables`` hold what they
        made. The incremental readers are fed the lines released since the last poll and stand
        in for their stages (:class:`~onebit.pipeline.tail.Tails`); every other polled stage
        is run on the snapshot by :func:`~onebit.pipeline.runner.run_stage`."""
        if self.origin is not None and self.options.incremental:  # only the lines released since the last poll
            here = self._context()
            for src in self.sources.values():
                self.tails.start(src, here, self.stage_list, self.origin)
            self.tails.poll(self.sources, final)
            say_clock_steps(self.tails, self.warned, self.echo)
        ctx = self._context()
        if self.origin is not None:
            ctx.time_origin = self.origin
        ctx.tables.update(self.tails.preset())
        skip = self.tails.stages
        for st in self.stage_list:
            if not st.polled or st.name in skip or skip_reason(st, ctx) is not None:
                continue
            done = run_stage(st, ctx)
            if done.error is not None:
                ctx.status[st.name] = f"failed: {done.error}"
                continue
            ctx.tables.update({k: v for k, v in done.made.items() if k != ARTIFACTS})
        return ctx

    def settle(self, final: bool) -> float:
        """An event at most this late is final: the horizon less the readers' look-ahead, and
        what the incremental readers emitted (``inf`` once the logs ended)."""
        if final:
            return math.inf
        return min(self.horizon - self.settle_s, math.nextafter(self.tails.until, -math.inf))

    # ----------------------------------------------------------------------- publish

    def publish(self, ctx: RunContext, until: float, final: bool) -> None:
        """The sensors' states settled since the last poll, then every live tracker's new rows."""
        tables = ctx.tables
        if "motion" in tables:
            settled = tables["motion"].filter(pl.col("t") <= until) if not final else tables["motion"]
            if settled.height > self.logged_edges:
                viz_live.log_states(self.rec, settled.slice(self.logged_edges))
                self.logged_edges = settled.height
        poll = Poll(tables, until, self.horizon, self.settle_s, final, self.options.incremental)
        for run in self.runs:
            stepper = run.entry.live.stepper
            if stepper is not None and stepper.steps(run.config, poll):
                if all(k in tables for k in stepper.needs):
                    if run.state is None:
                        run.state = stepper.start(run.entry.name, self.site, run.config, self.rg)
                    self.pub.rows(run.entry.name, stepper.advance(run.state, poll))
            elif run.entry.live.events:
                self._rerun_prefix(run, poll, ctx)

    def _rerun_prefix(self, run: _LiveTracker, poll: Poll, ctx: RunContext) -> None:
        """Re-run the tracker on the settled prefix of its inputs when a new settled event
        arrived; publish its rows up to that event not published before (a re-run could change
        an earlier row, which is never un-published: the report compares with the batch run)."""
        entry, tables = run.entry, poll.tables
        events = next((tables[k] for k in entry.live.events if k in tables), None)
        if events is None or events.height == 0:
            return
        until = None if poll.final else poll.until
        ev = events if until is None else events.filter(pl.col("t") <= until)
        if ev.height == 0:
            return
        last = math.inf if poll.final else float(ev["t"].max())
        if last <= run.published:
            return
        inputs = tracker_inputs(entry, ctx, until=until)
        if inputs is None:
            return
        res = entry.spec.run(inputs, self.site.tracked, run.config)
        upto = res["tracks"].filter(pl.col("t") <= last)
        # rows not published yet (a re-run may add rows dated earlier: beams gives an agent
        # created at a later crossing its initial region at the first crossing's time); an
        # estimate is published once: a later re-run's value for the same (track, t, region,
        # node) is not re-published (the final report compares)
        key = [c for c in upto.columns if c not in ("x", "y")]
        seen = run.sent
        rows = upto if seen is None else upto.join(seen.select(key), on=key, how="anti", nulls_equal=True)
        run.sent = upto if seen is None else pl.concat([seen, rows])
        run.published = last
        self.pub.estimates(entry.name, rows)

    # ----------------------------------------------------------------------- finish

    def finish(self) -> FollowResult:
        """Close the stream, run the batch run on the data followed, write the follow report."""
        viz_live.close_live(self.rec, self.served)
        self.echo(f"  followed {self.polls} polls; final batch run")
        final_data = self.dataset if self.options.replay is not None else self.data
        for m in self.mcaps if self.options.replay is None else ():  # the recordings as they are now
            shutil.copy(m.path, self.data / m.path.name)
        run = run_pipeline(
            final_data,
            self.out,
            trackers=self.trackers,
            config=self.config,
            tracker_entries=self.entries,
            progress=False,
            echo=self.echo,
        )
        report = pl.concat(
            [
                follow_report(self.out, self.live, self.online, self.pub, self.polls, self.batch_only),
                fault_rows(self.out, self.sources),
            ]
        )
        outputs.write_parquet(report, self.live / "report.parquet")
        outputs.write_csv(report, self.live / "report.csv")
        return FollowResult(run=run, report=report, live=self.live, batch_only=self.batch_only)

    def close(self) -> None:
        """Close the logs, stop a served page, remove the snapshot (after an error too)."""
        for src in self.sources.values():
            src.close()
        if self.served is not None:  # an error or an interrupt: the page's server ends with the follow
            self.served.stop()
        if self.snapshot is not None:
            shutil.rmtree(self.snapshot, ignore_errors=True)

    def run(self) -> FollowResult:
        """Start, then poll -> read -> settle -> publish until the logs end, then finish."""
        try:
            self.start()
            while True:
                new, final = self.poll()
                if new or final:
                    ctx = self.read(final)
                    self.publish(ctx, self.settle(final), final)
                if final:
                    break
                self.sleep(self.options.poll)
            return self.finish()
        finally:
            self.close()


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
    tracker_entries: tuple[TrackerEntry, ...] = TRACKERS,
) -> FollowResult:
    """Follow ``dataset`` (module docstring) and end with the batch run into ``out``.

    ``serve_web``: ``True`` serves the web viewer on :class:`~onebit.viz.live.WebServe`'s
    defaults (127.0.0.1 only, ports 9090 and 9876), a ``WebServe`` where it says.
    ``tracker_entries``: the trackers of the stage list, as for
    :func:`~onebit.pipeline.runner.run_pipeline` (each runs live as its ``live`` says).

    Raises :class:`OnebitError` for bad input found before anything is followed (dataset,
    ``OUT``, site, config, tracker names, no CSV log to follow, a port in use).
    """
    return Follow(
        dataset,
        out,
        trackers=trackers,
        config=config,
        options=options,
        connect=connect,
        serve_web=serve_web,
        echo=echo,
        clock=clock,
        sleep=sleep,
        tracker_entries=tracker_entries,
    ).run()
