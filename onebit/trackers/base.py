"""What every tracker shares: the stage signature and :class:`TrackerSpec`.

A tracker is a pure function ``run(inputs, site, config) -> outputs``:

- ``inputs``: dict of polars frames named as in :data:`TrackerSpec.needs` /
  :data:`TrackerSpec.wants`, plus ``region_graph`` (:class:`~onebit.core.region_graph.RegionGraph`);
- ``config``: a frozen keyword-only dataclass validated at construction (its lengths are in
  the site's units: :func:`onebit.core.units.config_in_site_units` converts them once);
- ``outputs``: dict of polars frames (saved by the pipeline as ``<tracker>_<key>`` tables,
  ``tracks`` as ``<tracker>_tracks`` in the TRACKS schema) and, under the key ``"artifacts"``,
  an optional dict of in-memory results (arrays, models) that only the tracker's Rerun
  logging function needs; artifacts are never saved.

A tracker does no file I/O, never imports rerun or another tracker, never measures
wall-clock time (the runner times stages) and keeps no state between calls. Trackers are
declared in the pipeline's stage list (:mod:`onebit.pipeline.stages`), not registered here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: Key of the in-memory results a tracker hands to its viz function (never saved as a table).
ARTIFACTS = "artifacts"

#: Key in ``inputs`` of an optional ``progress(done, total)`` callback: a tracker with a long
#: loop (filter iterations, HMM windows) calls it after each step. The runner supplies it (a
#: bar on a terminal); it does no I/O the tracker can see, so the tracker stays pure.
PROGRESS = "progress"

#: ``progress(done, total)``
Progress = Callable[[int, int], None]


def _ignore(done: int, total: int) -> None:
    pass


def progress_of(inputs: dict) -> Progress:
    """The ``progress`` callback of ``inputs``, or one that does nothing."""
    cb = inputs.get(PROGRESS)
    return cb if callable(cb) else _ignore


@dataclass(frozen=True)
class TrackerSpec:
    """A tracker: name, the tables it needs (and may use), its config class and its run function."""

    name: str
    needs: tuple[str, ...]
    config: type
    run: Callable[..., dict[str, Any]]
    #: ``available(site) -> reason to skip or None`` (e.g. the site has no motion sensors).
    available: Callable[..., str | None] | None = None
    help: str = ""
    #: optional input tables: passed in ``inputs`` when an earlier stage produced them.
    wants: tuple[str, ...] = ()
    #: ``fits(inputs, site, config) -> reason to skip or None``: whether this run's inputs are
    #: within what the tracker can do in a sensible time (istate: its stage count), checked by
    #: the pipeline before the run; the reason names the setting that lifts the bound.
    fits: Callable[..., str | None] | None = None
    #: ``shares(config) -> key or None``: trackers whose keys are equal compute a common part
    #: and share it when run in one process one after the other (hmm2 and findinghumo-flow
    #: decode the same run: :func:`onebit.models.graph_hmm.decoding.decode_motion`); a run
    #: that works trackers side by side keeps them in one call.
    shares: Callable[[Any], Any] | None = None
    #: a multi-person tracker: it writes ``people`` (t, present), or the runner makes it from
    #: its tracks (``onebit.pipeline.homes.people_from_tracks``), scored against ``truth_count``
    counts_people: bool = False


def instants_bound(frames, tracker: str, field: str, bound: int, cost: str) -> str | None:
    """The reason a tracker of frame logs skips a log of more instants (distinct ``slot`` of
    ``frames``) than ``bound`` (its ``[tracker] field``; 0 = no bound), or ``None``: a
    :data:`TrackerSpec.fits` for trackers whose cost is per instant (``cost``: what one costs)."""
    if not bound or frames is None or frames.height == 0:
        return None
    instants = frames["slot"].n_unique()
    if instants <= bound:
        return None
    return (
        f"the frames hold {instants:,} instants, more than {field} = {bound:,} ({cost}); "
        f"set [{tracker}] {field} = 0 (no bound) in --config to run it"
    )


def home_count_bound(inputs: dict) -> int:
    """The most people the home's count model (stage ``occupancy``, table ``occupancy_people``)
    says are in at once; 0 when the run has no such table (no bound from it)."""
    people = inputs.get("occupancy_people")
    if people is None or people.height == 0:
        return 0
    return int(people["present"].max())
