"""The runner: runs the declared stage list (:mod:`onebit.pipeline.stages`) on a dataset.

``run_pipeline(dataset, out)`` checks its inputs, loads the site, then runs every stage whose
inputs exist, in order. Stages that depend on a missing or failed input are skipped with the
reason; a stage that fails is recorded in ``run.toml`` with its error and the others' outputs
stay. The runner times every stage (``timings`` table); stages never read the clock.

A run is one transaction (:func:`onebit.core.writers.folder_transaction`): every file of the
run (``tables/``, ``rrd/``, ``logs/``, ``report.*``, ``run.toml``) is written into a fresh
work folder ``OUT/.onebit-work-<pid>`` and swapped in when the run ends, so ``OUT`` holds
either the previous complete run or this one -- never a mixture (a kill during the swap
itself leaves ``OUT/INCOMPLETE``, which ``onebit report`` refuses). A failed stage of this run
therefore never sits beside an older run's outputs, and the work folders and ``.partial``
files of runs that died are removed by the next run into ``OUT``.

Checked before anything is written: the dataset folder (exists, was not cut while being
simulated, no symlink leading out of it), ``OUT`` (not a file, not the dataset or inside it,
empty or a run folder), ``site.toml``, every ``run.toml`` section (a known stage, valid values)
of ``--config`` and of the dataset's own ``run.toml``, and the ``--trackers`` names.

Nothing useful done does not look like success: a run where every stage was skipped is an
error (and ``OUT`` is left as it was), and a tracker asked for by name that could not run
makes the run not ``ok``.
"""

from __future__ import annotations

import copy
import multiprocessing
import os
import pickle
import tempfile
import time
import traceback
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import polars as pl

from onebit.core import writers as outputs
from onebit.core.config import config_from_mapping, load_toml
from onebit.core.errors import ConfigError, DiskFullError, InputError, OnebitError, bounded, is_disk_full
from onebit.core.memory import release_freed_memory
from onebit.core.parallel import CORES_ENV, available_cores, cpu_seconds, one_core_each, run_beside, worker_cpu_seconds
from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.core.tables import REJECTS, REPORT
from onebit.pipeline.context import RunContext, Stage, check_made, dataset_run_config
from onebit.pipeline.progress import ProgressSink, progress_sink
from onebit.pipeline.stages import TRACKERS, TrackerEntry, stages
from onebit.readers.mcap_io import load_topic_map, read_mcap
from onebit.readers.rows import RawRows
from onebit.trackers.base import ARTIFACTS, PROGRESS
from onebit.viz.blueprint import save_run_blueprint
from onebit.viz.recording import rerun_enabled, stage_recording
from onebit.viz.site import log_site

#: The entries of a run folder; a new run replaces exactly these (other entries are kept).
RUN_ENTRIES = ("tables", "rrd", "logs", "report.parquet", "report.csv", "run.toml")
#: onebit's entries of a run folder that a run keeps as they are: ``live`` (``onebit follow``'s
#: published rows, stream and report, :mod:`onebit.pipeline.follow`).
KEPT_ENTRIES = ("live",)
#: Sections a run record (``OUT/run.toml``) holds besides the stage configs; a run record
#: given as ``--config`` (to repeat a run) contributes only its stage sections.
RUN_RECORD_SECTIONS = ("stages", "summary", "time", "problems", "timing")
#: Files of a dataset folder the runner reads (a symlink among them must stay inside the folder).
_DATASET_SUFFIXES = (".csv", ".mcap", ".toml", ".mp4")


# --------------------------------------------------------------------------- running


@dataclass
class RunResult:
    out: Path
    status: dict[str, str]
    report: pl.DataFrame
    ok: bool
    #: why the run is not ``ok`` beyond a stage's status (a tracker asked for by name did not run)
    problems: list[str] = field(default_factory=list)


def _check_run_section(values: dict[str, Any], *, source: str | Path) -> None:
    """``[run]``: what the run does by default; today ``trackers``, the trackers a plain
    ``onebit run`` (no ``--trackers``) runs -- an importer writes it where some trackers cannot
    serve its data (a month of a home: the slot HMMs' cost grows with the slots)."""
    for key, value in values.items():
        if key != "trackers":
            raise ConfigError(f"{source}: [run] {key}: unknown key; known: ['trackers']")
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise ConfigError(f'{source}: [run] trackers: a list of tracker names, e.g. ["residents"]')


