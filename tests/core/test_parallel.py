"""Cores a stage may use, and runs side by side in worker processes."""

from __future__ import annotations

import math
import os

import pytest

from onebit.core.parallel import (
    CORES_ENV,
    available_cores,
    cpu_seconds,
    one_core_each,
    run_beside,
    worker_cpu_seconds,
)


def test_available_cores_from_the_environment_or_the_affinity(monkeypatch):
    monkeypatch.delenv(CORES_ENV, raising=False)
    assert available_cores() == len(os.sched_getaffinity(0))
    monkeypatch.setenv(CORES_ENV, "3")
    assert available_cores() == 3
    for bad in ("0", "-2", "two", "1.5"):
        monkeypatch.setenv(CORES_ENV, bad)
        with pytest.raises(ValueError, match=CORES_ENV):
            available_cores()


def test_one_core_each_marks_a_pool_worker(monkeypatch):
    monkeypatch.delenv(CORES_ENV, raising=False)
    one_core_each()
    assert available_cores() == 1


def test_run_beside_gives_the_calls_results_in_order_with_or_without_workers():
    here_calls = []

    def here():
        here_calls.append(1)
        return "here"

    args = [(n,) for n in (5, 0, 7, 3)]
    want = [math.factorial(n) for (n,) in args]
    for workers in (0, 1, 3):
        first, rest = run_beside(here, math.factorial, args, workers=workers)
        assert (first, rest) == ("here", want)
    assert len(here_calls) == 3
    assert run_beside(here, math.factorial, [], workers=2) == ("here", [])


def test_run_beside_raises_a_workers_exception_here():
    with pytest.raises(ValueError, match="factorial"):
        run_beside(lambda: 1, math.factorial, [(2,), (-1,)], workers=2)


def _burn(n: int) -> int:
    return sum(i * i for i in range(n))


def test_the_workers_cpu_is_counted_here():
    """A stage's CPU (the runner's ``work_cpu_s``) includes what its worker processes spent:
    each call measures its own ``process_time`` in its worker and hands it back."""
    before_workers, before = worker_cpu_seconds(), cpu_seconds()
    run_beside(lambda: None, _burn, [(300_000,), (300_000,)], workers=2)
    spent = worker_cpu_seconds() - before_workers
    assert spent > 0
    assert cpu_seconds() - before >= spent
    same = worker_cpu_seconds()
    run_beside(lambda: None, _burn, [(1000,)], workers=0)  # here: nothing sent to a worker
    assert worker_cpu_seconds() == same


def _dies_in_a_worker(n: int) -> int:
    import multiprocessing

    if multiprocessing.parent_process() is not None:  # a worker: die as an out-of-memory kill would
        os._exit(9)
    return n * 2


def test_a_worker_that_dies_costs_only_time():
    """A pool broken by a dead worker: the calls it held are made here, with the same results."""
    first, rest = run_beside(lambda: "here", _dies_in_a_worker, [(1,), (2,), (3,)], workers=2)
    assert (first, rest) == ("here", [2, 4, 6])


def _unpicklable(n: int):
    return lambda: n  # a result no worker can hand back


def test_a_result_a_worker_cannot_hand_back_is_made_here():
    first, rest = run_beside(lambda: 0, _unpicklable, [(3,), (4,)], workers=2)
    assert first == 0 and [f() for f in rest] == [3, 4]
