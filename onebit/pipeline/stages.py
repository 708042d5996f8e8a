"""The declared pipeline: every stage, in order, with what it needs and what it makes.

::

    crossings  beams.csv | crossings.csv   -> crossings, aborted, beam_events
    truth      truth.csv                   -> truth, true_crossings, sim_crossings
    truth_events truth_events.csv          -> truth_events (per-event identity truth: t, sensor, residents)
    residents_profile residents_profile.csv -> residents_profile (known residents, learned from labelled days)
    camera     camera.mp4                  -> camera_truth, camera_detections
    frames     frames.csv (frame-sampled)  -> levels, motion, proximity, proximity_frames
    motion     motion.csv                  -> motion, motion_suppressed   (skipped with frames.csv)
    proximity  proximity.csv               -> proximity, proximity_frames, proximity_suppressed
    ignore     site.toml ignore = true     -> ignored (rows of ignored sensors the trackers will not see)
    correct    crossings                   -> corrected_crossings, correct_insertions, correct_initial
    <tracker>  its TrackerSpec.needs       -> <tracker>_tracks, <tracker>_<table>...   (one per TRACKERS entry)
    scores     everything above            -> crossing_matches, <tracker>_scores, ...

Each stage's ``makes`` is checked by the runner (:func:`onebit.pipeline.context.check_made`):
a stage returning a table it does not declare, or one an earlier stage made, fails.

The work of the reader stages (a raw log -> its tables) is in :mod:`onebit.pipeline.reading`;
this file only declares them.

Adding a tracker: its package under :mod:`onebit.trackers` (a ``TrackerSpec``), a scoring
function in :mod:`onebit.scoring` (built on :mod:`onebit.scoring.association`; the MOT metrics
of :mod:`onebit.scoring.mot` are added for every tracker), a ``log_run`` in :mod:`onebit.viz`
-- and one :class:`TrackerEntry` line in :data:`TRACKERS` (``docs/extending.md``). No
registry, no plugin loading: this file is the whole list.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import polars as pl

from onebit.core.config import config_from_mapping
from onebit.core.errors import OnebitError
from onebit.core.tables import REJECTS
from onebit.core.units import config_in_site_units
from onebit.models.occupancy import OccupancyConfig
from onebit.pipeline import homes, reading
from onebit.pipeline.context import ReportRow, RunContext, Stage
from onebit.pipeline.homes import count_metric, count_rows, people_from_tracks
from onebit.pipeline.reading import TIME_SOURCES, run_time_origin, without_ignored  # noqa: F401  (the first two for follow)
from onebit.readers.motion import MotionConfig
from onebit.readers.proximity import ProximityConfig
from onebit.scoring import beams as score_beams
from onebit.scoring import binpf as score_binpf
from onebit.scoring import clustertrack as score_clustertrack
from onebit.scoring import findinghumo as score_findinghumo
from onebit.scoring import intruder as score_intruder
from onebit.scoring import istate as score_istate
from onebit.scoring import residents as score_residents
from onebit.scoring.crossings import ScoresConfig, score_crossings
from onebit.scoring.identity import baseline_rows, graph_hops, identity_scores
from onebit.scoring.mot import Gate, mot_rows
from onebit.scoring.serve import CannotServe
from onebit.trackers import beams, binpf, clustertrack, findinghumo, findinghumo_flow, intruder, istate, residents
from onebit.trackers.base import ARTIFACTS, PROGRESS, TrackerSpec
from onebit.trackers.beams.correction import CorrectConfig
from onebit.viz import beams as viz_beams
from onebit.viz import binpf as viz_binpf
from onebit.viz import clustertrack as viz_clustertrack
from onebit.viz import findinghumo as viz_findinghumo
from onebit.viz import intruder as viz_intruder
from onebit.viz import istate as viz_istate
from onebit.viz import occupancy as viz_occupancy
from onebit.viz import residents as viz_residents
from onebit.viz.families import Look
from onebit.viz.tracks import log_scores

#: ``score(tracker, tables, site, region_graph) -> (report rows, tables)``
ScoreFn = Callable[..., tuple[list[ReportRow], dict[str, pl.DataFrame]]]
#: ``log_run(rec, tracker, outputs, *, site, region_graph, config, tables, look)``
VizFn = Callable[..., None]
#: ``metric(tracker, tables, site, region_graph) -> report rows``: a metric the scores stage
#: adds for every tracker that ran (``[]`` when the run lacks what it needs)
MetricFn = Callable[[str, dict[str, pl.DataFrame], Any, Any], list[ReportRow]]


@dataclass(frozen=True)
class TrackerEntry:
    """One tracker in the pipeline, declared once: the tracker, how it is scored, its MOT gate,
    how it is logged and the scenario it is tested on.

    ``inputs`` maps an input name of the tracker to the tables that may feed it, first
    present wins (the beams tracker reads the corrected crossings when the ``correct``
    stage made them, else the decoded ones).
    """

    spec: TrackerSpec
    score: ScoreFn
    viz: VizFn | None = None
    inputs: dict[str, tuple[str, ...]] = field(default_factory=dict)
    #: the MOT gate of its tracks (:class:`onebit.scoring.mot.Gate`); ``None`` = no MOT rows
    gate: Gate | None = None
    #: the built-in scenario (``onebit simulate NAME``) the tests run it on: the contract tests
    #: of the trackers and of the scorers (``None``: no scenario serves it)
    scenario: str | None = None
    #: how its recordings and its blueprint tab look: family and colour
    #: (:class:`onebit.viz.families.Look`; the error unit is set from ``gate``, see :attr:`drawn`)
    look: Look = field(default_factory=Look)

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def drawn(self) -> Look:
        """:attr:`look` with its error unit from the MOT gate: a gate in hops is an error plot in hops."""
        return replace(self.look, hops=self.gate is not None and self.gate.unit == "hops")


#: The MOT gates the papers share (``TrackerEntry.gate``; docs/metrics.md, "Standard MOT metrics").
CELLS_GATE = Gate(
    "point",
    2.0,
    "cells",
    "Schiff & Goldberg score in grid cells; 'within two world-space cells' is their accuracy criterion "
    "(VIII: perfect sensors put every estimate there) and the intruder's bounding prism is 2 cells wide",
)
HOPS_GATE = Gate(
    "node", 1.0, "hops", "De et al. score hops on the sensor graph; 1 hop = the adjacent sensor, the PIR's resolution"
)

#: Colours of the FindingHuMo decoder and its two baselines (one entry each, made in a loop below).
FINDINGHUMO_RGB: dict[str, tuple[int, int, int]] = {
    "findinghumo": (255, 200, 60),
    "hmm1": (90, 200, 255),
    "hmm2": (240, 110, 200),
}

#: Every tracker, in the order their stages run.
TRACKERS: tuple[TrackerEntry, ...] = (
    TrackerEntry(
        beams.SPEC,
        score_beams.score,
        viz_beams.log_run,
        {"crossings": ("corrected_crossings", "crossings")},
        Gate(
            "region", 1.0, "hops", "Bobadilla et al. localise to a region; 1 hop = the adjacent region, one beam away"
        ),
        scenario="beams-lab",
        look=Look("beams", (64, 196, 255)),
    ),
    TrackerEntry(
        intruder.SPEC,
        score_intruder.score,
        viz_intruder.log_run,
        gate=CELLS_GATE,
        scenario="pir14",
        look=Look("intruder", (70, 225, 110)),
    ),
    TrackerEntry(
        intruder.NAIVE_SPEC,
        score_intruder.score,
        viz_intruder.log_run,
        gate=CELLS_GATE,
        scenario="pir14",
        look=Look("intruder", (200, 120, 255)),
    ),
    TrackerEntry(
        clustertrack.SPEC,
        score_clustertrack.score,
        viz_clustertrack.log_run,
        gate=Gate(
            "point",
            1.0,
            "R",
            "Singh et al. report error in units of the sensing radius R; within R the target is resolved",
        ),
        scenario="proximity-line",
        look=Look("clustertrack", (255, 160, 40)),
    ),
    TrackerEntry(
        binpf.SPEC,
        score_binpf.score,
        viz_binpf.log_run,
        gate=Gate(
            "point",
            1.0,
            "m",
            "beyond the papers: a metric gate in world units; 1 m is about half the spacing of a ceiling "
            "array (Milan et al. score at 1.5 m)",
        ),
        scenario="proximity-grid",
        look=Look("binpf", (255, 110, 90)),
    ),
    *(
        TrackerEntry(
            spec,
            score_findinghumo.score,
            viz_findinghumo.log_run,
            gate=HOPS_GATE,
            scenario="hallway",
            look=Look("findinghumo", FINDINGHUMO_RGB[spec.name]),
        )
        for spec in findinghumo.SPECS
    ),
    TrackerEntry(
        findinghumo_flow.SPEC,
        score_findinghumo.score,
        viz_findinghumo.log_run,
        gate=HOPS_GATE,
        scenario="hallway",
        look=Look("findinghumo", (120, 240, 200)),
    ),
    TrackerEntry(
        istate.SPEC,
        score_istate.score,
        viz_istate.log_run,
        gate=Gate(
            "point",
            1.0,
            "sensing radius",
            "O'Kane's I-state has no unit of its own; a point summary within one "
            "sensing radius is what the sensors can tell apart",
        ),
        scenario="istate-room",
        look=Look("istate", (255, 235, 130)),
    ),
    TrackerEntry(
        residents.SPEC,
        score_residents.score,
        viz_residents.log_run,
        gate=Gate(
            "point",
            1.0,
            "sensing radius",
            "the residents tracker places each person at the sensor of their latest "
            "event: within one sensing radius the sensor covers them",
        ),
        scenario="hallway",
        look=Look("residents", (255, 140, 120)),
    ),
)

#: How every tracker is drawn, by name (:attr:`TrackerEntry.drawn`): what the viz and the
#: blueprint are given.
LOOKS: dict[str, Look] = {e.name: e.drawn for e in TRACKERS}


def tracker_names(entries: tuple[TrackerEntry, ...] = TRACKERS) -> tuple[str, ...]:
    return tuple(e.name for e in entries)


# --------------------------------------------------------------------------- trackers


def tracker_config(entry: TrackerEntry, ctx: RunContext):
    """The tracker's config from its ``run.toml`` section (``--config``, else the dataset's own
    ``run.toml``: :meth:`RunContext.section`), its lengths in the site's units."""
    cfg = config_from_mapping(entry.spec.config, ctx.section(entry.name), section=entry.name)
    ctx.record(entry.name, cfg)
    return config_in_site_units(cfg, ctx.site)


