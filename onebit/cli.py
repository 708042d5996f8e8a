"""The ``onebit`` command line: run, follow, compare, run-many, report, simulate, experiment, import (CASAS, trajectories), logs info / logs convert, init, check, snapshot."""

from __future__ import annotations

import argparse
import atexit
import gc
import re
import sys
import tempfile
import traceback
from pathlib import Path

import polars as pl

from onebit.core.config import load_toml
from onebit.core.errors import ConfigError, InputError, OnebitError, bounded, is_disk_full
from onebit.core.site import load_site
from onebit.core.writers import write_csv
from onebit.datasets.aras import import_aras, parse_days
from onebit.datasets.catalogue import IN_PLACE, all_scenarios, get_scenario
from onebit.datasets.importers import import_casas, import_trajectories
from onebit.datasets.irtracking import DEFAULT_RADIUS_M, PERIOD_S, import_irtracking
from onebit.datasets.scenario import parse_params, simulate_into
from onebit.datasets.skeleton import init_dataset
from onebit.experiments import get_experiment
from onebit.pipeline.check import check_dataset, format_check
from onebit.pipeline.config_show import add_config_command
from onebit.pipeline.executors import EXECUTORS, make_executor
from onebit.pipeline.follow import FollowConfig, follow, parse_speed
from onebit.pipeline.learn import learn_counts, learn_residents, write_profile
from onebit.pipeline.progress import Spinner
from onebit.pipeline.report import check_run_folder, format_report, format_run_summary, load_report, skipped_groups
from onebit.pipeline.runmany import format_summary, run_many
from onebit.pipeline.runner import load_run_config, run_pipeline
from onebit.pipeline.split import parse_period, split_dataset
from onebit.pipeline.stages import stages
from onebit.readers.loginfo import format_log_info, log_info
from onebit.readers.mcap_io import csv_folder_to_mcap, load_topic_map, mcap_to_csv_folder, tracks_for_views
from onebit.readers.trajectories import TrajectoryFormat
from onebit.trackers.beams.verify import parse_story, verify_path
from onebit.trackers.residents.known import Clock
from onebit.viz.compare import compare_runs
from onebit.viz.live import WebServe
from onebit.viz.snapshot import snapshot

_STAGE_LINE = re.compile(r"  [\w-]+: (ok|skipped \()")


def _quiet_echo(line: str) -> None:
    """The run's messages but its per-stage ``ok`` / ``skipped`` lines: the summary says those."""
    if not _STAGE_LINE.match(line):
        print(line)


def _cmd_run(args) -> int:
    trackers = tuple(t.strip() for t in args.trackers.split(",")) if args.trackers else None
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


def _web_serve(args) -> WebServe | None:
    """``--serve-web`` and its ``--web-port``, ``--grpc-port``, ``--bind`` as a :class:`WebServe`."""
    given = {
        flag: value
        for flag, value in (("--web-port", args.web_port), ("--grpc-port", args.grpc_port), ("--bind", args.bind))
        if value is not None
    }
    if not args.serve_web:
        if given:
            raise ConfigError(f"{', '.join(given)}: only with --serve-web")
        return None
    defaults = WebServe()
    return WebServe(
        bind=args.bind if args.bind is not None else defaults.bind,
        web_port=args.web_port if args.web_port is not None else defaults.web_port,
        grpc_port=args.grpc_port if args.grpc_port is not None else defaults.grpc_port,
    )


def _cmd_follow(args) -> int:
    trackers = tuple(t.strip() for t in args.trackers.split(",")) if args.trackers else None
    serve_web = _web_serve(args)
    config = load_run_config(args.config)
    options = FollowConfig(
        replay=parse_speed(args.replay) if args.replay else None, poll=args.poll, idle=args.idle, settle=args.settle
    )
    how = (
        f"replay at {options.replay:g}x"
        if options.replay
        else f"following the growing logs (ends after {options.idle:g} s idle)"
    )
    print(f"onebit follow {args.dataset} -> {args.out}: {how}")
    res = follow(
        args.dataset,
        args.out,
        trackers=trackers,
        config=config,
        options=options,
        connect=args.connect,
        serve_web=serve_web,
        echo=print,
    )
    print(format_report(res.run.report, title=f"report of {args.out}"))
    print(format_report(res.report, title=f"follow: online trackers ({res.live})"))
    print(f"Rerun: {res.live / 'rrd' / 'follow.rrd'} (live stream), {Path(args.out) / 'rrd'}/*.rrd (batch run)")
    for why in res.run.problems:
        print(f"onebit: run not ok: {why}", file=sys.stderr)
    return 0 if res.run.ok else 1


