"""The work of the reader stages declared in :mod:`onebit.pipeline.stages`: each raw log of a
dataset (a CSV file or an MCAP channel) -> its canonical tables, on the run's one time origin
(:func:`run_time_origin`), plus the stages that only reshape what the readers made (``ignore``,
``correct``, the homes' ``truth_count`` and ``occupancy``).

Besides the run's time origin (:func:`run_time_origin`, from every log's stamps:
:func:`origin_stamps`) and the filter of the ignored sensors' readings
(:func:`without_ignored`), each function here is the ``available``, ``work`` or ``viz`` of
one declared stage; the declarations (names, what each needs and makes, its config) are in
:func:`onebit.pipeline.stages.stages`. A stage reads its log through the format's one reader
(``read_beams``, ``read_motion``, ...: :mod:`onebit.readers.logs`), which takes the CSV file
or the MCAP channel's rows (``ctx.log(stem)``) and chooses its own path.

Each CSV log is read once per run: ``ctx.log(stem)`` is the run's one
:class:`~onebit.readers.logs.CsvLog` of the file; the time-origin step of a beam or toggle log
reads it in its reader's types and the log keeps that read for the reader, which takes it
(and the log drops it) -- when the stage that reads it will run (:func:`_read_taken`), else
nothing is kept.
"""

from __future__ import annotations

from typing import Any

import polars as pl

from onebit.core.config import config_from_mapping
from onebit.core.errors import InputError
from onebit.pipeline import homes
from onebit.pipeline.context import RunContext
from onebit.readers.beams import beam_dtypes, read_beams
from onebit.readers.camera import read_camera, truth_error
from onebit.readers.frames import edges_of_levels, read_frames
from onebit.readers.logs import Log, Stamps, log_name, log_stamps, typed_stamps
from onebit.readers.motion import MotionConfig, read_motion, site_rules, toggle_dtypes
from onebit.readers.proximity import ProximityConfig, proximity_frames, read_proximity
from onebit.readers.tables_csv import (
    read_crossings,
    read_residents_profile_csv,
    read_true_crossings,
    read_truth,
    read_truth_events,
)
from onebit.readers.timebase import TimeOrigin, time_origin
from onebit.scoring.crossings import true_crossings_from_truth, truth_regions
from onebit.trackers.beams.correction import CorrectConfig, run_correction
from onebit.viz import occupancy as viz_occupancy
from onebit.viz.beams_correct import log_corrected_crossings
from onebit.viz.colors import CAMERA_RGB
from onebit.viz.events import log_crossings
from onebit.viz.intruder import log_motion_states
from onebit.viz.tracks import log_point_tracks
from onebit.viz.truth import log_truth

# --------------------------------------------------------------------------- the time base

#: The raw logs whose stamps set a run's time origin (a CSV file or an MCAP channel each).
TIME_SOURCES = ("beams", "crossings", "truth", "truth_crossings", "truth_events", "motion", "proximity", "frames")


def run_time_origin(ctx: RunContext) -> TimeOrigin:
    """The run's one time origin (:mod:`onebit.readers.timebase`), computed on first use from
    the ``t`` stamps of every raw log of the dataset (CSV or MCAP channel; each log's
    time-origin step, :func:`origin_stamps`) and kept on ``ctx``
    (``ctx.time_origin``): ``site.toml``'s ``epoch`` if set, else the data's own start; lone
    stamps far from the rest fall outside its window and are rejected by every reader. A log
    whose header cannot be read is left out here (its own stage reports it). Raises
    :class:`~onebit.core.errors.InputError` on an absurd span. It goes to ``run.toml`` as the
    ``[time]`` table (source, origin as ISO and as the logs' number, span, lone stamps)."""
    if ctx.time_origin is not None:
        return ctx.time_origin
    frames: dict[str, Stamps] = {}
    for stem in TIME_SOURCES:
        log = ctx.log(stem)
        stamps = None if log is None else origin_stamps(ctx.site, stem, log, keep=_read_taken(ctx, stem))
        if stamps is not None:
            frames[log_name(log)] = stamps
    origin = time_origin(frames, epoch=ctx.site.epoch)
    ctx.time_origin = origin
    return origin


def origin_stamps(site, stem: str, log: Log, *, keep: bool = True) -> Stamps | None:
    """The time-origin step of the log ``stem``: its stamps, read as its reader reads them (a
    beam or toggle log in its reader's types, :func:`~onebit.readers.logs.typed_stamps`: the
    same numbers, and an absurd span names them the same way; a
    :class:`~onebit.readers.logs.CsvLog` keeps that read for its reader unless ``keep`` is
    false), ``None`` when it cannot be read."""
    if stem == "beams":
        ids = tuple(site.beam_ids)
        return typed_stamps(log, beam_dtypes(ids) if ids else None, keep=keep)
    if stem in ("motion", "proximity"):
        ids = [m.id for m in (site.motion_sensors if stem == "motion" else site.proximity_sensors)]
        return typed_stamps(log, toggle_dtypes(ids) if ids else None, keep=keep)
    return log_stamps(log)


