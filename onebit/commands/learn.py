"""``onebit learn residents``: a known-residents profile (and the home's count model) from labelled datasets."""

from __future__ import annotations

from pathlib import Path

import polars as pl

from onebit.core.writers import write_csv
from onebit.pipeline.learn import learn_counts, learn_residents, write_profile
from onebit.trackers.residents.known import Clock


def _cmd_learn_residents(args) -> int:
    """Write the profile, and ``count_profile.csv`` beside it when the datasets have ``truth_count.csv``."""
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


def add_learn_command(sub) -> None:
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