def default_trackers(config: dict[str, Any], dataset_sections: dict[str, Any]) -> tuple[str, ...]:
    """``[run] trackers`` of ``--config``, else of the dataset's own ``run.toml`` (``()``: all)."""
    for sections in (config, dataset_sections):
        run = sections.get("run")
        if isinstance(run, dict) and run.get("trackers"):
            return tuple(run["trackers"])
    return ()


def _is_run_record(data: dict[str, Any]) -> bool:
    return "recording_id" in data and isinstance(data.get("stages"), dict)


def load_run_config(path: str | Path | None) -> dict[str, Any]:
    """The sections of a ``run.toml`` given as ``--config`` (checked by :func:`check_sections`
    when the run starts). A run record (``OUT/run.toml`` of an earlier run) gives its stage
    sections only, so a run can be repeated with ``--config OUT/run.toml``."""
    if path is None:
        return {}
    data = load_toml(path, error=InputError)
    if _is_run_record(data):
        return {k: v for k, v in data.items() if isinstance(v, dict) and k not in RUN_RECORD_SECTIONS}
    return data


def check_sections(sections: dict[str, Any], stage_list: list[Stage], *, source: str | Path) -> None:
    """Every section names a stage of ``stage_list`` and holds valid values for its config.

    Raises :class:`ConfigError` naming ``source``, the section and, for an unknown one, the
    known sections (the stage names, from the stage list).
    """
    known = {st.name: st for st in stage_list}
    record = _is_run_record(sections)
    for name, values in sections.items():
        if record and (name in RUN_RECORD_SECTIONS or not isinstance(values, dict)):
            continue
        if name == "run" and isinstance(values, dict):
            _check_run_section(values, source=source)
            continue
        if not isinstance(values, dict):
            raise ConfigError(
                f"{source}: '{name}' is outside any section; put it under the [stage] it configures "
                f"(sections: {sorted(known)})"
            )
        if name not in known:
            raise ConfigError(f"{source}: unknown section [{name}]; known sections: {sorted(known)}")
        cls = known[name].config
        if cls is not None:
            try:
                config_from_mapping(cls, values, section=name)
            except (ConfigError, TypeError, ValueError) as exc:
                what = str(exc) if str(exc).startswith(f"[{name}]") else f"[{name}] {exc}"
                raise ConfigError(f"{source}: {what}") from None


def check_dataset(dataset: Path) -> Path:
    """The dataset folder can be read: it exists, no interrupted ``onebit simulate`` left it
    ``INCOMPLETE``, and no file the runner reads is a symlink leading outside it."""
    if not dataset.is_dir():
        raise InputError("dataset folder does not exist" if not dataset.exists() else "is not a folder", file=dataset)
    if outputs.is_incomplete(dataset):
        raise InputError(
            "the dataset is incomplete (a simulation into it was interrupted); simulate it again", file=dataset
        )
    root = dataset.resolve()
    for entry in sorted(dataset.iterdir()):
        if entry.is_symlink() and entry.suffix.lower() in _DATASET_SUFFIXES:
            target = entry.resolve()
            if root not in target.parents:
                raise InputError(
                    f"is a symlink to {target}, outside the dataset folder; copy the file in instead", file=entry
                )
    return root


