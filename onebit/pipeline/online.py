"""How a tracker runs while ``onebit follow`` reads a growing log: :class:`Live`, a field of its
:class:`~onebit.pipeline.stages.TrackerEntry`, and the steppers of the trackers that run online.

A tracker runs live in one of four ways (:attr:`Live.mode`):

* ``online`` -- a :class:`Stepper` steps it over what became final at each poll, keeping its
  state (``intruder``, ``beams``, ``istate``, ``binpf``); where the stepper does not apply
  (``beams`` after the correction, ``istate`` with a config that is not sequential, or
  ``FollowConfig(incremental=False)``) it is re-run on the settled prefix instead;
* ``lagged`` -- it steps online when its config asks for a bounded-delay decoding
  (``decoding = "lagged"``: the FindingHuMo HMMs), else it is re-run on the settled prefix;
* ``prefix`` -- re-run on the settled prefix of its input whenever a new settled event
  (:attr:`Live.events`) arrives; the rows up to that event not published before are published;
* ``batch`` -- run only by the final batch run.

The follow loop (:mod:`onebit.pipeline.follow`) knows these modes, never a tracker's name.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import polars as pl

from onebit.core.errors import ConfigError
from onebit.models.graph_hmm.decoding import build_eatg
from onebit.trackers.beams import online as beams_online
from onebit.trackers.binpf import online as binpf_online
from onebit.trackers.binpf import stage as binpf_stage
from onebit.trackers.findinghumo import lagged as hmm_online
from onebit.trackers.findinghumo.stage import FindingHumoConfig
from onebit.trackers.intruder import online as intruder_online
from onebit.trackers.istate import online as istate_online

#: The ways a tracker runs live (module docstring).
ONLINE, LAGGED, PREFIX, BATCH = "online", "lagged", "prefix", "batch"
MODES = (ONLINE, LAGGED, PREFIX, BATCH)


@dataclass(frozen=True)
class Poll:
    """What one poll of ``onebit follow`` hands a tracker that runs live."""

    #: the tables the reader stages made of the log so far
    tables: dict[str, pl.DataFrame]
    #: an event at ``t <= until`` is settled (``inf`` once the logs ended)
    until: float
    #: the log time known so far
    horizon: float
    #: the readers' look-ahead, seconds
    settle: float
    #: the logs ended: everything is settled
    final: bool
    #: ``FollowConfig.incremental``
    incremental: bool


@dataclass(frozen=True)
class Stepper:
    """A tracker's incremental run: ``start(name, site, config, region_graph) -> state`` once,
    then at every poll ``advance(state, poll) -> tables`` (``tracks`` and any other table it
    publishes as ``<tracker>_<table>``)."""

    start: Callable[[str, Any, Any, Any], Any]
    advance: Callable[[Any, Poll], dict[str, pl.DataFrame]]
    #: the tables it steps over: it waits until they are there
    needs: tuple[str, ...] = ()
    #: it steps only with ``FollowConfig(incremental=True)``
    incremental: bool = False
    #: ``config_ok(config)``: whether its config lets it step (else it is re-run on the prefix)
    config_ok: Callable[[Any], bool] | None = None
    #: ``tables_ok(tables)``: whether it steps on this poll's tables (else the prefix re-run)
    tables_ok: Callable[[dict[str, pl.DataFrame]], bool] | None = None
    #: how it publishes when :attr:`config_ok` makes it step (``lagged`` mode; else :attr:`Live.note`)
    note: str | None = None

    def steps(self, config: Any, poll: Poll) -> bool:
        """Whether it steps at this poll (else it is re-run on the settled prefix, when it has one)."""
        return (
            (not self.incremental or poll.incremental)
            and (self.config_ok is None or self.config_ok(config))
            and (self.tables_ok is None or self.tables_ok(poll.tables))
        )


@dataclass(frozen=True)
class Live:
    """How a tracker runs while ``onebit follow`` reads a growing log (module docstring)."""

    mode: str = BATCH
    #: how often it publishes, said when the follow starts
    note: str = ""
    #: re-run on the settled prefix: the input tables whose settled events close its rows (first present)
    events: tuple[str, ...] = ()
    stepper: Stepper | None = None

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ConfigError(f"Live.mode = {self.mode!r}; one of {list(MODES)}")
        if self.mode in (ONLINE, LAGGED) and self.stepper is None:
            raise ConfigError(f"Live.mode = {self.mode!r} needs a stepper")
        if self.mode in (LAGGED, PREFIX) and not self.events:
            raise ConfigError(f"Live.mode = {self.mode!r} needs the events that close a prefix re-run's rows")

    def says(self, config: Any) -> str:
        """How it publishes with ``config``."""
        s = self.stepper
        if self.mode == LAGGED and s is not None and s.note and (s.config_ok is None or s.config_ok(config)):
            return s.note
        return self.note


BATCH_ONLY = Live()


# --------------------------------------------------------------------------- the steppers


def _intruder_advance(state, poll: Poll) -> dict[str, pl.DataFrame]:
    return intruder_online.advance(
        state,
        poll.tables["motion"],
        horizon=min(poll.horizon, poll.until + poll.settle),
        settle=poll.settle,
        final=poll.final,
    )


#: intruder: the particle filter's posterior stepped over each slot once it is final
INTRUDER = Stepper(
    start=lambda name, site, cfg, rg: intruder_online.start(site, cfg), advance=_intruder_advance, needs=("motion",)
)


def _beams_advance(state, poll: Poll) -> dict[str, pl.DataFrame]:
    cr = poll.tables["crossings"]
    return {
        "tracks": beams_online.advance(
            state, cr if poll.final else cr.filter(pl.col("t") <= poll.until), final=poll.final
        )
    }


#: beams: each final crossing fed to Algorithm 1 as a resumable pass (the reader's crossings:
#: when the correction ran, its programme is over the whole string, and beams is re-run instead)
BEAMS = Stepper(
    start=lambda name, site, cfg, rg: beams_online.start(site, cfg, rg),
    advance=_beams_advance,
    incremental=True,
    tables_ok=lambda tables: "corrected_crossings" not in tables and "crossings" in tables,
)


def _istate_advance(state, poll: Poll) -> dict[str, pl.DataFrame]:
    inputs = {k: poll.tables[k] for k in ("motion", "proximity", "crossings") if k in poll.tables}
    return {"tracks": istate_online.advance(state, inputs, until=poll.until, final=poll.final)}


#: istate: O'Kane's filter stage by stage, when its config lets the batch run be sequential
ISTATE = Stepper(
    start=lambda name, site, cfg, rg: istate_online.start(site, cfg),
    advance=_istate_advance,
    incremental=True,
    config_ok=lambda cfg: istate_online.supported(cfg) is None,
)


def _binpf_advance(state, poll: Poll) -> dict[str, pl.DataFrame]:
    frames = poll.tables["proximity_frames"]
    return {"tracks": binpf_online.advance(state, frames, until=poll.until, final=poll.final)}


#: binpf: the particle filter's state kept, frame k committed once frame k + commit_lag is filtered
BINPF = Stepper(
    start=lambda name, site, cfg, rg: binpf_stage.start_follow(site.tracked, cfg),
    advance=_binpf_advance,
    needs=("proximity_frames",),
)

#: How the HMM trackers publish with ``decoding = "lagged"``.
LAGGED_NOTE = "per block of tau slots, final D' slots after it (decoding = 'lagged', incremental)"


def hmm_stepper(decoder: str) -> Stepper:
    """A FindingHuMo HMM of window decoder ``decoder`` (``adaptive``, ``full1``, ``full2``):
    with ``decoding = "lagged"`` it commits a block of ``tau`` slots once ``decision_lag``
    slots after it have arrived (:mod:`onebit.trackers.findinghumo.lagged`)."""

    def start(name: str, site, cfg, rg):
        eatg = build_eatg(site, np.zeros((0, len(site.sensor_graph.nodes)), bool), cfg)
        cpda = cfg.c_windows if isinstance(cfg, FindingHumoConfig) else None
        return hmm_online.start(name, decoder, site, cfg, eatg, cpda_windows=cpda)

    def advance(state, poll: Poll) -> dict[str, pl.DataFrame]:
        motion = poll.tables["motion"]
        return {"tracks": hmm_online.advance(state, motion, settled_until=poll.until, final=poll.final)}

    return Stepper(
        start=start,
        advance=advance,
        needs=("motion",),
        config_ok=lambda cfg: getattr(cfg, "decoding", "batch") == "lagged",
        note=LAGGED_NOTE,
    )
