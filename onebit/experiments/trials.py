"""Running a study's trials on an executor (serial, a local process pool or Ray).

A study lists its trials as picklable arguments of one module-level trial function that
seeds its own random generators; :func:`run_trials` runs them on the executor the user chose
(``onebit experiment NAME OUT --executor local|ray [--workers N] [--ray-address ADDR]``) and
returns the values **in the order of the trials**, so the study's tables are the same on
every executor. A study's tables hold no wall-clock times: those go to ``timings.csv``
(:func:`write_timings`), one row per trial with the worker that ran it.

A trial that raises, or whose worker died more often than the executor retries, makes the
whole study fail with :class:`StudyError` naming those trials -- after the others finished,
so the message lists every failure at once.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import polars as pl

from onebit.core import writers
from onebit.core.errors import OnebitError
from onebit.pipeline.executors import Executor, SerialExecutor, TaskOutcome, make_executor

TIMINGS = pl.Schema({"trial": pl.String, "seconds": pl.Float64, "worker": pl.String})


class StudyError(OnebitError):
    """Trials of a study failed; the message names them and their errors."""


def resolve_executor(executor: Executor | None, workers: int | None = None) -> Executor:
    """The executor given, else ``workers`` > 1 -> a local pool of that size, else serial."""
    if executor is not None:
        return executor
    if workers is not None and workers > 1:
        return make_executor("local", workers=workers)
    return SerialExecutor()


def run_trials(
    fn: Callable[[Any], Any],
    trials: Sequence[Any],
    *,
    executor: Executor | None,
    label: Callable[[Any], str],
    echo: Callable[[str], None],
    study: str,
) -> tuple[list[Any], pl.DataFrame]:
    """``fn(trial)`` for every trial on ``executor`` (``None``: serial). Returns the values in
    the trials' order and a timings frame (:data:`TIMINGS`). Raises :class:`StudyError` when
    any trial failed."""
    executor = executor or SerialExecutor()
    n = len(trials)
    echo(f"{study}: {n} trial(s) on {executor.describe()}")
    count = 0

    def progress(o: TaskOutcome) -> None:
        nonlocal count
        count += 1
        state = f"{o.seconds:.1f} s" if o.ok else f"FAILED: {o.error}"
        echo(f"  [{count}/{n}] {label(trials[o.index])}: {state}")

    outcomes = executor.map(fn, trials, on_done=progress)
    bad = [o for o in outcomes if not o.ok]
    if bad:
        lines = [f"  {label(trials[o.index])}: {o.error}" for o in bad[:10]]
        more = f"\n  ... and {len(bad) - 10} more" if len(bad) > 10 else ""
        tb = next((o.traceback for o in bad if o.traceback), None)
        raise StudyError(
            f"{study}: {len(bad)} of {n} trial(s) failed:\n"
            + "\n".join(lines)
            + more
            + (f"\nfirst traceback:\n{tb}" if tb else "")
        )
    timings = pl.DataFrame(
        [{"trial": label(trials[o.index]), "seconds": o.seconds, "worker": o.worker} for o in outcomes], schema=TIMINGS
    )
    return [o.value for o in outcomes], timings


def format_table(df: pl.DataFrame) -> str:
    """A study's summary for the terminal: every column, no shape line."""
    with pl.Config(tbl_cols=-1, tbl_rows=-1, tbl_width_chars=200, tbl_hide_dataframe_shape=True, fmt_str_lengths=40):
        return str(df)


def write_timings(timings: pl.DataFrame, out: Path) -> None:
    """``out/timings.csv``: the one file of a study that differs from run to run."""
    writers.write_csv(timings, Path(out) / "timings.csv")
