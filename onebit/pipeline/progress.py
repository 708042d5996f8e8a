"""Progress on the terminal: which stage is running, and how far it is inside the stage.

The runner tells a :class:`ProgressSink` when a stage starts (:meth:`~ProgressSink.stage`)
and forwards the stage's own reports (:meth:`~ProgressSink.step`: ``done`` of ``total``
iterations, windows, ...) from the callback it hands to trackers in their inputs
(:data:`onebit.trackers.base.PROGRESS`); trackers stay pure: they call a function they were
given and know nothing of terminals. :func:`progress_sink` picks the terminal bar (``rich``,
only on an interactive terminal and never in CI) or a silent sink; tests pass a recorder.
"""

from __future__ import annotations

import os
import sys
from typing import Protocol

from rich.console import Console
from rich.progress import BarColumn, Progress, SpinnerColumn, TaskProgressColumn, TextColumn, TimeElapsedColumn


class ProgressSink(Protocol):
    """What the runner reports to."""

    def stage(self, name: str, index: int, total: int) -> None:
        """Stage ``name`` (``index`` of ``total``, 0-based) starts."""

    def step(self, done: int, total: int) -> None:
        """The running stage has done ``done`` of its ``total`` steps."""

    def close(self) -> None:
        """The run is over."""


class Silent:
    """A sink that shows nothing (not a terminal, CI, ``progress=False``)."""

    def stage(self, name: str, index: int, total: int) -> None:
        pass

    def step(self, done: int, total: int) -> None:
        pass

    def close(self) -> None:
        pass


class RichBar:
    """A ``rich`` bar over the stages; it names the running stage and moves inside it."""

    def __init__(self, title: str = "stages") -> None:
        self.p = Progress(
            SpinnerColumn(),
            TextColumn("{task.description}"),
            BarColumn(),
            TaskProgressColumn(),
            TimeElapsedColumn(),
            transient=True,
            console=Console(stderr=True),
        )
        self.p.start()
        self.task = self.p.add_task(title, total=None)
        self.name = title
        self.index = 0

    def stage(self, name: str, index: int, total: int) -> None:
        self.name, self.index = name, index
        self.p.update(self.task, total=total, completed=index, description=f"{name} ({index + 1}/{total})")

    def step(self, done: int, total: int) -> None:
        if total > 0:
            frac = min(max(done / total, 0.0), 1.0)
            self.p.update(self.task, completed=self.index + frac, description=f"{self.name}: {done}/{total}")

    def close(self) -> None:
        self.p.stop()


class Spinner:
    """An indeterminate ``rich`` status line with the elapsed time, for work without steps
    (``onebit simulate``): ``with Spinner("simulating beams-lab"): ...``."""

    def __init__(self, what: str, *, enabled: bool | None = None) -> None:
        self.what = what
        self.enabled = interactive() if enabled is None else enabled
        self.p: Progress | None = None

    def __enter__(self) -> Spinner:
        if self.enabled:
            self.p = Progress(
                SpinnerColumn(),
                TextColumn("{task.description}"),
                TimeElapsedColumn(),
                transient=True,
                console=Console(stderr=True),
            )
            self.p.start()
            self.p.add_task(self.what, total=None)
        return self

    def __exit__(self, *exc) -> None:
        if self.p is not None:
            self.p.stop()


def interactive() -> bool:
    """Show progress: stderr is a terminal and this is not CI (``CI`` unset)."""
    return sys.stderr.isatty() and not os.environ.get("CI")


def progress_sink(progress: bool | ProgressSink | None) -> ProgressSink:
    """The sink for ``run_pipeline(progress=...)``: ``None`` = a bar when :func:`interactive`,
    ``True`` / ``False`` = a bar / nothing, or a sink of the caller's."""
    if progress is None:
        progress = interactive()
    if progress is True:
        return RichBar()
    if progress is False:
        return Silent()
    return progress
