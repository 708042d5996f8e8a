"""``onebit learn residents``: a known-residents profile from labelled dataset folders.

Each dataset folder with a ``truth_events.csv`` (CASAS resident annotations, as ``onebit import
casas`` writes it) is one labelled session; the profile
(:func:`onebit.trackers.residents.known.learn_profile`) sums their counts and is written as
``residents_profile.csv``. Put that file in a dataset folder and the ``residents`` tracker
decodes it with the known residents (docs/residents.md, "Known residents").
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.core.writers import write_csv
from onebit.readers.tables_csv import read_truth_events_csv
from onebit.trackers.residents.known import Clock, learn_profile


@dataclass(frozen=True)
class Learned:
    """What was learned: the profile, the sessions and labelled events it came from, the
    truth_events lines rejected (each with its reason, in ``rejects``)."""

    profile: pl.DataFrame
    sessions: int
    events: int
    rejects: pl.DataFrame


def learn_residents(datasets: list[Path], *, clock: Clock | None = None) -> Learned:
    """The profile of the labelled sessions ``datasets`` (module docstring); with a ``clock``
    the residents' habits are also counted by time (the ``day`` clock reads each dataset's
    ``site.toml`` epoch)."""
    if not datasets:
        raise InputError("no dataset folders to learn from")
    labelled, rejects, epochs = [], [], []
    for ds in datasets:
        if clock is not None and clock.kind == "day":
            epochs.append(load_site(Path(ds) / "site.toml").epoch)
        path = Path(ds) / "truth_events.csv"
        if not path.exists():
            raise InputError("no truth_events.csv: a profile is learned from labelled sessions", file=path)
        te, rej = read_truth_events_csv(path)
        labelled.append(te)
        rejects.append(rej)
    events = sum(te.height for te in labelled)
    if events == 0:
        raise InputError("the truth_events.csv files have no labelled event", file=Path(datasets[0]))
    return Learned(
        learn_profile(labelled, clock=clock, epochs=epochs or None), len(labelled), events, pl.concat(rejects)
    )


def write_profile(learned: Learned, out: Path) -> Path:
    """``out`` (a ``residents_profile.csv``), written atomically."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_csv(learned.profile, out)
    return out