def check_out(out: Path, dataset: Path) -> str | None:
    """``OUT`` can take this run: it is not a file, does not overlap the dataset, and is empty
    or a run folder (then its run's entries are replaced). Returns what will be replaced
    (a sentence for the console) or ``None``."""
    if out.exists() and not out.is_dir():
        raise InputError("OUT is a file, not a folder; give a folder for the run (it is created if needed)", file=out)
    out_r, data_r = out.resolve(), dataset.resolve()
    if out_r == data_r or data_r in out_r.parents:
        raise InputError(
            f"OUT is {'the dataset folder' if out_r == data_r else 'inside the dataset folder'} {dataset}; the run would "
            "write among the dataset's own files (its run.toml holds the simulation's initial condition); give another folder",
            file=out,
        )
    if out_r in data_r.parents:
        raise InputError(f"the dataset {dataset} is inside OUT; give an OUT folder outside the dataset", file=out)
    if not out.is_dir():
        return None
    visible = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    if not visible:
        return None
    if outputs.is_incomplete(out):
        return "OUT holds an interrupted run (INCOMPLETE): replacing it"
    record: dict[str, Any] = {}
    if (out / "run.toml").is_file():
        try:
            record = load_toml(out / "run.toml", error=InputError)
        except InputError:
            record = {}
    ours = [n for n in visible if n in RUN_ENTRIES]
    if not _is_run_record(record) and len(ours) + sum(n in KEPT_ENTRIES for n in visible) < len(visible):
        foreign = [n for n in visible if n not in RUN_ENTRIES and n not in KEPT_ENTRIES]
        shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
        raise InputError(
            f"OUT is not empty and is not a onebit run folder (it holds {shown}); "
            "give an empty or new folder, or an earlier run's folder",
            file=out,
        )
    what = (
        f"the previous run (recording {record['recording_id']})" if _is_run_record(record) else f"the run files {ours}"
    )
    kept = [n for n in visible if n not in RUN_ENTRIES and n not in KEPT_ENTRIES]
    if not ours and not _is_run_record(record):
        return None
    return f"OUT holds {what}: replacing it" + (f"; keeping {kept} (not onebit's)" if kept else "")