def _cmd_compare(args) -> int:
    labels = tuple(args.labels.split(",", 1)) if args.labels else None
    if labels is not None and len(labels) != 2:
        raise ConfigError(f"--labels {args.labels!r}: expected two names, A,B")
    res = compare_runs(args.run_a, args.run_b, args.out, labels=labels)
    print(
        f"compared {args.run_a} (A/) and {args.run_b} (B/): {res.views} views side by side, {sum(res.chunks.values())} chunks"
    )
    print(f"open with: rerun {res.rrd} {res.blueprint}")
    return 0


def _executor(args):
    """The executor of ``--executor/--workers/--ray-address`` (run-many, experiment)."""
    return make_executor(args.executor, workers=args.workers, address=args.ray_address)


def _add_executor_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--executor",
        choices=EXECUTORS,
        default="local",
        help="where the tasks run: serial (this process), local (a process pool, default) or ray",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="processes of the local pool / CPUs of a local Ray instance (default: one per core); "
        "with --ray-address: at most N tasks at a time (default: the cluster's CPUs)",
    )
    p.add_argument(
        "--ray-address",
        default=None,
        metavar="ADDR",
        help="join a running Ray cluster (e.g. auto or HEAD:6379; see 'ray start --head'); "
        "default: start a local Ray instance",
    )


