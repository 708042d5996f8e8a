"""The ``binpf`` stage: frames of a binary sensor array -> labelled tracks of several people.

Input: ``proximity_frames`` (FRAMES: slot, t, sensor, on -- each sensor's *level* at every
frame, so a sensor held on is presence). The site's proximity sensors give the positions
:math:`p_s` and the footprint radii :math:`R_s` (``r_outer``); ``radius`` overrides them.
The frame period is the frames' own spacing. ``targets`` in ``site.toml`` (or the config's
``targets``) bounds the number of people reported at once; the filter estimates the count
itself (:mod:`onebit.trackers.binpf.filter`, the equations).

Outputs (tables ``binpf_<key>``):

- ``tracks`` (TRACKS): one row per reported track per frame (``track`` = ``b<label>``),
  after joining tracklets across short gaps (:mod:`onebit.trackers.binpf.link`; the filled
  frames are interpolated).
- ``existence``: frame, t, track, x, y, r, reported -- every live Bernoulli component;
  ``reported`` is the filter's rule (:math:`r \\ge r_{out}`), or with ``evidence_ratio > 0``
  the sensors' support over a window (:mod:`onebit.trackers.binpf.evidence`).
- ``frames``: t, on (sensors on), live, births, deaths, merges, reported (tracks in
  ``tracks`` at the frame), count = the expected number of people :math:`\\sum_i r_i`.
- ``links``: joins (tracklets joined).
"""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.config import MAX_PARTICLES, check_size
from onebit.core.errors import ConfigError
from onebit.core.site import Site
from onebit.core.tables import FRAMES, TRACKS, check_schema, conform
from onebit.trackers.base import ARTIFACTS, TrackerSpec, instants_bound, progress_of
from onebit.trackers.binpf import online as binpf_online
from onebit.trackers.binpf.config import BinPFConfig
from onebit.trackers.binpf.evidence import evidence_rows
from onebit.trackers.binpf.filter import FilterParams, run_filter
from onebit.trackers.binpf.link import link_tracklets
from onebit.trackers.binpf.online import frame_levels

NAME = "binpf"


def _linked(existence: pl.DataFrame, config: BinPFConfig, period: float, bound: int):
    """The reported rows, tracklets joined over the whole log: ``(frame, track, x, y, joins)``."""
    rep = existence.filter(pl.col("reported"))
    f, lab, x, y = (
        rep["frame"].to_numpy(),
        rep["track"].to_numpy().astype(str),
        rep["x"].to_numpy(),
        rep["y"].to_numpy(),
    )
    joins = 0
    if config.link and rep.height:
        f, lab, x, y, joins = link_tracklets(
            f,
            lab,
            x,
            y,
            period=period,
            max_gap=config.link_gap,
            max_speed=config.link_speed,
            slack=config.link_slack,
            max_out=bound,
        )
    return f, lab, x, y, joins


def available(site: Site) -> str | None:
    return (
        None
        if site.proximity_sensors
        else "site has no proximity sensors (binary sensors with a position and a radius)"
    )


def frame_period(times: np.ndarray) -> float:
    """The frames' spacing: the median difference of consecutive frame times (1.0 for < 2 frames)."""
    d = np.diff(times)
    d = d[d > 0]
    return float(np.median(d)) if d.size else 1.0


def fits(inputs: dict, site: Site, config: BinPFConfig) -> str | None:
    """Reason to skip on these inputs, or ``None``: more frames than ``config.max_frames``."""
    return instants_bound(
        inputs.get("proximity_frames"),
        NAME,
        "max_frames",
        config.max_frames,
        "~0.35 ms each with the default particles",
    )