def run_pipeline(
    dataset: str | Path,
    out: str | Path,
    *,
    trackers: tuple[str, ...] | None = None,
    config: dict[str, Any] | None = None,
    tracker_entries: tuple[TrackerEntry, ...] = TRACKERS,
    progress: bool | ProgressSink | None = None,
    echo: Callable[[str], None] | None = None,
    rrd: bool = True,
    cores: int = 0,
) -> RunResult:
    """Run every available stage on ``dataset``, writing the run folder ``out`` as one transaction.

    ``trackers`` selects trackers by name (default: all; a tracker named here that cannot
    run makes the run not ``ok``); ``config`` holds ``run.toml`` sections; ``tracker_entries``
    is the tracker list of the stage list (a test or an extension may pass its own, see
    ``docs/extending.md``); ``progress``: a bar on a terminal (``None``), ``True``/``False``,
    or a :class:`~onebit.pipeline.progress.ProgressSink`; ``rrd=False`` (``--no-rrd``) writes
    no Rerun recordings (no ``rrd/`` folder, no viz calls): the tables, report and run record
    are the same, for batch sweeps where nobody will open the recordings. ``cores``: the most
    trackers worked at once, side by side (the runs's process and worker processes, each
    tracker on one core; the tables and report are the same for any value); 0 = the cores
    this process may use (:func:`onebit.core.parallel.available_cores`: ``ONEBIT_CORES``, else
    its CPU affinity; 1 in a ``run-many`` pool's worker) once the run's tables hold
    :data:`DETACH_MIN_ROWS` rows, else 1; 1 = one tracker after another, here.

    The run record ``run.toml`` holds, besides each stage's status, a ``[timing]`` table: per
    stage the seconds of its work (``work_s``, as in its status), of its recording (``viz_s``:
    opening the ``.rrd``, the site and the stage's viz call, closing it) and of writing its
    tables (``write_s``), and the CPU seconds of the work and of the recording (``work_cpu_s``,
    ``viz_cpu_s``: the process's, every thread's, and of the worker processes a stage ran
    pieces in, :func:`onebit.core.parallel.cpu_seconds`; on a shared machine the wall times
    grow with the load, these hardly); ``blueprint_s`` (``blueprint_cpu_s``), ``run_s`` (stages
    to record; ``run_cpu_s``), ``worker_cpu_s`` (the part of ``run_cpu_s`` spent in worker
    processes) and ``entered_unix`` (the wall clock when this function was called: a caller that
    knows when its process started gets the start-up from it).

    Raises :class:`OnebitError` (``out`` untouched) for bad input found before or instead of
    any work: dataset, ``OUT``, site, config, tracker names, or every stage skipped.
    """
    entered = time.time()
    if isinstance(cores, bool) or not isinstance(cores, int) or cores < 0:
        raise ConfigError(f"cores = {cores!r}: expected a whole number >= 0 (0 = the cores available)")
    dataset, out = Path(dataset), Path(out)
    echo = echo or (lambda s: None)
    check_dataset(dataset)
    replacing = check_out(out, dataset)
    site = load_site(dataset / "site.toml")
    stage_list = stages(tracker_entries)
    config = copy.deepcopy(dict(config or {}))  # the run reads it (RunContext.config); never the caller's dicts
    check_sections(config, stage_list, source="--config")
    dataset_sections = dataset_run_config(dataset)
    check_sections(dataset_sections, stage_list, source=dataset / "run.toml")
    known = [e.name for e in tracker_entries]
    requested = tuple(trackers) if trackers else default_trackers(config, dataset_sections)
    for tr in requested:
        if tr not in known:
            where = "--trackers" if trackers else "[run] trackers"
            raise ConfigError(f"{where}: unknown tracker {tr!r}; known: {sorted(known)}")
    trackers = requested or tuple(known)
    rg = build_region_graph(site)
    if replacing:
        echo(f"  {replacing}")
    sink = progress_sink(progress)
    crash: BaseException | None = None
    try:
        with outputs.folder_transaction(out, replaces=RUN_ENTRIES.__contains__) as work:
            ctx = RunContext(
                dataset,
                work,
                site,
                rg,
                config,
                trackers=trackers,
                progress=sink.step,
                dataset_sections=dataset_sections,
            )
            try:
                with rerun_enabled():  # recordings are written whatever RERUN says (viz.recording)
                    result = _run_stages(
                        ctx,
                        stage_list,
                        requested,
                        known,
                        sink=sink,
                        echo=echo,
                        rrd=rrd,
                        entered=entered,
                        looks={e.name: e.drawn for e in tracker_entries},
                        cores=cores,
                    )
            except OnebitError:
                raise
            except Exception as exc:  # a bug, not bad input: keep what was done and the traceback
                if is_disk_full(exc):  # the system, not a bug: OUT left as it was
                    raise DiskFullError(work) from exc
                crash = exc
                result = _record_crash(ctx, exc)
    finally:
        sink.close()
    if crash is not None:
        crash.add_note(f"onebit: the run was recorded as failed; traceback in {out / 'logs' / 'run.traceback.txt'}")
        raise crash
    status, report, ok, problems = result
    return RunResult(out, status, report, ok, problems)


#: A run detaches its trackers side by side (``cores = 0``) from this many rows in its
#: tables when they start: below it the trackers take seconds, less than starting workers.
DETACH_MIN_ROWS = 200_000


@dataclass
class _Detached:
    """What a detached stage's work gave: its tables, or its error (``onebit``: an
    :class:`OnebitError`, said as it is; else a bug, with the traceback), and its seconds."""

    made: dict[str, Any] | None
    seconds: float
    cpu: float
    error: str | None = None
    onebit: bool = False
    traceback: str | None = None


class _DetachedError(Exception):
    def __init__(self, outcome: _Detached) -> None:
        super().__init__(outcome.error)
        self.outcome = outcome


def _run_job(fn: Callable[..., dict[str, Any]], args: tuple) -> _Detached:
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        made = fn(*args)
    except OnebitError as exc:
        return _Detached(None, time.perf_counter() - t0, time.process_time() - c0, str(exc), onebit=True)
    except Exception as exc:  # a bug: its traceback goes to logs/, as in the run's own process
        return _Detached(
            None,
            time.perf_counter() - t0,
            time.process_time() - c0,
            f"{type(exc).__name__}: {exc}",
            traceback=traceback.format_exc(limit=8),
        )
    return _Detached(made, time.perf_counter() - t0, time.process_time() - c0)


