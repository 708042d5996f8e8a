"""What the stages of one run share (:class:`RunContext`) and what a stage is (:class:`Stage`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import polars as pl

from onebit.core.config import load_toml
from onebit.core.errors import InputError
from onebit.core.region_graph import RegionGraph
from onebit.core.site import Site
from onebit.core.tables import REJECTS
from onebit.readers.logs import CsvLog
from onebit.readers.rows import RawRows
from onebit.readers.timebase import TimeOrigin

#: A report row: (stage, metric, value, unit).
ReportRow = tuple[str, str, float, str]


def _no_progress(done: int, total: int) -> None:
    pass


@dataclass
class RunContext:
    """What the stages share during one run: the dataset, the site, the config sections, the
    tables made so far, the report rows and each stage's status.

    ``config`` holds the ``--config`` sections as given and is only read (:meth:`section`);
    what a stage resolved from its section (defaults filled in, ``n`` from the site) goes to
    ``resolved``, which the runner writes to ``run.toml``."""

    dataset: Path
    out: Path
    site: Site
    region_graph: RegionGraph
    config: dict[str, Any]
    tables: dict[str, pl.DataFrame] = field(default_factory=dict)
    report: list[ReportRow] = field(default_factory=list)
    mcap_channels: dict[str, RawRows] = field(default_factory=dict)
    trackers: tuple[str, ...] = ()
    status: dict[str, str] = field(default_factory=dict)
    #: wall-clock seconds of every stage that ran (measured by the runner, never by a stage)
    seconds: dict[str, float] = field(default_factory=dict)
    #: each tracker's config as built from its section, once per run (:func:`onebit.pipeline.tracking.tracker_config`)
    configs: dict[str, Any] = field(default_factory=dict)
    #: ``progress(done, total)`` of the running stage: the runner forwards it to its bar;
    #: trackers get it in their inputs (:data:`onebit.trackers.base.PROGRESS`)
    progress: Callable[[int, int], None] = _no_progress
    #: the sections of the dataset's own ``run.toml`` (``None``: read it on first use)
    dataset_sections: dict[str, Any] | None = None
    #: the run's one time origin (:func:`onebit.pipeline.reading.run_time_origin` computes it
    #: on first use; ``onebit follow`` sets it to the one of its first snapshot)
    time_origin: TimeOrigin | None = None
    #: each stage's config as it ran, by section (``run.toml``'s stage sections)
    resolved: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: the run's CSV logs by stem, one :class:`~onebit.readers.logs.CsvLog` each (:meth:`log`)
    csv_logs: dict[str, CsvLog] = field(default_factory=dict)

    def record(self, section: str, cfg: Any, **extra: Any) -> None:
        """Keep ``cfg`` (a config dataclass) as the resolved ``[section]`` of the run record:
        its fields that are set (``None`` is left out: TOML has no null), then ``extra``."""
        self.resolved[section] = {k: v for k, v in asdict(cfg).items() if v is not None} | extra

    def log(self, stem: str) -> CsvLog | RawRows | None:
        """The raw log ``<stem>`` (:data:`~onebit.readers.logs.Log`): the dataset's
        ``<stem>.csv`` (one :class:`~onebit.readers.logs.CsvLog` for the run, so that the
        time-origin step and the reader share its one typed read), else the rows of the MCAP
        channel ``/<stem>``, else ``None``."""
        p = self.dataset / f"{stem}.csv"
        if p.exists():
            log = self.csv_logs.get(stem)
            if log is None:
                log = self.csv_logs[stem] = CsvLog(p)
            return log
        return self.mcap_channels.get(f"/{stem}")

    def has_source(self, stem: str) -> bool:
        return (self.dataset / f"{stem}.csv").exists() or f"/{stem}" in self.mcap_channels

    def add_rejects(self, rej: pl.DataFrame | None) -> None:
        if rej is not None and rej.height:
            old = self.tables.get("rejects", pl.DataFrame(schema=REJECTS))
            self.tables["rejects"] = pl.concat([old, rej.select(REJECTS.names()).cast(dict(REJECTS))])

    def section(self, name: str) -> dict:
        """Config section ``[name]``: from ``--config`` when it has one, else from the dataset's
        own ``run.toml`` (simulators write known initial conditions there), else empty."""
        if name in self.config:
            return dict(self.config[name] or {})
        if self.dataset_sections is None:
            self.dataset_sections = dataset_run_config(self.dataset)
        section = self.dataset_sections.get(name, {})
        return dict(section) if isinstance(section, dict) else {}


def dataset_run_config(dataset: Path) -> dict[str, Any]:
    """The dataset's own ``run.toml`` (simulators write known initial conditions there), or
    ``{}``; a broken one is an :class:`InputError` naming it, never ignored."""
    p = Path(dataset) / "run.toml"
    return load_toml(p, error=InputError) if p.exists() else {}


@dataclass(frozen=True)
class Stage:
    """A named pipeline stage: what it needs, what it makes, the work and its Rerun logging.

    ``available(ctx)`` returns the reason to skip or ``None``; ``work(ctx)`` returns the tables
    it made (it may add report rows and rejects to ``ctx``); ``viz(rec, ctx, made)`` logs what
    it made to the stage's recording.

    ``makes`` names every table the stage may return (it may return fewer: a log without
    aborted passes has no ``aborted``); a name ending in ``_*`` declares every table of that
    prefix (a tracker stage makes ``<tracker>_*``). The runner checks what ``work`` returned
    (:func:`check_made`): a table not declared, one an earlier stage made, or a value that is
    not a table fails the stage, naming them.
    """

    name: str
    needs: tuple[str, ...]
    makes: tuple[str, ...]
    available: Callable[[RunContext], str | None]
    work: Callable[[RunContext], dict[str, Any]]
    viz: Callable[[Any, RunContext, dict[str, Any]], None] | None = None
    #: the config class of its ``run.toml`` section (a frozen dataclass), checked when the run starts
    config: type | None = None
    #: the work as one call that another process can make: ``detach(ctx) -> (fn, args, shares)``
    #: with ``fn(*args)`` returning what ``work(ctx)`` returns (``fn`` module-level, the
    #: arguments picklable; what it needs from ``ctx`` taken here, in this process) and
    #: ``shares`` a key or ``None``: stages of equal keys share a part of their work when made
    #: one after the other in one process, so they are kept in one call. The runner may run the
    #: detachable stages of a run side by side on the cores (trackers: pure functions of their
    #: inputs); ``None``: always ``work`` here
    detach: Callable[[RunContext], tuple[Callable[..., dict[str, Any]], tuple, Any]] | None = None
    #: ``onebit follow`` runs it at every poll on the logs read so far (the readers of the sensor
    #: logs, whose tables the trackers step over); the others run in its final batch run only
    polled: bool = False

    def declares(self, table: str) -> bool:
        """Whether ``table`` is among :attr:`makes` (by name, or by a ``prefix_*`` entry)."""
        return any(table == m or (m.endswith("_*") and table.startswith(m[:-1])) for m in self.makes)


class StageContractError(Exception):
    """A stage returned what its declaration does not allow (a bug in the stage, not bad input)."""


def check_made(stage: Stage, made: dict[str, Any], tables: dict[str, Any], *, extra: tuple[str, ...] = ()) -> None:
    """Raise :class:`StageContractError` unless every table ``stage.work`` returned (``made``;
    the keys in ``extra``, in-memory results for its viz, are not tables) is declared in
    ``stage.makes``, is a polars frame, and was not made by an earlier stage (in ``tables``)."""
    names = [k for k in made if k not in extra]
    undeclared = [k for k in names if not stage.declares(k)]
    if undeclared:
        raise StageContractError(
            f"stage '{stage.name}' returned table(s) {undeclared} it does not declare (makes = {list(stage.makes)}); "
            "declare them in its Stage (onebit/pipeline/stages.py)"
        )
    not_frames = [f"{k} ({type(made[k]).__name__})" for k in names if not isinstance(made[k], pl.DataFrame)]
    if not_frames:
        raise StageContractError(
            f"stage '{stage.name}' returned non-table value(s) {not_frames}; a stage returns polars frames"
        )
    replaced = [k for k in names if k in tables]
    if replaced:
        raise StageContractError(
            f"stage '{stage.name}' returned table(s) {replaced} that an earlier stage made; a table has one maker"
        )
