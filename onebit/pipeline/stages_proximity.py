"""The ``proximity`` reader stage: ``proximity.csv`` or the ``/proximity`` MCAP channel ->
tables ``proximity`` (accepted edges), ``proximity_frames`` (readings at the instants of the
``[proximity]`` config) and ``proximity_suppressed`` (edges the debounce removed).

The ``[proximity]`` section comes from ``--config``; when that has none, from the dataset's
own ``run.toml`` (the simulators write the instants there), else the defaults.
"""

from __future__ import annotations

import tomllib
from dataclasses import asdict

import polars as pl

from onebit.errors import InputError
from onebit.pipeline.runner import RunContext, Stage
from onebit.readers.proximity import TOGGLE_COLUMNS, ProximityConfig, proximity_frames, read_proximity
from onebit.trackers.base import config_from_mapping


def _available(ctx: RunContext) -> str | None:
    if not ctx.site.proximity_sensors:
        return "site.toml has no proximity sensors"
    if not ctx.has_source("proximity"):
        return "no proximity.csv or /proximity MCAP channel in the dataset"
    return None


def _section(ctx: RunContext) -> dict:
    if "proximity" in ctx.config:
        return ctx.config["proximity"]
    p = ctx.dataset / "run.toml"
    if p.exists():
        try:
            return dict(tomllib.loads(p.read_text(encoding="utf-8")).get("proximity", {}))
        except tomllib.TOMLDecodeError as exc:  # a broken run.toml is reported, never ignored
            raise InputError(f"not valid TOML: {exc}", file=p) from None
    return {}


def _work(ctx: RunContext, log) -> dict[str, pl.DataFrame]:
    cfg = config_from_mapping(ProximityConfig, _section(ctx), section="proximity")
    ctx.config.setdefault("proximity", {}).update(asdict(cfg))
    ids = [p.id for p in ctx.site.proximity_sensors]
    raw, path = ctx.source("proximity", TOGGLE_COLUMNS)
    res = read_proximity(raw, ids, epoch=ctx.site.epoch, path=path, rules=cfg.rules)
    ctx.add_rejects(res.rejects)
    frames = proximity_frames(
        res.motion,
        ids,
        period=cfg.period,
        start=None if cfg.start < 0 else cfg.start,
        instants=cfg.instants or None,
    )
    ctx.report += [
        ("proximity", "edges", float(res.motion.height), "edges"),
        ("proximity", "suppressed", float(res.suppressed.height), "edges"),
        ("proximity", "rejected", float(res.rejects.height), "rows"),
        ("proximity", "instants", float(frames["slot"].n_unique()) if frames.height else 0.0, "instants"),
    ]
    return {"proximity": res.motion, "proximity_frames": frames, "proximity_suppressed": res.suppressed}


STAGES = [Stage("proximity", (), ("proximity", "proximity_frames", "proximity_suppressed"), _available, _work)]
