"""``onebit run-many``: the pipeline on many dataset folders, one task per dataset.

A building logs a dataset folder per day per floor; :func:`run_many` runs the whole pipeline
(:func:`onebit.pipeline.runner.run_pipeline`, exactly as ``onebit run``) on each of them on
an executor (:mod:`onebit.pipeline.executors`: serial, a local process pool or Ray) and
writes::

    OUT/<name>/            one complete run folder per dataset (tables/, rrd/, report.*, run.toml)
    OUT/summary.parquet    one row per dataset x report metric: dataset, status, error, stage,
    OUT/summary.csv        metric, value, unit (a dataset without a report: one row, nulls)
    OUT/run-many.toml      the executor, and per dataset its status, seconds and worker

``<name>`` is the dataset's path relative to the deepest folder holding all the datasets'
parent folders (``data/day1/floor2`` and ``data/day2/floor2`` -> ``day1/floor2``,
``day2/floor2``; datasets side by side -> their folder names).

Atomic run folders. Each dataset's run is written under a hidden temporary name next to its
final place (``OUT/.<name>.partial-<token>-<pid>``) and renamed into place only once the
runner has returned, so ``OUT/<name>`` is always either absent, the previous complete run, or
this one -- never half written, whatever happens to the worker. A worker killed mid-task
leaves only its hidden temporary folder, which the driver deletes at the end (and a later
run-many of the same datasets deletes those of a driver that was killed itself); the task is
retried (see the executors) or reported ``failed`` in the summary. A failed dataset does not
stop the others. On a Ray cluster, ``OUT`` and the dataset folders must be on a file system
every node sees at the same path (NFS, a shared volume).
"""

from __future__ import annotations

import glob
import io
import os
import shutil
import time
import uuid
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import polars as pl
from rich.console import Console
from rich.table import Table

from onebit.core import writers
from onebit.core.errors import ConfigError, InputError
from onebit.pipeline.executors import Executor, SerialExecutor, TaskOutcome
from onebit.pipeline.runner import run_pipeline

#: ``OUT/summary.parquet``: one row per dataset x metric of its report.
SUMMARY = pl.Schema(
    {
        "dataset": pl.String,
        "status": pl.String,
        "error": pl.String,
        "stage": pl.String,
        "metric": pl.String,
        "value": pl.Float64,
        "unit": pl.String,
    }
)

#: Per dataset (printed, and in ``run-many.toml``): status, time and where it ran.
DATASETS = pl.Schema(
    {
        "dataset": pl.String,
        "status": pl.String,
        "error": pl.String,
        "run": pl.String,
        "metrics": pl.Int64,
        "seconds": pl.Float64,
        "worker": pl.String,
    }
)

GLOB_CHARS = frozenset("*?[")


@dataclass(frozen=True)
class DatasetJob:
    """One task of run-many: run the pipeline on ``dataset`` into the run folder ``out``."""

    dataset: str
    name: str
    out: str
    token: str
    trackers: tuple[str, ...] | None = None
    config: dict[str, Any] = field(default_factory=dict)
    #: write the Rerun recordings (``--no-rrd``: ``False``)
    rrd: bool = True


@dataclass
class RunManyResult:
    out: Path
    summary: pl.DataFrame
    datasets: pl.DataFrame
    ok: bool
    seconds: float
    executor: str


# --------------------------------------------------------------------------- which datasets


def find_datasets(
    specs: Iterable[str | Path], *, out: str | Path | None = None, echo: Callable[[str], None] | None = None
) -> list[Path]:
    """Dataset folders from command-line arguments: folders, globs (``'data/*/floor*'``,
    ``**`` allowed) and files listing one folder or glob per line (``#`` comments; relative
    lines are relative to the list file's folder). Glob matches that are not folders are left
    out; a glob or list that yields nothing is an error. Duplicates are dropped, and so is
    anything inside ``out`` (a later ``data/*`` would otherwise match the run folders).
    A named folder that does not exist is kept: it fails as a dataset, named in the summary."""
    echo = echo or (lambda s: None)
    found: list[Path] = []
    for spec in specs:
        found += _expand(str(spec), base=None, depth=0)
    seen: set[Path] = set()
    out_abs = Path(os.path.abspath(out)) if out is not None else None
    result = []
    for p in found:
        a = Path(os.path.abspath(p))
        if a in seen:
            continue
        seen.add(a)
        if out_abs is not None and (a == out_abs or out_abs in a.parents):
            echo(f"  leaving out {p}: it is inside the output folder {out}")
            continue
        result.append(a)
    if not result:
        raise ConfigError("run-many: no dataset folders given (folders, globs or a file listing folders)")
    return result


