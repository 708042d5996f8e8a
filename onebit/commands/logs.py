"""``onebit logs info|convert|split``: inspecting, converting and cutting raw logs."""

from __future__ import annotations

from pathlib import Path

import polars as pl

from onebit.core.config import load_toml
from onebit.core.errors import OnebitError
from onebit.pipeline.split import parse_period, split_dataset
from onebit.readers.loginfo import format_log_info, log_info
from onebit.readers.mcap_io import csv_folder_to_mcap, load_topic_map, mcap_to_csv_folder, tracks_for_views


def _cmd_logs_split(args) -> int:
    """``onebit logs split DATASET OUT``: one dataset folder per period."""
    parts = split_dataset(Path(args.dataset), Path(args.out), every=parse_period(args.every))
    rows = sum(sum(p.rows.values()) for p in parts)
    print(f"split {args.dataset} into {len(parts)} parts of {args.every} ({rows} rows) under {args.out}")
    print(f"run them all: onebit run-many {args.out}/part-* --out RUNS")
    return 0


def _cmd_logs_info(args) -> int:
    """``onebit logs info FILE``: what a log holds."""
    print(format_log_info(log_info(args.file)))
    return 0


def _run_tracks(run: Path) -> pl.DataFrame:
    """Every ``tables/<tracker>_tracks.parquet`` of a run folder, as view input (lined up
    with the raw logs' own stamps by the run's ``[time]`` origin)."""
    parts = sorted((run / "tables").glob("*_tracks.parquet"))
    if not parts:
        raise OnebitError(f"--run {run}: no tables/*_tracks.parquet (not a finished run folder?)")
    tracks = pl.concat([pl.read_parquet(p).select("tracker", "track", "t", "x", "y") for p in parts])
    time = load_toml(run / "run.toml").get("time", {}) if (run / "run.toml").is_file() else {}
    offset = float(time.get("origin_s", 0.0)) if time.get("source") == "data" else 0.0
    return tracks_for_views(tracks, offset_s=offset)


def _cmd_logs_convert(args) -> int:
    """``onebit logs convert IN OUT``: MCAP -> CSV folder, or a folder (and a run's tracks) -> MCAP."""
    src, dst = Path(args.src), Path(args.dst)
    if src.suffix.lower() == ".mcap":
        topic_map = load_topic_map(args.topics) if args.topics else None
        conv = mcap_to_csv_folder(src, dst, topic_map=topic_map)
        if conv.rejects.height:
            print(f"  {conv.rejects.height} message(s) not carried over:")
            for source, line, reason in conv.rejects.select("source", "line", "reason").head(10).iter_rows():
                print(f"    {source}{'' if line is None else f':{line}'}: {reason}")
    elif dst.suffix.lower() == ".mcap":
        tracks = _run_tracks(Path(args.run)) if args.run else None
        csv_folder_to_mcap(src, dst, views=not args.no_views, tracks=tracks)
    else:
        raise OnebitError("one of IN and OUT must be an .mcap file")
    print(f"converted {src} -> {dst}")
    return 0


def add_logs_commands(sub) -> None:
    """``logs info|convert``: inspecting and converting raw logs."""
    lg = sub.add_parser("logs", help="inspect or convert raw logs")
    lsub = lg.add_subparsers(dest="logs_command", required=True)
    li = lsub.add_parser("info", help="channels, sensors, time span, rates and rejects of a log")
    li.add_argument("file")
    li.set_defaults(func=_cmd_logs_info)
    lc = lsub.add_parser("convert", help="CSV/Parquet folder <-> MCAP (chunked, zstd, raw channels + Foxglove views)")
    lc.add_argument("src")
    lc.add_argument("dst")
    lc.add_argument(
        "--no-views", action="store_true", help="raw channels only (no Foxglove SceneUpdate/PointCloud/Log views)"
    )
    lc.add_argument("--run", metavar="RUN", help="a run folder of this dataset: add its tracks as views")
    lc.add_argument(
        "--topics", metavar="TOML", help="MCAP -> CSV: mcap_topics.toml mapping ROS 2 Bool topics to sensors"
    )
    lc.set_defaults(func=_cmd_logs_convert)
    ls = lsub.add_parser("split", help="cut a long dataset into one dataset folder per day (or per --every)")
    ls.add_argument("dataset")
    ls.add_argument("out", help="folder for the parts (OUT/part-000, ...) and split.toml")
    ls.add_argument("--every", default="1d", help="period of a part: 1d (default), 6h, 90m, 3600 (seconds)")
    ls.set_defaults(func=_cmd_logs_split)