def tracker_inputs(entry: TrackerEntry, ctx: RunContext) -> dict[str, Any]:
    """The tracker's input tables (its ``needs``, first present source wins, and ``wants``),
    without the rows of ignored sensors (:func:`without_ignored`), the region graph and the
    progress callback. The tracker is run on ``ctx.site.tracked`` (no ignored sensor)."""
    ignored = ctx.site.ignored
    inputs: dict[str, Any] = {}
    for key in entry.spec.needs:
        sources = entry.inputs.get(key, (key,))
        src = next(s for s in sources if s in ctx.tables)
        inputs[key] = without_ignored(src, ctx.tables[src], ignored)
    inputs.update({k: without_ignored(k, ctx.tables[k], ignored) for k in entry.spec.wants if k in ctx.tables})
    if "levels" in ctx.tables:  # a frame log: every sensor's reading at every frame, for any tracker that reads it
        inputs.setdefault("levels", without_ignored("levels", ctx.tables["levels"], ignored))
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


def tracker_stage(entry: TrackerEntry) -> Stage:
    name = entry.name
    spec = entry.spec

    def available(ctx: RunContext) -> str | None:
        if name not in ctx.trackers:
            return f"tracker '{name}' not selected (--trackers)"
        for key in spec.needs:
            if not any(s in ctx.tables for s in entry.inputs.get(key, (key,))):
                return f"input table '{key}' not produced by an earlier stage"
        if not spec.needs and spec.wants and not any(k in ctx.tables for k in spec.wants):
            return f"none of its input tables ({', '.join(spec.wants)}) was produced by an earlier stage"
        site = ctx.site.tracked
        reason = spec.available(site) if spec.available is not None else None
        if reason is None and spec.fits is not None:  # the inputs' size against the tracker's bound
            cfg = config_in_site_units(config_from_mapping(spec.config, ctx.section(name), section=name), site)
            reason = spec.fits(tracker_inputs(entry, ctx), site, cfg)
        return reason

    def work(ctx: RunContext) -> dict[str, Any]:
        fn, args, _ = detach(ctx)
        return fn(*args)

    def detach(ctx: RunContext) -> tuple[Callable[..., dict[str, Any]], tuple, Any]:
        cfg = ctx.configs[name] = tracker_config(entry, ctx)
        shares = spec.shares(cfg) if spec.shares is not None else None
        args = (name, spec.run, tracker_inputs(entry, ctx), ctx.site.tracked, cfg, spec.counts_people)
        return detached_tracker, args, shares

    def viz(rec, ctx: RunContext, made: dict) -> None:
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
            config=ctx.configs[name],
            tables=ctx.tables,
            look=entry.drawn,
        )

    return Stage(name, (), (f"{name}_tracks", f"{name}_*"), available, work, viz, config=spec.config, detach=detach)