def _expand(spec: str, *, base: Path | None, depth: int) -> list[Path]:
    path = Path(spec).expanduser()
    if base is not None and not path.is_absolute():
        path = base / path
    if GLOB_CHARS & set(spec):
        hits = sorted(Path(h) for h in glob.glob(str(path), recursive=True) if Path(h).is_dir())
        if not hits:
            raise InputError(f"no dataset folder matches the glob {spec!r}", file=base)
        return hits
    if path.is_file() and depth == 0:
        return _read_list(path)
    if path.is_file():
        raise InputError("a dataset list may name folders and globs, not another list file", file=path)
    return [path]


def _read_list(path: Path) -> list[Path]:
    out: list[Path] = []
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the dataset list: {exc}", file=path) from None
    for line in lines:
        line = line.split("#", 1)[0].strip()
        if line:
            out += _expand(line, base=path.parent, depth=1)
    if not out:
        raise InputError("the dataset list names no folder", file=path)
    return out


def dataset_names(datasets: Sequence[Path]) -> list[str]:
    """Run-folder names: each dataset's path relative to the deepest common folder of the
    datasets' parents (posix form). Refuses a dataset nested in another (its run folder
    would sit inside the other's)."""
    parents = [str(Path(d).parent) for d in datasets]
    root = Path(os.path.commonpath(parents)) if parents else Path(".")
    names = [Path(d).relative_to(root).as_posix() for d in datasets]
    taken = set(names)
    for n in names:
        parts = n.split("/")
        for k in range(1, len(parts)):
            outer = "/".join(parts[:k])
            if outer in taken:
                raise ConfigError(f"run-many: dataset {n!r} is inside dataset {outer!r}; give one or the other")
    return names


# --------------------------------------------------------------------------- one task


def partial_name(final: Path, token: str) -> Path:
    """The hidden temporary run folder a worker fills before the rename (pid last)."""
    return final.with_name(f".{final.name}.partial-{token}-{os.getpid()}")


def commit_folder(tmp: Path, final: Path) -> Path:
    """Put the finished folder ``tmp`` in place of ``final``: one rename when ``final`` does
    not exist; otherwise the old folder is first renamed aside (hidden), then deleted. At no
    moment does ``final`` hold a mix of the two."""
    if final.exists():
        aside = final.with_name(f".{final.name}.old-{uuid.uuid4().hex[:8]}")
        os.replace(final, aside)
        os.replace(tmp, final)
        shutil.rmtree(aside, ignore_errors=True)
    else:
        os.replace(tmp, final)
    return final


