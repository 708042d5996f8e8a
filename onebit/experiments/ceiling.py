"""``onebit experiment ceiling OUT --data DIR``: every positional tracker on the real ceiling array.

For each sequence of Milan et al.'s ``irtracking`` recordings a user may develop on
(:data:`SEQUENCES`: the synthetic ``s1-easy/medium/hard``, ``testanton``, ``testanton-long``
and the real ``r1-easy``; ``r1-medium`` and ``r1-hard`` are held out and **never** imported or
run here, :data:`HELD_OUT`), the experiment

1. imports it (``onebit import irtracking``: ``SEQ.txt``, else the ``SEQ.xml`` detections, with
   ``SEQ_gt.xml`` as truth) into ``OUT/datasets/SEQ``, ``targets`` not from the truth;
2. runs the pipeline with every onebit tracker that answers with positions (those whose inputs
   the dataset lacks are listed as skipped, with the reason), scored at 1.0 and 1.5 m
   (``[scores] gates_m = [1.0, 1.5]``; 1.5 m is the authors' ``CLEAR_MOT.m`` threshold), every
   frame scored (:mod:`onebit.scoring.mot`);
3. scores two baselines with the same scorer: the **room centre** (one track at the room's
   centre at every frame: what a tracker that knows nothing answers) and, when Stone Soup is
   installed (``pip install -e .[bench]``) and the repository's ``benchmarks`` package is
   importable (run from the repository), **Stone Soup** GNN and JPDA Kalman trackers fed every
   firing sensor as a point detection (``benchmarks/stonesoup_ceiling.py``).

Writes ``results.csv`` / ``results.parquet`` (one row per sequence and tracker: status,
``mota@1m``, ``mota@1.5m``, ``idf1@1m``, ``idf1@1.5m``, ``count_error`` (people per frame),
``max_tracks``, ``seconds``) and prints the table. ``--quick``: the two short sequences only.
"""

from __future__ import annotations

import importlib
import time
from pathlib import Path

import polars as pl

from onebit.core import writers
from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.datasets.irtracking import import_irtracking
from onebit.experiments.trials import format_table
from onebit.pipeline.executors import Executor
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import TRACKERS
from onebit.readers.tables_csv import read_truth_csv
from onebit.scoring.mot import metric_gate_rows

#: The sequences a user may develop on, in the order of the table.
SEQUENCES = ("s1-easy", "s1-medium", "s1-hard", "testanton", "testanton-long", "r1-easy")
#: Held out for evaluation: never imported, run or looked at by this experiment.
HELD_OUT = ("r1-medium", "r1-hard")
QUICK = ("testanton", "s1-easy")
GATES_M = (1.0, 1.5)
#: Every onebit tracker whose tracks are positions (beams answers in regions of a beam site).
POSITIONAL = tuple(e.name for e in TRACKERS if e.name != "beams")
COLUMNS = ("mota@1m", "mota@1.5m", "idf1@1m", "idf1@1.5m", "count_error", "max_tracks")
RESULT_SCHEMA = pl.Schema(
    {
        "sequence": pl.String,
        "tracker": pl.String,
        "status": pl.String,
        **{c: pl.Float64 for c in COLUMNS},
        "seconds": pl.Float64,
    }
)


def sequence_files(data: Path, name: str) -> tuple[Path, Path]:
    """(readings, truth) of a sequence: ``data/SEQ.txt`` (else ``SEQ.xml``) and ``data/SEQ_gt.xml``."""
    if name in HELD_OUT:
        raise InputError(f"{name} is held out for evaluation: this experiment never reads it", field="sequence")
    folder = data / "data" if (data / "data").is_dir() else data
    readings = folder / f"{name}.txt"
    if not readings.exists():
        readings = folder / f"{name}.xml"
    truth = folder / f"{name}_gt.xml"
    for p in (readings, truth):
        if not p.exists():
            raise InputError("missing (is --data the irtracking clone?)", file=p)
    return readings, truth


def room_centre_tracks(times, site, name: str = "room-centre") -> pl.DataFrame:
    """One track at the centre of the room's bounding box at every time: the know-nothing answer."""
    minx, miny, maxx, maxy = site.boundary.bounds
    t = pl.Series("t", times, dtype=pl.Float64).unique().sort()
    return pl.DataFrame({"tracker": name, "track": f"{name}-0", "t": t, "x": (minx + maxx) / 2, "y": (miny + maxy) / 2})


