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
a stage returning a table it does not declare, or one an earlier stage made, fails. ``onebit
run`` and ``onebit follow`` run this one list with one step
(:func:`onebit.pipeline.runner.run_stage`); ``follow`` runs the stages declared ``polled`` at
every poll, and each tracker as its entry's ``live`` says (:mod:`onebit.pipeline.online`).

This file declares; the work is elsewhere: a tracker's stage in :mod:`onebit.pipeline.tracking`,
the scores in :mod:`onebit.pipeline.scores`, the readers' stages beside them.

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
from onebit.core.errors import InputError
from onebit.models.occupancy import OccupancyConfig
from onebit.pipeline import (
    homes,
    tracking,  # its tracker_stage, read when stages() is called (tracking reads this module)
)
from onebit.pipeline.context import ReportRow, RunContext, Stage
from onebit.pipeline.homes import count_metric
from onebit.pipeline.online import BATCH_ONLY, BEAMS, BINPF, INTRUDER, ISTATE, LAGGED, ONLINE, PREFIX, Live, hmm_stepper
from onebit.pipeline.scores import MetricFn, identity_metric, scores_stage
from onebit.readers.beams import BEAM_COLUMNS, beam_dtypes, decode_beam_log, decode_raw_beams
from onebit.readers.camera import read_camera, truth_error
from onebit.readers.frames import edges_of_levels, read_frame_rows, read_frames_csv
from onebit.readers.motion import TOGGLE_COLUMNS, MotionConfig, read_motion, read_motion_csv, site_rules, toggle_dtypes
from onebit.readers.proximity import ProximityConfig, proximity_frames, read_proximity, read_proximity_csv
from onebit.readers.rows import read_typed_csv
from onebit.readers.tables_csv import (
    crossings_from_rows,
    read_crossings_csv,
    read_residents_profile_csv,
    read_true_crossings_csv,
    read_truth_csv,
    read_truth_events_csv,
    true_crossings_columns,
    true_crossings_from_rows,
    truth_events_from_rows,
    truth_from_rows,
)
from onebit.readers.timebase import TimeOrigin, time_origin
from onebit.scoring import beams as score_beams
from onebit.scoring import binpf as score_binpf
from onebit.scoring import clustertrack as score_clustertrack
from onebit.scoring import findinghumo as score_findinghumo
from onebit.scoring import intruder as score_intruder
from onebit.scoring import istate as score_istate
from onebit.scoring import residents as score_residents
from onebit.scoring.crossings import true_crossings_from_truth, truth_regions
from onebit.scoring.mot import Gate
from onebit.trackers import beams, binpf, clustertrack, findinghumo, findinghumo_flow, intruder, istate, residents
from onebit.trackers.base import TrackerSpec
from onebit.trackers.beams.correction import CorrectConfig, run_correction
from onebit.viz import beams as viz_beams
from onebit.viz import binpf as viz_binpf
from onebit.viz import clustertrack as viz_clustertrack
from onebit.viz import findinghumo as viz_findinghumo
from onebit.viz import intruder as viz_intruder
from onebit.viz import istate as viz_istate
from onebit.viz import occupancy as viz_occupancy
from onebit.viz import residents as viz_residents
from onebit.viz.beams_correct import log_corrected_crossings
from onebit.viz.colors import CAMERA_RGB
from onebit.viz.events import log_crossings
from onebit.viz.families import Look
from onebit.viz.intruder import log_motion_states
from onebit.viz.tracks import log_point_tracks
from onebit.viz.truth import log_truth

#: ``score(tracker, tables, site, region_graph) -> (report rows, tables)``
ScoreFn = Callable[..., tuple[list[ReportRow], dict[str, pl.DataFrame]]]
#: ``log_run(rec, tracker, outputs, *, site, region_graph, config, tables, look)``
VizFn = Callable[..., None]


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
    #: how it runs while ``onebit follow`` reads a growing log (:class:`onebit.pipeline.online.Live`:
    #: online, lagged, re-run on the settled prefix, or batch only)
    live: Live = BATCH_ONLY

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

