"""Rerun logging for onebit: entity paths, colours, recordings, blueprint.

Nothing outside this package imports rerun. Every function takes an explicit
:class:`rerun.RecordingStream`; :class:`StageLog` wraps one (or none, for pure runs and
tests) so a stage's caller can log what the stage produced without checking whether
recording is on.
"""

from __future__ import annotations

import polars as pl
import rerun as rr

from onebit.datasets.region_graph import RegionGraph
from onebit.datasets.site import Site
from onebit.viz import colors, paths
from onebit.viz.blueprint import make_blueprint, send_blueprint
from onebit.viz.colors import color_of, colors_of
from onebit.viz.events import log_crossings
from onebit.viz.recording import (
    APPLICATION_ID,
    close_recording,
    discard_recording,
    open_recording,
    stage_path,
    stage_recording,
)
from onebit.viz.site import log_site
from onebit.viz.tracks import log_occupancy, log_point_tracks, log_region_tracks, log_scores
from onebit.viz.truth import log_truth

__all__ = [
    "APPLICATION_ID",
    "StageLog",
    "close_recording",
    "color_of",
    "colors",
    "colors_of",
    "discard_recording",
    "log_crossings",
    "log_occupancy",
    "log_point_tracks",
    "log_region_tracks",
    "log_scores",
    "log_site",
    "log_truth",
    "make_blueprint",
    "open_recording",
    "paths",
    "send_blueprint",
    "stage_path",
    "stage_recording",
]


class StageLog:
    """What one stage logs, to ``rec`` or -- when ``rec`` is ``None`` -- nowhere.

    Examples
    --------
    >>> StageLog(None).truth(None)   # a null log: every method is a no-op
    """

    def __init__(self, rec: rr.RecordingStream | None) -> None:
        self.rec = rec

    @property
    def enabled(self) -> bool:
        return self.rec is not None

    def site(self, site: Site, region_graph: RegionGraph | None = None) -> None:
        if self.rec is not None:
            log_site(self.rec, site, region_graph)

    def crossings(self, crossings: pl.DataFrame | None, aborted: pl.DataFrame | None = None) -> None:
        if self.rec is not None:
            log_crossings(self.rec, crossings, aborted=aborted)

    def truth(self, truth: pl.DataFrame | None) -> None:
        if self.rec is not None:
            log_truth(self.rec, truth)

    def region_tracks(self, tracker: str, tracks: pl.DataFrame | None, region_graph: RegionGraph) -> None:
        if self.rec is not None:
            log_region_tracks(self.rec, tracker, tracks, region_graph)

    def point_tracks(self, tracker: str, tracks: pl.DataFrame | None) -> None:
        if self.rec is not None:
            log_point_tracks(self.rec, tracker, tracks)

    def occupancy(self, tracker: str, occ: pl.DataFrame | None) -> None:
        if self.rec is not None:
            log_occupancy(self.rec, tracker, occ)

    def scores(self, tracker: str, scores: pl.DataFrame | None) -> None:
        if self.rec is not None:
            log_scores(self.rec, tracker, scores)

    def emit(self, fn, *args, **kwargs) -> None:
        """Call ``fn(rec, *args, **kwargs)`` -- a logging function of a ``onebit.viz`` module --
        when recording is on. Trackers log through this so they never import rerun."""
        if self.rec is not None:
            fn(self.rec, *args, **kwargs)

    def blueprint(self, trackers: list[str]) -> None:
        if self.rec is not None:
            send_blueprint(self.rec, trackers=trackers)