#: A worker hands a table of this many bytes or more back through a file (Arrow IPC,
#: uncompressed, read here once), not the pipe: a pickled table is held twice on each side
#: while it passes -- the table and its bytes -- (the 24-hour home's ``istate_regions``, 0.7 GB,
#: took the day's process tree over 2 GB); through a file, once on each side.
SPILL_BYTES = 64 * 2**20


@dataclass(frozen=True)
class _Spilled:
    """A table a worker wrote to ``path`` (Arrow IPC) for this process to read."""

    path: str


def _spill(made: dict[str, Any], limit: int) -> None:
    """Replace the tables of ``made`` of ``limit`` bytes or more by files (in a worker)."""
    for key, value in made.items():
        if key != ARTIFACTS and isinstance(value, pl.DataFrame) and value.estimated_size() >= limit:
            fd, path = tempfile.mkstemp(prefix="onebit-table-", suffix=".arrow")
            os.close(fd)
            value.write_ipc(path, compression="uncompressed")
            made[key] = _Spilled(path)


def _unspill(made: dict[str, Any]) -> None:
    """Read the tables a worker left in files (:func:`_spill`) and remove the files."""
    for key, value in made.items():
        if isinstance(value, _Spilled):
            try:
                made[key] = pl.read_ipc(value.path)
            finally:
                Path(value.path).unlink(missing_ok=True)


def _run_lane(jobs: list[tuple[str, Callable, tuple]], spill: int = SPILL_BYTES) -> list[_Detached]:
    """Detached stages one after another, each on one core: in a worker process (its large
    tables handed back through files, :func:`_spill`), or here when this process takes them
    (:func:`onebit.core.parallel.run_beside`)."""
    worker = multiprocessing.parent_process() is not None
    if worker:
        one_core_each()
    out = [_run_job(fn, args) for _, fn, args in jobs]
    if worker:
        for o in out:
            if o.made is not None:
                _spill(o.made, spill)
    return out


def _portable(fn: Callable, args: tuple) -> bool:
    """Whether ``fn`` and the functions among ``args`` pickle by reference (module-level)."""
    try:
        pickle.dumps([fn, *(a for a in args if callable(a))])
    except Exception:
        return False
    return True


def _without_progress(args: tuple) -> tuple:
    """``args`` with the progress callback taken out of its input tables (a bar of this
    process; a worker's stage reports nothing)."""
    return tuple(
        {k: v for k, v in a.items() if k != PROGRESS} if isinstance(a, dict) and PROGRESS in a else a for a in args
    )


def run_cores(ctx: RunContext, cores: int) -> int:
    """Cores for the detached stages: ``cores`` when > 0, else :func:`available_cores` when
    the run's tables hold at least :data:`DETACH_MIN_ROWS` rows, else 1."""
    if cores > 0:
        return cores
    rows = sum(t.height for t in ctx.tables.values() if isinstance(t, pl.DataFrame))
    return available_cores() if rows >= DETACH_MIN_ROWS else 1


def _detachable(rest: list[Stage], ctx: RunContext) -> list[Stage]:
    """The detachable stages from the start of ``rest`` on (up to the first that is not) that
    would run now: available, their input tables made."""
    out = []
    for st in rest:
        if st.detach is None:
            break
        if all(n in ctx.tables for n in st.needs) and st.available(ctx) is None:
            out.append(st)
    return out


