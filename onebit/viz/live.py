"""The Rerun stream of ``onebit follow``: estimates as they are published, to a file and a viewer.

A live stream has one recording id (the follow run's), the same entity paths as the batch
recordings (``<tracker>/tracks/<track>``, ``sensors/<id>``, ``site/...``), and goes to an
``.rrd`` always -- written as it grows, so a crash leaves the data logged so far -- and,
when asked, to a viewer a user has open (``--connect``, a gRPC URL such as
``rerun+http://127.0.0.1:9876/proxy``) or to a web viewer this process serves
(``--serve-web``). Each publication is a handful of rows: they are sent with
``send_columns`` (one call per track), never one ``log`` per row.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import colors, paths
from onebit.viz.frame import log_world_frame
from onebit.viz.intruder import log_motion_states
from onebit.viz.recording import APPLICATION_ID, rerun_enabled
from onebit.viz.site import log_site

rr = lazy_module("rerun")
rrb = lazy_module("rerun.blueprint")

#: port of the web viewer of ``--serve-web`` (Rerun's default)
WEB_PORT = 9090
#: entity of the delay series, one Scalars per tracker: follow/delay/<tracker>
DELAY_ROOT = "follow/delay"


def open_live(
    path: str | Path, *, recording_id: str, connect: str | None = None, serve_web: bool = False
) -> tuple[rr.RecordingStream, str | None]:
    """A recording stream writing ``path`` as it grows, plus a viewer connection if asked.

    Returns the stream and the URL a browser opens (``serve_web``) or ``None``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with rerun_enabled():
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
        sinks = [rr.FileSink(str(path))]
        if connect:
            sinks.append(rr.GrpcSink(connect))
        url = None
        if serve_web:
            server = rr.GrpcServerSink()
            sinks.append(server)
            url = server.uri
        rec.set_sinks(*sinks)
        if serve_web:
            rr.serve_web_viewer(web_port=WEB_PORT, connect_to=url, open_browser=False)
            url = f"http://localhost:{WEB_PORT} (the page connects to {url.replace('0.0.0.0', 'localhost')})"
    return rec, url


def log_live_site(rec: rr.RecordingStream, site, region_graph) -> None:
    """The site once (static), as in every stage recording."""
    log_site(rec, site, region_graph)


def log_states(rec: rr.RecordingStream, edges: pl.DataFrame) -> None:
    """New accepted toggle edges (``t``, ``sensor``, ``on``) on ``sensors/<id>`` as on / off
    state changes, styled as in the batch recordings (:func:`onebit.viz.intruder.log_motion_states`)."""
    if edges is None or edges.height == 0:
        return
    log_motion_states(rec, edges, sorted(edges["sensor"].unique().to_list()))


def live_blueprint(trackers: list[str]) -> rrb.Blueprint:
    """The stream's layout: the site with the estimates as published, the sensors' states and
    the publication delay of every tracker on one plot."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(
                name="site: estimates as they are published",
                origin="/",
                contents=["+ site/**", *[f"+ {paths.tracker_root(t)}/**" for t in trackers]],
            ),
            rrb.Vertical(
                rrb.StateTimelineView(name="sensors: on / off", origin="/", contents=["+ sensors/**"]),
                rrb.TimeSeriesView(
                    name="publication delay (s, wall clock)", origin="/", contents=[f"+ {DELAY_ROOT}/**"]
                ),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def log_estimates(
    rec: rr.RecordingStream, tracker: str, rows: pl.DataFrame, *, rgb: tuple[int, int, int] | None = None
) -> None:
    """Newly published track rows (``track``, ``t``, ``x``, ``y``) as points on
    ``<tracker>/tracks/<track>`` in the tracker's colour ``rgb``; rows without a position are skipped."""
    if rows is None or rows.height == 0 or "x" not in rows.columns:
        return
    rows = rows.drop_nulls(["t", "x", "y"])
    if rows.height == 0:
        return
    log_world_frame(rec, paths.tracker_root(tracker))
    color = colors.tracker_color(tracker, rgb=rgb)
    for (track,), g in rows.sort("t").group_by("track", maintain_order=True):
        xy = g.select("x", "y").to_numpy().astype(np.float64)
        rec.send_columns(
            paths.track(tracker, str(track)),
            indexes=[paths.time_column(g["t"].to_numpy())],
            columns=rr.Points2D.columns(positions=xy, colors=[color] * len(xy), radii=[-4.0] * len(xy)),
        )


def log_delays(rec: rr.RecordingStream, tracker: str, t: np.ndarray, delay_s: np.ndarray) -> None:
    """The publication delay (s) of each estimate on ``follow/delay/<tracker>`` over ``t``."""
    if len(t) == 0:
        return
    rec.send_columns(
        f"{DELAY_ROOT}/{paths.part(tracker)}",
        indexes=[paths.time_column(t)],
        columns=rr.Scalars.columns(scalars=np.asarray(delay_s, dtype=np.float64)),
    )


def send_live_blueprint(rec: rr.RecordingStream, trackers: list[str]) -> None:
    """Send :func:`live_blueprint` with the stream (the viewer opens on it)."""
    rec.send_blueprint(live_blueprint(trackers), make_active=True, make_default=True)


def close_live(rec: rr.RecordingStream) -> None:
    """Flush and close every sink."""
    rec.flush()
    rec.disconnect()
