"""``onebit experiment ceiling OUT --data CLONE [--sequences a,b,...]``: every positional tracker on the real ceiling array.

The experiment runs on every sequence of Milan et al.'s ``irtracking`` recordings found in the
clone (:func:`find_sequences`: a ``SEQ_gt.xml`` truth with its ``SEQ.txt`` readings or
``SEQ.xml`` detections, in ``CLONE/data`` or ``CLONE``), or on those named by ``--sequences``
(an unknown name is an error that lists the sequences found). For each sequence it

1. imports it (``onebit import irtracking``: ``SEQ.txt``, else the ``SEQ.xml`` detections, with
   ``SEQ_gt.xml`` as truth) into ``OUT/datasets/SEQ``, ``targets`` not from the truth;
2. runs the pipeline with every onebit tracker that answers with positions (those whose inputs
   the dataset lacks are listed as skipped, with the reason), scored at 1.0 and 1.5 m
   (``[scores] gates_m = [1.0, 1.5]``; 1.5 m is the authors' ``CLEAR_MOT.m`` threshold), every
   frame scored (:mod:`onebit.scoring.mot`);
3. scores the peers with the same scorer: the **room centre** (one track at the room's centre
   at every frame: what a tracker that knows nothing answers) and the **Stone Soup** GNN and
   JPDA Kalman trackers fed every firing sensor as a point detection
   (:mod:`onebit.experiments.peers.stonesoup`). Stone Soup is the ``bench`` extra
   (``pip install 'onebit[bench]'``); without it its rows say so and the rest runs.

Writes ``results.csv`` / ``results.parquet`` (one row per sequence and tracker: status,
``mota@1m``, ``mota@1.5m``, ``idf1@1m``, ``idf1@1.5m``, ``hota@1m``, ``hota@1.5m``,
``count_error`` (people per frame), ``max_tracks``, ``seconds``) and prints the table.
``--quick``: the two short sequences :data:`QUICK` (when ``--sequences`` is not given).
"""

from __future__ import annotations

import time
from pathlib import Path

import polars as pl

from onebit.core import writers
from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.datasets.irtracking import import_irtracking
from onebit.experiments.peers import stonesoup
from onebit.experiments.trials import format_table
from onebit.pipeline.executors import Executor
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import TRACKERS
from onebit.readers.tables_csv import read_truth_csv
from onebit.scoring.mot import metric_gate_rows

#: The two short sequences of the irtracking clone: ``--quick``.
QUICK = ("testanton", "s1-easy")
#: The truth file of a sequence is ``SEQ`` + this.
TRUTH_SUFFIX = "_gt.xml"
GATES_M = (1.0, 1.5)
#: Every onebit tracker whose tracks are positions (beams answers in regions of a beam site).
POSITIONAL = tuple(e.name for e in TRACKERS if e.name != "beams")
COLUMNS = ("mota@1m", "mota@1.5m", "idf1@1m", "idf1@1.5m", "hota@1m", "hota@1.5m", "count_error", "max_tracks")
RESULT_SCHEMA = pl.Schema(
    {
        "sequence": pl.String,
        "tracker": pl.String,
        "status": pl.String,
        **{c: pl.Float64 for c in COLUMNS},
        "seconds": pl.Float64,
    }
)


def data_folder(data: Path) -> Path:
    """Where the sequences are: ``data/data`` in a clone of the repository, else ``data`` itself."""
    data = Path(data)
    if not data.is_dir():
        raise InputError("not a folder (is --data the irtracking clone?)", file=data)
    return data / "data" if (data / "data").is_dir() else data


def find_sequences(data: Path) -> tuple[str, ...]:
    """Every sequence in the clone, sorted by name: each ``SEQ_gt.xml`` (truth) that has
    ``SEQ.txt`` (readings) or ``SEQ.xml`` (detections) beside it."""
    folder = data_folder(data)
    names = (p.name[: -len(TRUTH_SUFFIX)] for p in folder.glob(f"*{TRUTH_SUFFIX}"))
    return tuple(sorted(n for n in names if n and ((folder / f"{n}.txt").is_file() or (folder / f"{n}.xml").is_file())))


