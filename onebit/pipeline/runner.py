"""The runner: runs the declared stage list (:mod:`onebit.pipeline.stages`) on a dataset.

``run_pipeline(dataset, out)`` loads the site, then runs every stage whose inputs exist, in
order. Each stage writes its tables to ``OUT/tables/<name>.parquet`` and its Rerun recording
to ``OUT/rrd/<stage>.rrd`` (same application and recording id for all stages) as soon as it
finishes, atomically; a stage that fails is recorded in ``OUT/run.toml`` with its error and
the others' outputs stay. Stages that depend on a missing or failed input are skipped with
the reason. The runner times every stage (``timings`` table); stages never read the clock.
"""

from __future__ import annotations

import os
import sys
import time
import tomllib
import traceback
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import polars as pl
from rich.progress import Progress

from onebit.core import writers as outputs
from onebit.core.errors import ConfigError, InputError, OnebitError
from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.core.tables import REJECTS, REPORT
from onebit.pipeline.context import RunContext
from onebit.pipeline.stages import TRACKERS, TrackerEntry, stages
from onebit.readers.mcap_io import read_mcap
from onebit.readers.rows import RawRows
from onebit.trackers.base import ARTIFACTS
from onebit.viz.blueprint import send_blueprint
from onebit.viz.recording import stage_recording
from onebit.viz.site import log_site


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
    tracker_entries: tuple[TrackerEntry, ...] = TRACKERS,
    progress: bool | None = None,
    echo: Callable[[str], None] | None = None,
) -> RunResult:
    """Run every available stage on ``dataset``, writing the run folder ``out``.

    ``trackers`` selects trackers by name (default: all); ``config`` holds ``run.toml``
    sections; ``tracker_entries`` is the tracker list of the stage list (a test or an
    extension may pass its own, see ``docs/extending.md``).
    """
    dataset, out = Path(dataset), Path(out)
    echo = echo or (lambda s: None)
    if not dataset.is_dir():
        raise InputError("dataset folder does not exist", file=dataset)
    site = load_site(dataset / "site.toml")
    rg = build_region_graph(site)
    known = [e.name for e in tracker_entries]
    trackers = tuple(trackers) if trackers else tuple(known)
    for tr in trackers:
        if tr not in known:
            raise ConfigError(f"--trackers: unknown tracker {tr!r}; known: {sorted(known)}")
    ctx = RunContext(dataset, out, site, rg, dict(config or {}), trackers=trackers)
    (out / "tables").mkdir(parents=True, exist_ok=True)
    (out / "rrd").mkdir(parents=True, exist_ok=True)
    recording_id = str(uuid.uuid4())
    status = ctx.status

    mcaps = sorted(dataset.glob("*.mcap"))
    if mcaps:
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

    stage_list = stages(tracker_entries)
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
        t0 = time.perf_counter()
        try:
            with stage_recording(out, st.name, recording_id) as rec:
                log_site(rec, site, rg)
                send_blueprint(rec, trackers=list(trackers))
                made = st.work(ctx)
                ctx.seconds[st.name] = time.perf_counter() - t0
                if st.viz is not None:
                    st.viz(rec, ctx, made)
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
            if name == ARTIFACTS:  # in-memory results for the stage's viz only
                continue
            ctx.tables[name] = df
            outputs.write_parquet(df, out / "tables" / f"{name}.parquet")
        status[st.name] = f"ok ({ctx.seconds[st.name]:.2f} s)"
        echo(f"  {st.name}: ok")
        for part, state in status.items():  # parts of a stage that failed on their own (scores/<tracker>)
            if part.startswith(f"{st.name}/"):
                echo(f"  {part}: {state}")
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
