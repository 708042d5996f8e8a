"""Executors: where independent tasks run -- in this process, in a local process pool, or on Ray.

``onebit run-many`` (one task per dataset) and the papers' studies (one task per trial or
seed) split their work into independent tasks: a module-level function ``fn`` and one
picklable argument per task. An executor runs ``fn(item)`` for every item and hands back one
:class:`TaskOutcome` per item, **in the order of the items** whatever order they finished in,
so a table built from the outcomes is the same on every executor: a task is a pure function
of its argument (it seeds its own random generators), the executor only decides where it runs.

======================  =====================================================================
executor                runs on
======================  =====================================================================
``serial``              this process, one task after the other (debugging, tiny jobs)
``local``               a process pool of ``workers`` processes on this machine (default:
                        one per core). Workers are forked from a *fork server* that imported
                        onebit once, so a worker starts in milliseconds and never inherits a
                        parent's polars/OpenMP thread pools.
``ray``                 Ray tasks (``pip install 'onebit[ray]'``): a local Ray instance with
                        ``workers`` CPUs when no address is given, or an existing cluster
                        (``address``, e.g. ``"auto"`` or ``"10.0.0.5:6379"``; start one with
                        ``ray start --head`` and ``ray start --address HEAD:6379`` on workers).
======================  =====================================================================

Failures. An exception raised by ``fn`` is caught in the worker and becomes that item's
outcome (``error`` and ``traceback``); it is not retried (the same input fails the same way)
and the other tasks go on. A worker *process* that dies (killed, out of memory, segfault) is
different: the task it was running is run again, up to ``max_retries`` more times, then
reported as failed with ``worker died``. The local pool cannot tell which task killed a
broken pool, so every task in flight at that moment is charged one attempt and resubmitted to
a fresh pool; Ray retries the one task (``max_retries`` of ``ray.remote``).

Usage::

    with make_executor("local", workers=2) as ex:
        outcomes = ex.map(fn, items, on_done=lambda o: print(o.index, o.ok))
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import socket
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from typing import Any

from onebit.core.errors import ConfigError, OnebitError
from onebit.core.parallel import one_core_each

#: The executors by name, as ``--executor`` takes them.
EXECUTORS = ("serial", "local", "ray")
#: How often a task whose worker process died is run again before it is reported as failed.
MAX_RETRIES = 2
#: Modules the local pool's fork server imports once, so forked workers start ready.
PRELOAD = ("onebit.pipeline.executors", "onebit.pipeline.runner")
#: Object store of a local Ray instance (bytes): results are small tables, not arrays.
RAY_OBJECT_STORE = 256 * 1024**2

RAY_MISSING = (
    "--executor ray needs Ray, an optional extra of onebit: pip install 'onebit[ray]' "
    "(from a checkout: pip install -e '.[ray]'; make test installs it)"
)

NO_START = (
    "no task finished on that pool: if the processes could not start, a script that uses "
    "the local executor must guard its entry point with `if __name__ == '__main__':`"
)


class ExecutorError(OnebitError):
    """An executor that cannot start: Ray not installed, a cluster that cannot be joined."""


@dataclass(frozen=True)
class TaskOutcome:
    """What became of one task: its ``value``, or the ``error`` that stopped it.

    ``error`` is ``None`` on success; otherwise ``"TypeName: message"`` (the message alone for
    onebit's own errors) or ``"worker died ..."``. ``seconds`` is the task's wall-clock time
    in the worker, ``worker`` the ``host:pid`` that ran it (the last attempt).
    """

    index: int
    value: Any = None
    error: str | None = None
    traceback: str | None = None
    seconds: float = 0.0
    worker: str = ""
    attempts: int = 1

    @property
    def ok(self) -> bool:
        return self.error is None


def call_task(fn: Callable[[Any], Any], item: Any) -> TaskOutcome:
    """Run ``fn(item)`` in a worker and wrap the result or the exception (index filled in by
    the executor). Exceptions do not escape: a failing task must not stop the others."""
    worker = f"{socket.gethostname()}:{os.getpid()}"
    t0 = time.perf_counter()
    try:
        value = fn(item)
    except Exception as exc:  # reported as this task's outcome, with the traceback
        if isinstance(exc, OnebitError):  # bad input: the message says it all
            msg, tb = str(exc), None
        else:  # a bug: keep the traceback
            msg, tb = f"{type(exc).__name__}: {exc}", traceback.format_exc(limit=12)
        return TaskOutcome(-1, error=msg, traceback=tb, seconds=time.perf_counter() - t0, worker=worker)
    return TaskOutcome(-1, value=value, seconds=time.perf_counter() - t0, worker=worker)


def call_task_in_pool(fn: Callable[[Any], Any], item: Any) -> TaskOutcome:
    """:func:`call_task` in a worker of a pool of tasks (local processes, Ray): the stages of
    this process use one core each (:func:`onebit.core.parallel.one_core_each`), since every
    core already runs a task of the pool."""
    one_core_each()
    return call_task(fn, item)


def _died(index: int, attempts: int, detail: str = "") -> TaskOutcome:
    what = f"worker died while running this task (killed or crashed; {attempts} attempt(s))"
    return TaskOutcome(index, error=what + (f": {detail}" if detail else ""), attempts=attempts)


OnDone = Callable[[TaskOutcome], None] | None


class Executor:
    """Runs ``fn`` over items; see the module docstring. Use as a context manager (or call
    :meth:`close`) so pools and a Ray instance this executor started are shut down."""

    kind = "serial"

    def __init__(self, *, workers: int | None = None, max_retries: int = MAX_RETRIES) -> None:
        if workers is not None and (not isinstance(workers, int) or workers < 1):
            raise ConfigError(f"--workers: must be an integer >= 1, got {workers!r}")
        if not isinstance(max_retries, int) or max_retries < 0:
            raise ConfigError(f"max_retries: must be an integer >= 0, got {max_retries!r}")
        self.workers = workers
        self.max_retries = max_retries

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Release what this executor started (nothing for the serial one)."""

    def describe(self) -> str:
        return "serial (this process)"

    def map(self, fn: Callable[[Any], Any], items: Iterable[Any], *, on_done: OnDone = None) -> list[TaskOutcome]:
        """``fn(item)`` for every item; one outcome per item, in the items' order.
        ``on_done(outcome)`` is called in this process as each task finishes (any order)."""
        outcomes = []
        for i, item in enumerate(items):
            o = replace(call_task(fn, item), index=i)
            outcomes.append(o)
            if on_done is not None:
                on_done(o)
        return outcomes


class SerialExecutor(Executor):
    """Every task in this process, in order."""


class LocalPoolExecutor(Executor):
    """A process pool on this machine (``workers`` processes, default one per core)."""

    kind = "local"

    def __init__(self, *, workers: int | None = None, max_retries: int = MAX_RETRIES) -> None:
        super().__init__(workers=workers, max_retries=max_retries)
        self.workers = workers or os.cpu_count() or 1

    def describe(self) -> str:
        return f"local process pool, {self.workers} worker(s)"

    @staticmethod
    def _context(fn: Callable) -> multiprocessing.context.BaseContext:
        ctx = multiprocessing.get_context("forkserver")
        # takes effect when the fork server starts (the first pool of this process)
        ctx.set_forkserver_preload(list(dict.fromkeys([*PRELOAD, fn.__module__])))
        return ctx

    def map(self, fn: Callable[[Any], Any], items: Iterable[Any], *, on_done: OnDone = None) -> list[TaskOutcome]:
        items = list(items)
        outcomes: list[TaskOutcome | None] = [None] * len(items)
        attempts = [0] * len(items)
        todo = deque(range(len(items)))
        ctx = self._context(fn)
        while todo:
            # at most `workers` tasks in flight, so a broken pool charges only tasks that ran
            with ProcessPoolExecutor(max_workers=self.workers, mp_context=ctx) as pool:
                inflight: dict[Any, int] = {}
                broken, finished = False, 0
                while todo or inflight:
                    while todo and not broken and len(inflight) < self.workers:
                        i = todo.popleft()
                        try:
                            fut = pool.submit(call_task_in_pool, fn, items[i])
                        except BrokenProcessPool:
                            todo.appendleft(i)
                            broken = True
                            break
                        attempts[i] += 1
                        inflight[fut] = i
                    if not inflight:
                        break
                    done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                    for fut in done:
                        i = inflight.pop(fut)
                        try:
                            o = replace(fut.result(), index=i, attempts=attempts[i])
                        except BrokenProcessPool:
                            broken = True
                            if attempts[i] <= self.max_retries:
                                todo.appendleft(i)  # run it again on a fresh pool
                                continue
                            o = _died(i, attempts[i], "" if finished else NO_START)
                        except Exception as exc:  # e.g. a result that cannot be pickled
                            o = TaskOutcome(i, error=f"{type(exc).__name__}: {exc}", attempts=attempts[i])
                        outcomes[i] = o
                        finished += 1
                        if on_done is not None:
                            on_done(o)
        return [o for o in outcomes if o is not None]


class RayExecutor(Executor):
    """Ray tasks: a local Ray instance (``workers`` CPUs) or an existing cluster (``address``).

    An instance this executor started is shut down by :meth:`close`; a Ray that was already
    initialised in this process (by the caller, a notebook, a test fixture) is used as it is
    and left running.
    """

    kind = "ray"

    def __init__(
        self, *, workers: int | None = None, address: str | None = None, max_retries: int = MAX_RETRIES
    ) -> None:
        super().__init__(workers=workers, max_retries=max_retries)
        self.address = address
        self._ray = None
        self._started = False

    def describe(self) -> str:
        where = f"cluster at {self.address}" if self.address else "local Ray instance"
        limit = f", at most {self.workers} task(s) at a time" if self.workers else ""
        return f"ray, {where}{limit}"

    def start(self):
        """Import Ray and connect (idempotent); returns the ``ray`` module."""
        if self._ray is not None:
            return self._ray
        try:
            import ray  # optional extra: onebit[ray]
        except ImportError:
            raise ExecutorError(RAY_MISSING) from None
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        if not ray.is_initialized():
            opts: dict[str, Any] = dict(include_dashboard=False, logging_level=logging.WARNING, log_to_driver=False)
            try:
                if self.address:
                    ray.init(address=self.address, **opts)
                else:
                    # "local": a new instance even when RAY_ADDRESS is set or a `ray start` cluster runs here
                    ray.init(
                        address="local",
                        num_cpus=self.workers or os.cpu_count() or 1,
                        object_store_memory=RAY_OBJECT_STORE,
                        **opts,
                    )
            except (ConnectionError, RuntimeError, ValueError) as exc:
                where = f"the Ray cluster at {self.address!r}" if self.address else "a local Ray instance"
                hint = (
                    " (start one with 'ray start --head' on the head node; a cluster with token"
                    " authentication, on by default in recent Ray versions, also needs"
                    " RAY_AUTH_MODE=token and its token -- 'ray get-auth-token' on the head -- in"
                    " RAY_AUTH_TOKEN or ~/.ray/auth_token; on the head node itself --ray-address auto works)"
                    if self.address
                    else ""
                )
                raise ExecutorError(f"--executor ray: cannot start or join {where}{hint}: {exc}") from None
            self._started = True
        self._ray = ray
        return ray

    def close(self) -> None:
        if self._ray is not None and self._started:
            self._ray.shutdown()
        self._ray, self._started = None, False

    def map(self, fn: Callable[[Any], Any], items: Iterable[Any], *, on_done: OnDone = None) -> list[TaskOutcome]:
        ray = self.start()
        items = list(items)
        remote = ray.remote(num_cpus=1, max_retries=self.max_retries, retry_exceptions=False)(call_task_in_pool)
        fn_ref = ray.put(fn)
        limit = self.workers or len(items) or 1
        outcomes: list[TaskOutcome | None] = [None] * len(items)
        todo = deque(range(len(items)))
        inflight: dict[Any, int] = {}
        while todo or inflight:
            while todo and len(inflight) < limit:
                i = todo.popleft()
                inflight[remote.remote(fn_ref, items[i])] = i
            done, _ = ray.wait(list(inflight), num_returns=1)
            for ref in done:
                i = inflight.pop(ref)
                try:
                    o = replace(ray.get(ref), index=i)
                except (
                    ray.exceptions.WorkerCrashedError,
                    ray.exceptions.NodeDiedError,
                    ray.exceptions.LocalRayletDiedError,
                    ray.exceptions.OutOfMemoryError,
                ) as exc:
                    o = _died(i, self.max_retries + 1, type(exc).__name__)
                except ray.exceptions.RayError as exc:
                    first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
                    o = TaskOutcome(i, error=f"{type(exc).__name__}: {first}")
                outcomes[i] = o
                if on_done is not None:
                    on_done(o)
        return [o for o in outcomes if o is not None]


def make_executor(
    kind: str = "local", *, workers: int | None = None, address: str | None = None, max_retries: int = MAX_RETRIES
) -> Executor:
    """The executor named ``kind`` (``serial``, ``local``, ``ray``), checked like the CLI's
    ``--executor``, ``--workers`` and ``--ray-address`` options."""
    if kind not in EXECUTORS:
        raise ConfigError(f"--executor: unknown executor {kind!r}; known: {', '.join(EXECUTORS)}")
    if address is not None and kind != "ray":
        raise ConfigError(f"--ray-address: only with --executor ray (got --executor {kind})")
    if kind == "ray":
        return RayExecutor(workers=workers, address=address, max_retries=max_retries)
    if kind == "local":
        return LocalPoolExecutor(workers=workers, max_retries=max_retries)
    return SerialExecutor(workers=workers, max_retries=max_retries)


def failed(outcomes: Sequence[TaskOutcome]) -> list[TaskOutcome]:
    return [o for o in outcomes if not o.ok]