def _detach_batch(
    stages: list[Stage], ctx: RunContext, cores: int, *, spill: int | None = None
) -> dict[str, _Detached]:
    """Run the work of ``stages`` (detachable, available) side by side on ``cores``: this
    process the first, ``cores - 1`` worker processes the others in order, each taking the
    next when it is free, and this process too once its own is done
    (:func:`onebit.core.parallel.run_beside`); each stage's work on one core. A stage whose
    work cannot be sent (a local function) is worked here; a call a worker cannot make or
    hand back (artifacts that do not pickle, a worker killed) is made here again by
    ``run_beside``."""
    units: list[list[tuple[str, Callable, tuple]]] = []  # calls: stages sharing work stay in one
    by_key: dict[Any, list] = {}
    for st in stages:
        fn, args, shares = st.detach(ctx)
        job = (st.name, fn, args)
        if shares is not None and shares in by_key:
            by_key[shares].append(job)
            continue
        units.append([job])
        if shares is not None:
            by_key[shares] = units[-1]
    k = min(cores, len(units))
    here_jobs = list(units[0])
    away = []
    for unit in units[1:]:
        if all(_portable(f, a) for _, f, a in unit):
            away.append([(n, f, _without_progress(a)) for n, f, a in unit])
        else:
            here_jobs += unit
    old = os.environ.get(CORES_ENV)
    os.environ[CORES_ENV] = "1"  # every stage of the batch on one core: the batch fills them
    try:
        mine, theirs = run_beside(
            lambda: [_run_job(f, a) for _, f, a in here_jobs],
            _run_lane,
            [(lane, SPILL_BYTES if spill is None else spill) for lane in away],
            workers=k - 1,
        )
    finally:
        if old is None:
            os.environ.pop(CORES_ENV, None)
        else:
            os.environ[CORES_ENV] = old
    out = {n: o for (n, _, _), o in zip(here_jobs, mine)}
    for lane, outcomes in zip(away, theirs):
        for (n, _, _), o in zip(lane, outcomes):
            if o.made is not None:
                _unspill(o.made)
            out[n] = o
    return out


