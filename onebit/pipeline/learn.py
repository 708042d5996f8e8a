"""``onebit learn residents``: a known-residents profile from labelled dataset folders.

Each dataset folder with a ``truth_events.csv`` (CASAS resident annotations, as ``onebit import
casas`` writes it) is one labelled session; the profile
(:func:`onebit.trackers.residents.known.learn_profile`) sums their counts and is written as
``residents_profile.csv``. Put that file in a dataset folder and the ``residents`` tracker
decodes it with the known residents (docs/residents.md, "Known residents").

Folders that also have ``truth_count.csv`` (how many were home: ``onebit import aras`` writes
it) teach the home's count model too (:func:`learn_counts`, :mod:`onebit.models.occupancy`):
its statistics are written as ``count_profile.csv`` beside the residents profile; put it in a
dataset folder and the ``occupancy`` stage decodes the count with it (docs/homes.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.core.writers import write_csv
from onebit.models.occupancy import OccupancyConfig, learn_stats
from onebit.readers.motion import MotionConfig, read_motion_csv, site_rules
from onebit.readers.tables_csv import read_truth_count_csv, read_truth_events_csv
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


def learn_counts(datasets: list[Path], cfg: OccupancyConfig | None = None) -> pl.DataFrame | None:
    """The count model's statistics (:func:`onebit.models.occupancy.learn_stats`) summed over
    the folders that have ``truth_count.csv`` (``None``: none has). Each folder's motion log is
    read as a run reads it (debounced, level sensors held)."""
    cfg = cfg or OccupancyConfig()
    parts = []
    for ds in datasets:
        ds = Path(ds)
        if not (ds / "truth_count.csv").exists():
            continue
        site = load_site(ds / "site.toml")
        if not (ds / "motion.csv").exists():
            raise InputError("truth_count.csv without motion.csv: the count is learned from the motion log", file=ds)
        ids = [m.id for m in site.motion_sensors]
        motion = read_motion_csv(
            ds / "motion.csv", ids, epoch=site.epoch, rules=site_rules(site, MotionConfig()), held=site.level_sensors
        ).motion
        tc, _ = read_truth_count_csv(ds / "truth_count.csv", epoch=site.epoch)
        if tc.height:
            parts.append(learn_stats(motion, tc, site.tracked, cfg))
    if not parts:
        return None
    return pl.concat(parts).group_by("term", "state", "key").agg(pl.col("count").sum()).sort("term", "state", "key")
