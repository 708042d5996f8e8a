"""The pipeline: a declared list of named stages, each with its inputs and outputs.

``run_pipeline(dataset, out)`` loads the site, then runs every stage whose inputs exist, in
order. Each stage writes its tables to ``OUT/tables/<name>.parquet`` and its Rerun recording
to ``OUT/rrd/<stage>.rrd`` (same application and recording id for all stages) as soon as it
finishes, atomically; a stage that fails is recorded in ``OUT/run.toml`` with its error and
the others' outputs stay. Stages that depend on a missing or failed input are skipped with
the reason.
"""

from __future__ import annotations

import os
import sys
import time
import tomllib
import traceback
import uuid
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import polars as pl

from onebit.datasets.region_graph import RegionGraph, build_region_graph
from onebit.datasets.site import Site, load_site
from onebit.errors import ConfigError, InputError, OnebitError
from onebit.pipeline import outputs
from onebit.pipeline.scores import (
    ScoresConfig,
    assignment_scores,
    error_summary,
    match_crossings,
    region_scores,
    true_crossings_from_truth,
    truth_regions,
)
from onebit.readers.rows import RawRows, read_csv_rows
from onebit.tables import REJECTS, REPORT
from onebit.trackers import load_trackers
from onebit.trackers.base import REGISTRY, config_from_mapping

load_trackers()


@dataclass
class RunContext:
    """What the stages share during one run."""

    dataset: Path
    out: Path
    site: Site
    region_graph: RegionGraph
    config: dict[str, Any]
    tables: dict[str, pl.DataFrame] = field(default_factory=dict)
    report: list[tuple[str, str, float, str]] = field(default_factory=list)
    mcap_channels: dict[str, RawRows] = field(default_factory=dict)
    trackers: tuple[str, ...] = ("beams",)
    status: dict[str, str] = field(default_factory=dict)

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

    def add_rejects(self, rej: pl.DataFrame) -> None:
        if rej is not None and rej.height:
            old = self.tables.get("rejects", pl.DataFrame(schema=REJECTS))
            self.tables["rejects"] = pl.concat([old, rej.select(REJECTS.names()).cast(dict(REJECTS))])


@dataclass(frozen=True)
class Stage:
    """A named pipeline stage: what it needs, what it makes, and the work."""

    name: str
    needs: tuple[str, ...]  # tables produced by earlier stages
    makes: tuple[str, ...]
    available: Callable[[RunContext], str | None]  # reason to skip, or None
    work: Callable[[RunContext, Any], dict[str, pl.DataFrame]]


# --------------------------------------------------------------------------- stages


def _crossings_available(ctx: RunContext) -> str | None:
    if ctx.has_source("beams") or ctx.has_source("crossings"):
        return None
    return "no beams.csv, crossings.csv or /beams, /crossings MCAP channel in the dataset"


def _crossings_work(ctx: RunContext, log) -> dict[str, pl.DataFrame]:
    from onebit.readers.beams import BEAM_COLUMNS, decode_raw_beams
    from onebit.readers.tables_csv import crossings_from_rows

    site = ctx.site
    out: dict[str, pl.DataFrame] = {}
    if ctx.has_source("beams"):
        raw, path = ctx.source("beams", BEAM_COLUMNS)
        dec = decode_raw_beams(raw, site.beam_ids, epoch=site.epoch, path=path)
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
        raw, path = ctx.source("crossings", ("t", "beam", "direction"))
        cr, rej = crossings_from_rows(raw, site.beam_ids, epoch=site.epoch, path=path)
        ctx.add_rejects(rej)
        out["crossings"] = cr
        ctx.report.append(("crossings", "decoded", float(cr.height), "crossings"))
    log.crossings(out["crossings"], out.get("aborted"))
    return out


def _truth_available(ctx: RunContext) -> str | None:
    return None if ctx.has_source("truth") else "no truth.csv or /truth MCAP channel in the dataset"