def _cmd_run_many(args) -> int:
    trackers = tuple(t.strip() for t in args.trackers.split(",")) if args.trackers else None
    config = load_run_config(args.config)
    with _executor(args) as ex:
        res = run_many(
            args.datasets, args.out, trackers=trackers, config=config, executor=ex, echo=print, rrd=not args.no_rrd
        )
    print(format_summary(res))
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
    if args.scenario in IN_PLACE:  # from-truth: adds the logs to the folder's own site.toml and truth.csv
        with Spinner(f"simulating {args.scenario} in {args.dataset}"):
            sc.write(
                Path(args.dataset),
                seed=args.seed,
                duration=args.duration,
                agents=args.agents,
                drop=args.drop,
                camera=not args.no_camera,
                params=parse_params(args.param),
            )
        print(
            f"wrote the sensor logs of {args.dataset}/site.toml from its truth.csv (seed {args.seed}); "
            f"now: onebit run {args.dataset} --out OUT"
        )
        return 0
    with Spinner(f"simulating {args.scenario} into {args.dataset}"):
        out = simulate_into(
            sc,
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
    import inspect

    mod = get_experiment(args.name)
    extra = {}
    if args.name == "residents":  # a folder of real sessions, not a simulation
        extra = dict(
            results=Path(args.results) if args.results else None,
            trackers=tuple(t.strip() for t in args.trackers.split(",") if t.strip()) if args.trackers else None,
            layout=args.layout,
            rooms=args.rooms,
            scale=args.scale,
            graph_radius=args.graph_radius,
            targets=args.targets,
            doors=tuple(d.strip() for d in args.doors.split(",") if d.strip()) if args.doors else (),
            config=load_run_config(args.config),
            cross_validate=args.cross_validate,
            profile_clock=args.profile_clock,
        )
    else:
        if args.config is not None:
            raise ConfigError(f"experiment {args.name!r} takes no --config")
        params = inspect.signature(mod.run).parameters
        trackers = tuple(t.strip() for t in args.trackers.split(",") if t.strip()) if args.trackers else None
        sequences = None if args.sequences is None else tuple(q.strip() for q in args.sequences.split(",") if q.strip())
        pairs = (("data", args.data), ("trackers", trackers), ("sequences", sequences))
        for key, value in (*pairs, ("learn", args.learn), ("decode", args.decode)):
            if value is not None:
                if key not in params:
                    raise ConfigError(f"experiment {args.name!r} takes no --{key}")
                extra[key] = value
    with _executor(args) as ex:
        out = mod.run(
            Path(args.out), seed=args.seed, trials=args.trials, quick=args.quick, echo=print, executor=ex, **extra
        )
    print(f"experiment {args.name}: results in {out}")
    return 0


def _cmd_learn_residents(args) -> int:
    clock = Clock(args.clock, args.bins) if args.clock != "none" else None
    learned = learn_residents([Path(d) for d in args.datasets], clock=clock)
    out = write_profile(learned, Path(args.out))
    residents = learned.profile["resident"].n_unique()
    print(
        f"learned {residents} residents from {learned.events} labelled events in {learned.sessions} sessions "
        f"({learned.rejects.height} truth_events lines rejected) -> {out}"
    )

    counts = learn_counts([Path(d) for d in args.datasets])
    if counts is not None:
        path = Path(args.out).parent / "count_profile.csv"
        write_csv(counts, path)
        hours = counts.filter(pl.col("term") == "bins")["count"].sum() / 60.0
        print(f"learned the home's count model from {hours:.1f} labelled hours (truth_count.csv) -> {path}")
    return 0


def _cmd_logs_split(args) -> int:
    parts = split_dataset(Path(args.dataset), Path(args.out), every=parse_period(args.every))
    rows = sum(sum(p.rows.values()) for p in parts)
    print(f"split {args.dataset} into {len(parts)} parts of {args.every} ({rows} rows) under {args.out}")
    print(f"run them all: onebit run-many {args.out}/part-* --out RUNS")
    return 0


def _cmd_logs_info(args) -> int:
    print(format_log_info(log_info(args.file)))
    return 0


def _run_tracks(run: Path) -> pl.DataFrame:
    """Every ``tables/<tracker>_tracks.parquet`` of a run folder, as view input (lined up
    with the raw logs' own stamps by the run's ``[time]`` origin)."""
    import polars as pl

    parts = sorted((run / "tables").glob("*_tracks.parquet"))
    if not parts:
        raise OnebitError(f"--run {run}: no tables/*_tracks.parquet (not a finished run folder?)")
    tracks = pl.concat([pl.read_parquet(p).select("tracker", "track", "t", "x", "y") for p in parts])
    time = load_toml(run / "run.toml").get("time", {}) if (run / "run.toml").is_file() else {}
    offset = float(time.get("origin_s", 0.0)) if time.get("source") == "data" else 0.0
    return tracks_for_views(tracks, offset_s=offset)


def _cmd_logs_convert(args) -> int:
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


def _cmd_import_aras(args) -> int:

    res = import_aras(args.house, args.dataset, days=parse_days(args.days))
    c = res.counts
    print(
        f"imported {args.house} -> {args.dataset}: {c['days']} days, {c['lines']} lines, {c['motion_csv']} level changes "
        f"of {c['person_sensors']} person sensors in motion.csv, {c['other_csv']} in other.csv, "
        f"{c['truth_events']} resident-labelled events, {c['rejected']} rejected lines, {c['short_days']} short days; "
        "see import.toml"
    )
    return 0


def _cmd_import_casas(args) -> int:
    doors = tuple(d.strip() for d in args.doors.split(",") if d.strip()) if args.doors else ()
    res = import_casas(
        args.log,
        args.dataset,
        layout=args.layout,
        targets=args.targets,
        doors=doors,
        window_s=args.window,
        min_count=args.min_count,
        min_share=args.min_share,
        spacing_m=args.spacing,
        hold_s=args.hold,
        hold_samples=args.hold_samples,
        scale=args.scale,
        rooms=args.rooms,
        graph_radius=args.graph_radius,
        count=args.count,
    )
    c = res.counts
    print(
        f"imported {args.log} -> {args.dataset}: {c['events']} events ({c['motion_csv']} motion/contact in motion.csv, "
        f"{c['lost_off_repaired']} lost OFFs repaired, {c['other_csv']} others in other.csv, {c['annotations']} annotated, "
        f"{c['truth_events']} resident-labelled in truth_events.csv), {c['rejected']} rejected lines, "
        f"{c['reordered']} out of order (sorted); {c['sensors']} sensors, {c['edges']} edges "
        f"({res.info['graph']['source']} graph, positions: {res.info['layout']['positions']}); see import.toml"
    )
    return 0


def _cmd_import_irtracking(args) -> int:
    res = import_irtracking(
        args.readings,
        args.dataset,
        truth=args.truth,
        coordinates=args.coordinates,
        period=args.period,
        radius=args.radius,
        r_inner=args.r_inner,
        targets=args.targets,
        name=args.name,
    )
    c = res.info["counts"]
    truth = f", truth.csv ({c['truth_rows']} positions of {c['truth_targets']} people)" if "truth_rows" in c else ""
    print(
        f"imported {args.readings} -> {args.dataset}: site.toml ({c['sensors']} sensors), frames.csv ({c['frames']} frames, "
        f"{c['active_readings']} active readings){truth}; {c['rejected']} rejected{' (rejects.csv)' if c['rejected'] else ''}; "
        "see import.toml"
    )
    return 0


def _cmd_import_trajectories(args) -> int:
    fmt = TrajectoryFormat(
        delimiter={"tab": "\t", "space": " "}.get(args.delimiter, args.delimiter),
        time=args.time_column,
        track=args.track_column,
        x=args.x_column,
        y=args.y_column,
        time_unit=args.time_unit,
        scale=args.scale,
        offset=(args.offset_x, args.offset_y),
        flip_x=args.flip_x,
        flip_y=args.flip_y,
        swap_xy=args.swap_xy,
        join=tuple(tuple(i.strip() for i in j.split(",")) for j in args.join or []),
    )
    res = import_trajectories(args.file, args.dataset, fmt)
    c = res.counts
    print(
        f"imported {args.file} -> {args.dataset}/truth.csv: {c['positions']} positions of {c['tracks']} tracks, "
        f"{c['rejected']} rejected rows{' (truth_rejects.csv)' if c['rejected'] else ''}; see truth_import.toml"
    )
    return 0


def verify_run(out: str | Path, story: str, **scores: float) -> pl.DataFrame:
    """:func:`verify_path` on the ``beams_assignment`` table of a finished run folder ``out``.

    A story label naming a beam the run's site does not have is a ``ValueError`` naming it
    and the beams there are (when the site can be found from the run's ``run.toml``)."""
    if Path(out).is_dir():
        check_run_folder(out)  # refuses a folder an interrupted run left INCOMPLETE
    path = Path(out) / "tables" / "beams_assignment.parquet"
    if not path.exists():
        raise InputError("no beams_assignment table: run the beams tracker first (onebit run)", file=path)
    beams = _run_beams(Path(out))
    unknown = sorted({tok.removesuffix("^-1") for tok in parse_story(story)} - set(beams)) if beams else []
    if unknown:
        raise ValueError(
            f"label(s) {', '.join(map(repr, unknown))} name no beam of the run; its beams are {', '.join(beams)}"
        )
    return verify_path(story, pl.read_parquet(path), **scores)


def _run_beams(out: Path) -> list[str]:
    """The beam ids of the run's site (its ``run.toml`` names the dataset), or ``[]`` if unknown."""
    try:
        dataset = Path(str(load_toml(out / "run.toml", error=InputError).get("dataset", "")))
        return list(load_site(dataset / "site.toml").beam_ids)
    except (OnebitError, OSError):
        return []


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
    print(
        f"plausible against the observation string: {'yes' if ok else 'no'}; "
        f"agents whose reconstructed path contains it: {', '.join(plausible_agents) or 'none'}"
    )
    return 0 if ok else 1


def build_parser() -> argparse.ArgumentParser:
    """The ``onebit`` command line: one step per group of subcommands."""
    p = argparse.ArgumentParser(prog="onebit", description="Tracking from one-bit sensors.")
    sub = p.add_subparsers(dest="command", required=True)
    _add_run_commands(sub)
    _add_simulate_command(sub)
    _add_experiment_command(sub)
    _add_verify_path_command(sub)
    _add_import_commands(sub)
    _add_learn_command(sub)
    _add_logs_commands(sub)
    _add_user_data_commands(sub)
    add_config_command(sub)
    return p


def _cmd_init(args) -> int:

    path, found = init_dataset(args.dataset, args.logs, force=args.force)
    for log, fmt, sensors in found:
        kinds: dict[str, int] = {}
        for s in sensors:
            kinds[s.kind] = kinds.get(s.kind, 0) + 1
        print(
            f"{log}: read as {fmt}, {len(sensors)} sensors ({', '.join(f'{n} {k}' for k, n in sorted(kinds.items()))})"
        )
    print(
        f"wrote {path}: every line marked CHECK is a guess or a placeholder (kinds, positions, boundary); "
        f"correct them, then 'onebit check {args.dataset}'"
    )
    return 0


def _cmd_check(args) -> int:

    print(format_check(check_dataset(args.dataset)))
    return 0


def _cmd_snapshot(args) -> int:

    snapshot(args.run, args.at, args.out, view=args.view)
    return 0


def _add_user_data_commands(sub) -> None:
    """``init``, ``check`` and ``snapshot``: setting up a dataset of one's own, and pictures of a run."""
    ini = sub.add_parser("init", help="write a commented site.toml skeleton from logs (kinds guessed, marked CHECK)")
    ini.add_argument("dataset", help="the dataset folder (made if missing)")
    ini.add_argument(
        "--from",
        dest="logs",
        nargs="+",
        required=True,
        metavar="LOG",
        help="a CASAS log, a toggle CSV (t,sensor,value), a frame log (t,1,2,... or t,active) or a per-second file",
    )
    ini.add_argument("--force", action="store_true", help="replace an existing site.toml")
    ini.set_defaults(func=_cmd_init)
    ck = sub.add_parser(
        "check", help="which trackers can run on a dataset, what each lacks, which sensors look like non-person sensors"
    )
    ck.add_argument("dataset")
    ck.set_defaults(func=_cmd_check)
    sn = sub.add_parser("snapshot", help="render a run's recordings headless to PNGs (any tab) in Rerun's viewer")
    sn.add_argument("run", help="a run folder (with rrd/)")
    sn.add_argument("--at", nargs="+", type=float, required=True, metavar="T", help="times on t (s)")
    sn.add_argument(
        "--view", metavar="NAME", help="the tab to render (its name or the start of it); default: the first"
    )
    sn.add_argument("--out", required=True, metavar="DIR", help="folder for the PNGs (<tab>-t<T>.png)")
    sn.set_defaults(func=_cmd_snapshot)


def _add_run_commands(sub) -> None:
    """``run``, ``follow``, ``compare``, ``run-many`` and ``report``: running the pipeline and reading its runs."""
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
        default=0,
        help="most trackers worked at once, side by side (the same tables); 0 = the cores available, "
        "on logs of 200 000 rows or more (default); 1 = one after another",
    )
    r.add_argument(
        "--full-report",
        action="store_true",
        help="print every stage as it ends and every row of the report (default: one summary table, "
        "the skipped stages one line per reason; the whole report is in OUT/report.csv and onebit report)",
    )
    r.set_defaults(func=_cmd_run)

    fo = sub.add_parser(
        "follow",
        help="follow a dataset's logs as they grow (or replay them), publish estimates live, end with the batch run",
    )
    fo.add_argument("dataset")
    fo.add_argument("--out", required=True, help="run folder: OUT/live/ holds the live tables, stream and report")
    fo.add_argument(
        "--replay", metavar="SPEED", help="replay a finished log at SPEED (e.g. 20x) instead of following growth"
    )
    fo.add_argument("--trackers", help="comma-separated tracker names (default: all)")
    fo.add_argument("--config", help="run.toml with one [section] per stage")
    fo.add_argument(
        "--poll", type=float, default=0.25, help="seconds between polls: the publication cadence (default 0.25)"
    )
    fo.add_argument(
        "--idle", type=float, default=10.0, help="seconds without a new line that end a live run (default 10)"
    )
    fo.add_argument(
        "--settle", type=float, default=None, help="seconds before an event is final (default: the readers' look-ahead)"
    )
    fo.add_argument(
        "--connect",
        metavar="URL",
        nargs="?",
        const="rerun+http://127.0.0.1:9876/proxy",
        help="also stream to a Rerun viewer that is open (default URL rerun+http://127.0.0.1:9876/proxy)",
    )
    fo.add_argument(
        "--serve-web",
        action="store_true",
        help="also serve the stream to a web viewer (prints its URL); it listens on 127.0.0.1 only "
        "(this machine) unless --bind says otherwise: from another machine, forward both ports over "
        "SSH (ssh -L 9090:127.0.0.1:9090 -L 9876:127.0.0.1:9876 HOST), see docs/live.md",
    )
    fo.add_argument(
        "--web-port", type=int, default=None, help="--serve-web: port of the page (default 9090; 0 = a free one)"
    )
    fo.add_argument(
        "--grpc-port",
        type=int,
        default=None,
        help="--serve-web: port of the stream the page reads (default 9876; 0 = a free one)",
    )
    fo.add_argument(
        "--bind",
        metavar="ADDR",
        default=None,
        help="--serve-web: address both ports listen on (default 127.0.0.1: this machine only; "
        "0.0.0.0: every interface, so anyone on the network sees the live view -- no password)",
    )
    fo.set_defaults(func=_cmd_follow)

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
    _add_executor_options(rm)
    rm.set_defaults(func=_cmd_run_many)

    rp = sub.add_parser("report", help="print the report of a finished run")
    rp.add_argument("out")
    rp.set_defaults(func=_cmd_report)


