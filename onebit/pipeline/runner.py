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
from onebit.core.parallel import cpu_seconds, worker_cpu_seconds
from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.core.tables import REJECTS, REPORT
from onebit.pipeline import stages as declaration
from onebit.pipeline.context import RunContext, Stage, check_made, dataset_run_config
from onebit.pipeline.detach import SideBySide, Worked, failed
from onebit.pipeline.progress import ProgressSink, progress_sink
from onebit.pipeline.stages import TRACKERS, TrackerEntry
from onebit.readers.mcap_io import load_topic_map, read_mcap
from onebit.readers.rows import RawRows
from onebit.trackers.base import ARTIFACTS
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


def checked_sections(dataset: Path, config: dict[str, Any] | None, stage_list: list[Stage]) -> tuple[dict, dict]:
    """``--config``'s sections (a copy: a run never changes the caller's dicts) and the
    dataset's own ``run.toml``, each checked against ``stage_list`` (:func:`check_sections`)."""
    config = copy.deepcopy(dict(config or {}))
    check_sections(config, stage_list, source="--config")
    dataset_sections = dataset_run_config(dataset)
    check_sections(dataset_sections, stage_list, source=dataset / "run.toml")
    return config, dataset_sections


def check_tracker_names(names: tuple[str, ...], known: list[str], *, where: str) -> None:
    """Every name of ``names`` is a declared tracker; else a :class:`ConfigError` naming ``where``."""
    for tr in names:
        if tr not in known:
            raise ConfigError(f"{where}: unknown tracker {tr!r}; known: {sorted(known)}")


def _crashed(exc: Exception, work: Path) -> Exception:
    """An error of the stage loop: bad input and a full disk end the run (``OUT`` left as it
    was), so they are raised; a bug is returned, to be recorded as the run's failure."""
    if isinstance(exc, OnebitError):
        raise exc
    if is_disk_full(exc):  # the system, not a bug: OUT left as it was
        raise DiskFullError(work) from exc
    return exc


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
    :data:`~onebit.pipeline.detach.DETACH_MIN_ROWS` rows, else 1; 1 = one tracker after another, here.

    The run record ``run.toml`` holds each stage's status and a ``[timing]`` table (:func:`_finish`).

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
    stage_list = declaration.stages(tracker_entries)  # read at run time: the one declaration
    config, dataset_sections = checked_sections(dataset, config, stage_list)
    known = [e.name for e in tracker_entries]
    requested = tuple(trackers) if trackers else default_trackers(config, dataset_sections)
    check_tracker_names(requested, known, where="--trackers" if trackers else "[run] trackers")
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
                trackers=requested or tuple(known),
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
            except Exception as exc:  # a bug, not bad input: keep what was done and the traceback
                crash = _crashed(exc, work)
                result = _record_crash(ctx, exc)
    finally:
        sink.close()
    if crash is not None:
        crash.add_note(f"onebit: the run was recorded as failed; traceback in {out / 'logs' / 'run.traceback.txt'}")
        raise crash
    status, report, ok, problems = result
    return RunResult(out, status, report, ok, problems)


# --------------------------------------------------------------------------- one stage


def skip_reason(st: Stage, ctx: RunContext) -> str | None:
    """Why ``st`` does not run on ``ctx`` now (its own ``available``, then its input tables), or ``None``."""
    missing = [n for n in st.needs if n not in ctx.tables]
    reason = st.available(ctx)
    if reason is None and missing:
        reason = f"input table(s) {missing} not produced by an earlier stage"
    return reason


def run_stage(st: Stage, ctx: RunContext, *, worked: Worked | None = None) -> Worked:
    """The work of the available stage ``st`` on ``ctx``: the one step ``onebit run`` and
    ``onebit follow`` share.

    ``st.work(ctx)`` here, or ``worked``: what a worker made of it
    (:class:`~onebit.pipeline.detach.SideBySide`); timed (``ctx.seconds``) and checked against
    the stage's declaration (:func:`~onebit.pipeline.context.check_made`). A failure is the
    outcome's ``error`` (with a ``traceback`` when it is a bug, not bad input); a full disk
    stops everything (:class:`DiskFullError`). The tables are the caller's to keep and write.
    """
    t0, c0 = time.perf_counter(), cpu_seconds()
    try:
        if worked is not None and worked.error is not None:
            return worked
        made = st.work(ctx) if worked is None else worked.made
        seconds = ctx.seconds[st.name] = time.perf_counter() - t0 if worked is None else worked.seconds
        check_made(st, made, ctx.tables, extra=(ARTIFACTS,))
    except DiskFullError:  # not this stage's failure: the whole run stops, OUT left as it was
        raise
    except Exception as exc:  # bad input, or a bug: keep the other stages (and the traceback)
        if is_disk_full(exc):  # the system, not a bug: the whole run stops, OUT left as it was
            raise DiskFullError(ctx.out) from exc
        return failed(exc, time.perf_counter() - t0, cpu_seconds() - c0)
    return Worked(made, seconds, cpu_seconds() - c0 if worked is None else worked.cpu)