def _truth_work(ctx: RunContext, log) -> dict[str, pl.DataFrame]:
    from onebit.readers.tables_csv import true_crossings_columns, true_crossings_from_rows, truth_from_rows

    raw, path = ctx.source("truth", ("t", "target", "x", "y"))
    truth, rej = truth_from_rows(raw, epoch=ctx.site.epoch, path=path)
    ctx.add_rejects(rej)
    truth = truth_regions(truth, ctx.region_graph)
    out = {"truth": truth, "true_crossings": true_crossings_from_truth(truth, ctx.site, ctx.region_graph)}
    if ctx.has_source("truth_crossings"):
        raw, path = ctx.source("truth_crossings", true_crossings_columns(ctx.dataset / "truth_crossings.csv"))
        sim_cr, rej = true_crossings_from_rows(raw, ctx.site.beam_ids, epoch=ctx.site.epoch, path=path)
        ctx.add_rejects(rej)
        out["sim_crossings"] = sim_cr
    log.truth(truth)
    return out


def _camera_available(ctx: RunContext) -> str | None:
    if not (ctx.dataset / "camera.mp4").exists():
        return "no camera.mp4 in the dataset"
    if ctx.site.camera is None:
        return "camera.mp4 present but site.toml has no [camera]"
    return None


def _camera_work(ctx: RunContext, log) -> dict[str, pl.DataFrame]:
    from onebit.readers.camera import read_camera, truth_error

    res = read_camera(ctx.dataset / "camera.mp4", ctx.site)
    ctx.add_rejects(res.rejects)
    cam_truth = truth_regions(res.truth, ctx.region_graph)
    ctx.report.append(("camera", "frames", float(res.frames), "frames"))
    ctx.report.append(("camera", "tracks", float(cam_truth["target"].n_unique()) if cam_truth.height else 0.0, "tracks"))
    if "truth" in ctx.tables:
        err = truth_error(res.truth, ctx.tables["truth"], diagonal=ctx.site.diagonal)
        ctx.report += [
            ("camera", "truth_error", float(err["mean"]), ctx.site.units),
            ("camera", "truth_error_rel", float(err["rel"]), "fraction of diagonal"),
            ("camera", "missed", float(err["missed"]), "points"),
        ]
    log.point_tracks("camera", cam_truth.with_columns(track=pl.col("target"), tracker=pl.lit("camera")))
    return {"camera_truth": cam_truth, "camera_detections": res.detections}


#: (tracker, input table) -> the table fed instead when an earlier stage made it
#: (the ``correct`` stage's false-negative-corrected crossings for the beams tracker).
INPUT_ALIASES: dict[tuple[str, str], str] = {("beams", "crossings"): "corrected_crossings"}


def _input_table(ctx: RunContext, tracker: str, key: str) -> pl.DataFrame:
    alias = INPUT_ALIASES.get((tracker, key))
    return ctx.tables[alias] if alias in ctx.tables else ctx.tables[key]


def _tracker_stage(name: str) -> Stage:
    spec = REGISTRY[name]

    def available(ctx: RunContext) -> str | None:
        if name not in ctx.trackers:
            return f"tracker '{name}' not selected (--trackers)"
        if spec.available is not None:
            return spec.available(ctx.site)
        return None

    def work(ctx: RunContext, log) -> dict[str, pl.DataFrame]:
        cfg = config_from_mapping(spec.config, ctx.config.get(name), section=name)
        inputs = {k: _input_table(ctx, name, k) for k in spec.needs}
        inputs.update({k: ctx.tables[k] for k in spec.wants if k in ctx.tables})
        inputs["region_graph"] = ctx.region_graph
        out = spec.run(inputs, ctx.site, cfg, log)
        ctx.config.setdefault(name, {}).update(asdict(cfg))
        return {f"{name}_{k}" if k != "tracks" else f"{name}_tracks": v for k, v in out.items()}

    return Stage(name, spec.needs, (), available, work)


def _scores_available(ctx: RunContext) -> str | None:
    return None