def _add_simulate_command(sub) -> None:
    """``simulate``: a scenario's dataset folder with ground truth."""
    s = sub.add_parser("simulate", help="write a simulated dataset folder with ground truth")
    s.add_argument("scenario", help="scenario name ('onebit simulate list DIR' lists them)")
    s.add_argument("dataset")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--duration", type=float, default=None, help="seconds (default: the scenario's)")
    s.add_argument(
        "--agents",
        "--users",
        "--targets",
        dest="agents",
        type=int,
        default=None,
        help="number of agents / users / targets (default: the scenario's)",
    )
    s.add_argument("--drop", type=float, default=0.0, help="probability that a crossing / reading is lost")
    s.add_argument("--no-camera", action="store_true", help="do not render camera.mp4")
    s.add_argument("--param", action="append", metavar="KEY=VALUE", help="scenario-specific option (repeatable)")
    s.set_defaults(func=_cmd_simulate)


def _add_experiment_command(sub) -> None:
    """``experiment``: a paper's study."""
    e = sub.add_parser("experiment", help="reproduce a paper's study: simulate, run, tabulate, plot")
    e.add_argument(
        "name", help="schiff, singh, okane, ..., residents (OUT = a folder of CASAS sessions), ceiling, homes (ARAS)"
    )
    e.add_argument("out")
    e.add_argument("--results", default=None, help="residents: results folder (default OUT/residents-study)")
    e.add_argument(
        "--trackers",
        default=None,
        help="residents, ceiling: comma-separated trackers (default: residents: residents,hmm1,hmm2,findinghumo,"
        "findinghumo-flow; ceiling every positional one)",
    )
    e.add_argument("--layout", default=None, help="residents: floor plan / layout for every session (as import casas)")
    e.add_argument("--rooms", default=None, help="residents: floor plan rooms JSON")
    e.add_argument("--scale", type=float, default=None, help="residents: floor plan metres per pixel")
    e.add_argument("--graph-radius", type=float, default=None, help="residents: floor plan graph radius (m)")
    e.add_argument("--targets", type=int, default=None, help="residents: site.toml targets for every session")
    e.add_argument("--doors", default=None, help="residents: contacts that are doors to the outside")
    e.add_argument("--config", default=None, help="residents: run.toml with one [section] per stage, for every session")
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--trials", type=int, default=None, help="trials per setting (default: the paper's)")
    e.add_argument("--quick", action="store_true", help="a reduced study (smoke test)")
    e.add_argument(
        "--cross-validate",
        action="store_true",
        help="residents: each session also decoded with the known residents learned from the other sessions "
        "(leave one session out; the residents tracker and the supervised 'habits' baseline)",
    )
    e.add_argument(
        "--profile-clock",
        choices=("none", "day", "session"),
        default="none",
        help="residents --cross-validate: the profiles' clock (onebit learn residents --clock; 10 bins)",
    )
    e.add_argument(
        "--data",
        default=None,
        help="ceiling: the irtracking recordings (a clone of antonmil/irtracking); homes: an ARAS house folder",
    )
    e.add_argument("--learn", default=None, help="homes: the labelled days, A-B (default: the first half)")
    e.add_argument("--decode", default=None, help="homes: the days to decode, A-B[,C-D...] (default: the second half)")
    e.add_argument(
        "--sequences",
        default=None,
        help="ceiling: comma-separated sequences of the clone (default: every sequence found in it)",
    )
    _add_executor_options(e)
    e.set_defaults(func=_cmd_experiment)


def _add_verify_path_command(sub) -> None:
    """``verify-path``: a story's plausibility against a beams run."""
    vp = sub.add_parser("verify-path", help="is a story (crossing labels) plausible? Smith-Waterman vs a beams run")
    vp.add_argument("out", help="run folder of a finished 'onebit run' with the beams tracker")
    vp.add_argument("--story", required=True, help='crossing labels, e.g. "a b^-1 c"')
    vp.add_argument("--match", type=float, default=2.0, help="score of a matching label")
    vp.add_argument("--mismatch", type=float, default=-1.0, help="score of a mismatching label (<= 0)")
    vp.add_argument("--gap", type=float, default=1.0, help="penalty of a gap (> 0)")
    vp.set_defaults(func=_cmd_verify_path)


def _add_learn_command(sub) -> None:
    """``learn residents``: a known-residents profile from labelled dataset folders."""
    ln = sub.add_parser("learn", help="learn a model from labelled dataset folders (known residents)")
    lsub = ln.add_subparsers(dest="learn_command", required=True)
    lr = lsub.add_parser(
        "residents",
        help="a residents_profile.csv from datasets with truth_events.csv (put it in a dataset: known residents)",
    )
    lr.add_argument("datasets", nargs="+", help="labelled dataset folders (e.g. imported CASAS sessions)")
    lr.add_argument("--out", required=True, help="the profile to write (residents_profile.csv)")
    lr.add_argument(
        "--clock",
        choices=("none", "day", "session"),
        default="none",
        help="also learn the residents' habits by time: day (time of day, from the sites' epoch: homes over days) "
        "or session (first to last event: scripted sessions); default none",
    )
    lr.add_argument("--bins", type=int, default=10, help="parts of the clock (default 10)")
    lr.set_defaults(func=_cmd_learn_residents)


def _add_import_commands(sub) -> None:
    """``import casas|irtracking|trajectories``: dataset folders from the field's own recordings."""
    im = sub.add_parser("import", help="make a dataset folder from the field's own recordings (CASAS, trajectories)")
    isub = im.add_subparsers(dest="import_command", required=True)
    ic = isub.add_parser(
        "casas",
        help="a CASAS smart-home log (.txt, or pymrt events.csv) -> motion.csv, truth_events.csv, other.csv, annotations.csv, site.toml",
    )
    ic.add_argument("log")
    ic.add_argument("dataset")
    ic.add_argument(
        "--layout",
        help="layout.toml (positions, edges), or a floor plan sensors.json / sensors.csv / pymrt site.json "
        "(pixels or normalised, with --scale; edges from geometry); without it the graph is learned from the log",
    )
    ic.add_argument(
        "--rooms", default=None, help="floor plan rooms (JSON: rectangles or polygons, in the plan's coordinates)"
    )
    ic.add_argument(
        "--scale",
        type=float,
        default=None,
        help="floor plan: metres per pixel (or per plan width for normalised coordinates)",
    )
    ic.add_argument(
        "--graph-radius",
        type=float,
        default=None,
        help="floor plan graph: link sensors within this many metres "
        "(default: the smallest distance that keeps the graph connected)",
    )
    ic.add_argument("--targets", type=int, default=None, help="the most residents present at once (site.toml targets)")
    ic.add_argument(
        "--count",
        type=int,
        default=None,
        help="the people in throughout, when known and constant (a one-resident session): written as "
        "truth_count.csv, so every people count is scored per minute",
    )
    ic.add_argument(
        "--window", type=float, default=5.0, help="learned graph: s between two sensors' ON for a transition"
    )
    ic.add_argument("--min-count", type=int, default=3, help="learned graph: transitions an edge needs")
    ic.add_argument(
        "--min-share", type=float, default=0.1, help="learned graph: share of the less busy sensor's transitions"
    )
    ic.add_argument("--spacing", type=float, default=3.0, help="force layout: edge length (m)")
    ic.add_argument(
        "--doors", default=None, help="comma-separated contact ids that are doors to the outside (entry/exit nodes)"
    )
    ic.add_argument(
        "--hold", type=float, default=5.0, help="lost OFF repair: hold time (s) of a sensor with too few on-durations"
    )
    ic.add_argument(
        "--hold-samples",
        type=int,
        default=5,
        help="lost OFF repair: on-durations a sensor needs for its own (median) hold time",
    )
    ic.set_defaults(func=_cmd_import_casas)
    ia = isub.add_parser(
        "aras",
        help="an ARAS house folder (DAY_N.txt, README) -> motion.csv, truth_count.csv, annotations.csv, "
        "truth_events.csv, site.toml (docs/homes.md)",
    )
    ia.add_argument("house", help="the house folder: DAY_1.txt ... and the README naming the sensor columns")
    ia.add_argument("dataset")
    ia.add_argument("--days", default=None, help="days to import, A-B (default: every day file found)")
    ia.set_defaults(func=_cmd_import_aras)
    ir = isub.add_parser(
        "irtracking",
        help="Milan et al.'s ceiling IR array (SEQ.txt or SEQ.xml detections) -> site.toml, frames.csv, truth.csv",
    )
    ir.add_argument("readings", help="SEQ.txt (one line of 50 channels per frame) or SEQ.xml (CVML detections)")
    ir.add_argument("dataset")
    ir.add_argument("--truth", default=None, help="SEQ_gt.xml (CVML, pixels x 25 = mm) -> truth.csv")
    ir.add_argument(
        "--coordinates",
        default=None,
        help="getSensorCoordinates.m (default: next to the readings or up to two folders above)",
    )
    ir.add_argument("--period", type=float, default=PERIOD_S, help="seconds between frames (2 Hz)")
    ir.add_argument("--radius", type=float, default=DEFAULT_RADIUS_M, help="footprint radius of a sensor, m")
    ir.add_argument("--r-inner", type=float, default=None, help="radius a reading 0 clears, m (default: --radius)")
    ir.add_argument(
        "--targets", type=int, default=None, help="most people present at once (default 6, the recordings' most)"
    )
    ir.add_argument("--name", default=None, help="site name (default: the readings' file name)")
    ir.set_defaults(func=_cmd_import_irtracking)
    it = isub.add_parser("trajectories", help="a people-counter / indoor-positioning export -> truth.csv")
    it.add_argument("file")
    it.add_argument("dataset")
    it.add_argument(
        "--delimiter", default=None, help="',', ';', 'tab', '|' or 'space' (default: sniffed from the header)"
    )
    it.add_argument("--time-column", default=None, help="default: t, time, timestamp, ts, ...")
    it.add_argument("--track-column", default=None, help="default: track, id, track_id, person_id, ...")
    it.add_argument("--x-column", default=None)
    it.add_argument("--y-column", default=None)
    it.add_argument("--time-unit", default="auto", choices=("auto", "s", "ms", "us", "iso"))
    it.add_argument("--scale", type=float, default=1.0, help="x, y times this (0.001: mm -> m)")
    it.add_argument("--offset-x", type=float, default=0.0, help="added to x after scaling")
    it.add_argument("--offset-y", type=float, default=0.0, help="added to y after scaling")
    it.add_argument("--flip-x", action="store_true", help="negate x (before the offset)")
    it.add_argument("--flip-y", action="store_true", help="negate y (before the offset)")
    it.add_argument("--swap-xy", action="store_true", help="swap the x and y columns")
    it.add_argument("--join", action="append", metavar="A,B", help="track ids that are one person (repeatable)")
    it.set_defaults(func=_cmd_import_trajectories)


def _add_logs_commands(sub) -> None:
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


def _skip_the_exit_collection() -> None:
    """At exit, after every other exit handler (they run last registered first): freeze the heap
    so the interpreter's final garbage collection does not walk it. That walk costs 0.2-0.3 s
    after a 10^6-row run (polars, numba, Rerun's classes), a tenth of the run; every file is
    closed by then (recordings flushed, run folders renamed), and the process is ending."""
    gc.freeze()


def main(argv: list[str] | None = None) -> int:
    atexit.unregister(_skip_the_exit_collection)  # once per process, however often main runs
    atexit.register(_skip_the_exit_collection)
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except OnebitError as exc:
        print(f"onebit: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("onebit: interrupted (folders being written were left as they were before)", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug (or the system: disk full): one line, the traceback kept for a bug report
        if is_disk_full(exc):  # not a bug; and no room for a traceback file either
            print(f"onebit: error: no space left on the device: {bounded(str(exc))}", file=sys.stderr)
            return 1
        what = "error" if isinstance(exc, OSError) else "internal error"
        print(f"onebit: {what}: {bounded(f'{type(exc).__name__}: {exc}')}", file=sys.stderr)
        notes = [n for n in getattr(exc, "__notes__", []) if n.startswith("onebit:")]
        if notes:
            print(notes[0], file=sys.stderr)
        else:
            with tempfile.NamedTemporaryFile("w", prefix="onebit-traceback-", suffix=".txt", delete=False) as fh:
                fh.write("".join(traceback.format_exception(exc)))
            print(f"onebit: the traceback is in {fh.name}; please attach it to a bug report", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
