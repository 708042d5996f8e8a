"""What every tracker stage shares: the stage signature and the registry.

A stage is ``run(inputs, site, config, log) -> outputs``: ``inputs`` and ``outputs`` are
dicts of polars frames, ``config`` a frozen keyword-only dataclass validated at construction,
and ``log`` the stage's handle into :mod:`onebit.viz` (a no-op ``StageLog(None)`` in pure runs).
Stages do no file I/O and keep no state between calls.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Callable

from onebit.errors import ConfigError


@dataclass(frozen=True)
class TrackerSpec:
    """A registered tracker: name, the tables it needs, its config class and its run function."""

    name: str
    needs: tuple[str, ...]
    config: type
    run: Callable[..., dict[str, Any]]
    #: ``score(tables, site, log) -> (report_rows, tables)``, run by the ``scores`` stage when
    #: the tracker ran: ``tables`` holds every table of the run (truth, the tracker's outputs
    #: named ``<tracker>_<name>``, ...); ``report_rows`` are ``(stage, metric, value, unit)``.
    score: Callable[..., tuple[list[tuple[str, str, float, str]], dict[str, Any]]] | None = None
    #: ``available(site) -> reason to skip or None`` (e.g. the site has no motion sensors).
    available: Callable[..., str | None] | None = None
    help: str = ""
    #: optional input tables: passed in ``inputs`` when an earlier stage produced them.
    wants: tuple[str, ...] = ()


REGISTRY: dict[str, TrackerSpec] = {}


def register(spec: TrackerSpec) -> TrackerSpec:
    REGISTRY[spec.name] = spec
    return spec


def config_from_mapping(cls: type, values: dict[str, Any] | None, *, section: str):
    """Build a config dataclass from a ``run.toml`` section, naming unknown fields."""
    values = dict(values or {})
    known = {f.name for f in fields(cls)}
    for k in values:
        if k not in known:
            raise ConfigError(f"[{section}] unknown field '{k}'; known fields: {sorted(known)}")
    return cls(**values)


def check_choice(obj, name: str, allowed: tuple) -> None:
    value = getattr(obj, name)
    if value not in allowed:
        raise ConfigError(f"{type(obj).__name__}.{name} = {value!r}; allowed values: {list(allowed)}")


def check_range(obj, name: str, lo=None, hi=None, *, types=(int, float)) -> None:
    value = getattr(obj, name)
    ok = isinstance(value, types) and not isinstance(value, bool)
    ok = ok and (lo is None or value >= lo) and (hi is None or value <= hi)
    if not ok:
        raise ConfigError(f"{type(obj).__name__}.{name} = {value!r}; allowed range: [{lo}, {hi}]")