# --------------------------------------------------------------------------- scores


def identity_metric(tracker: str, tables: dict[str, pl.DataFrame], site, region_graph) -> list[ReportRow]:
    """Identity per event (:func:`onebit.scoring.identity.identity_scores`, docs/metrics.md) of a
    tracker that wrote ``<tracker>_events``, when the dataset has ``truth_events``."""
    te, ev = tables.get("truth_events"), tables.get(f"{tracker}_events")
    if te is None or not te.height or ev is None:
        return []
    return identity_scores(te, ev, tracks=tables.get(f"{tracker}_tracks")).rows(tracker)


#: The metrics of every tracker beyond its own (``TrackerEntry.score``) and the MOT rows: one
#: line per metric (docs/extending.md, "A report metric").
METRICS: tuple[MetricFn, ...] = (identity_metric, count_metric)


def scores_stage(trackers: tuple[TrackerEntry, ...] = TRACKERS, metrics: tuple[MetricFn, ...] | None = None) -> Stage:
    """The ``scores`` stage: crossings against the truth, then every tracker that ran ok: its
    paper's metrics (``entry.score``), the standard MOT metrics (:func:`onebit.scoring.mot.mot_rows`)
    and every metric of ``metrics`` (default :data:`METRICS`), then the identity baselines."""

    def work(ctx: RunContext) -> dict[str, pl.DataFrame]:
        cfg = config_from_mapping(ScoresConfig, ctx.section("scores"), section="scores")
        ctx.record("scores", cfg)
        tables = dict(ctx.tables)
        tables["timings"] = pl.DataFrame(
            {"stage": list(ctx.seconds), "seconds": list(ctx.seconds.values())},
            schema={"stage": pl.String, "seconds": pl.Float64},
        )
        rows, out = score_crossings(tables, cfg)
        ctx.report += rows
        site = ctx.site.tracked  # the trackers' view: no ignored sensor
        tables.update(out)
        for entry in trackers:
            if entry.name not in ctx.trackers or not ctx.status.get(entry.name, "").startswith("ok"):
                continue
            try:  # one tracker's scoring failing (say, a sensor without a region) keeps the others'
                rows, made = entry.score(entry.name, tables, site, ctx.region_graph)
                rows = rows + mot_rows(entry.name, entry.gate, tables, site, ctx.region_graph, gates_m=cfg.gates_m)
            except CannotServe as exc:  # the tracker's model does not fit the data: a flag, no number
                ctx.status[f"scores/{entry.name}"] = f"cannot serve the data: {exc}"
                ctx.report.append((entry.name, "cannot_serve", 1.0, "flag"))
                continue
            except OnebitError as exc:
                ctx.status[f"scores/{entry.name}"] = f"failed: {exc}"
                continue
            ctx.report += rows
            out.update(made)
            tables.update(made)
        for entry in trackers:  # the metrics of every tracker (METRICS)
            if entry.name not in ctx.trackers or not ctx.status.get(entry.name, "").startswith("ok"):
                continue
            for fn in METRICS if metrics is None else metrics:
                try:
                    ctx.report += fn(entry.name, tables, site, ctx.region_graph)
                except OnebitError as exc:
                    ctx.status[f"scores/{entry.name}"] = f"failed: {exc}"
        te = tables.get("truth_events")
        if te is not None and te.height:  # what a tracker's identity per event is compared with
            ctx.report += baseline_rows(
                te, graph_hops(site), profile=tables.get("residents_profile"), epoch=ctx.site.epoch
            )
        ctx.report += count_rows(tables)  # the count model's and the count baselines' scores
        rej = ctx.tables.get("rejects", pl.DataFrame(schema=REJECTS))
        ctx.report.append(("rejects", "rows", float(rej.height), "rows"))
        out["timings"] = tables["timings"]
        return out

    def viz(rec, ctx: RunContext, made: dict) -> None:
        for entry in trackers:
            sc = made.get(f"{entry.name}_scores")
            if sc is not None:
                tracks = ctx.tables.get(f"{entry.name}_tracks")
                ids = (
                    tracks["track"].drop_nulls().unique().to_list()
                    if tracks is not None and "track" in tracks.columns
                    else None
                )
                log_scores(rec, entry.name, sc, track_ids=ids, look=entry.drawn)

    makes = (
        "crossing_matches",
        "corrected_targets",
        "correct_recovered",
        "timings",
        *(f"{e.name}_*" for e in trackers),
    )
    return Stage("scores", (), makes, lambda ctx: None, work, viz, config=ScoresConfig)


