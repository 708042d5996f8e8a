"""``onebit init``, ``check`` and ``snapshot``: setting up a dataset of one's own, and pictures of a run."""

from __future__ import annotations

from onebit.datasets.skeleton import init_dataset
from onebit.pipeline.check import check_dataset, format_check
from onebit.viz.snapshot import snapshot


def _cmd_init(args) -> int:
    """``onebit init DATASET --from LOG...``: a commented ``site.toml`` skeleton."""
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
    """``onebit check DATASET``: which trackers can run, what each lacks."""
    print(format_check(check_dataset(args.dataset)))
    return 0


def _cmd_snapshot(args) -> int:
    """``onebit snapshot RUN --at T... --out DIR``: PNGs of a run's recordings."""
    snapshot(args.run, args.at, args.out, view=args.view)
    return 0


def add_user_data_commands(sub) -> None:
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
