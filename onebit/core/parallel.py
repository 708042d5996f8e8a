"""Cores a stage may use, and independent pieces of one stage run in processes side by side.

A tracker whose work splits into independent runs (CLUSTERTRACK's runs with different seeds)
may run them in worker processes: :func:`run_beside` starts the pieces in a process pool
(``forkserver``: a fresh interpreter forks the workers, so no thread of this process -- polars',
numba's, Rerun's -- is copied into them), runs one piece in this process meanwhile, and returns
every result in order. The results are what the same calls give in this process (the workers
run the same code on the same, pickled, arguments), so a run's output does not depend on how
many cores it had.

How many: :func:`available_cores` -- the CPUs this process may run on
(``os.sched_getaffinity``), or the environment's ``ONEBIT_CORES`` when set. The run-many pools
set ``ONEBIT_CORES=1`` in their workers (:func:`one_core_each`): there every core already runs a
dataset, and a stage that started its own pool would only make them wait for each other.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

#: The environment variable that caps the cores a stage uses (an integer >= 1).
CORES_ENV = "ONEBIT_CORES"

_worker_cpu = 0.0  # CPU seconds of the calls run_beside made in workers, this process's total


def worker_cpu_seconds() -> float:
    """CPU seconds the calls :func:`run_beside` sent to worker processes have taken so far in
    this process (each measured in its worker): a stage's CPU is this process's
    ``time.process_time()`` plus what this adds during the stage (:func:`cpu_seconds`)."""
    return _worker_cpu


def cpu_seconds() -> float:
    """``time.process_time()`` plus :func:`worker_cpu_seconds`: the CPU a stage costs, its
    workers' included (the runner's ``work_cpu_s``)."""
    return time.process_time() + _worker_cpu


def _timed(fn: Callable[..., Any], args: tuple) -> tuple[Any, float]:
    c = time.process_time()
    out = fn(*args)
    return out, time.process_time() - c


def available_cores() -> int:
    """The cores a stage may use: ``ONEBIT_CORES`` when set (>= 1), else the CPUs this process
    may run on. A value that is not a positive integer raises ``ValueError`` naming it."""
    raw = os.environ.get(CORES_ENV)
    if raw is not None and raw.strip():
        try:
            n = int(raw)
        except ValueError:
            n = 0
        if n < 1:
            raise ValueError(f"environment variable {CORES_ENV}={raw!r}: expected a whole number of cores >= 1")
        return n
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - platforms without affinity
        return max(1, os.cpu_count() or 1)


def one_core_each() -> None:
    """Mark this process as one worker of a pool of datasets: its stages use one core."""
    os.environ[CORES_ENV] = "1"


def _context() -> multiprocessing.context.BaseContext:
    """``forkserver`` where the platform has it (Linux, macOS), else ``spawn`` (Windows)."""
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def run_beside(
    here: Callable[[], Any],
    fn: Callable[..., Any],
    elsewhere: Sequence[tuple],
    *,
    workers: int,
    preload: Sequence[str] = (),
) -> tuple[Any, list[Any]]:
    """``(here(), [fn(*args) for args in elsewhere])``, the second in ``min(workers,
    len(elsewhere))`` worker processes while this process computes the first; then this
    process makes, in order, every call no worker has taken yet (so the cores stay busy
    whatever each call costs); with ``workers <= 0`` or nothing elsewhere, everything here,
    in order. ``fn`` must be a module-level function
    and its arguments picklable; ``preload``: modules the fork server imports once (``fn``'s
    module is always one). A call that fails in a worker for any reason -- workers that cannot
    start or die (killed, out of memory: the pool breaks), arguments a worker cannot unpickle (a
    function of a module only this process can import), or ``fn`` raising -- is made again
    here: it gives the same result, or raises here what it raised there. The pool is shut
    down either way."""
    if workers <= 0 or not elsewhere:
        return here(), [fn(*args) for args in elsewhere]
    ctx = _context()
    if ctx.get_start_method() == "forkserver":
        ctx.set_forkserver_preload(list(dict.fromkeys([*preload, fn.__module__])))
    try:
        pool = ProcessPoolExecutor(max_workers=min(workers, len(elsewhere)), mp_context=ctx)
        futures = [pool.submit(_timed, fn, args) for args in elsewhere]
    except (OSError, BrokenProcessPool):  # no worker could be started here: everything in this process
        return here(), [fn(*args) for args in elsewhere]
    with pool:
        try:
            first = here()
        except BaseException:
            for f in futures:
                f.cancel()
            raise
        rest: list[Any] = [None] * len(futures)
        waiting = []
        for k, (f, args) in enumerate(zip(futures, elsewhere)):
            if f.cancel():  # no worker has taken it yet: this process is free, so it makes it
                rest[k] = fn(*args)
            else:
                waiting.append(k)
        for k in waiting:
            try:
                out, cpu = futures[k].result()
            except Exception:  # the worker died, could not take the call, or fn raised: make it here
                out = fn(*elsewhere[k])
            else:
                _add_worker_cpu(cpu)
            rest[k] = out
        return first, rest


def _add_worker_cpu(seconds: float) -> None:
    global _worker_cpu
    _worker_cpu += seconds