# --------------------------------------------------------------------------- the list


def stages(trackers: tuple[TrackerEntry, ...] = TRACKERS) -> list[Stage]:
    """The declared pipeline, in order (module docstring)."""
    return [
        Stage(
            "crossings",
            (),
            ("crossings", "aborted", "beam_events"),
            reading.crossings_available,
            reading.crossings_work,
            reading.crossings_viz,
        ),
        Stage(
            "truth",
            (),
            ("truth", "true_crossings", "sim_crossings"),
            reading.truth_available,
            reading.truth_work,
            reading.truth_viz,
        ),
        Stage("truth_events", (), ("truth_events",), reading.truth_events_available, reading.truth_events_work),
        Stage("residents_profile", (), ("residents_profile",), reading.profile_available, reading.profile_work),
        Stage("truth_count", (), ("truth_count",), homes.truth_count_available, reading.truth_count_work),
        Stage("count_profile", (), ("count_profile",), homes.count_profile_available, homes.count_profile_work),
        Stage(
            "camera",
            (),
            ("camera_truth", "camera_detections"),
            reading.camera_available,
            reading.camera_work,
            reading.camera_viz,
        ),
        Stage(
            "frames",
            (),
            ("levels", "motion", "proximity", "proximity_frames"),
            reading.frames_available,
            reading.frames_work,
            reading.frames_viz,
        ),
        Stage(
            "motion",
            (),
            ("motion", "motion_suppressed"),
            reading.motion_available,
            reading.motion_work,
            reading.motion_viz,
            config=MotionConfig,
        ),
        Stage(
            "proximity",
            (),
            ("proximity", "proximity_frames", "proximity_suppressed"),
            reading.proximity_available,
            reading.proximity_work,
            config=ProximityConfig,
        ),
        Stage("ignore", (), ("ignored",), reading.ignore_available, reading.ignore_work),
        Stage(
            "occupancy",
            ("motion",),
            ("occupancy_bins", "occupancy_people"),
            homes.occupancy_available,
            reading.occupancy_work,
            viz_occupancy.log_occupancy,
            config=OccupancyConfig,
        ),
        Stage(
            "correct",
            ("crossings",),
            ("corrected_crossings", "correct_insertions", "correct_initial"),
            reading.correct_available,
            reading.correct_work,
            reading.correct_viz,
            config=CorrectConfig,
        ),
        *(tracker_stage(e) for e in trackers),
        scores_stage(trackers),
    ]