def _run_stages(
    ctx: RunContext,
    stage_list: list[Stage],
    requested: tuple[str, ...],
    tracker_names: list[str],
    *,
    sink: ProgressSink,
    echo: Callable[[str], None],
    rrd: bool = True,
    entered: float | None = None,
    looks: dict | None = None,
    cores: int = 0,
) -> tuple[dict[str, str], pl.DataFrame, bool, list[str]]:
    """Run the stages into ``ctx.out`` (the work folder) and write the run's record there.

    A stage's work runs first, then (``rrd``) its recording is written: opened, the site
    logged, the stage's viz called, closed; a failure in either leaves no ``.rrd`` of the
    stage. Work, recording and table writing are timed apart (``timing`` of ``run.toml``);
    ``looks`` (tracker -> :class:`~onebit.viz.families.Look`) lay out the run's blueprint."""
    work, dataset, site = ctx.out, ctx.dataset, ctx.site
    (work / "tables").mkdir(parents=True, exist_ok=True)
    if rrd:
        (work / "rrd").mkdir(parents=True, exist_ok=True)
    recording_id = str(uuid.uuid4())
    status = ctx.status
    timing: dict[str, Any] = {"entered_unix": round(entered if entered is not None else time.time(), 6), "rrd": rrd}
    _read_mcaps(ctx, echo)
    started, started_cpu, started_workers = time.time(), cpu_seconds(), worker_cpu_seconds()
    detached: dict[str, _Detached] = {}
    for i, st in enumerate(stage_list):
        sink.stage(st.name, i, len(stage_list))
        missing = [n for n in st.needs if n not in ctx.tables]
        reason = st.available(ctx)
        if reason is None and missing:
            reason = f"input table(s) {missing} not produced by an earlier stage"
        if reason is not None:
            status[st.name] = f"skipped: {reason}"
            echo(f"  {st.name}: skipped ({reason})")
            continue
        if st.detach is not None and st.name not in detached and run_cores(ctx, cores) > 1:
            batch = _detachable(stage_list[i:], ctx)
            if len(batch) >= 2:  # this stage and the detachable ones after it, side by side
                detached.update(_detach_batch(batch, ctx, run_cores(ctx, cores)))
        t0, c0 = time.perf_counter(), cpu_seconds()
        try:
            if st.name in detached:  # worked already, here or in a worker
                done = detached.pop(st.name)
                if done.error is not None:
                    raise _DetachedError(done)
                made, work_s, work_cpu = done.made, done.seconds, done.cpu
            else:
                made = st.work(ctx)
                work_s, work_cpu = None, None
            release_freed_memory()  # what the work dropped, before its recording and the next stage
            ctx.seconds[st.name] = time.perf_counter() - t0 if work_s is None else work_s
            check_made(st, made, ctx.tables, extra=(ARTIFACTS,))
            t1, c1 = time.perf_counter(), cpu_seconds()
            if rrd:
                with stage_recording(work, st.name, recording_id) as rec:
                    log_site(rec, site, ctx.region_graph)
                    if st.viz is not None:
                        st.viz(rec, ctx, made)
                release_freed_memory()
            timing[st.name] = {
                "work_s": round(ctx.seconds[st.name], 6),
                "viz_s": round(time.perf_counter() - t1, 6),
                "work_cpu_s": round(c1 - c0 if work_cpu is None else work_cpu, 6),
                "viz_cpu_s": round(cpu_seconds() - c1, 6),
            }
        except DiskFullError:  # not this stage's failure: the whole run stops, OUT left as it was
            raise
        except OnebitError as exc:
            status[st.name] = f"failed: {exc}"
            echo(f"  {st.name}: FAILED: {exc}")
            continue
        except _DetachedError as exc:  # the detached work's error, said as the work here would
            done = exc.outcome
            if done.onebit:
                status[st.name] = f"failed: {done.error}"
                echo(f"  {st.name}: FAILED: {done.error}")
            else:
                status[st.name] = bounded(f"failed: {done.error}", 2000)
                outputs.write_text(done.traceback or "", work / "logs" / f"{st.name}.traceback.txt")
                echo(f"  {st.name}: FAILED with {bounded(done.error)} (traceback in logs/{st.name}.traceback.txt)")
            continue
        except Exception as exc:  # a bug, not bad input: keep the other stages, keep the traceback
            if is_disk_full(exc):  # the system, not a bug: the whole run stops, OUT left as it was
                raise DiskFullError(work) from exc
            tb = traceback.format_exc(limit=8)
            status[st.name] = bounded(f"failed: {type(exc).__name__}: {exc}", 2000)
            outputs.write_text(tb, work / "logs" / f"{st.name}.traceback.txt")
            echo(
                f"  {st.name}: FAILED with {bounded(f'{type(exc).__name__}: {exc}')} (traceback in logs/{st.name}.traceback.txt)"
            )
            continue
        t2 = time.perf_counter()
        for name, df in made.items():
            if name == ARTIFACTS:  # in-memory results for the stage's viz only
                continue
            ctx.tables[name] = df
            outputs.write_parquet(df, work / "tables" / f"{name}.parquet")
        timing[st.name]["write_s"] = round(time.perf_counter() - t2, 6)
        status[st.name] = f"ok ({ctx.seconds[st.name]:.2f} s)"
        echo(f"  {st.name}: ok")
        for part, state in status.items():  # parts of a stage that failed on their own (scores/<tracker>)
            if part.startswith(f"{st.name}/"):
                echo(f"  {part}: {state}")

    # nothing useful done: no stage read or corrected any input (trackers and scores on nothing do not count)
    data_stages = [st.name for st in stage_list if st.name not in {*tracker_names, "scores"}]
    if all(status.get(n, "").startswith("skipped") for n in data_stages):
        why = "; ".join(f"{n}: {s}" for n, s in status.items() if n in data_stages or n.startswith("mcap:"))
        bad = [f"{n[5:]}: {s[8:]}" for n, s in status.items() if n.startswith("mcap:") and s.startswith("failed: ")]
        if bad:  # an unreadable file is the news, not the stages it left with nothing
            why = "; ".join(f"{n}: {s}" for n, s in status.items() if n in data_stages)
            raise InputError(
                f"unreadable input: {'; '.join(bad)}; nothing else to read ({why}); OUT was left as it was",
                file=dataset,
            )
        raise InputError(f"nothing to do: no input could be read ({why}); OUT was left as it was", file=dataset)
    problems = [
        f"tracker '{tr}' was asked for (--trackers) but did not run: {status.get(tr, 'not run')[len('skipped: ') :]}"
        for tr in requested
        if status.get(tr, "").startswith("skipped")
    ]
    for p in problems:
        echo(f"  {p}")
    t3, c3 = time.perf_counter(), time.process_time()
    if rrd:
        save_run_blueprint(work / "rrd", units=site.units, looks=looks)  # the viewer layout of what the stages logged
    timing["blueprint_s"] = round(time.perf_counter() - t3, 6)
    timing["blueprint_cpu_s"] = round(time.process_time() - c3, 6)
    rejects = ctx.tables.get("rejects", pl.DataFrame(schema=REJECTS))
    outputs.write_parquet(rejects, work / "tables" / "rejects.parquet")
    report = pl.DataFrame(ctx.report, schema=REPORT, orient="row")
    outputs.write_parquet(report, work / "report.parquet")
    outputs.write_csv(report, work / "report.csv")
    ok = all(not s.startswith("failed") for s in status.values()) and not problems
    timing["run_s"] = round(time.time() - started, 6)
    timing["run_cpu_s"] = round(cpu_seconds() - started_cpu, 6)
    timing["worker_cpu_s"] = round(worker_cpu_seconds() - started_workers, 6)
    _write_record(
        ctx,
        recording_id=recording_id,
        seconds=time.time() - started,
        ok=ok,
        problems=problems,
        rejects=rejects.height,
        timing=timing,
    )
    return status, report, ok, problems