def _read_taken(ctx: RunContext, stem: str) -> bool:
    """Whether the stage that reads the log ``stem`` in its typed read will run (so the
    time-origin step keeps that read for it): ``crossings`` for beams, ``motion``, ``proximity``."""
    available = {"beams": crossings_available, "motion": motion_available, "proximity": proximity_available}.get(stem)
    return available is not None and available(ctx) is None


# --------------------------------------------------------------------------- reader stages


def crossings_available(ctx: RunContext) -> str | None:
    if ctx.has_source("beams") or ctx.has_source("crossings"):
        return None
    return "no beams.csv, crossings.csv or /beams, /crossings MCAP channel in the dataset"


def crossings_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    """The raw beam log (:func:`~onebit.readers.beams.read_beams`), else the crossings log
    (:func:`~onebit.readers.tables_csv.read_crossings`)."""
    site = ctx.site
    if ctx.has_source("beams"):
        dec = read_beams(ctx.log("beams"), site.beam_ids, epoch=run_time_origin(ctx))
        ctx.add_rejects(dec.rejects)
        ctx.report += [
            ("crossings", "decoded", float(dec.crossings.height), "crossings"),
            ("crossings", "aborted", float(dec.aborted.height), "passes"),
            ("crossings", "unfinished", float(dec.unfinished.height), "passes"),
        ]
        if ctx.has_source("crossings"):
            ctx.report.append(("crossings", "ignored_crossings_csv", 1.0, "flag"))
        return {"crossings": dec.crossings, "aborted": dec.aborted, "beam_events": dec.events}
    cr, rej = read_crossings(ctx.log("crossings"), site.beam_ids, epoch=run_time_origin(ctx))
    ctx.add_rejects(rej)
    ctx.report.append(("crossings", "decoded", float(cr.height), "crossings"))
    return {"crossings": cr}


def crossings_viz(rec, ctx: RunContext, made: dict) -> None:
    log_crossings(rec, made["crossings"], aborted=made.get("aborted"), site=ctx.site)


def truth_available(ctx: RunContext) -> str | None:
    return None if ctx.has_source("truth") else "no truth.csv or /truth MCAP channel in the dataset"


def truth_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    """The truth log (:func:`~onebit.readers.tables_csv.read_truth`) with each point's region
    and the crossings it implies, and the simulator's true crossings when the dataset has them
    (:func:`~onebit.readers.tables_csv.read_true_crossings`)."""
    truth, rej = read_truth(ctx.log("truth"), epoch=run_time_origin(ctx))
    ctx.add_rejects(rej)
    truth = truth_regions(truth, ctx.region_graph)
    out = {"truth": truth, "true_crossings": true_crossings_from_truth(truth, ctx.site, ctx.region_graph)}
    if ctx.has_source("truth_crossings"):
        sim_cr, rej = read_true_crossings(ctx.log("truth_crossings"), ctx.site.beam_ids, epoch=run_time_origin(ctx))
        ctx.add_rejects(rej)
        out["sim_crossings"] = sim_cr
    return out


def truth_viz(rec, ctx: RunContext, made: dict) -> None:
    log_truth(rec, made["truth"], diagonal=ctx.site.diagonal)
    viz_occupancy.log_truth_people(rec, made["truth"])  # the summary tab's true count


def truth_events_available(ctx: RunContext) -> str | None:
    return (
        None if ctx.has_source("truth_events") else "no truth_events.csv or /truth_events MCAP channel in the dataset"
    )


def truth_events_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    te, rej = read_truth_events(ctx.log("truth_events"), epoch=run_time_origin(ctx))
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


def profile_available(ctx: RunContext) -> str | None:
    return None if (ctx.dataset / "residents_profile.csv").exists() else "no residents_profile.csv in the dataset"


def profile_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    """``residents_profile.csv`` (learned by ``onebit learn residents``): the known residents'
    profile the ``residents`` tracker decodes with (docs/residents.md, "Known residents")."""
    prof, rej = read_residents_profile_csv(ctx.dataset / "residents_profile.csv")
    ctx.add_rejects(rej)
    ctx.report += [
        ("residents_profile", "residents", float(prof["resident"].n_unique()), "residents"),
        ("residents_profile", "events", float(prof.filter(pl.col("from").is_null())["count"].sum()), "events"),
    ]
    return {"residents_profile": prof}


def camera_available(ctx: RunContext) -> str | None:
    if not (ctx.dataset / "camera.mp4").exists():
        return "no camera.mp4 in the dataset"
    if ctx.site.camera is None:
        return "camera.mp4 present but site.toml has no [camera]"
    return None


def camera_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
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