def _scores_work(ctx: RunContext, log) -> dict[str, pl.DataFrame]:
    cfg = config_from_mapping(ScoresConfig, ctx.config.get("scores"), section="scores")
    ctx.config.setdefault("scores", {}).update(asdict(cfg))
    out: dict[str, pl.DataFrame] = {}
    t = ctx.tables
    if "crossings" in t and "true_crossings" in t:
        m = match_crossings(t["crossings"], t["true_crossings"], cfg.crossing_tolerance_s)
        n_true = t["true_crossings"].height
        recovered = m["true_id"].drop_nulls().n_unique()
        ctx.report.append(("crossings", "decoded_match", recovered / n_true if n_true else 1.0, "fraction"))
        ctx.report.append(("crossings", "true", float(n_true), "crossings"))
        ctx.report.append(("crossings", "spurious", float(m["true_id"].null_count()), "crossings"))
        out["crossing_matches"] = m
        beams_m = m  # true target of every crossing the beams tracker read
        if "corrected_crossings" in t:
            from onebit.pipeline.stages_correct import score_correction

            rows, tables, beams_m = score_correction(t, m)
            ctx.report += rows
            out.update(tables)
        if "beams_assignment" in t:
            acc, mapping = assignment_scores(beams_m, t["beams_assignment"])
            n_true_agents = t["truth"]["target"].n_unique()
            n_rec = t["beams_agents"].height
            ctx.report += [
                ("beams", "assignment_accuracy", acc, "fraction"),
                ("beams", "agent_count_error", float(n_rec - n_true_agents), "agents"),
                ("beams", "agents", float(n_rec), "agents"),
            ]
            sc = region_scores(t["beams_tracks"], t["truth"], mapping, ctx.region_graph, tracker="beams")
            ctx.report += error_summary(sc, stage="beams", unit=ctx.site.units)
            out["scores"] = sc
            log.scores("beams", sc)
    for name in ctx.trackers:
        spec = REGISTRY[name]
        if spec.score is None or ctx.status.get(name, "").split(" ")[0] != "ok":
            continue
        rows, tables = spec.score(t, ctx.site, log)
        ctx.report += rows
        out.update(tables)
    if "sim_crossings" in t and "true_crossings" in t:
        # how well truth positions reproduce the simulator's own crossing list
        m2 = match_crossings(t["true_crossings"], t["sim_crossings"], cfg.crossing_tolerance_s)
        n = t["sim_crossings"].height
        ctx.report.append(("truth", "crossings_from_positions", m2["true_id"].drop_nulls().n_unique() / n if n else 1.0, "fraction"))
    rej = t.get("rejects", pl.DataFrame(schema=REJECTS))
    ctx.report.append(("rejects", "rows", float(rej.height), "rows"))
    return out


def stages() -> list[Stage]:
    """The declared pipeline: reader stages, contributed stages, one stage per tracker, scores."""
    from onebit.pipeline.plugins import extra_stages

    return [
        Stage("crossings", (), ("crossings", "aborted", "beam_events"), _crossings_available, _crossings_work),
        Stage("truth", (), ("truth", "true_crossings"), _truth_available, _truth_work),
        Stage("camera", (), ("camera_truth", "camera_detections"), _camera_available, _camera_work),
        *extra_stages(),
        *[_tracker_stage(name) for name in REGISTRY],
        Stage("scores", (), ("crossing_matches", "scores"), _scores_available, _scores_work),
    ]


# --------------------------------------------------------------------------- running


@dataclass
class RunResult:
    out: Path
    status: dict[str, str]
    report: pl.DataFrame
    ok: bool


def load_run_config(path: str | Path | None) -> dict[str, Any]:
    if path is None:
        return {}
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read config: {exc.strerror}", file=path) from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}", file=path) from None
    return {k: v for k, v in data.items() if isinstance(v, dict)}


