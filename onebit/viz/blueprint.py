"""The default viewer layout sent with every recording."""

from __future__ import annotations

import rerun as rr
import rerun.blueprint as rrb

from onebit.viz import paths


def make_blueprint(*, trackers: list[str]) -> rrb.Blueprint:
    """Site view (site + truth + each tracker's tracks and particles) on the left; occupancy,
    error and the sensor event log on the right; time panel on ``t``."""
    roots = [paths.tracker_root(t) for t in trackers]
    spatial = rrb.Spatial2DView(
        name="site",
        origin="/",
        contents=[f"{paths.SITE}/**", f"{paths.TRUTH}/**", *[f"{r}/**" for r in roots], *[f"-{r}/occupancy/**" for r in roots]],
    )
    occupancy = rrb.TimeSeriesView(
        name="occupancy", origin="/", contents=[f"{r}/occupancy/**" for r in roots] or ["-/**"]
    )
    error = rrb.TimeSeriesView(name="error", origin=paths.SCORES)
    sensors = rrb.TextLogView(name="sensors", origin=paths.SENSORS)
    return rrb.Blueprint(
        rrb.Horizontal(spatial, rrb.Vertical(occupancy, error, sensors), column_shares=[3, 2]),
        rrb.TimePanel(timeline=paths.TIMELINE),
        collapse_panels=False,
    )


def send_blueprint(rec: rr.RecordingStream, *, trackers: list[str]) -> None:
    """Send :func:`make_blueprint` on ``rec`` as the active and default layout."""
    rec.send_blueprint(make_blueprint(trackers=trackers), make_active=True, make_default=True)