def run_dataset(job: DatasetJob) -> dict[str, Any]:
    """The task: run the pipeline on one dataset into a temporary folder, rename it into
    place. Returns ``{"ok", "status", "report"}`` (the report as a polars frame)."""
    final = Path(job.out)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = partial_name(final, job.token)
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        res = run_pipeline(
            job.dataset, tmp, trackers=job.trackers, config=dict(job.config), progress=False, rrd=job.rrd
        )
        commit_folder(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {"ok": res.ok, "status": dict(res.status), "report": res.report}


# --------------------------------------------------------------------------- many


def run_many(
    datasets: Iterable[str | Path],
    out: str | Path,
    *,
    trackers: Iterable[str] | None = None,
    config: dict[str, Any] | None = None,
    executor: Executor | None = None,
    echo: Callable[[str], None] | None = None,
    rrd: bool = True,
) -> RunManyResult:
    """Run the pipeline on every dataset folder on ``executor`` (default: serial) and write
    ``out`` (see the module docstring). ``datasets`` takes what :func:`find_datasets` takes.
    ``result.ok`` is true when every dataset ran and every stage of every run succeeded;
    ``rrd=False`` (``--no-rrd``) writes no Rerun recordings."""
    echo = echo or (lambda s: None)
    executor = executor or SerialExecutor()
    out = Path(os.path.abspath(out))  # workers (Ray) may run in another working folder
    folders = find_datasets(datasets, out=out, echo=echo)
    names = dataset_names(folders)
    out.mkdir(parents=True, exist_ok=True)
    token = uuid.uuid4().hex[:10]
    jobs = [
        DatasetJob(
            str(d), n, str(out / n), token, tuple(trackers) if trackers is not None else None, dict(config or {}), rrd
        )
        for d, n in zip(folders, names)
    ]
    echo(f"onebit run-many: {len(jobs)} dataset(s) -> {out} on {executor.describe()}")
    done = 0

    def progress(o: TaskOutcome) -> None:
        nonlocal done
        done += 1
        state = ("ok" if o.value["ok"] else "stage(s) failed") if o.ok else f"FAILED: {o.error}"
        echo(f"  [{done}/{len(jobs)}] {names[o.index]}: {state} ({o.seconds:.1f} s, {o.worker or '?'})")

    t0 = time.perf_counter()
    _remove_partials(jobs, stale=True)
    try:
        outcomes = executor.map(run_dataset, jobs, on_done=progress)
    finally:
        _remove_partials(jobs)
    seconds = time.perf_counter() - t0
    summary, per_dataset = _tables(jobs, outcomes)
    for job, o in zip(jobs, outcomes):
        if o.traceback:
            writers.write_text(o.traceback, out / "logs" / f"{job.name.replace('/', '__')}.traceback.txt")
    writers.write_parquet(summary, out / "summary.parquet")
    writers.write_csv(summary, out / "summary.csv")
    ok = bool(per_dataset.height) and bool((per_dataset["status"] == "ok").all())
    doc = {
        "executor": executor.describe(),
        "seconds": round(seconds, 3),
        "ok": ok,
        "datasets": {
            r["dataset"]: r["status"] if r["error"] is None else f"{r['status']}: {r['error']}"
            for r in per_dataset.iter_rows(named=True)
        },
        "seconds_per_dataset": {r["dataset"]: round(r["seconds"], 3) for r in per_dataset.iter_rows(named=True)},
        "worker": {r["dataset"]: r["worker"] for r in per_dataset.iter_rows(named=True)},
    }
    writers.write_text(writers.to_toml(doc), out / "run-many.toml")
    return RunManyResult(out, summary, per_dataset, ok, seconds, executor.describe())


def _remove_partials(jobs: Sequence[DatasetJob], *, stale: bool = False) -> None:
    """Delete the hidden temporary folders of this run's tasks (left by killed workers), or
    with ``stale``, those any earlier run-many left for these datasets (a killed driver)."""
    for job in jobs:
        final = Path(job.out)
        pattern = f".{glob.escape(final.name)}.partial-{'*' if stale else job.token + '-*'}"
        for p in final.parent.glob(pattern):
            shutil.rmtree(p, ignore_errors=True)


def _tables(jobs: Sequence[DatasetJob], outcomes: Sequence[TaskOutcome]) -> tuple[pl.DataFrame, pl.DataFrame]:
    parts, rows = [], []
    for job, o in zip(jobs, outcomes):
        if o.ok:
            failed = {k: v for k, v in o.value["status"].items() if v.startswith("failed")}
            status = "ok" if o.value["ok"] else "failed"
            error = "; ".join(f"{k}: {v}" for k, v in failed.items()) or None
            report = o.value["report"]
            run = job.out
        else:
            status, error, report, run = "failed", o.error, None, None
        ident = dict(dataset=job.name, status=status, error=error)
        if report is not None and report.height:
            parts.append(
                report.select(
                    **{k: pl.lit(v, SUMMARY[k]) for k, v in ident.items()},
                    stage="stage",
                    metric="metric",
                    value=pl.col("value").cast(pl.Float64),
                    unit="unit",
                )
            )
        else:
            parts.append(
                pl.DataFrame([ident], schema={k: SUMMARY[k] for k in ident}).with_columns(
                    stage=pl.lit(None, pl.String),
                    metric=pl.lit(None, pl.String),
                    value=pl.lit(None, pl.Float64),
                    unit=pl.lit(None, pl.String),
                )
            )
        rows.append(
            {
                **ident,
                "run": run,
                "metrics": report.height if report is not None else 0,
                "seconds": o.seconds,
                "worker": o.worker,
            }
        )
    summary = pl.concat(parts).select(SUMMARY.names()).cast(dict(SUMMARY)) if parts else pl.DataFrame(schema=SUMMARY)
    return summary, pl.DataFrame(rows, schema=DATASETS)


def format_summary(result: RunManyResult) -> str:
    """The printed table: one line per dataset (status, metrics, seconds, error)."""
    table = Table(title=f"run-many summary of {result.out} ({result.executor}, {result.seconds:.1f} s)")
    for col, just in (
        ("dataset", "left"),
        ("status", "left"),
        ("metrics", "right"),
        ("seconds", "right"),
        ("error", "left"),
    ):
        table.add_column(col, justify=just)
    for r in result.datasets.iter_rows(named=True):
        table.add_row(r["dataset"], r["status"], str(r["metrics"]), f"{r['seconds']:.1f}", (r["error"] or "")[:200])
    buf = io.StringIO()
    Console(file=buf, width=140, force_terminal=False, color_system=None).print(table)
    failed = result.datasets.filter(pl.col("status") != "ok")["dataset"].to_list()
    n = result.datasets.height
    tail = f"{n - len(failed)} of {n} dataset(s) ok" + (f"; failed: {', '.join(failed)}" if failed else "")
    return buf.getvalue() + tail + f"\nsummary: {result.out / 'summary.parquet'} (and summary.csv)\n"
