"""The declared pipeline: every stage, in order, with what it needs and what it makes.

::

    crossings  beams.csv | crossings.csv   -> crossings, aborted, beam_events
    truth      truth.csv                   -> truth, true_crossings, sim_crossings
    truth_events truth_events.csv          -> truth_events (per-event identity truth: t, sensor, residents)
    residents_profile residents_profile.csv -> residents_profile (known residents, learned from labelled days)
    camera     camera.mp4                  -> camera_truth, camera_detections
    frames     frames.csv (frame-sampled)  -> levels, motion, proximity, proximity_frames
    motion     motion.csv                  -> motion, motion_suppressed   (skipped with frames.csv)
    proximity  proximity.csv               -> proximity, proximity_frames, proximity_suppressed
    ignore     site.toml ignore = true     -> ignored (rows of ignored sensors the trackers will not see)
    correct    crossings                   -> corrected_crossings, correct_insertions, correct_initial
    <tracker>  its TrackerSpec.needs       -> <tracker>_tracks, <tracker>_<table>...   (one per TRACKERS entry)
    scores     everything above            -> crossing_matches, <tracker>_scores, ...

Each stage's ``makes`` is checked by the runner (:func:`onebit.pipeline.context.check_made`):
a stage returning a table it does not declare, or one an earlier stage made, fails. ``onebit
run`` and ``onebit follow`` run this one list with one step
(:func:`onebit.pipeline.runner.run_stage`); ``follow`` runs the stages declared ``polled`` at
every poll, and each tracker as its entry's ``live`` says (:mod:`onebit.pipeline.online`).

This file declares; the work is elsewhere: a tracker's stage in :mod:`onebit.pipeline.tracking`,
the scores in :mod:`onebit.pipeline.scores`, the reader stages' work (a raw log -> its tables)
in :mod:`onebit.pipeline.reading`.

Adding a tracker: its package under :mod:`onebit.trackers` (a ``TrackerSpec``), a scoring
function in :mod:`onebit.scoring` (built on :mod:`onebit.scoring.association`; the MOT metrics
of :mod:`onebit.scoring.mot` are added for every tracker), a ``log_run`` in :mod:`onebit.viz`
-- and one :class:`TrackerEntry` line in :data:`TRACKERS` (``docs/extending.md``). No
registry, no plugin loading: this file is the whole list.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import polars as pl

from onebit.models.occupancy import OccupancyConfig
from onebit.pipeline import (
    homes,
    reading,
    tracking,  # its tracker_stage, read when stages() is called (tracking reads this module)
)
from onebit.pipeline.context import ReportRow, Stage
from onebit.pipeline.homes import count_metric
from onebit.pipeline.online import BATCH_ONLY, BEAMS, BINPF, INTRUDER, ISTATE, LAGGED, ONLINE, PREFIX, Live, hmm_stepper
from onebit.pipeline.reading import TIME_SOURCES, run_time_origin, without_ignored  # noqa: F401  (for follow, tracking)
from onebit.pipeline.scores import MetricFn, identity_metric, scores_stage
from onebit.readers.motion import MotionConfig
from onebit.readers.proximity import ProximityConfig
from onebit.scoring import beams as score_beams
from onebit.scoring import binpf as score_binpf
from onebit.scoring import clustertrack as score_clustertrack
from onebit.scoring import findinghumo as score_findinghumo
from onebit.scoring import intruder as score_intruder
from onebit.scoring import istate as score_istate
from onebit.scoring import residents as score_residents
from onebit.scoring.mot import Gate
from onebit.trackers import beams, binpf, clustertrack, findinghumo, findinghumo_flow, intruder, istate, residents
from onebit.trackers.base import TrackerSpec
from onebit.trackers.beams.correction import CorrectConfig
from onebit.viz import beams as viz_beams
from onebit.viz import binpf as viz_binpf
from onebit.viz import clustertrack as viz_clustertrack
from onebit.viz import findinghumo as viz_findinghumo
from onebit.viz import intruder as viz_intruder
from onebit.viz import istate as viz_istate
from onebit.viz import occupancy as viz_occupancy
from onebit.viz import residents as viz_residents
from onebit.viz.families import Look

#: ``score(tracker, tables, site, region_graph) -> (report rows, tables)``
ScoreFn = Callable[..., tuple[list[ReportRow], dict[str, pl.DataFrame]]]
#: ``log_run(rec, tracker, outputs, *, site, region_graph, config, tables, look)``
VizFn = Callable[..., None]


@dataclass(frozen=True)
class TrackerEntry:
    """One tracker in the pipeline, declared once: the tracker, how it is scored, its MOT gate,
    how it is logged and the scenario it is tested on.

    ``inputs`` maps an input name of the tracker to the tables that may feed it, first
    present wins (the beams tracker reads the corrected crossings when the ``correct``
    stage made them, else the decoded ones).
    """

    spec: TrackerSpec
    score: ScoreFn
    viz: VizFn | None = None
    inputs: dict[str, tuple[str, ...]] = field(default_factory=dict)
    #: the MOT gate of its tracks (:class:`onebit.scoring.mot.Gate`); ``None`` = no MOT rows
    gate: Gate | None = None
    #: the built-in scenario (``onebit simulate NAME``) the tests run it on: the contract tests
    #: of the trackers and of the scorers (``None``: no scenario serves it)
    scenario: str | None = None
    #: how its recordings and its blueprint tab look: family and colour
    #: (:class:`onebit.viz.families.Look`; the error unit is set from ``gate``, see :attr:`drawn`)
    look: Look = field(default_factory=Look)
    #: how it runs while ``onebit follow`` reads a growing log (:class:`onebit.pipeline.online.Live`:
    #: online, lagged, re-run on the settled prefix, or batch only)
    live: Live = BATCH_ONLY

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def drawn(self) -> Look:
        """:attr:`look` with its error unit from the MOT gate: a gate in hops is an error plot in hops."""
        return replace(self.look, hops=self.gate is not None and self.gate.unit == "hops")


#: The MOT gates the papers share (``TrackerEntry.gate``; docs/metrics.md, "Standard MOT metrics").
CELLS_GATE = Gate(
    "point",
    2.0,
    "cells",
    "Schiff & Goldberg score in grid cells; 'within two world-space cells' is their accuracy criterion "
    "(VIII: perfect sensors put every estimate there) and the intruder's bounding prism is 2 cells wide",
)
HOPS_GATE = Gate(
    "node", 1.0, "hops", "De et al. score hops on the sensor graph; 1 hop = the adjacent sensor, the PIR's resolution"
)

#: Colours of the FindingHuMo decoder and its two baselines (one entry each, made in a loop below).
FINDINGHUMO_RGB: dict[str, tuple[int, int, int]] = {
    "findinghumo": (255, 200, 60),
    "hmm1": (90, 200, 255),
    "hmm2": (240, 110, 200),
}

#: The window decoder of each FindingHuMo HMM (its ``decoding = "lagged"`` online run).
HMM_DECODERS: dict[str, str] = {"findinghumo": "adaptive", "hmm1": "full1", "hmm2": "full2"}

#: Every tracker, in the order their stages run.
TRACKERS: tuple[TrackerEntry, ...] = (
    TrackerEntry(
        beams.SPEC,
        score_beams.score,
        viz_beams.log_run,
        {"crossings": ("corrected_crossings", "crossings")},
        Gate(
            "region", 1.0, "hops", "Bobadilla et al. localise to a region; 1 hop = the adjacent region, one beam away"
        ),
        scenario="beams-lab",
        look=Look("beams", (64, 196, 255)),
        live=Live(
            ONLINE,
            "per crossing (incremental; re-run on the settled prefix when [correct] runs)",
            events=("corrected_crossings", "crossings"),
            stepper=BEAMS,
        ),
    ),
    TrackerEntry(
        intruder.SPEC,
        score_intruder.score,
        viz_intruder.log_run,
        gate=CELLS_GATE,
        scenario="pir14",
        look=Look("intruder", (70, 225, 110)),
        live=Live(ONLINE, "per iteration (incremental particle filter)", stepper=INTRUDER),
    ),
    TrackerEntry(
        intruder.NAIVE_SPEC,
        score_intruder.score,
        viz_intruder.log_run,
        gate=CELLS_GATE,
        scenario="pir14",
        look=Look("intruder", (200, 120, 255)),
        live=Live(PREFIX, "per iteration", events=("motion",)),
    ),
    TrackerEntry(
        clustertrack.SPEC,
        score_clustertrack.score,
        viz_clustertrack.log_run,
        gate=Gate(
            "point",
            1.0,
            "R",
            "Singh et al. report error in units of the sensing radius R; within R the target is resolved",
        ),
        scenario="proximity-line",
        look=Look("clustertrack", (255, 160, 40)),
    ),
    TrackerEntry(
        binpf.SPEC,
        score_binpf.score,
        viz_binpf.log_run,
        gate=Gate(
            "point",
            1.0,
            "m",
            "beyond the papers: a metric gate in world units; 1 m is about half the spacing of a ceiling "
            "array (Milan et al. score at 1.5 m)",
        ),
        scenario="proximity-grid",
        look=Look("binpf", (255, 110, 90)),
        live=Live(
            ONLINE, "per frame, committed after [binpf] commit_lag frames (incremental particle filter)", stepper=BINPF
        ),
    ),
    *(
        TrackerEntry(
            spec,
            score_findinghumo.score,
            viz_findinghumo.log_run,
            gate=HOPS_GATE,
            scenario="hallway",
            look=Look("findinghumo", FINDINGHUMO_RGB[spec.name]),
            live=Live(
                LAGGED,
                "per window (re-run on the settled prefix)",
                events=("motion",),
                stepper=hmm_stepper(HMM_DECODERS[spec.name]),
            ),
        )
        for spec in findinghumo.SPECS
    ),
    TrackerEntry(
        findinghumo_flow.SPEC,
        score_findinghumo.score,
        viz_findinghumo.log_run,
        gate=HOPS_GATE,
        scenario="hallway",
        look=Look("findinghumo", (120, 240, 200)),
    ),
    TrackerEntry(
        istate.SPEC,
        score_istate.score,
        viz_istate.log_run,
        gate=Gate(
            "point",
            1.0,
            "sensing radius",
            "O'Kane's I-state has no unit of its own; a point summary within one "
            "sensing radius is what the sensors can tell apart",
        ),
        scenario="istate-room",
        look=Look("istate", (255, 235, 130)),
        live=Live(
            ONLINE,
            "per stage (incremental with latency_auto = false; else re-run on the settled prefix)",
            events=("motion", "proximity", "crossings"),
            stepper=ISTATE,
        ),
    ),
    TrackerEntry(
        residents.SPEC,
        score_residents.score,
        viz_residents.log_run,
        gate=Gate(
            "point",
            1.0,
            "sensing radius",
            "the residents tracker places each person at the sensor of their latest "
            "event: within one sensing radius the sensor covers them",
        ),
        scenario="hallway",
        look=Look("residents", (255, 140, 120)),
    ),
)

#: How every tracker is drawn, by name (:attr:`TrackerEntry.drawn`): what the viz and the
#: blueprint are given.
LOOKS: dict[str, Look] = {e.name: e.drawn for e in TRACKERS}


def tracker_names(entries: tuple[TrackerEntry, ...] = TRACKERS) -> tuple[str, ...]:
    return tuple(e.name for e in entries)


# --------------------------------------------------------------------------- scores

#: The metrics of every tracker beyond its own (``TrackerEntry.score``) and the MOT rows: one
#: line per metric (docs/extending.md, "A report metric").
METRICS: tuple[MetricFn, ...] = (identity_metric, count_metric)


# --------------------------------------------------------------------------- the list


#: The stages before the trackers, in order: the readers of the raw logs and of the truth,
#: the profiles, the ignored sensors, the count model and the beams' correction.
INPUT_STAGES: tuple[Stage, ...] = (
    Stage(
        "crossings",
        (),
        ("crossings", "aborted", "beam_events"),
        reading.crossings_available,
        reading.crossings_work,
        reading.crossings_viz,
        polled=True,
    ),
    Stage(
        "truth",
        (),
        ("truth", "true_crossings", "sim_crossings"),
        reading.truth_available,
        reading.truth_work,
        reading.truth_viz,
    ),
    Stage("truth_events", (), ("truth_events",), reading.truth_events_available, reading.truth_events_work),
    Stage("residents_profile", (), ("residents_profile",), reading.profile_available, reading.profile_work),
    Stage("truth_count", (), ("truth_count",), homes.truth_count_available, reading.truth_count_work),
    Stage("count_profile", (), ("count_profile",), homes.count_profile_available, homes.count_profile_work),
    Stage(
        "camera",
        (),
        ("camera_truth", "camera_detections"),
        reading.camera_available,
        reading.camera_work,
        reading.camera_viz,
    ),
    Stage(
        "frames",
        (),
        ("levels", "motion", "proximity", "proximity_frames"),
        reading.frames_available,
        reading.frames_work,
        reading.frames_viz,
        polled=True,
    ),
    Stage(
        "motion",
        (),
        ("motion", "motion_suppressed"),
        reading.motion_available,
        reading.motion_work,
        reading.motion_viz,
        config=MotionConfig,
        polled=True,
    ),
    Stage(
        "proximity",
        (),
        ("proximity", "proximity_frames", "proximity_suppressed"),
        reading.proximity_available,
        reading.proximity_work,
        config=ProximityConfig,
        polled=True,
    ),
    Stage("ignore", (), ("ignored",), reading.ignore_available, reading.ignore_work),
    Stage(
        "occupancy",
        ("motion",),
        ("occupancy_bins", "occupancy_people"),
        homes.occupancy_available,
        reading.occupancy_work,
        viz_occupancy.log_occupancy,
        config=OccupancyConfig,
    ),
    Stage(
        "correct",
        ("crossings",),
        ("corrected_crossings", "correct_insertions", "correct_initial"),
        reading.correct_available,
        reading.correct_work,
        reading.correct_viz,
        config=CorrectConfig,
        polled=True,
    ),
)


def stages(trackers: tuple[TrackerEntry, ...] = TRACKERS) -> list[Stage]:
    """The declared pipeline, in order (module docstring): :data:`INPUT_STAGES`, a stage per
    tracker, the scores."""
    return [
        *INPUT_STAGES,
        *(tracking.tracker_stage(e) for e in trackers),
        scores_stage(trackers, METRICS),
    ]
