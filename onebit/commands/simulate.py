"""``onebit simulate``: a scenario's dataset folder with ground truth (``simulate list``: the scenarios)."""

from __future__ import annotations

from pathlib import Path

from onebit.datasets.catalogue import IN_PLACE, all_scenarios, get_scenario
from onebit.datasets.scenario import parse_params, simulate_into
from onebit.pipeline.progress import Spinner


def _cmd_simulate(args) -> int:
    """``onebit simulate SCENARIO DATASET``: write the dataset (or, for a from-truth scenario, its logs)."""
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


def add_simulate_command(sub) -> None:
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
