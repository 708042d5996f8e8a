"""``onebit run``, ``run-many``, ``compare`` and ``report``: running the pipeline and reading its runs."""

from __future__ import annotations

import re
import sys
from pathlib import Path

from onebit.commands.follow import add_follow_command
from onebit.commands.options import add_executor_options, default_of, executor, tracker_names
from onebit.core.errors import ConfigError
from onebit.pipeline.report import format_report, format_run_summary, load_report, skipped_groups
from onebit.pipeline.runmany import format_summary, run_many
from onebit.pipeline.runner import load_run_config, run_pipeline
from onebit.pipeline.stages import stages
from onebit.viz.compare import compare_runs

_STAGE_LINE = re.compile(r"  [\w-]+: (ok|skipped \()")


def _quiet_echo(line: str) -> None:
    """The run's messages but its per-stage ``ok`` / ``skipped`` lines: the summary says those."""
    if not _STAGE_LINE.match(line):
        print(line)


def _cmd_run(args) -> int:
    """``onebit run DATASET --out OUT``: the pipeline, then its summary (or the whole report)."""
    trackers = tracker_names(args.trackers)
    config = load_run_config(args.config)
    print(f"onebit run {args.dataset} -> {args.out}")
    echo = print if args.full_report else _quiet_echo
    res = run_pipeline(
        args.dataset, args.out, trackers=trackers, config=config, echo=echo, rrd=not args.no_rrd, cores=args.cores
    )
    if args.full_report:
        print(format_report(res.report, title=f"report of {args.out}"))
    else:
        for line in skipped_groups(res.status, stages()):
            print(f"  {line}")
        print(format_run_summary(res.report, res.status, title=f"summary of {args.out}"), end="")
    rrd = (
        "Rerun recordings: none (--no-rrd)"
        if args.no_rrd
        else f"Rerun recordings: rerun {Path(args.out) / 'rrd'}/*.rrd"
    )
    if args.full_report:
        print(rrd)
    else:  # one line: where the rest is
        print(f"the whole report ({res.report.height} rows): onebit report {args.out}; {rrd}")
    failed = [name for name, state in res.status.items() if state.startswith("failed")]
    for why in (
        [f"stage(s) failed: {', '.join(failed)} (see {Path(args.out) / 'run.toml'})"] if failed else []
    ) + res.problems:
        print(f"onebit: run not ok: {why}", file=sys.stderr)
    return 0 if res.ok else 1


def _cmd_compare(args) -> int:
    """``onebit compare A B``: one recording with both runs side by side."""
    labels = tuple(args.labels.split(",", 1)) if args.labels else None
    if labels is not None and len(labels) != 2:
        raise ConfigError(f"--labels {args.labels!r}: expected two names, A,B")
    res = compare_runs(args.run_a, args.run_b, args.out, labels=labels)
    print(
        f"compared {args.run_a} (A/) and {args.run_b} (B/): {res.views} views side by side, {sum(res.chunks.values())} chunks"
    )
    print(f"open with: rerun {res.rrd} {res.blueprint}")
    return 0


def _cmd_run_many(args) -> int:
    """``onebit run-many DATASET... --out OUT``: one run per dataset on an executor."""
    trackers = tracker_names(args.trackers)
    config = load_run_config(args.config)
    with executor(args) as ex:
        res = run_many(
            args.datasets, args.out, trackers=trackers, config=config, executor=ex, echo=print, rrd=not args.no_rrd
        )
    print(format_summary(res))
    return 0 if res.ok else 1


def _cmd_report(args) -> int:
    """``onebit report OUT``: the report of a finished run."""
    print(format_report(load_report(args.out), title=f"report of {args.out}"))
    return 0


def add_run_commands(sub) -> None:
    """``run``, ``follow`` (:mod:`onebit.commands.follow`), ``compare``, ``run-many`` and ``report``:
    running the pipeline and reading its runs."""
    _add_run(sub)
    add_follow_command(sub)
    _add_compare(sub)
    _add_run_many(sub)
    rp = sub.add_parser("report", help="print the report of a finished run")
    rp.add_argument("out")
    rp.set_defaults(func=_cmd_report)


def _add_run(sub) -> None:
    r = sub.add_parser("run", help="run every stage whose inputs exist on a dataset folder")
    r.add_argument("dataset")
    r.add_argument("--out", required=True, help="run folder to write")
    r.add_argument("--trackers", help="comma-separated tracker names (default: all)")
    r.add_argument("--config", help="run.toml with one [section] per stage")
    r.add_argument(
        "--no-rrd",
        action="store_true",
        help="write no Rerun recordings (rrd/): the same tables and report, faster (batch sweeps)",
    )
    r.add_argument(
        "--cores",
        type=int,
        default=default_of(run_pipeline, "cores"),
        help="most trackers worked at once, side by side (the same tables); 0 = the cores available, "
        "on logs of 200 000 rows or more; 1 = one after another (default %(default)s)",
    )
    r.add_argument(
        "--full-report",
        action="store_true",
        help="print every stage as it ends and every row of the report (default: one summary table, "
        "the skipped stages one line per reason; the whole report is in OUT/report.csv and onebit report)",
    )
    r.set_defaults(func=_cmd_run)


def _add_compare(sub) -> None:
    cp = sub.add_parser(
        "compare", help="two runs side by side on one timeline (one .rrd with A/ and B/, and a blueprint)"
    )
    cp.add_argument("run_a")
    cp.add_argument("run_b")
    cp.add_argument(
        "--out",
        default="compare.rrd",
        help="recording to write (default compare.rrd; the blueprint goes next to it as .rbl)",
    )
    cp.add_argument(
        "--labels", metavar="A,B", help="names of the two sides in the view titles (default: the folder names)"
    )
    cp.set_defaults(func=_cmd_compare)


def _add_run_many(sub) -> None:
    rm = sub.add_parser("run-many", help="run the pipeline on many dataset folders (process pool or Ray)")
    rm.add_argument(
        "datasets",
        nargs="+",
        metavar="DATASET",
        help="dataset folders, globs ('data/*/floor*') or files listing one folder per line",
    )
    rm.add_argument("--out", required=True, help="folder for one run folder per dataset and summary.parquet/.csv")
    rm.add_argument("--trackers", help="comma-separated tracker names (default: all)")
    rm.add_argument("--config", help="run.toml with one [section] per stage, for every dataset")
    rm.add_argument("--no-rrd", action="store_true", help="write no Rerun recordings (as onebit run --no-rrd)")
    add_executor_options(rm)
    rm.set_defaults(func=_cmd_run_many)