def _read_mcaps(ctx: RunContext, echo: Callable[[str], None]) -> None:
    """Every ``*.mcap`` of the dataset: its channels become sources, its rejects rejects; the
    dataset's ``mcap_topics.toml`` maps foreign boolean topics (ROS 2 bags) to sensors."""
    topics = ctx.dataset / "mcap_topics.toml"
    for mp in sorted(ctx.dataset.glob("*.mcap")):
        try:
            contents = read_mcap(mp, topic_map=load_topic_map(topics) if topics.is_file() else None)
        except OnebitError as exc:
            ctx.status[f"mcap:{mp.name}"] = f"failed: {exc}"
            echo(f"  {mp.name}: failed: {exc}")
            continue
        ctx.add_rejects(contents.rejects)
        if contents.unreadable:  # cut inside its header: a failed input, not an absent one
            why = contents.rejects["reason"][-1]
            ctx.status[f"mcap:{mp.name}"] = f"failed: {why}"
            echo(f"  {mp.name}: failed: {why}")
        for topic, frame in contents.channels.items():
            ctx.mcap_channels.setdefault(topic, RawRows(f"{mp.name}:{topic}", frame, pl.DataFrame(schema=REJECTS)))


def _write_record(
    ctx: RunContext,
    *,
    recording_id: str,
    seconds: float,
    ok: bool,
    problems: list[str],
    rejects: int,
    timing: dict | None = None,
) -> None:
    """``run.toml``: dataset, recording id, each stage's status, problems, timing and the resolved config."""
    run_doc = {
        "dataset": str(ctx.dataset.resolve()),
        "recording_id": recording_id,
        "site": ctx.site.name,
        "trackers": list(ctx.trackers),
        "seconds": round(seconds, 3),
        "ok": ok,
        "problems": list(problems),
        "stages": ctx.status,
        "summary": {"rejects": rejects, "tables": sorted(ctx.tables)},
        **({"timing": timing} if timing is not None else {}),
        **({"time": ctx.time_origin.as_dict()} if ctx.time_origin is not None else {}),
        **{k: v for k, v in ctx.config.items() if isinstance(v, dict)},  # --config's sections, as given
        **ctx.resolved,  # each stage that ran: its section as it ran
    }
    outputs.write_text(outputs.to_toml(run_doc), ctx.out / "run.toml")


def _record_crash(ctx: RunContext, exc: BaseException) -> tuple[dict[str, str], pl.DataFrame, bool, list[str]]:
    """Record a run the runner itself could not finish (a bug): ``logs/run.traceback.txt`` and
    a ``run.toml`` with ``ok = false`` and the error, beside what the stages wrote."""
    problem = bounded(f"the runner failed: {type(exc).__name__}: {exc}", 2000)
    outputs.write_text("".join(traceback.format_exception(exc)), ctx.out / "logs" / "run.traceback.txt")
    report = pl.DataFrame(ctx.report, schema=REPORT, orient="row")
    outputs.write_parquet(report, ctx.out / "report.parquet")
    outputs.write_csv(report, ctx.out / "report.csv")
    _write_record(ctx, recording_id="", seconds=0.0, ok=False, problems=[problem], rejects=0)
    return ctx.status, report, False, [problem]