def _log_stage(st: Stage, ctx: RunContext, made: dict[str, Any], recording_id: str) -> None:
    """The stage's recording: opened, the site logged, the stage's viz called, closed."""
    with stage_recording(ctx.out, st.name, recording_id) as rec:
        log_site(rec, ctx.site, ctx.region_graph)
        if st.viz is not None:
            st.viz(rec, ctx, made)
    release_freed_memory()


def _recorded(st: Stage, ctx: RunContext, done: Worked, recording_id: str | None) -> tuple[Worked, dict]:
    """``done`` with its recording written (``recording_id``; ``None``: no recordings) and its
    timing, or the recording's failure."""
    t1, c1 = time.perf_counter(), cpu_seconds()
    try:
        if recording_id is not None:
            _log_stage(st, ctx, done.made, recording_id)
    except DiskFullError:
        raise
    except Exception as exc:
        if is_disk_full(exc):
            raise DiskFullError(ctx.out) from exc
        return failed(exc, done.seconds, done.cpu), {}
    return done, {
        "work_s": round(done.seconds, 6),
        "viz_s": round(time.perf_counter() - t1, 6),
        "work_cpu_s": round(done.cpu, 6),
        "viz_cpu_s": round(cpu_seconds() - c1, 6),
    }


def _say_failed(name: str, done: Worked, ctx: RunContext, echo: Callable[[str], None]) -> None:
    """A stage's failure in its status: bad input as it is said, a bug with its traceback in ``logs/``."""
    if done.onebit:
        ctx.status[name] = f"failed: {done.error}"
        echo(f"  {name}: FAILED: {done.error}")
        return
    ctx.status[name] = bounded(f"failed: {done.error}", 2000)
    outputs.write_text(done.traceback or "", ctx.out / "logs" / f"{name}.traceback.txt")
    echo(f"  {name}: FAILED with {bounded(done.error)} (traceback in logs/{name}.traceback.txt)")


def _keep(st: Stage, ctx: RunContext, made: dict[str, Any], timing: dict, echo: Callable[[str], None]) -> None:
    """The tables a stage made: into the run's tables and ``tables/``; its status ok."""
    t2 = time.perf_counter()
    for name, df in made.items():
        if name == ARTIFACTS:  # in-memory results for the stage's viz only
            continue
        ctx.tables[name] = df
        outputs.write_parquet(df, ctx.out / "tables" / f"{name}.parquet")
    timing["write_s"] = round(time.perf_counter() - t2, 6)
    ctx.status[st.name] = f"ok ({ctx.seconds[st.name]:.2f} s)"
    echo(f"  {st.name}: ok")
    for part, state in ctx.status.items():  # parts of a stage that failed on their own (scores/<tracker>)
        if part.startswith(f"{st.name}/"):
            echo(f"  {part}: {state}")


# --------------------------------------------------------------------------- the stage loop


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

    Each available stage is worked (:func:`run_stage`; the detachable ones maybe side by side,
    :class:`~onebit.pipeline.detach.SideBySide`), then (``rrd``) its recording is written; a
    failure in either leaves no ``.rrd`` of the stage. Work, recording and table writing are
    timed apart (``timing`` of ``run.toml``); ``looks`` (tracker ->
    :class:`~onebit.viz.families.Look`) lay out the run's blueprint."""
    (ctx.out / "tables").mkdir(parents=True, exist_ok=True)
    if rrd:
        (ctx.out / "rrd").mkdir(parents=True, exist_ok=True)
    recording_id = str(uuid.uuid4())
    timing: dict[str, Any] = {"entered_unix": round(entered if entered is not None else time.time(), 6), "rrd": rrd}
    _read_mcaps(ctx, echo)
    started = (time.time(), cpu_seconds(), worker_cpu_seconds())
    beside = SideBySide(cores)
    for i, st in enumerate(stage_list):
        sink.stage(st.name, i, len(stage_list))
        reason = skip_reason(st, ctx)
        if reason is not None:
            ctx.status[st.name] = f"skipped: {reason}"
            echo(f"  {st.name}: skipped ({reason})")
            continue
        done = run_stage(st, ctx, worked=beside.take(stage_list[i:], ctx))
        release_freed_memory()  # what the work dropped, before its recording and the next stage
        if done.error is None:
            done, timing[st.name] = _recorded(st, ctx, done, recording_id if rrd else None)
        if done.error is not None:
            _say_failed(st.name, done, ctx, echo)
            continue
        _keep(st, ctx, done.made, timing[st.name], echo)
    _check_did_something(ctx, stage_list, tracker_names)
    problems = [
        f"tracker '{tr}' was asked for (--trackers) but did not run: {ctx.status.get(tr, 'not run')[len('skipped: ') :]}"
        for tr in requested
        if ctx.status.get(tr, "").startswith("skipped")
    ]
    for p in problems:
        echo(f"  {p}")
    return _finish(ctx, recording_id, problems, timing, started, rrd=rrd, looks=looks)


