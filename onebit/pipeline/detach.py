"""Stages worked side by side: the detachable stages of a run (trackers) in worker processes.

The stage loop (:func:`onebit.pipeline.runner.run_stage`) takes each stage's work from here
when a batch of them was worked ahead (:class:`SideBySide`), else works it itself; either way
the outcome is a :class:`Worked`. A stage's ``detach(ctx)`` gives its work as one call
``fn(*args)`` that another process can make (:class:`~onebit.pipeline.context.Stage`); the
calls run on the cores with :func:`onebit.core.parallel.run_beside`, the large tables a worker
makes come back through files (:data:`SPILL_BYTES`).
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import polars as pl

from onebit.core.errors import OnebitError
from onebit.core.parallel import CORES_ENV, available_cores, one_core_each, run_beside
from onebit.pipeline.context import RunContext, Stage
from onebit.trackers.base import ARTIFACTS, PROGRESS

#: A run detaches its trackers side by side (``cores = 0``) from this many rows in its
#: tables when they start: below it the trackers take seconds, less than starting workers.
DETACH_MIN_ROWS = 200_000


@dataclass
class Worked:
    """What a stage's work gave, here or in a worker: its tables, or its error (``onebit``: an
    :class:`OnebitError`, said as it is; else a bug, with the traceback), and its seconds."""

    made: dict[str, Any] | None
    seconds: float
    cpu: float
    error: str | None = None
    onebit: bool = False
    traceback: str | None = None


def failed(exc: Exception, seconds: float, cpu: float) -> Worked:
    """The outcome of a work that raised ``exc``: an :class:`OnebitError` said as it is, else a
    bug with its traceback (it goes to ``logs/``)."""
    if isinstance(exc, OnebitError):
        return Worked(None, seconds, cpu, str(exc), onebit=True)
    return Worked(None, seconds, cpu, f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc(limit=8))


def run_job(fn: Callable[..., dict[str, Any]], args: tuple) -> Worked:
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        made = fn(*args)
    except Exception as exc:  # a bug's traceback goes to logs/, as in the run's own process
        return failed(exc, time.perf_counter() - t0, time.process_time() - c0)
    return Worked(made, time.perf_counter() - t0, time.process_time() - c0)


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


def _run_lane(jobs: list[tuple[str, Callable, tuple]], spill: int = SPILL_BYTES) -> list[Worked]:
    """Detached stages one after another, each on one core: in a worker process (its large
    tables handed back through files, :func:`_spill`), or here when this process takes them
    (:func:`onebit.core.parallel.run_beside`)."""
    worker = multiprocessing.parent_process() is not None
    if worker:
        one_core_each()
    out = [run_job(fn, args) for _, fn, args in jobs]
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


def detachable(rest: list[Stage], ctx: RunContext) -> list[Stage]:
    """The detachable stages from the start of ``rest`` on (up to the first that is not) that
    would run now: available, their input tables made."""
    out = []
    for st in rest:
        if st.detach is None:
            break
        if all(n in ctx.tables for n in st.needs) and st.available(ctx) is None:
            out.append(st)
    return out


def detach_batch(stages: list[Stage], ctx: RunContext, cores: int, *, spill: int | None = None) -> dict[str, Worked]:
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
            lambda: [run_job(f, a) for _, f, a in here_jobs],
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


class SideBySide:
    """The detachable stages of one run worked ahead, side by side on ``cores`` (0: see
    :func:`run_cores`): when the loop reaches a detachable stage, it and the detachable ones
    right after it that would run now are worked at once (:func:`detach_batch`); the loop then
    takes each one's outcome (:meth:`take`) instead of working it."""

    def __init__(self, cores: int) -> None:
        self.cores = cores
        self.done: dict[str, Worked] = {}

    def take(self, rest: list[Stage], ctx: RunContext) -> Worked | None:
        """The outcome of ``rest[0]`` (an available stage) if it was worked side by side (now
        or with an earlier batch), else ``None`` (the loop works it here)."""
        st = rest[0]
        if st.detach is not None and st.name not in self.done and run_cores(ctx, self.cores) > 1:
            batch = detachable(rest, ctx)
            if len(batch) >= 2:  # this stage and the detachable ones after it, side by side
                self.done.update(detach_batch(batch, ctx, run_cores(ctx, self.cores)))
        return self.done.pop(st.name, None)
