"""What the stages of one run share (:class:`RunContext`) and what a stage is (:class:`Stage`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import polars as pl

from onebit.core.config import load_toml
from onebit.core.errors import InputError
from onebit.core.region_graph import RegionGraph
from onebit.core.site import Site
from onebit.core.tables import REJECTS
from onebit.readers.rows import RawRows, read_csv_column, read_csv_rows

#: A report row: (stage, metric, value, unit).
ReportRow = tuple[str, str, float, str]


def _no_progress(done: int, total: int) -> None:
    pass


@dataclass
class RunContext:
    """What the stages share during one run: the dataset, the site, the config sections, the
    tables made so far, the report rows and each stage's status."""

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
    #: each tracker's resolved config (lengths in the site's units), for its viz function
    configs: dict[str, Any] = field(default_factory=dict)
    #: ``progress(done, total)`` of the running stage: the runner forwards it to its bar;
    #: trackers get it in their inputs (:data:`onebit.trackers.base.PROGRESS`)
    progress: Callable[[int, int], None] = _no_progress
    #: the sections of the dataset's own ``run.toml`` (``None``: read it on first use)
    dataset_sections: dict[str, Any] | None = None
    #: typed reads of the dataset's CSV logs made for the time origin, by stem (``beams``,
    #: ``motion``, ``proximity``), taken by their reader stage: each file is read once
    typed_reads: dict[str, Any] = field(default_factory=dict)

    def source(self, stem: str, columns: tuple[str, ...]) -> tuple[RawRows, Path | None] | None:
        """String rows of ``<stem>.csv`` in the dataset, else of the MCAP channel ``/<stem>``."""
        p = self.dataset / f"{stem}.csv"
        if p.exists():
            return read_csv_rows(p, columns), p
        if f"/{stem}" in self.mcap_channels:
            return self.mcap_channels[f"/{stem}"], None
        return None

    def stamps(self, stem: str) -> tuple[str, pl.DataFrame] | None:
        """(source name, ``line`` + String ``t``) of ``<stem>.csv`` (typed in one read when it
        can, :func:`~onebit.readers.rows.read_csv_column`), else of the MCAP channel."""
        p = self.dataset / f"{stem}.csv"
        if p.exists():
            return p.name, read_csv_column(p, "t")
        if f"/{stem}" in self.mcap_channels:
            raw = self.mcap_channels[f"/{stem}"]
            return raw.source, raw.frame
        return None

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
    """

    name: str
    needs: tuple[str, ...]
    makes: tuple[str, ...]
    available: Callable[[RunContext], str | None]
    work: Callable[[RunContext], dict[str, Any]]
    viz: Callable[[Any, RunContext, dict[str, Any]], None] | None = None
    #: the config class of its ``run.toml`` section (a frozen dataclass), checked when the run starts
    config: type | None = None