def camera_viz(rec, ctx: RunContext, made: dict) -> None:
    cam = made["camera_truth"]
    log_point_tracks(rec, "camera", cam.with_columns(track=pl.col("target"), tracker=pl.lit("camera")), rgb=CAMERA_RGB)


def _frame_sensor_ids(site) -> list[str]:
    """Every binary sensor a frame log may list: motion, then proximity sensors (each id once)."""
    return list(dict.fromkeys([m.id for m in site.motion_sensors] + [p.id for p in site.proximity_sensors]))


def frames_available(ctx: RunContext) -> str | None:
    if not ctx.has_source("frames"):
        return "no frames.csv or /frames MCAP channel in the dataset"
    if not _frame_sensor_ids(ctx.site):
        return "frame log present but site.toml declares no binary sensors (binary_sensors, motion_sensors, proximity_sensors)"
    return None


def frames_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    """A frame-sampled log (:mod:`onebit.readers.frames`) -> ``levels`` (every frame x every
    sensor) and, from them, what the trackers read: ``motion`` (toggle edges of the motion and
    binary sensors), ``proximity_frames`` (the proximity and
    binary sensors' levels at every frame) and ``proximity`` (edges of the proximity-only
    sensors; a binary sensor's edges are in ``motion`` once)."""
    site = ctx.site
    ids = _frame_sensor_ids(site)
    log = read_frames(ctx.log("frames"), ids, epoch=run_time_origin(ctx))
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


def frames_viz(rec, ctx: RunContext, made: dict) -> None:
    if "motion" in made:
        log_motion_states(rec, made["motion"], [m.id for m in ctx.site.motion_sensors])


def motion_available(ctx: RunContext) -> str | None:
    if ctx.has_source("frames"):
        return "the readings come from the frame log (frames.csv or /frames)"
    if not ctx.has_source("motion"):
        return "no motion.csv or /motion MCAP channel in the dataset"
    if not ctx.site.motion_sensors:
        return "motion log present but site.toml has no [[motion_sensors]]"
    return None


def motion_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    cfg = config_from_mapping(MotionConfig, ctx.section("motion"), section="motion")
    ctx.record("motion", cfg)
    site = ctx.site
    ids = [m.id for m in site.motion_sensors]
    rules = site_rules(site, cfg)
    res = read_motion(ctx.log("motion"), ids, epoch=run_time_origin(ctx), rules=rules, held=site.level_sensors)
    ctx.add_rejects(res.rejects)
    ctx.report += [
        ("motion", "edges", float(res.motion.height), "edges"),
        ("motion", "suppressed", float(res.suppressed.height), "edges"),
        ("motion", "held", float(res.held), "rows"),
        ("motion", "rejected", float(res.rejects.height), "rows"),
    ]
    return {"motion": res.motion, "motion_suppressed": res.suppressed}


def motion_viz(rec, ctx: RunContext, made: dict) -> None:
    log_motion_states(rec, made["motion"], [m.id for m in ctx.site.motion_sensors])


def proximity_available(ctx: RunContext) -> str | None:
    if ctx.has_source("frames"):
        return "the readings come from the frame log (frames.csv or /frames)"
    if not ctx.site.proximity_sensors:
        return "site.toml has no proximity sensors"
    if not ctx.has_source("proximity"):
        return "no proximity.csv or /proximity MCAP channel in the dataset"
    return None


def proximity_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    cfg = config_from_mapping(ProximityConfig, ctx.section("proximity"), section="proximity")
    ctx.record("proximity", cfg)
    ids = [p.id for p in ctx.site.proximity_sensors]
    res = read_proximity(
        ctx.log("proximity"), ids, epoch=run_time_origin(ctx), rules=cfg.rules, held=ctx.site.level_sensors
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


def truth_count_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    return homes.truth_count_work(ctx, run_time_origin(ctx))


def occupancy_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    return homes.occupancy_work(ctx, without_ignored("motion", ctx.tables["motion"], ctx.site.ignored))


def ignore_available(ctx: RunContext) -> str | None:
    return None if ctx.site.ignored else "no sensor has ignore = true in site.toml"


def ignore_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    """Count what the readers read of the ignored sensors (kept in their tables, left out of
    every tracker's inputs by :func:`onebit.pipeline.stages.tracker_inputs`): one row per
    (table, sensor)."""
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


def correct_available(ctx: RunContext) -> str | None:
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


def correct_work(ctx: RunContext) -> dict[str, pl.DataFrame]:
    cfg = config_from_mapping(CorrectConfig, ctx.section("correct"), section="correct")
    n = cfg.n if cfg.n is not None else ctx.site.targets
    ctx.record("correct", cfg, n=n)
    crossings = without_ignored("crossings", ctx.tables["crossings"], ctx.site.ignored)
    res = run_correction(crossings, ctx.region_graph, cfg, n)
    ctx.report += res.report
    return res.tables


def correct_viz(rec, ctx: RunContext, made: dict) -> None:
    log_corrected_crossings(rec, made["corrected_crossings"], ctx.site)