def choose_sequences(data: Path, sequences: tuple[str, ...] | None = None, *, quick: bool = False) -> tuple[str, ...]:
    """The sequences to run, in table order: ``sequences`` if given (each must be in the clone),
    else :data:`QUICK` with ``quick``, else every sequence found (:func:`find_sequences`)."""
    found = find_sequences(data)
    if not found:
        raise InputError(
            f"no irtracking sequence here (a SEQ{TRUTH_SUFFIX} with SEQ.txt or SEQ.xml; is --data the irtracking clone?)",
            file=data_folder(data),
        )
    if sequences is not None and not tuple(sequences):
        raise InputError(f"names no sequence; found: {', '.join(found)}", field="sequences")
    chosen = tuple(sequences) if sequences is not None else (QUICK if quick else found)
    for name in chosen:
        if name not in found:
            raise InputError(
                f"unknown sequence {name!r}: no {name}{TRUTH_SUFFIX} with {name}.txt or {name}.xml in "
                f"{data_folder(data)}; found: {', '.join(found)}",
                field="sequences",
            )
    return tuple(dict.fromkeys(chosen))


def sequence_files(data: Path, name: str) -> tuple[Path, Path]:
    """(readings, truth) of a sequence: ``SEQ.txt`` (else ``SEQ.xml``) and ``SEQ_gt.xml``."""
    folder = data_folder(data)
    readings = folder / f"{name}.txt"
    if not readings.exists():
        readings = folder / f"{name}.xml"
    truth = folder / f"{name}{TRUTH_SUFFIX}"
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
    """The Stone Soup peer module (the library itself is imported when a peer runs)."""
    return stonesoup


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
    stonesoup = _stonesoup()
    why = stonesoup.missing()
    for label, jpda in (("stonesoup-gnn", False), ("stonesoup-jpda", True)):
        if why is not None:
            rows.append(_row(name, label, f"skipped: {why}", {}, None))
            continue
        t0 = time.perf_counter()
        tracks = stonesoup.track(levels, site, jpda=jpda, name=label)
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
    sequences: tuple[str, ...] | None = None,
) -> Path:
    """The registered entry point (see :mod:`onebit.experiments`); ``data`` is the irtracking
    clone (``--data``); ``sequences`` picks sequences of it (``--sequences``, default every one
    found: :func:`choose_sequences`); ``trackers`` picks onebit trackers (default
    :data:`POSITIONAL`). ``seed``/``trials``/``executor`` do not apply (the recordings are
    fixed; one pass)."""
    if data is None:
        raise InputError(
            "the ceiling experiment needs the irtracking recordings: onebit experiment ceiling OUT --data CLONE",
            field="data",
        )
    data, out = Path(data), Path(out)
    chosen = tuple(trackers) if trackers else POSITIONAL
    unknown = [t for t in chosen if t not in POSITIONAL]
    if unknown:
        raise InputError(f"unknown positional tracker {unknown[0]!r}; known: {list(POSITIONAL)}", field="trackers")
    names = choose_sequences(data, sequences, quick=quick)
    why = _stonesoup().missing()
    if why is not None:
        echo(f"note: {why}; the other rows run")
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in names:
        rows += one_sequence(data, out, name, trackers=chosen, echo=echo)
    results = pl.DataFrame(rows, schema=RESULT_SCHEMA)
    writers.write_parquet(results, out / "results.parquet")
    writers.write_csv(results, out / "results.csv")
    shown = results.filter(~pl.col("status").str.starts_with("skipped: tracker")).with_columns(
        [pl.col(c).round(3) for c in (*COLUMNS, "seconds")]
    )
    echo(format_table(shown))
    return out
