"""The ``motion`` reader stage: ``motion.csv`` (or the ``/motion`` MCAP channel) -> tables.

Makes ``motion`` (accepted edges, MOTION), ``frames`` (FRAMES at ``[motion] period``) and
``motion_suppressed`` (edges removed by the debounce rules). Debounce rules come, per
sensor, from the sensor's type in ``site.toml`` (``[sensor_types.<type>]`` keys
``chatter_window`` and ``min_on``); ``run.toml`` ``[motion]`` keys of the same names, when
set, apply to every sensor instead.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import polars as pl

from onebit.errors import ConfigError
from onebit.pipeline.runner import RunContext, Stage
from onebit.readers.motion import TOGGLE_COLUMNS, DebounceRules, motion_frames, read_motion
from onebit.trackers.base import config_from_mapping


@dataclass(frozen=True, kw_only=True)
class MotionConfig:
    """``run.toml`` ``[motion]``.

    period : slot length of the ``frames`` table (s).
    chatter_window : relay-chatter window (s) for every sensor; ``None`` = from the sensor type.
    min_on : minimum on-time (s) for every sensor; ``None`` = from the sensor type.
    """

    period: float = 1.0
    chatter_window: float | None = None
    min_on: float | None = None

    def __post_init__(self) -> None:
        p = self.period
        if isinstance(p, bool) or not isinstance(p, (int, float)) or not math.isfinite(p) or p <= 0:
            raise ConfigError(f"MotionConfig.period = {p!r}; allowed range: (0, inf) seconds")
        for name in ("chatter_window", "min_on"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0):
                raise ConfigError(f"MotionConfig.{name} = {v!r}; allowed range: [0, inf) seconds")


def site_rules(site, cfg: MotionConfig) -> dict[str, DebounceRules]:
    """Per-sensor debounce rules: the sensor type's, overridden by ``cfg`` where set."""
    out: dict[str, DebounceRules] = {}
    for ms in site.motion_sensors:
        typ = site.sensor_types.get(ms.type, {}) if isinstance(site.sensor_types, dict) else {}
        vals = {k: typ[k] for k in ("chatter_window", "min_on") if k in typ}
        for k in ("chatter_window", "min_on"):
            if getattr(cfg, k) is not None:
                vals[k] = getattr(cfg, k)
        try:
            out[ms.id] = DebounceRules(**vals)
        except ConfigError as exc:
            raise ConfigError(f"site.toml [sensor_types.{ms.type}]: {exc}") from None
    return out


def _available(ctx: RunContext) -> str | None:
    if not ctx.has_source("motion"):
        return "no motion.csv or /motion MCAP channel in the dataset"
    if not ctx.site.motion_sensors:
        return "motion log present but site.toml has no [[motion_sensors]]"
    return None


def _work(ctx: RunContext, log) -> dict[str, pl.DataFrame]:
    cfg = config_from_mapping(MotionConfig, ctx.config.get("motion"), section="motion")
    ctx.config.setdefault("motion", {}).update({k: v for k, v in asdict(cfg).items() if v is not None})
    site = ctx.site
    ids = [m.id for m in site.motion_sensors]
    raw, path = ctx.source("motion", TOGGLE_COLUMNS)
    res = read_motion(raw, ids, epoch=site.epoch, path=path, rules=site_rules(site, cfg))
    ctx.add_rejects(res.rejects)
    frames = motion_frames(res.motion, ids, period=cfg.period)
    ctx.report += [
        ("motion", "edges", float(res.motion.height), "edges"),
        ("motion", "suppressed", float(res.suppressed.height), "edges"),
        ("motion", "rejected", float(res.rejects.height), "rows"),
    ]
    from onebit.viz.intruder import log_motion_states

    log.emit(log_motion_states, res.motion, ids)
    return {"motion": res.motion, "frames": frames, "motion_suppressed": res.suppressed}


STAGES = [Stage("motion", (), ("motion", "frames", "motion_suppressed"), _available, _work)]
