"""Rerun logging for onebit: entity paths, colours, recordings, the blueprint of a run.

Nothing outside this package imports rerun (an import-linter contract holds it). Every
function takes an explicit :class:`rerun.RecordingStream`; the pipeline's stage list calls
them with what each stage produced (trackers never log). Each tracker family has a
``log_run(rec, tracker, outputs, *, site, region_graph, config, tables)`` in its module; the
runner writes the run's layout with :func:`save_run_blueprint` once every stage has logged
(``OUT/rrd/blueprint.rbl``; ``docs/viewing.md``).
"""

from __future__ import annotations

from onebit.viz import colors, paths
from onebit.viz.blueprint import make_blueprint, save_blueprint, save_run_blueprint
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
from onebit.viz.tracks import (
    log_occupancy,
    log_point_tracks,
    log_region_tracks,
    log_scores,
)
from onebit.viz.trails import TRAIL_S
from onebit.viz.truth import log_truth

__all__ = [
    "APPLICATION_ID",
    "TRAIL_S",
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
    "save_blueprint",
    "save_run_blueprint",
    "stage_path",
    "stage_recording",
]