#: The window decoder of each FindingHuMo HMM (its ``decoding = "lagged"`` online run).
HMM_DECODERS: dict[str, str] = {"findinghumo": "adaptive", "hmm1": "full1", "hmm2": "full2"}

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
        live=Live(
            ONLINE,
            "per crossing (incremental; re-run on the settled prefix when [correct] runs)",
            events=("corrected_crossings", "crossings"),
            stepper=BEAMS,
        ),
    ),
    TrackerEntry(
        intruder.SPEC,
        score_intruder.score,
        viz_intruder.log_run,
        gate=CELLS_GATE,
        scenario="pir14",
        look=Look("intruder", (70, 225, 110)),
        live=Live(ONLINE, "per iteration (incremental particle filter)", stepper=INTRUDER),
    ),
    TrackerEntry(
        intruder.NAIVE_SPEC,
        score_intruder.score,
        viz_intruder.log_run,
        gate=CELLS_GATE,
        scenario="pir14",
        look=Look("intruder", (200, 120, 255)),
        live=Live(PREFIX, "per iteration", events=("motion",)),
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
        live=Live(
            ONLINE, "per frame, committed after [binpf] commit_lag frames (incremental particle filter)", stepper=BINPF
        ),
    ),
    *(
        TrackerEntry(
            spec,
            score_findinghumo.score,
            viz_findinghumo.log_run,
            gate=HOPS_GATE,
            scenario="hallway",
            look=Look("findinghumo", FINDINGHUMO_RGB[spec.name]),
            live=Live(
                LAGGED,
                "per window (re-run on the settled prefix)",
                events=("motion",),
                stepper=hmm_stepper(HMM_DECODERS[spec.name]),
            ),
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
        live=Live(
            ONLINE,
            "per stage (incremental with latency_auto = false; else re-run on the settled prefix)",
            events=("motion", "proximity", "crossings"),
            stepper=ISTATE,
        ),
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


# --------------------------------------------------------------------------- the time base

#: The raw logs whose stamps set a run's time origin, with the columns read from them.
TIME_SOURCES = ("beams", "crossings", "truth", "truth_crossings", "truth_events", "motion", "proximity", "frames")


def run_time_origin(ctx: RunContext) -> TimeOrigin:
    """The run's one time origin (:mod:`onebit.readers.timebase`), computed on first use from
    the ``t`` stamps of every raw log of the dataset (CSV or MCAP channel) and kept on ``ctx``
    (``ctx.time_origin``): ``site.toml``'s ``epoch`` if set, else the data's own start; lone
    stamps far from the rest fall outside its window and are rejected by every reader. A log
    whose header cannot be read is left out here (its own stage reports it). Raises
    :class:`~onebit.core.errors.InputError` on an absurd span. It goes to ``run.toml`` as the
    ``[time]`` table (source, origin as ISO and as the logs' number, span, lone stamps)."""
    if ctx.time_origin is not None:
        return ctx.time_origin
    frames: dict[str, pl.DataFrame | list[pl.DataFrame]] = {}
    for stem in TIME_SOURCES:
        if not ctx.has_source(stem):
            continue
        split = _typed_read(ctx, stem)
        if split is not None:  # read once, typed: its stamps here, the rest by the reader stage
            ctx.typed_reads[stem] = split
            frames[f"{stem}.csv"] = [split.good.select("line", "t"), split.rest.frame.select("line", "t")]
            continue
        try:
            name, frame = ctx.stamps(stem)
        except InputError:
            continue
        frames[name] = frame
    origin = time_origin(frames, epoch=ctx.site.epoch)
    ctx.time_origin = origin
    return origin


def _typed_read(ctx: RunContext, stem: str):
    """The typed read (:func:`~onebit.readers.rows.read_typed_csv`) of ``<stem>.csv`` in the
    reader stage's types, for the logs whose reader takes it (beams, motion, proximity), else
    ``None`` (no such CSV, another log, or a file the typed read cannot take)."""
    csv = ctx.dataset / f"{stem}.csv"
    if stem not in ("beams", "motion", "proximity") or not csv.exists():
        return None
    if stem == "beams":
        ids = list(ctx.site.beam_ids)
    else:
        ids = [m.id for m in (ctx.site.motion_sensors if stem == "motion" else ctx.site.proximity_sensors)]
    if not ids:  # its stage will not read it: the stamps alone
        return None
    return read_typed_csv(csv, beam_dtypes(tuple(ids)) if stem == "beams" else toggle_dtypes(ids))


# --------------------------------------------------------------------------- reader stages


def _crossings_available(ctx: RunContext) -> str | None:
    if ctx.has_source("beams") or ctx.has_source("crossings"):
        return None
    return "no beams.csv, crossings.csv or /beams, /crossings MCAP channel in the dataset"


def _crossings_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    site = ctx.site
    out: dict[str, pl.DataFrame] = {}
    if ctx.has_source("beams"):
        csv = ctx.dataset / "beams.csv"
        if csv.exists():  # a clean file is typed in one read (decode_beam_log), else line by line
            dec = decode_beam_log(
                csv, site.beam_ids, epoch=run_time_origin(ctx), split=ctx.typed_reads.pop("beams", None)
            )
        else:
            raw, path = ctx.source("beams", BEAM_COLUMNS)
            dec = decode_raw_beams(raw, site.beam_ids, epoch=run_time_origin(ctx), path=path)
        ctx.add_rejects(dec.rejects)
        out.update(crossings=dec.crossings, aborted=dec.aborted, beam_events=dec.events)
        ctx.report += [
            ("crossings", "decoded", float(dec.crossings.height), "crossings"),
            ("crossings", "aborted", float(dec.aborted.height), "passes"),
            ("crossings", "unfinished", float(dec.unfinished.height), "passes"),
        ]
        if ctx.has_source("crossings"):
            ctx.report.append(("crossings", "ignored_crossings_csv", 1.0, "flag"))
    else:
        csv = ctx.dataset / "crossings.csv"
        if csv.exists():  # typed in one read, only the lines it cannot take row by row
            cr, rej = read_crossings_csv(csv, site.beam_ids, epoch=run_time_origin(ctx))
        else:
            raw, path = ctx.source("crossings", ("t", "beam", "direction"))
            cr, rej = crossings_from_rows(raw, site.beam_ids, epoch=run_time_origin(ctx), path=path)
        ctx.add_rejects(rej)
        out["crossings"] = cr
        ctx.report.append(("crossings", "decoded", float(cr.height), "crossings"))
    return out


def _crossings_viz(rec, ctx: RunContext, made: dict) -> None:
    log_crossings(rec, made["crossings"], aborted=made.get("aborted"), site=ctx.site)


def _truth_available(ctx: RunContext) -> str | None:
    return None if ctx.has_source("truth") else "no truth.csv or /truth MCAP channel in the dataset"


def _truth_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    csv = ctx.dataset / "truth.csv"
    if csv.exists():  # typed in one read, only the lines it cannot take row by row
        truth, rej = read_truth_csv(csv, epoch=run_time_origin(ctx))
    else:
        raw, path = ctx.source("truth", ("t", "target", "x", "y"))
        truth, rej = truth_from_rows(raw, epoch=run_time_origin(ctx), path=path)
    ctx.add_rejects(rej)
    truth = truth_regions(truth, ctx.region_graph)
    out = {"truth": truth, "true_crossings": true_crossings_from_truth(truth, ctx.site, ctx.region_graph)}
    if ctx.has_source("truth_crossings"):
        csv = ctx.dataset / "truth_crossings.csv"
        columns = true_crossings_columns(csv)
        if csv.exists() and "dropped" not in columns:  # typed in one read, as truth.csv
            sim_cr, rej = read_true_crossings_csv(csv, ctx.site.beam_ids, epoch=run_time_origin(ctx))
        else:
            raw, path = ctx.source("truth_crossings", columns)
            sim_cr, rej = true_crossings_from_rows(raw, ctx.site.beam_ids, epoch=run_time_origin(ctx), path=path)
        ctx.add_rejects(rej)
        out["sim_crossings"] = sim_cr
    return out


def _truth_viz(rec, ctx: RunContext, made: dict) -> None:
    log_truth(rec, made["truth"], diagonal=ctx.site.diagonal)
    viz_occupancy.log_truth_people(rec, made["truth"])  # the summary tab's true count


def _truth_events_available(ctx: RunContext) -> str | None:
    return (
        None if ctx.has_source("truth_events") else "no truth_events.csv or /truth_events MCAP channel in the dataset"
    )


def _truth_events_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    csv = ctx.dataset / "truth_events.csv"
    if csv.exists():
        te, rej = read_truth_events_csv(csv, epoch=run_time_origin(ctx))
    else:
        raw, path = ctx.source("truth_events", ("t", "sensor", "residents"))
        te, rej = truth_events_from_rows(raw, epoch=run_time_origin(ctx), path=path)
    ctx.add_rejects(rej)
    ctx.report += [
        ("truth_events", "events", float(te.height), "events"),
        (
            "truth_events",
            "residents",
            float(te["residents"].str.split(";").explode().n_unique()) if te.height else 0.0,
            "residents",
        ),
    ]
    return {"truth_events": te}


def _profile_available(ctx: RunContext) -> str | None:
    return None if (ctx.dataset / "residents_profile.csv").exists() else "no residents_profile.csv in the dataset"


def _profile_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    """``residents_profile.csv`` (learned by ``onebit learn residents``): the known residents'
    profile the ``residents`` tracker decodes with (docs/residents.md, "Known residents")."""
    prof, rej = read_residents_profile_csv(ctx.dataset / "residents_profile.csv")
    ctx.add_rejects(rej)
    ctx.report += [
        ("residents_profile", "residents", float(prof["resident"].n_unique()), "residents"),
        ("residents_profile", "events", float(prof.filter(pl.col("from").is_null())["count"].sum()), "events"),
    ]
    return {"residents_profile": prof}


def _camera_available(ctx: RunContext) -> str | None:
    if not (ctx.dataset / "camera.mp4").exists():
        return "no camera.mp4 in the dataset"
    if ctx.site.camera is None:
        return "camera.mp4 present but site.toml has no [camera]"
    return None


def _camera_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    res = read_camera(ctx.dataset / "camera.mp4", ctx.site)
    ctx.add_rejects(res.rejects)
    shift = run_time_origin(ctx).numeric  # camera.t0 is on the logs' clock: on the run's time base too
    detections = res.detections.with_columns(pl.col("t") - shift) if shift else res.detections
    cam_truth = truth_regions(res.truth.with_columns(pl.col("t") - shift) if shift else res.truth, ctx.region_graph)
    ctx.report.append(("camera", "frames", float(res.frames), "frames"))
    ctx.report.append(
        ("camera", "tracks", float(cam_truth["target"].n_unique()) if cam_truth.height else 0.0, "tracks")
    )
    if "truth" in ctx.tables:
        err = truth_error(cam_truth.select(res.truth.columns), ctx.tables["truth"], diagonal=ctx.site.diagonal)
        ctx.report += [
            ("camera", "truth_error", float(err["mean"]), ctx.site.units),
            ("camera", "truth_error_rel", float(err["rel"]), "fraction of diagonal"),
            ("camera", "missed", float(err["missed"]), "points"),
        ]
    return {"camera_truth": cam_truth, "camera_detections": detections}


def _camera_viz(rec, ctx: RunContext, made: dict) -> None:
    cam = made["camera_truth"]
    log_point_tracks(rec, "camera", cam.with_columns(track=pl.col("target"), tracker=pl.lit("camera")), rgb=CAMERA_RGB)


def _frame_sensor_ids(site) -> list[str]:
    """Every binary sensor a frame log may list: motion, then proximity sensors (each id once)."""
    return list(dict.fromkeys([m.id for m in site.motion_sensors] + [p.id for p in site.proximity_sensors]))


def _frames_available(ctx: RunContext) -> str | None:
    if not ctx.has_source("frames"):
        return "no frames.csv or /frames MCAP channel in the dataset"
    if not _frame_sensor_ids(ctx.site):
        return "frame log present but site.toml declares no binary sensors (binary_sensors, motion_sensors, proximity_sensors)"
    return None


def _frames_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    """A frame-sampled log (:mod:`onebit.readers.frames`) -> ``levels`` (every frame x every
    sensor) and, from them, what the trackers read: ``motion`` (toggle edges of the motion and
    binary sensors), ``proximity_frames`` (the proximity and
    binary sensors' levels at every frame) and ``proximity`` (edges of the proximity-only
    sensors; a binary sensor's edges are in ``motion`` once)."""
    site = ctx.site
    ids = _frame_sensor_ids(site)
    csv = ctx.dataset / "frames.csv"
    if csv.exists():
        log = read_frames_csv(csv, ids, epoch=run_time_origin(ctx))
    else:  # the MCAP channel /frames: the list layout (t, active)
        log = read_frame_rows(ctx.mcap_channels["/frames"], ids, layout="list", epoch=run_time_origin(ctx))
    ctx.add_rejects(log.rejects)
    levels = log.levels
    motion_ids = [m.id for m in site.motion_sensors]
    prox_ids = [p.id for p in site.proximity_sensors]
    prox_only = [p for p in prox_ids if p not in set(motion_ids)]
    out = {"levels": levels}
    if motion_ids:
        out["motion"] = edges_of_levels(levels, motion_ids)
    if prox_ids:
        out["proximity_frames"] = levels.filter(pl.col("sensor").is_in(prox_ids))
        out["proximity"] = edges_of_levels(levels, prox_only)
    ctx.report += [
        ("frames", "frames", float(log.frames), "frames"),
        ("frames", "period", float(log.period) if log.period is not None else float("nan"), "s"),
        ("frames", "on_readings", float(levels["on"].sum()) if levels.height else 0.0, "readings"),
        ("frames", "unlisted", float(log.unlisted), "readings"),
        ("frames", "rejected", float(log.rejects.height), "rows"),
    ]
    for stem in ("motion", "proximity"):
        if ctx.has_source(stem):  # one source of readings per sensor: the frame log
            ctx.report.append(("frames", f"ignored_{stem}_csv", 1.0, "flag"))
    return out


def _frames_viz(rec, ctx: RunContext, made: dict) -> None:
    if "motion" in made:
        log_motion_states(rec, made["motion"], [m.id for m in ctx.site.motion_sensors])


def _motion_available(ctx: RunContext) -> str | None:
    if ctx.has_source("frames"):
        return "the readings come from the frame log (frames.csv or /frames)"
    if not ctx.has_source("motion"):
        return "no motion.csv or /motion MCAP channel in the dataset"
    if not ctx.site.motion_sensors:
        return "motion log present but site.toml has no [[motion_sensors]]"
    return None


def _motion_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    cfg = config_from_mapping(MotionConfig, ctx.section("motion"), section="motion")
    ctx.record("motion", cfg)
    site = ctx.site
    ids = [m.id for m in site.motion_sensors]
    csv = ctx.dataset / "motion.csv"
    if csv.exists():  # a clean file is typed in one read (read_motion_csv), else line by line
        res = read_motion_csv(
            csv,
            ids,
            epoch=run_time_origin(ctx),
            rules=site_rules(site, cfg),
            held=site.level_sensors,
            split=ctx.typed_reads.pop("motion", None),
        )
    else:
        raw, path = ctx.source("motion", TOGGLE_COLUMNS)
        res = read_motion(
            raw, ids, epoch=run_time_origin(ctx), path=path, rules=site_rules(site, cfg), held=site.level_sensors
        )
    ctx.add_rejects(res.rejects)
    ctx.report += [
        ("motion", "edges", float(res.motion.height), "edges"),
        ("motion", "suppressed", float(res.suppressed.height), "edges"),
        ("motion", "held", float(res.held), "rows"),
        ("motion", "rejected", float(res.rejects.height), "rows"),
    ]
    return {"motion": res.motion, "motion_suppressed": res.suppressed}


def _motion_viz(rec, ctx: RunContext, made: dict) -> None:
    log_motion_states(rec, made["motion"], [m.id for m in ctx.site.motion_sensors])


def _proximity_available(ctx: RunContext) -> str | None:
    if ctx.has_source("frames"):
        return "the readings come from the frame log (frames.csv or /frames)"
    if not ctx.site.proximity_sensors:
        return "site.toml has no proximity sensors"
    if not ctx.has_source("proximity"):
        return "no proximity.csv or /proximity MCAP channel in the dataset"
    return None


def _proximity_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    cfg = config_from_mapping(ProximityConfig, ctx.section("proximity"), section="proximity")
    ctx.record("proximity", cfg)
    ids = [p.id for p in ctx.site.proximity_sensors]
    csv = ctx.dataset / "proximity.csv"
    if csv.exists():  # a clean file is typed in one read (read_proximity_csv), else line by line
        res = read_proximity_csv(
            csv,
            ids,
            epoch=run_time_origin(ctx),
            rules=cfg.rules,
            held=ctx.site.level_sensors,
            split=ctx.typed_reads.pop("proximity", None),
        )
    else:
        raw, path = ctx.source("proximity", TOGGLE_COLUMNS)
        res = read_proximity(
            raw, ids, epoch=run_time_origin(ctx), path=path, rules=cfg.rules, held=ctx.site.level_sensors
        )
    ctx.add_rejects(res.rejects)
    frames = proximity_frames(
        res.motion, ids, period=cfg.period, start=None if cfg.start < 0 else cfg.start, instants=cfg.instants or None
    )
    ctx.report += [
        ("proximity", "edges", float(res.motion.height), "edges"),
        ("proximity", "suppressed", float(res.suppressed.height), "edges"),
        ("proximity", "held", float(res.held), "rows"),
        ("proximity", "rejected", float(res.rejects.height), "rows"),
        ("proximity", "instants", float(frames["slot"].n_unique()) if frames.height else 0.0, "instants"),
    ]
    return {"proximity": res.motion, "proximity_frames": frames, "proximity_suppressed": res.suppressed}


# --------------------------------------------------------------------------- correction (Bobadilla V)


# --------------------------------------------------------------------------- ignored sensors

#: The tables of readings a tracker may read, with the column naming their sensor: an ignored
#: sensor's rows are left out of them (:func:`without_ignored`) before any tracker sees them.
READINGS = {
    "motion": "sensor",
    "proximity": "sensor",
    "levels": "sensor",
    "proximity_frames": "sensor",
    "crossings": "beam",
    "corrected_crossings": "beam",
    "beam_events": "beam",
    "aborted": "beam",
}


def without_ignored(name: str, table: Any, ignored: frozenset[str]) -> Any:
    """``table`` (the run's table ``name``) without the rows of the ``ignored`` sensors
    (``site.toml`` ``ignore = true``) when it is a table of readings (:data:`READINGS`); any
    other value as it is."""
    col = READINGS.get(name)
    if not ignored or col is None or not isinstance(table, pl.DataFrame) or col not in table.columns:
        return table
    return table.filter(~pl.col(col).is_in(sorted(ignored)))


def _truth_count_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    return homes.truth_count_work(ctx, run_time_origin(ctx))


def _occupancy_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    return homes.occupancy_work(ctx, without_ignored("motion", ctx.tables["motion"], ctx.site.ignored))


def _ignore_available(ctx: RunContext) -> str | None:
    return None if ctx.site.ignored else "no sensor has ignore = true in site.toml"


def _ignore_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    """Count what the readers read of the ignored sensors (kept in their tables, left out of
    every tracker's inputs by :func:`tracker_inputs`): one row per (table, sensor)."""
    ignored = sorted(ctx.site.ignored)
    parts = []
    for name, col in READINGS.items():
        df = ctx.tables.get(name)
        if df is None or col not in df.columns:
            continue
        parts.append(
            df.filter(pl.col(col).is_in(ignored))
            .group_by(col)
            .len("rows")
            .select(pl.lit(name).alias("table"), pl.col(col).alias("sensor"), pl.col("rows").cast(pl.Int64))
        )
    schema = {"table": pl.String, "sensor": pl.String, "rows": pl.Int64}
    out = pl.concat(parts) if parts else pl.DataFrame(schema=schema)
    out = out.sort("table", "sensor")
    ctx.report += [
        ("ignore", "ignored_sensors", float(len(ignored)), "sensors"),
        ("ignore", "ignored_rows", float(out["rows"].sum()) if out.height else 0.0, "rows"),
    ]
    return {"ignored": out}


def _correct_available(ctx: RunContext) -> str | None:
    if not ctx.site.beams:
        return "site has no beams"
    try:
        section = ctx.section("correct")
    except InputError:  # a broken run.toml: run the stage so it fails naming the file
        return None
    if section.get("enabled", True) is False:
        return "disabled: [correct] enabled = false"
    n = section.get("n")
    if n is None and ctx.site.targets is None:
        return "number of agents unknown: set site.toml targets or run.toml [correct] n"
    return None


def _correct_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    cfg = config_from_mapping(CorrectConfig, ctx.section("correct"), section="correct")
    n = cfg.n if cfg.n is not None else ctx.site.targets
    ctx.record("correct", cfg, n=n)
    crossings = without_ignored("crossings", ctx.tables["crossings"], ctx.site.ignored)
    res = run_correction(crossings, ctx.region_graph, cfg, n)
    ctx.report += res.report
    return res.tables


def _correct_viz(rec, ctx: RunContext, made: dict) -> None:
    log_corrected_crossings(rec, made["corrected_crossings"], ctx.site)


# --------------------------------------------------------------------------- scores

#: The metrics of every tracker beyond its own (``TrackerEntry.score``) and the MOT rows: one
#: line per metric (docs/extending.md, "A report metric").
METRICS: tuple[MetricFn, ...] = (identity_metric, count_metric)


# --------------------------------------------------------------------------- the list


def stages(trackers: tuple[TrackerEntry, ...] = TRACKERS) -> list[Stage]:
    """The declared pipeline, in order (module docstring)."""
    return [
        Stage(
            "crossings",
            (),
            ("crossings", "aborted", "beam_events"),
            _crossings_available,
            _crossings_work,
            _crossings_viz,
            polled=True,
        ),
        Stage("truth", (), ("truth", "true_crossings", "sim_crossings"), _truth_available, _truth_work, _truth_viz),
        Stage("truth_events", (), ("truth_events",), _truth_events_available, _truth_events_work),
        Stage("residents_profile", (), ("residents_profile",), _profile_available, _profile_work),
        Stage("truth_count", (), ("truth_count",), homes.truth_count_available, _truth_count_work),
        Stage("count_profile", (), ("count_profile",), homes.count_profile_available, homes.count_profile_work),
        Stage("camera", (), ("camera_truth", "camera_detections"), _camera_available, _camera_work, _camera_viz),
        Stage(
            "frames",
            (),
            ("levels", "motion", "proximity", "proximity_frames"),
            _frames_available,
            _frames_work,
            _frames_viz,
            polled=True,
        ),
        Stage(
            "motion",
            (),
            ("motion", "motion_suppressed"),
            _motion_available,
            _motion_work,
            _motion_viz,
            config=MotionConfig,
            polled=True,
        ),
        Stage(
            "proximity",
            (),
            ("proximity", "proximity_frames", "proximity_suppressed"),
            _proximity_available,
            _proximity_work,
            config=ProximityConfig,
            polled=True,
        ),
        Stage("ignore", (), ("ignored",), _ignore_available, _ignore_work),
        Stage(
            "occupancy",
            ("motion",),
            ("occupancy_bins", "occupancy_people"),
            homes.occupancy_available,
            _occupancy_work,
            viz_occupancy.log_occupancy,
            config=OccupancyConfig,
        ),
        Stage(
            "correct",
            ("crossings",),
            ("corrected_crossings", "correct_insertions", "correct_initial"),
            _correct_available,
            _correct_work,
            _correct_viz,
            config=CorrectConfig,
            polled=True,
        ),
        *(tracking.tracker_stage(e) for e in trackers),
        scores_stage(trackers, METRICS),
    ]
