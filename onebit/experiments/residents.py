"""``onebit experiment residents DIR``: who is who at home, on every CASAS session of a folder.

Every CASAS session file of ``DIR`` (``*.txt``, and pymrt ``*.csv`` event logs; sorted by name:
``P01.txt``, ``P02.txt``, ...) is imported (:func:`onebit.datasets.importers.import_casas`,
with the options given: a floor plan, rooms, scale, doors, targets) into
``RESULTS/datasets/<session>`` and run (:func:`onebit.pipeline.runner.run_pipeline`) with the
chosen trackers into ``RESULTS/runs/<session>``; the identity scores of each tracker and of the
two baselines (:mod:`onebit.scoring.identity`) are collected into one table, one row per
session and method:

``session, method, status, accuracy, ari, switches_per_hour, count_error, attributed, events, seconds``

(``seconds``: the tracker's stage time measured by the runner; null for the baselines), written
to ``RESULTS/results.csv`` and ``results.parquet`` (every identity error of the ``residents``
tracker, with where the other resident was, to ``RESULTS/errors.csv``), with the mean over sessions per method
(``session = "mean"``) appended. A tracker that fails on a session is a row with its status
and null scores, never a dropped row. ``RESULTS`` defaults to ``DIR/residents-study``.

With ``--cross-validate`` (leave one session out) each session's dataset also gets the
``residents_profile.csv`` learned from all the other sessions (:mod:`onebit.pipeline.learn`),
so the ``residents`` tracker decodes it with known residents, and the supervised baseline
``baseline-habits`` is added; no session's own labels are used to decode it.

Only the files in ``DIR`` are read: to run some sessions, point it at a folder that holds
those (e.g. symbolic links to P01.txt..P13.txt).
"""

from __future__ import annotations

from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.core.writers import write_csv, write_parquet
from onebit.datasets.importers import import_casas
from onebit.pipeline.learn import learn_residents, write_profile
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import TRACKERS
from onebit.scoring.identity import ERRORS, error_table, graph_hops
from onebit.trackers.residents.known import Clock

#: The multi-person trackers of a motion log, which write ``<tracker>_events`` (the default
#: ``--trackers``): from their declarations, in the pipeline's order.
DEFAULT_TRACKERS = tuple(e.name for e in TRACKERS if e.spec.counts_people and e.spec.needs == ("motion",))
#: The baselines' report stages and their names here.
BASELINES = {
    "identity-busier": "baseline-busier",
    "identity-nearest": "baseline-nearest",
    "identity-habits": "baseline-habits",
}

RESULTS = pl.Schema(
    {
        "session": pl.String,
        "method": pl.String,
        "status": pl.String,
        "accuracy": pl.Float64,
        "ari": pl.Float64,
        "switches_per_hour": pl.Float64,
        "count_error": pl.Float64,
        "attributed": pl.Float64,
        "events": pl.Float64,
        "seconds": pl.Float64,
    }
)
_METRICS = {
    "identity_accuracy": "accuracy",
    "identity_ari": "ari",
    "identity_switches_per_hour": "switches_per_hour",
    "count_error_per_minute": "count_error",
    "identity_attributed": "attributed",
    "identity_events": "events",
}


def sessions(folder: Path) -> list[Path]:
    """The session files of ``folder``: ``*.txt`` and ``*.csv``, sorted by name (not README)."""
    files = sorted(
        p
        for p in folder.iterdir()
        if p.is_file() and p.suffix.lower() in (".txt", ".csv") and not p.name.lower().startswith("readme")
    )
    if not files:
        raise InputError("no CASAS session files (*.txt, *.csv) in this folder", file=folder)
    return files


def session_rows(
    session: str, report: pl.DataFrame, status: dict[str, str], trackers: tuple[str, ...], timings: pl.DataFrame | None
) -> list[dict]:
    """One row per tracker and baseline of one session's run report."""
    rows = []
    for stage, method in [(t, t) for t in trackers] + list(BASELINES.items()):
        sub = report.filter(pl.col("stage") == stage)
        row = {"session": session, "method": method, "status": status.get(stage, "ok") if stage in trackers else "ok"}
        for metric, col in _METRICS.items():
            v = sub.filter(pl.col("metric") == metric)["value"]
            row[col] = float(v[0]) if v.len() else None
        secs = (
            timings.filter(pl.col("stage") == stage)["seconds"]
            if timings is not None and stage in trackers
            else pl.Series([], dtype=pl.Float64)
        )
        row["seconds"] = float(secs[0]) if secs.len() else None
        rows.append(row)
    return rows


#: The tracker whose every identity error the study lists (``errors.csv``).
DIAGNOSED = "residents"


