"""``onebit experiment NAME OUT``: a paper's study (simulate, run, tabulate, plot)."""

from __future__ import annotations

import inspect
from pathlib import Path

from onebit.commands.options import add_executor_options, executor
from onebit.core.errors import ConfigError
from onebit.experiments import get_experiment
from onebit.pipeline.runner import load_run_config


def _names(text: str | None) -> tuple[str, ...] | None:
    """A comma-separated list (empty items left out), or ``None`` when not given."""
    return tuple(t.strip() for t in text.split(",") if t.strip()) if text else None


def _cmd_experiment(args) -> int:
    """Run the study ``args.name`` with the options it takes (an option it does not take is an error)."""
    mod = get_experiment(args.name)
    extra = {}
    if args.name == "residents":  # a folder of real sessions, not a simulation
        extra = dict(
            results=Path(args.results) if args.results else None,
            trackers=_names(args.trackers),
            layout=args.layout,
            rooms=args.rooms,
            scale=args.scale,
            graph_radius=args.graph_radius,
            targets=args.targets,
            doors=_names(args.doors) or (),
            config=load_run_config(args.config),
            cross_validate=args.cross_validate,
            profile_clock=args.profile_clock,
        )
    else:
        if args.config is not None:
            raise ConfigError(f"experiment {args.name!r} takes no --config")
        params = inspect.signature(mod.run).parameters
        trackers = _names(args.trackers)
        sequences = None if args.sequences is None else tuple(q.strip() for q in args.sequences.split(",") if q.strip())
        pairs = (("data", args.data), ("trackers", trackers), ("sequences", sequences))
        for key, value in (*pairs, ("learn", args.learn), ("decode", args.decode)):
            if value is not None:
                if key not in params:
                    raise ConfigError(f"experiment {args.name!r} takes no --{key}")
                extra[key] = value
    with executor(args) as ex:
        out = mod.run(
            Path(args.out), seed=args.seed, trials=args.trials, quick=args.quick, echo=print, executor=ex, **extra
        )
    print(f"experiment {args.name}: results in {out}")
    return 0


def add_experiment_command(sub) -> None:
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
    add_executor_options(e)
    e.set_defaults(func=_cmd_experiment)
