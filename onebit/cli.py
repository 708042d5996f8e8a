"""The ``onebit`` command line: run, report, simulate, logs info / logs convert."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import polars as pl

from onebit.core.errors import ConfigError, InputError, OnebitError
from onebit.datasets.catalogue import all_scenarios, get_scenario
from onebit.datasets.scenario import parse_params
from onebit.experiments import get_experiment
from onebit.pipeline.report import format_report, load_report
from onebit.pipeline.runner import load_run_config, run_pipeline
from onebit.readers.loginfo import format_log_info, log_info
from onebit.readers.mcap_io import csv_folder_to_mcap, mcap_to_csv_folder
from onebit.trackers.beams.verify import parse_story, verify_path


def _cmd_run(args) -> int:
    trackers = tuple(t.strip() for t in args.trackers.split(",")) if args.trackers else None
    config = load_run_config(args.config)
    print(f"onebit run {args.dataset} -> {args.out}")
    res = run_pipeline(args.dataset, args.out, trackers=trackers, config=config, echo=print)
    print(format_report(res.report, title=f"report of {args.out}"))
    print(f"Rerun recordings: {Path(args.out) / 'rrd'}/*.rrd   (open later with: rerun {Path(args.out) / 'rrd'}/*.rrd)")
    return 0 if res.ok else 1


def _cmd_report(args) -> int:
    print(format_report(load_report(args.out), title=f"report of {args.out}"))
    return 0


def _cmd_simulate(args) -> int:
    if args.scenario == "list":
        for name, sc in sorted(all_scenarios().items()):
            print(f"{name:28s} {sc.help}")
        return 0
    sc = get_scenario(args.scenario)
    out = sc.write(
        args.dataset,
        seed=args.seed,
        duration=args.duration,
        agents=args.agents,
        drop=args.drop,
        camera=not args.no_camera,
        params=parse_params(args.param),
    )
    dur = f", {args.duration:g} s" if args.duration is not None else ""
    print(f"wrote {args.scenario} dataset to {out} (seed {args.seed}{dur})")
    return 0


def _cmd_experiment(args) -> int:
    mod = get_experiment(args.name)
    out = mod.run(Path(args.out), seed=args.seed, trials=args.trials, quick=args.quick, echo=print)
    print(f"experiment {args.name}: results in {out}")
    return 0


def _cmd_logs_info(args) -> int:
    print(format_log_info(log_info(args.file)))
    return 0


def _cmd_logs_convert(args) -> int:
    src, dst = Path(args.src), Path(args.dst)
    if src.suffix.lower() == ".mcap":
        mcap_to_csv_folder(src, dst)
    elif dst.suffix.lower() == ".mcap":
        csv_folder_to_mcap(src, dst)
    else:
        raise OnebitError("one of IN and OUT must be an .mcap file")
    print(f"converted {src} -> {dst}")
    return 0


def verify_run(out: str | Path, story: str, **scores: float) -> pl.DataFrame:
    """:func:`verify_path` on the ``beams_assignment`` table of a finished run folder ``out``."""
    path = Path(out) / "tables" / "beams_assignment.parquet"
    if not path.exists():
        raise InputError("no beams_assignment table: run the beams tracker first (onebit run)", file=path)
    return verify_path(story, pl.read_parquet(path), **scores)


def _cmd_verify_path(args) -> int:
    """``onebit verify-path OUT --story "a b^-1 c"``: print the alignments; exit 0 when the
    story is plausible against the observation string, 1 when it is not."""
    try:
        res = verify_run(args.out, args.story, match=args.match, mismatch=args.mismatch, gap=args.gap)
    except ValueError as exc:
        raise ConfigError(f"--story: {exc}") from None
    with pl.Config(tbl_rows=-1, tbl_cols=-1, fmt_str_lengths=80, tbl_hide_dataframe_shape=True):
        print(f"story {' '.join(parse_story(args.story))!r} against the run {args.out}")
        print(res)
    obs = res.filter(pl.col("target") == "observation")
    ok = bool(obs["plausible"][0]) if obs.height else False
    plausible_agents = res.filter((pl.col("target") != "observation") & pl.col("plausible"))["target"].to_list()
    print(f"plausible against the observation string: {'yes' if ok else 'no'}; "
          f"agents whose reconstructed path contains it: {', '.join(plausible_agents) or 'none'}")
    return 0 if ok else 1


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="onebit", description="Tracking from one-bit sensors.")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run every stage whose inputs exist on a dataset folder")
    r.add_argument("dataset")
    r.add_argument("--out", required=True, help="run folder to write")
    r.add_argument("--trackers", help="comma-separated tracker names (default: all)")
    r.add_argument("--config", help="run.toml with one [section] per stage")
    r.set_defaults(func=_cmd_run)

    rp = sub.add_parser("report", help="print the report of a finished run")
    rp.add_argument("out")
    rp.set_defaults(func=_cmd_report)

    s = sub.add_parser("simulate", help="write a simulated dataset folder with ground truth")
    s.add_argument("scenario", help="scenario name ('onebit simulate list DIR' lists them)")
    s.add_argument("dataset")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--duration", type=float, default=None, help="seconds (default: the scenario's)")
    s.add_argument("--agents", "--users", "--targets", dest="agents", type=int, default=None,
                   help="number of agents / users / targets (default: the scenario's)")
    s.add_argument("--drop", type=float, default=0.0, help="probability that a crossing / reading is lost")
    s.add_argument("--no-camera", action="store_true", help="do not render camera.mp4")
    s.add_argument("--param", action="append", metavar="KEY=VALUE", help="scenario-specific option (repeatable)")
    s.set_defaults(func=_cmd_simulate)

    e = sub.add_parser("experiment", help="reproduce a paper's study: simulate, run, tabulate, plot")
    e.add_argument("name", help="schiff, singh, okane, ...")
    e.add_argument("out")
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--trials", type=int, default=None, help="trials per setting (default: the paper's)")
    e.add_argument("--quick", action="store_true", help="a reduced study (smoke test)")
    e.set_defaults(func=_cmd_experiment)

    vp = sub.add_parser("verify-path", help="is a story (crossing labels) plausible? Smith-Waterman vs a beams run")
    vp.add_argument("out", help="run folder of a finished 'onebit run' with the beams tracker")
    vp.add_argument("--story", required=True, help='crossing labels, e.g. "a b^-1 c"')
    vp.add_argument("--match", type=float, default=2.0, help="score of a matching label")
    vp.add_argument("--mismatch", type=float, default=-1.0, help="score of a mismatching label (<= 0)")
    vp.add_argument("--gap", type=float, default=1.0, help="penalty of a gap (> 0)")
    vp.set_defaults(func=_cmd_verify_path)

    lg = sub.add_parser("logs", help="inspect or convert raw logs")
    lsub = lg.add_subparsers(dest="logs_command", required=True)
    li = lsub.add_parser("info", help="channels, sensors, time span, rates and rejects of a log")
    li.add_argument("file")
    li.set_defaults(func=_cmd_logs_info)
    lc = lsub.add_parser("convert", help="CSV/Parquet folder <-> MCAP")
    lc.add_argument("src")
    lc.add_argument("dst")
    lc.set_defaults(func=_cmd_logs_convert)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except OnebitError as exc:
        print(f"onebit: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