def session_errors(session: str, dataset: Path, run_dir: Path, trackers: tuple[str, ...]) -> list[pl.DataFrame]:
    """Every identity error of :data:`DIAGNOSED` in one session's run
    (:func:`onebit.scoring.identity.error_table`), with the session; empty when it did not run."""
    tables = run_dir / "tables"
    te, ev = tables / "truth_events.parquet", tables / f"{DIAGNOSED}_events.parquet"
    if DIAGNOSED not in trackers or not te.exists() or not ev.exists():
        return []
    hops = graph_hops(load_site(dataset / "site.toml"))
    err = error_table(pl.read_parquet(te), pl.read_parquet(ev), hops)
    return [err.select(pl.lit(session).alias("session"), pl.all())]


def with_means(df: pl.DataFrame) -> pl.DataFrame:
    """``df`` and one ``session = "mean"`` row per method (means over the sessions it scored)."""
    num = [c for c, t in RESULTS.items() if t == pl.Float64]
    means = df.group_by("method", maintain_order=True).agg(
        pl.lit("mean").alias("session"),
        pl.format("{}/{} ok", pl.col("accuracy").is_not_null().sum(), pl.len()).alias("status"),
        *[pl.col(c).mean() for c in num],
    )
    return pl.concat([df, means.select(list(RESULTS))])


def run(
    out: Path,
    *,
    seed: int = 0,
    trials: int | None = None,
    quick: bool = False,
    echo=print,
    executor=None,
    results: Path | None = None,
    trackers: tuple[str, ...] | None = None,
    layout: str | None = None,
    rooms: str | None = None,
    scale: float | None = None,
    graph_radius: float | None = None,
    targets: int | None = None,
    doors: tuple[str, ...] = (),
    config: dict | None = None,
    cross_validate: bool = False,
    profile_clock: str = "none",
) -> Path:
    """The study (module docstring); ``out`` is the folder of session files. ``quick``: the
    first two sessions; ``trials``: the first ``trials`` sessions; ``config``: the stage
    sections of a ``run.toml`` (e.g. ``{"residents": {"habits": True}}``), for every session.
    Returns the results folder."""
    folder = Path(out)
    res_dir = Path(results) if results is not None else folder / "residents-study"
    trackers = tuple(trackers or DEFAULT_TRACKERS)
    files = sessions(folder)
    if quick:
        files = files[:2]
    if trials:
        files = files[:trials]
    rows: list[dict] = []
    errors: list[pl.DataFrame] = []
    datasets = {f.stem: res_dir / "datasets" / f.stem for f in files}
    for f in files:
        import_casas(
            f,
            datasets[f.stem],
            layout=layout,
            rooms=rooms,
            scale=scale,
            graph_radius=graph_radius,
            targets=targets,
            doors=doors,
        )
    for f in files:
        ds = datasets[f.stem]
        profile = ds / "residents_profile.csv"
        profile.unlink(missing_ok=True)
        if cross_validate:  # known residents learned from every other session (leave one out)
            others = [d for name, d in datasets.items() if name != f.stem]
            if not others:
                raise InputError("--cross-validate needs at least two sessions", file=folder)
            clock = Clock(profile_clock, 10) if profile_clock != "none" else None
            write_profile(learn_residents(others, clock=clock), profile)
        run_dir = res_dir / "runs" / f.stem
        res = run_pipeline(ds, run_dir, trackers=trackers, config=config, progress=False)
        errors += session_errors(f.stem, ds, run_dir, trackers)
        tpath = run_dir / "tables" / "timings.parquet"
        timings = pl.read_parquet(tpath) if tpath.exists() else None
        new = [  # the supervised baseline exists only with a profile (--cross-validate)
            r
            for r in session_rows(f.stem, res.report, res.status, trackers, timings)
            if r["method"] != "baseline-habits" or r["events"] is not None
        ]
        rows += new
        echo(
            f"{f.stem}: "
            + ", ".join(
                f"{r['method']} {r['accuracy']:.3f}" if r["accuracy"] is not None else f"{r['method']} -" for r in new
            )
        )
    _write_results(rows, errors, res_dir, echo)
    return res_dir


def _write_results(rows: list[dict], errors: list[pl.DataFrame], res_dir: Path, echo) -> None:
    """``results.csv``/``.parquet`` (with the means) and ``errors.csv`` of the study, and their
    tables echoed."""
    df = with_means(pl.DataFrame(rows, schema=RESULTS, orient="row"))
    res_dir.mkdir(parents=True, exist_ok=True)
    write_csv(df, res_dir / "results.csv")
    write_parquet(df, res_dir / "results.parquet")
    err = pl.concat(errors) if errors else pl.DataFrame(schema={"session": pl.String, **ERRORS})
    write_csv(err, res_dir / "errors.csv")
    with pl.Config(tbl_rows=-1, tbl_cols=-1, tbl_width_chars=200, float_precision=3, tbl_hide_dataframe_shape=True):
        echo(str(df))
        if err.height:
            echo(f"identity errors of {DIAGNOSED} by kind (every one in errors.csv; docs/residents.md):")
            echo(str(err.pivot(on="kind", index="session", values="t", aggregate_function="len").fill_null(0)))
        wide = df.pivot(on="method", index="session", values="accuracy")
        echo("identity accuracy (fraction of labelled events) per session and method:")
        echo(str(wide))