def logged_particles(config: BinPFConfig, frames: int, max_tracks: int) -> int:
    """Particles per track and frame sent to Rerun: ``log_particles``, fewer when that would
    exceed ``log_particles_max`` over ``frames`` frames of ``max_tracks`` tracks (at least 1)."""
    if config.log_particles == 0 or config.log_particles_max == 0 or frames == 0:
        return config.log_particles
    return min(config.log_particles, max(1, config.log_particles_max // (frames * max_tracks)))


def site_arrays(site: Site, config: BinPFConfig):
    """``(ids, sensors (S, 2), radii (S,), lo (2,), hi (2,))``: the proximity sensors in site
    order, their footprint radii (``radius`` or each ``r_outer``) and the site's bounding box."""
    ids = tuple(s.id for s in site.proximity_sensors)
    sensors = np.array([s.position for s in site.proximity_sensors], dtype=float).reshape(-1, 2)
    radii = np.array([config.radius or s.r_outer for s in site.proximity_sensors], dtype=float)
    minx, miny, maxx, maxy = site.boundary.bounds
    return ids, sensors, radii, np.array([minx, miny]), np.array([maxx, maxy])


def filter_params(config: BinPFConfig, site: Site, *, period: float) -> FilterParams:
    """The filter's parameters: the config's, the frame ``period`` and the bounds on tracks
    (``max_tracks``, ``max_out`` from ``targets``), checked against the particle budget."""
    bound = config.targets or (site.targets or 0)
    max_tracks = config.max_tracks or (bound + 1 if bound else 8)
    check_size(
        float(config.particles) * max_tracks,
        MAX_PARTICLES,
        what=f"particles ({config.particles} per track x {max_tracks} tracks)",
        field="[binpf] particles / max_tracks",
        hint="fewer particles or tracks",
    )
    return FilterParams(
        particles=config.particles,
        pd=config.pd,
        pf=config.pf,
        edge=config.edge,
        period=period,
        damping=config.damping,
        accel_sigma=config.accel_sigma,
        survival=config.survival,
        silent=config.silent,
        birth_r=config.birth_r,
        birth_explained=config.birth_explained,
        birth_link=config.birth_link,
        birth_speed=config.birth_speed,
        r_confirm=config.r_confirm,
        r_delete=config.r_delete,
        r_out=config.r_out,
        merge_distance=config.merge_distance,
        split_ratio=config.split_ratio,
        count_ratio=config.count_ratio,
        joint_distance=config.joint_distance,
        joint_ratio=config.joint_ratio,
        joint_met=config.joint_met,
        smooth_lag=config.smooth_lag,
        max_tracks=max_tracks,
        max_out=bound,
    )


def evidence_reported(
    res, on: np.ndarray, sensors: np.ndarray, radii: np.ndarray, config: BinPFConfig, p
) -> np.ndarray:
    """The rows reported by the sensors' support (``evidence_ratio > 0``,
    :mod:`onebit.trackers.binpf.evidence`): among every row of the tracks the filter reported
    at some frame, those whose support over ``evidence_window`` frames either side reaches
    ``log evidence_ratio``; at most ``max_out`` a frame."""
    once = np.isin(res.label, np.unique(res.label[res.reported]))
    return evidence_rows(
        res.frame, res.label, res.r, np.c_[res.x, res.y], on, sensors, radii, candidates=once,
        ratio=config.evidence_ratio, window=config.evidence_window, pd=p.pd, pf=p.pf, edge=p.edge,
        silent=p.silent, max_out=p.max_out,
    )  # fmt: skip


def run(inputs: dict, site: Site, config: BinPFConfig) -> dict:
    """The ``binpf`` stage (see the module docstring)."""
    frames = check_schema(inputs["proximity_frames"], FRAMES, name="proximity_frames")
    ids, sensors, radii, lo, hi = site_arrays(site, config)
    times, on = frame_levels(frames, ids)
    p = filter_params(config, site, period=frame_period(times))
    bound, max_tracks = p.max_out, p.max_tracks
    n_logged = logged_particles(config, len(times), max_tracks)
    if config.commit_lag:  # the online driver over the whole log: what `onebit follow` publishes
        res, (f, lab_i, x, y, joins) = binpf_online.run_lagged(
            times, on, p, sensors, radii, lo, hi, lag=config.commit_lag, link=config.link,
            link_gap=config.link_gap, link_speed=config.link_speed, link_slack=config.link_slack,
            seed=config.seed, log_particles=n_logged, progress=progress_of(inputs),
        )  # fmt: skip
        lab = np.char.add("b", lab_i.astype(str)) if lab_i.size else np.zeros(0, dtype=str)
    else:
        res = run_filter(
            on, sensors, radii, lo, hi, p, seed=config.seed, log_particles=n_logged, progress=progress_of(inputs)
        )
    track = np.char.add("b", res.label.astype(str)) if res.label.size else np.zeros(0, dtype=str)
    t = times[res.frame] if res.frame.size else np.zeros(0)
    reported = res.reported
    if config.evidence_ratio > 0 and not config.commit_lag:
        reported = evidence_reported(res, on, sensors, radii, config, p)
    existence = pl.DataFrame(
        {
            "frame": res.frame,
            "t": t,
            "track": track.astype(object),
            "x": res.x,
            "y": res.y,
            "r": res.r,
            "reported": reported,
        },
        schema={
            "frame": pl.Int64,
            "t": pl.Float64,
            "track": pl.String,
            "x": pl.Float64,
            "y": pl.Float64,
            "r": pl.Float64,
            "reported": pl.Boolean,
        },
    )
    if not config.commit_lag:
        f, lab, x, y, joins = _linked(existence, config, p.period, bound)
    tracks = conform(
        pl.DataFrame(
            {
                "tracker": [NAME] * len(f),
                "track": lab.astype(object),
                "t": times[f] if len(f) else np.zeros(0),
                "x": x,
                "y": y,
            },
            schema_overrides={"track": pl.String},
        ),
        TRACKS,
    )
    reported_per_frame = np.bincount(f, minlength=len(times)).astype(np.int64) if len(times) else np.zeros(0, np.int64)
    count = existence.group_by("frame").agg(pl.col("r").sum().alias("count"))
    per_frame = (
        pl.DataFrame(
            {
                "frame": np.arange(len(times)),
                "t": times,
                "on": on.sum(axis=1).astype(np.int64),
                "live": res.live,
                "births": res.births,
                "deaths": res.deaths,
                "merges": res.merges,
                "reported": reported_per_frame,
            }
        )
        .join(count, on="frame", how="left")
        .with_columns(pl.col("count").fill_null(0.0))
        .drop("frame")
    )
    artifacts = {
        "times": times,
        "on": on,
        "sensors": sensors,
        "radii": radii,
        "ids": ids,
        "particles_xy": res.particles_xy,
        "particles_t": times[res.particles_frame] if res.particles_frame.size else np.zeros(0),
        "particles_track": np.char.add("b", res.particles_label.astype(str))
        if res.particles_label.size
        else np.zeros(0, dtype=str),
    }
    return {
        "tracks": tracks,
        "existence": existence,
        "frames": per_frame,
        "links": pl.DataFrame({"joins": [joins]}),
        ARTIFACTS: artifacts,
    }


SPEC = TrackerSpec(
    name=NAME,
    needs=("proximity_frames",),
    counts_people=True,
    config=BinPFConfig,
    run=run,
    available=available,
    fits=fits,
    help="beyond the papers: labelled multi-Bernoulli particle filter for arrays of binary sensors (soft footprint, false alarms, held sensors)",
)


def start_follow(site: Site, config: BinPFConfig) -> binpf_online.FollowBinPF:
    """The driver for ``onebit follow`` from the ``[binpf]`` config (:class:`~onebit.trackers.binpf.stage.BinPFConfig`)."""
    if config.evidence_ratio:
        raise ConfigError(
            f"BinPFConfig.evidence_ratio = {config.evidence_ratio}: the evidence rule reads the frames after a row, "
            "so it runs in the batch stage only; set it to 0 for onebit follow"
        )
    if config.joint_distance:
        raise ConfigError(
            f"BinPFConfig.joint_distance = {config.joint_distance}: the joint update runs in the batch filter only; "
            "set it to 0 for onebit follow"
        )
    ids, sensors, radii, lo, hi = site_arrays(site, config)
    p = filter_params(config, site, period=1.0)
    lag = config.commit_lag or max(binpf_online.DEFAULT_COMMIT_LAG, config.smooth_lag)
    drv = binpf_online.start(
        p, sensors, radii, lo, hi, lag=lag, link=config.link, link_gap=config.link_gap,
        link_speed=config.link_speed, link_slack=config.link_slack, seed=config.seed,
    )  # fmt: skip
    return binpf_online.FollowBinPF(drv, ids)
