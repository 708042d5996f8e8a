"""What the stages of one run share (:class:`RunContext`) and what a stage is (:class:`Stage`)."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import polars as pl

from onebit.core.errors import InputError
from onebit.core.region_graph import RegionGraph
from onebit.core.site import Site
from onebit.core.tables import REJECTS
from onebit.readers.rows import RawRows, read_csv_rows

#: A report row: (stage, metric, value, unit).
ReportRow = tuple[str, str, float, str]


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

    def source(self, stem: str, columns: tuple[str, ...]) -> tuple[RawRows, Path | None] | None:
        """String rows of ``<stem>.csv`` in the dataset, else of the MCAP channel ``/<stem>``."""
        p = self.dataset / f"{stem}.csv"
        if p.exists():
            return read_csv_rows(p, columns), p
        if f"/{stem}" in self.mcap_channels:
            return self.mcap_channels[f"/{stem}"], None
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
        p = self.dataset / "run.toml"
        if p.exists():
            try:
                section = tomllib.loads(p.read_text(encoding="utf-8")).get(name, {})
            except tomllib.TOMLDecodeError as exc:  # a broken run.toml is reported, never ignored
                raise InputError(f"not valid TOML: {exc}", file=p) from None
            return dict(section) if isinstance(section, dict) else {}
        return {}


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
