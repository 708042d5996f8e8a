"""``onebit follow``: a dataset's logs followed as they grow (or replayed), estimates published live."""

from __future__ import annotations

import sys
from pathlib import Path

from onebit.commands.options import tracker_names
from onebit.core.errors import ConfigError
from onebit.pipeline.follow import FollowConfig, follow, parse_speed
from onebit.pipeline.report import format_report
from onebit.pipeline.runner import load_run_config
from onebit.viz.live import GRPC_PORT, LOCAL_BIND, WEB_PORT, WebServe

#: ``--connect`` without a URL: a Rerun viewer open on this machine, at its default port.
VIEWER_URL = "rerun+http://127.0.0.1:9876/proxy"


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
    """``onebit follow DATASET --out OUT``: live (or replayed) estimates, then the batch run."""
    trackers = tracker_names(args.trackers)
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


def add_follow_command(sub) -> None:
    """``follow``: its options, the live ones' defaults from :class:`FollowConfig` and :class:`WebServe`."""
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
        "--poll",
        type=float,
        default=FollowConfig.poll,
        help="seconds between polls: the publication cadence (default %(default)g)",
    )
    fo.add_argument(
        "--idle",
        type=float,
        default=FollowConfig.idle,
        help="seconds without a new line that end a live run (default %(default)g)",
    )
    fo.add_argument(
        "--settle", type=float, default=None, help="seconds before an event is final (default: the readers' look-ahead)"
    )
    fo.add_argument(
        "--connect",
        metavar="URL",
        nargs="?",
        const=VIEWER_URL,
        help=f"also stream to a Rerun viewer that is open (default URL {VIEWER_URL})",
    )
    _add_web_options(fo)
    fo.set_defaults(func=_cmd_follow)


def _add_web_options(fo) -> None:
    """``--serve-web`` and where it listens (defaults: :class:`WebServe`'s)."""
    fo.add_argument(
        "--serve-web",
        action="store_true",
        help=f"also serve the stream to a web viewer (prints its URL); it listens on {LOCAL_BIND} only "
        "(this machine) unless --bind says otherwise: from another machine, forward both ports over "
        f"SSH (ssh -L {WEB_PORT}:{LOCAL_BIND}:{WEB_PORT} -L {GRPC_PORT}:{LOCAL_BIND}:{GRPC_PORT} HOST), see docs/live.md",
    )
    fo.add_argument(
        "--web-port",
        type=int,
        default=None,
        help=f"--serve-web: port of the page (default {WEB_PORT}; 0 = a free one)",
    )
    fo.add_argument(
        "--grpc-port",
        type=int,
        default=None,
        help=f"--serve-web: port of the stream the page reads (default {GRPC_PORT}; 0 = a free one)",
    )
    fo.add_argument(
        "--bind",
        metavar="ADDR",
        default=None,
        help=f"--serve-web: address both ports listen on (default {LOCAL_BIND}: this machine only; "
        "0.0.0.0: every interface, so anyone on the network sees the live view -- no password)",
    )