def run_pipeline(
    dataset: str | Path,
    out: str | Path,
    *,
    trackers: tuple[str, ...] | None = None,
    config: dict[str, Any] | None = None,
    progress: bool | None = None,
    echo: Callable[[str], None] | None = None,
) -> RunResult:
    """Run every available stage on ``dataset``, writing the run folder ``out``."""
    from onebit.viz import StageLog, send_blueprint, stage_recording

    dataset, out = Path(dataset), Path(out)
    echo = echo or (lambda s: None)
    if not dataset.is_dir():
        raise InputError("dataset folder does not exist", file=dataset)
    site = load_site(dataset / "site.toml")
    rg = build_region_graph(site)
    trackers = tuple(trackers) if trackers else tuple(REGISTRY)
    for tr in trackers:
        if tr not in REGISTRY:
            raise ConfigError(f"--trackers: unknown tracker {tr!r}; known: {sorted(REGISTRY)}")
    ctx = RunContext(dataset, out, site, rg, dict(config or {}), trackers=trackers)
    (out / "tables").mkdir(parents=True, exist_ok=True)
    (out / "rrd").mkdir(parents=True, exist_ok=True)
    recording_id = str(uuid.uuid4())
    status = ctx.status

    mcaps = sorted(dataset.glob("*.mcap"))
    if mcaps:
        from onebit.readers.mcap_io import read_mcap

        for mp in mcaps:
            try:
                contents = read_mcap(mp)
            except OnebitError as exc:
                status[f"mcap:{mp.name}"] = f"failed: {exc}"
                echo(f"  {mp.name}: failed: {exc}")
                continue
            ctx.add_rejects(contents.rejects)
            for topic, frame in contents.channels.items():
                ctx.mcap_channels.setdefault(topic, RawRows(f"{mp.name}:{topic}", frame, pl.DataFrame(schema=REJECTS)))

    stage_list = stages()
    bar = _progress(progress, len(stage_list))
    started = time.time()
    for st in stage_list:
        missing = [n for n in st.needs if n not in ctx.tables]
        reason = st.available(ctx)
        if reason is None and missing:
            reason = f"input table(s) {missing} not produced by an earlier stage"
        if reason is not None:
            status[st.name] = f"skipped: {reason}"
            echo(f"  {st.name}: skipped ({reason})")
            bar.advance(st.name)
            continue
        t0 = time.time()
        try:
            with stage_recording(out, st.name, recording_id) as rec:
                log = StageLog(rec)
                log.site(site, rg)
                send_blueprint(rec, trackers=list(trackers))
                made = st.work(ctx, log)
        except OnebitError as exc:
            status[st.name] = f"failed: {exc}"
            echo(f"  {st.name}: FAILED: {exc}")
            bar.advance(st.name)
            continue
        except Exception as exc:  # a bug, not bad input: keep the other stages, keep the traceback
            tb = traceback.format_exc(limit=8)
            status[st.name] = f"failed: {type(exc).__name__}: {exc}"
            outputs.write_text(tb, out / "logs" / f"{st.name}.traceback.txt")
            echo(f"  {st.name}: FAILED with {type(exc).__name__}: {exc} (traceback in logs/{st.name}.traceback.txt)")
            bar.advance(st.name)
            continue
        for name, df in made.items():
            ctx.tables[name] = df
            outputs.write_parquet(df, out / "tables" / f"{name}.parquet")
        status[st.name] = f"ok ({time.time() - t0:.2f} s)"
        echo(f"  {st.name}: ok")
        bar.advance(st.name)
    bar.close()

    rejects = ctx.tables.get("rejects", pl.DataFrame(schema=REJECTS))
    outputs.write_parquet(rejects, out / "tables" / "rejects.parquet")
    report = pl.DataFrame(ctx.report, schema=REPORT, orient="row")
    outputs.write_parquet(report, out / "report.parquet")
    outputs.write_csv(report, out / "report.csv")
    ok = all(not s.startswith("failed") for s in status.values())
    run_doc = {
        "dataset": str(dataset.resolve()),
        "recording_id": recording_id,
        "site": site.name,
        "trackers": list(trackers),
        "seconds": round(time.time() - started, 3),
        "ok": ok,
        "stages": status,
        "summary": {"rejects": rejects.height, "tables": sorted(ctx.tables)},
        **{k: v for k, v in ctx.config.items() if isinstance(v, dict)},
    }
    outputs.write_text(outputs.to_toml(run_doc), out / "run.toml")
    return RunResult(out, status, report, ok)


class _NoBar:
    def advance(self, name: str) -> None:
        pass

    def close(self) -> None:
        pass


class _RichBar:
    def __init__(self, total: int) -> None:
        from rich.progress import Progress

        self.p = Progress(transient=True)
        self.p.start()
        self.task = self.p.add_task("stages", total=total)

    def advance(self, name: str) -> None:
        self.p.update(self.task, advance=1, description=name)

    def close(self) -> None:
        self.p.stop()


def _progress(progress: bool | None, total: int):
    if progress is None:
        progress = sys.stderr.isatty() and not os.environ.get("CI")
    return _RichBar(total) if progress else _NoBar()
