"""A tracker's stage: its config, its inputs, its work (here or in a worker) and its recording.

The stage list (:mod:`onebit.pipeline.stages`) declares one :class:`TrackerEntry` per tracker;
:func:`tracker_stage` makes its :class:`~onebit.pipeline.context.Stage`. ``onebit follow``
takes a tracker's config and inputs from here too (:func:`tracker_config`,
:func:`tracker_inputs`), so a tracker is fed the same way live and in a batch run.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import polars as pl

from onebit.core.config import config_from_mapping
from onebit.core.units import config_in_site_units
from onebit.pipeline import stages as declaration  # without_ignored, the reader stages' helper (read at call time)
from onebit.pipeline.context import RunContext, Stage
from onebit.pipeline.homes import people_from_tracks
from onebit.trackers.base import ARTIFACTS, PROGRESS
from onebit.viz import occupancy as viz_occupancy

if TYPE_CHECKING:
    from onebit.pipeline.stages import TrackerEntry


def tracker_config(entry: TrackerEntry, ctx: RunContext):
    """The tracker's config from its ``run.toml`` section (``--config``, else the dataset's own
    ``run.toml``: :meth:`RunContext.section`), its lengths in the site's units. Built once per
    run: the config as built is kept in ``ctx.configs`` (the run record writes it)."""
    cfg = ctx.configs.get(entry.name)
    if cfg is None:
        cfg = ctx.configs[entry.name] = config_from_mapping(
            entry.spec.config, ctx.section(entry.name), section=entry.name
        )
    return config_in_site_units(cfg, ctx.site)


def tracker_inputs(entry: TrackerEntry, ctx: RunContext, *, until: float | None = None) -> dict[str, Any] | None:
    """The tracker's input tables from ``ctx.tables`` (its ``needs``, first present source wins,
    and the ``wants`` present), without the rows of ignored sensors
    (:func:`onebit.pipeline.stages.without_ignored`), each cut at ``t <= until`` (``None``:
    whole; ``onebit follow`` re-runs a tracker on the settled prefix), with the region graph
    and the progress callback; ``None`` when a table it needs is missing. The tracker is run on
    ``ctx.site.tracked`` (no ignored sensor)."""
    ignored = ctx.site.ignored

    def table(name: str) -> pl.DataFrame:
        df = declaration.without_ignored(name, ctx.tables[name], ignored)
        return df if until is None or "t" not in df.columns else df.filter(pl.col("t") <= until)

    inputs: dict[str, Any] = {}
    for key in entry.spec.needs:
        src = next((s for s in entry.inputs.get(key, (key,)) if s in ctx.tables), None)
        if src is None:
            return None
        inputs[key] = table(src)
    inputs.update({k: table(k) for k in entry.spec.wants if k in ctx.tables})
    inputs["region_graph"] = ctx.region_graph
    inputs[PROGRESS] = ctx.progress
    return inputs


def detached_tracker(
    name: str, run: Callable, inputs: dict[str, Any], site, cfg, counts_people: bool = False
) -> dict[str, Any]:
    """A tracker stage's work on inputs taken from the run (:func:`tracker_inputs`): its
    tables named ``<tracker>_<table>``, its artifacts as they are. The stage's ``work`` is this
    call in the run's process; its ``detach`` hands the same call to a worker process. A
    multi-person tracker (``counts_people``) that writes no ``people`` gets it from its tracks
    (:func:`onebit.pipeline.homes.people_from_tracks`)."""
    out = run(inputs, site, cfg)
    if counts_people and "people" not in out:
        out = {**out, "people": people_from_tracks(out.get("tracks"))}
    made: dict[str, Any] = {f"{name}_{k}": v for k, v in out.items() if k != ARTIFACTS}
    if ARTIFACTS in out:
        made[ARTIFACTS] = out[ARTIFACTS]
    return made


class _TrackerStage:
    """The functions of one tracker's :class:`Stage` (:func:`tracker_stage`)."""

    def __init__(self, entry: TrackerEntry) -> None:
        self.entry = entry
        self.name = entry.name
        self.spec = entry.spec

    def available(self, ctx: RunContext) -> str | None:
        name, spec = self.name, self.spec
        if name not in ctx.trackers:
            return f"tracker '{name}' not selected (--trackers)"
        for key in spec.needs:
            if not any(s in ctx.tables for s in self.entry.inputs.get(key, (key,))):
                return f"input table '{key}' not produced by an earlier stage"
        if not spec.needs and spec.wants and not any(k in ctx.tables for k in spec.wants):
            return f"none of its input tables ({', '.join(spec.wants)}) was produced by an earlier stage"
        site = ctx.site.tracked
        reason = spec.available(site) if spec.available is not None else None
        if reason is None and spec.fits is not None:  # the inputs' size against the tracker's bound
            reason = spec.fits(tracker_inputs(self.entry, ctx), site, tracker_config(self.entry, ctx))
        return reason

    def work(self, ctx: RunContext) -> dict[str, Any]:
        fn, args, _ = self.detach(ctx)
        return fn(*args)

    def detach(self, ctx: RunContext) -> tuple[Callable[..., dict[str, Any]], tuple, Any]:
        cfg = tracker_config(self.entry, ctx)
        ctx.record(self.name, ctx.configs[self.name])
        shares = self.spec.shares(cfg) if self.spec.shares is not None else None
        args = (
            self.name,
            self.spec.run,
            tracker_inputs(self.entry, ctx),
            ctx.site.tracked,
            cfg,
            self.spec.counts_people,
        )
        return detached_tracker, args, shares

    def viz(self, rec, ctx: RunContext, made: dict) -> None:
        name, entry = self.name, self.entry
        out = {k[len(name) + 1 :]: v for k, v in made.items() if k.startswith(f"{name}_")}
        if ARTIFACTS in made:
            out[ARTIFACTS] = made[ARTIFACTS]
        # every tracker's people present, one step series the summary tab plots against the truth
        viz_occupancy.log_people(rec, name, out.get("people"), rgb=entry.drawn.rgb)
        if entry.viz is None:
            return
        entry.viz(
            rec,
            name,
            out,
            site=ctx.site.tracked,
            region_graph=ctx.region_graph,
            config=tracker_config(entry, ctx),
            tables=ctx.tables,
            look=entry.drawn,
        )


def tracker_stage(entry: TrackerEntry) -> Stage:
    """The stage of a tracker: it needs its spec's ``needs`` (each from the first present of its
    ``entry.inputs`` sources), makes ``<tracker>_tracks`` and ``<tracker>_*``; its work can be
    detached to a worker process (:mod:`onebit.pipeline.detach`)."""
    st = _TrackerStage(entry)
    name = entry.name
    return Stage(
        name,
        entry.spec.needs,
        (f"{name}_tracks", f"{name}_*"),
        st.available,
        st.work,
        st.viz,
        config=entry.spec.config,
        detach=st.detach,
    )