def _stonesoup():
    """The Stone Soup baseline module, or the reason it cannot run."""
    try:
        importlib.import_module("stonesoup")
    except ImportError:
        return None, "Stone Soup not installed (pip install -e .[bench])"
    try:
        return importlib.import_module("benchmarks.stonesoup_ceiling"), None
    except ImportError:
        return None, "benchmarks/stonesoup_ceiling.py not importable (run from the repository)"


def _row(sequence: str, tracker: str, status: str, rows: dict, seconds: float | None) -> dict:
    return {
        "sequence": sequence,
        "tracker": tracker,
        "status": status,
        **{c: rows.get(c) for c in COLUMNS},
        "seconds": seconds,
    }


def one_sequence(data: Path, out: Path, name: str, *, trackers: tuple[str, ...], echo=print) -> list[dict]:
    readings, truth_xml = sequence_files(data, name)
    ds = out / "datasets" / name
    import_irtracking(readings, ds, truth=truth_xml)
    res = run_pipeline(
        ds, out / "runs" / name, trackers=trackers, config={"scores": {"gates_m": list(GATES_M)}}, progress=False
    )
    timings = (
        pl.read_parquet(res.out / "tables" / "timings.parquet")
        if (res.out / "tables" / "timings.parquet").exists()
        else None
    )
    secs = dict(zip(timings["stage"], timings["seconds"])) if timings is not None else {}
    rows = []
    for tr in trackers:
        status = res.status.get(tr, "not run")
        got = {c: metric(res.report, f"{tr}/{c}") for c in COLUMNS} if status.startswith("ok") else {}
        rows.append(_row(name, tr, status.split(" (")[0] if status.startswith("ok") else status, got, secs.get(tr)))
    site = load_site(ds / "site.toml")
    truth, _ = read_truth_csv(ds / "truth.csv")
    levels = pl.read_parquet(res.out / "tables" / "levels.parquet")
    t0 = time.perf_counter()
    centre = room_centre_tracks(levels["t"], site)
    sec = time.perf_counter() - t0
    rows.append(
        _row(
            name,
            "room-centre",
            "ok",
            {r[1]: r[2] for r in metric_gate_rows("room-centre", centre, truth, site, GATES_M)},
            sec,
        )
    )
    mod, why = _stonesoup()
    for label, jpda in (("stonesoup-gnn", False), ("stonesoup-jpda", True)):
        if mod is None:
            rows.append(_row(name, label, f"skipped: {why}", {}, None))
            continue
        t0 = time.perf_counter()
        tracks = mod.track(levels, site, jpda=jpda, name=label)
        sec = time.perf_counter() - t0
        rows.append(
            _row(name, label, "ok", {r[1]: r[2] for r in metric_gate_rows(label, tracks, truth, site, GATES_M)}, sec)
        )
    echo(f"  {name}: done")
    return rows


def run(
    out: Path,
    *,
    seed: int = 0,
    trials: int | None = None,
    quick: bool = False,
    echo=print,
    executor: Executor | None = None,
    data: str | Path | None = None,
    trackers: tuple[str, ...] | None = None,
) -> Path:
    """The registered entry point (see :mod:`onebit.experiments`); ``data`` is the irtracking
    clone (``--data``); ``trackers`` picks onebit trackers (default :data:`POSITIONAL`).
    ``seed``/``trials``/``executor`` do not apply (the recordings are fixed; one pass)."""
    if data is None:
        raise InputError(
            "the ceiling experiment needs the irtracking recordings: onebit experiment ceiling OUT --data DIR",
            field="data",
        )
    data, out = Path(data), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    chosen = tuple(trackers) if trackers else POSITIONAL
    unknown = [t for t in chosen if t not in POSITIONAL]
    if unknown:
        raise InputError(f"unknown positional tracker {unknown[0]!r}; known: {list(POSITIONAL)}", field="trackers")
    rows = []
    for name in QUICK if quick else SEQUENCES:
        rows += one_sequence(data, out, name, trackers=chosen, echo=echo)
    results = pl.DataFrame(rows, schema=RESULT_SCHEMA)
    writers.write_parquet(results, out / "results.parquet")
    writers.write_csv(results, out / "results.csv")
    shown = results.filter(~pl.col("status").str.starts_with("skipped: tracker")).with_columns(
        [pl.col(c).round(3) for c in (*COLUMNS, "seconds")]
    )
    echo(format_table(shown))
    return out