def _check_did_something(ctx: RunContext, stage_list: list[Stage], tracker_names: list[str]) -> None:
    """Nothing useful done -- no stage read or corrected any input (trackers and scores on
    nothing do not count) -- is an :class:`InputError`, so ``OUT`` is left as it was."""
    status = ctx.status
    data_stages = [st.name for st in stage_list if st.name not in {*tracker_names, "scores"}]
    if not all(status.get(n, "").startswith("skipped") for n in data_stages):
        return
    why = "; ".join(f"{n}: {s}" for n, s in status.items() if n in data_stages or n.startswith("mcap:"))
    bad = [f"{n[5:]}: {s[8:]}" for n, s in status.items() if n.startswith("mcap:") and s.startswith("failed: ")]
    if bad:  # an unreadable file is the news, not the stages it left with nothing
        why = "; ".join(f"{n}: {s}" for n, s in status.items() if n in data_stages)
        raise InputError(
            f"unreadable input: {'; '.join(bad)}; nothing else to read ({why}); OUT was left as it was",
            file=ctx.dataset,
        )
    raise InputError(f"nothing to do: no input could be read ({why}); OUT was left as it was", file=ctx.dataset)


def _finish(
    ctx: RunContext,
    recording_id: str,
    problems: list[str],
    timing: dict[str, Any],
    started: tuple[float, float, float],
    *,
    rrd: bool,
    looks: dict | None,
) -> tuple[dict[str, str], pl.DataFrame, bool, list[str]]:
    """The run's blueprint, rejects, report and record (``run.toml``).

    The run record holds, besides each stage's status, a ``[timing]`` table: per
    stage the seconds of its work (``work_s``, as in its status), of its recording (``viz_s``:
    opening the ``.rrd``, the site and the stage's viz call, closing it) and of writing its
    tables (``write_s``), and the CPU seconds of the work and of the recording (``work_cpu_s``,
    ``viz_cpu_s``: the process's, every thread's, and of the worker processes a stage ran
    pieces in, :func:`onebit.core.parallel.cpu_seconds`; on a shared machine the wall times
    grow with the load, these hardly); ``blueprint_s`` (``blueprint_cpu_s``), ``run_s`` (stages
    to record; ``run_cpu_s``), ``worker_cpu_s`` (the part of ``run_cpu_s`` spent in worker
    processes) and ``entered_unix`` (the wall clock when this function was called: a caller that
    knows when its process started gets the start-up from it).
    """
    work = ctx.out
    t3, c3 = time.perf_counter(), time.process_time()
    if rrd:
        save_run_blueprint(
            work / "rrd", units=ctx.site.units, looks=looks
        )  # the viewer layout of what the stages logged
    timing["blueprint_s"] = round(time.perf_counter() - t3, 6)
    timing["blueprint_cpu_s"] = round(time.process_time() - c3, 6)
    rejects = ctx.tables.get("rejects", pl.DataFrame(schema=REJECTS))
    outputs.write_parquet(rejects, work / "tables" / "rejects.parquet")
    report = pl.DataFrame(ctx.report, schema=REPORT, orient="row")
    outputs.write_parquet(report, work / "report.parquet")
    outputs.write_csv(report, work / "report.csv")
    ok = all(not s.startswith("failed") for s in ctx.status.values()) and not problems
    timing["run_s"] = round(time.time() - started[0], 6)
    timing["run_cpu_s"] = round(cpu_seconds() - started[1], 6)
    timing["worker_cpu_s"] = round(worker_cpu_seconds() - started[2], 6)
    _write_record(
        ctx,
        recording_id=recording_id,
        seconds=time.time() - started[0],
        ok=ok,
        problems=problems,
        rejects=rejects.height,
        timing=timing,
    )
    return ctx.status, report, ok, problems


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
