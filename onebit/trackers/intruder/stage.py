"""Trackers ``intruder`` (the SIR particle filter) and ``intruder-naive`` (the room centre).

Input: the ``motion`` table (accepted PIR edges). The tracker slots it at its own period
``t_P`` (:func:`onebit.core.frames.motion_frames`), takes S_i = ``fired`` and the
refractory state B_i from :func:`onebit.core.frames.refractory_state` with each sensor's
``refractory`` (f_i) from ``site.toml``, and estimates the intruder's cell at the end of every
iteration (``t = start + (k + 1) t_P``). Lengths in the config are in **cells** (the paper's
units) and converted to world units with ``cell``, the size of a cell: given in metres and
converted once to the site's units (:func:`onebit.core.units.config_in_site_units`), so
the same ``run.toml`` means the same on a site drawn in cm and on one drawn in m. Each
sensor's detection probabilities are deployed on the cells within its detection region
(:func:`onebit.models.pir.deploy`); a sensor without one is an error.

Outputs: ``tracks`` (one track ``intruder``), ``iterations`` (per iteration: ESS, redraws,
clamped particles, spread, fired and blind sensor counts, ``cell``), ``coverage`` (the
deployed grid q_ij of every sensor: sensor, ix, iy, x, y, p_detect).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.config import MAX_PARTICLES
from onebit.core.errors import ConfigError
from onebit.core.frames import ABSENT_AFTER_S, motion_frames, outside_silence, refractory_state, silent_stretches
from onebit.core.params import param, validate
from onebit.core.site import Site
from onebit.core.tables import MOTION, TRACKS, check_schema, conform
from onebit.core.units import length
from onebit.models.motion import Motion, Room
from onebit.models.pir import Deployment, deploy
from onebit.trackers.base import ARTIFACTS, PROGRESS, TrackerSpec
from onebit.trackers.intruder.camera import pan_tilt_zoom
from onebit.trackers.intruder.filter import run_filter

NAME = "intruder"
NAIVE = "intruder-naive"


@dataclass(frozen=True, kw_only=True)
class IntruderConfig:
    """``run.toml`` ``[intruder]``; defaults are the paper's simulation values (section VIII)."""

    particles: int = param(1000, "number of particles (paper: 1000)", lo=1, hi=MAX_PARTICLES)
    period: float = param(2.0, "t_P, seconds per iteration", lo=1e-6, unit="s")
    v_max: float = param(4.0, "maximum speed", lo=0.0, unit="cells/s")
    speed_sigma: float = param(1.5, "std of the Gaussian added to the speed", lo=0.0, unit="cells/s")
    turn_scale: float | None = param(
        None,
        "sigma_theta = turn_scale / speed (rad * cells/s), capped at pi; unset = v_max (1 rad at top speed)",
        lo=0.0,
    )
    box_width: float = param(2.0, "intruder bounding prism width (x)", lo=1e-6, unit="cells")
    box_depth: float = param(2.0, "intruder bounding prism depth (y)", lo=1e-6, unit="cells")
    cell: float = length(1.0, "size of a cell (converted to site units: world units per cell)", lo=1e-9)
    resample: str = param("systematic", "resampling scheme", choices=("systematic", "multinomial"))
    resample_when: str = param(
        "always", "always (SIR), or ess: when ESS < ess_threshold * particles", choices=("always", "ess")
    )
    ess_threshold: float = param(0.5, 'fraction of particles, for resample_when = "ess"', lo=0.0, hi=1.0)
    max_retries: int = param(50, "rejection-sampling rounds before a particle is left in place", lo=1, hi=10_000)
    seed: int = param(0, "random seed", lo=0)
    start: float | None = param(
        None,
        "time the intruder enters; iteration k ends at start + (k+1) t_P; unset = the start of the slot "
        "(a multiple of t_P) holding the first edge, so the slots span the data wherever its clock is (Unix "
        "seconds, an early epoch)",
        unit="s",
    )
    end: float | None = param(None, "time it leaves; unset = the slot of the last edge", lo="start", unit="s")
    log_particles: int = param(1000, "particles per iteration sent to Rerun", lo=0, hi=MAX_PARTICLES)
    box_height: float = param(1.0, "intruder bounding prism height (for camera pointing)", lo=1e-6, unit="cells")
    camera_position: list[float] | None = length(
        None, "[x, y, z] of the pan-tilt-zoom camera (converted to site units); unset = no camera table"
    )
    camera_fov: float = param(60.0, "horizontal field of view of the camera at zoom 1", lo=1e-3, hi=179.0, unit="deg")
    camera_aspect: float = param(4.0 / 3.0, "image width / height", lo=1e-3)
    absent_after: float = param(
        ABSENT_AFTER_S,
        "no estimate inside a stretch this long with every sensor off and no edge (nobody present); "
        "0 = always estimate",
        lo=0.0,
        hi=1e12,
        unit="s",
    )
    false_alarm: float = param(
        0.02,
        "h of a sensor whose type states no false_positive (no type, or a site table without it): P(it fires "
        "in an iteration with nobody in its region); the built-in simulated types keep theirs (pir 0, "
        "pir-imperfect 0.25). Real ceiling IR: ~0.008 per 0.5 s frame = ~0.03 per 2 s iteration; 0 = the "
        "paper's perfect sensors",
        lo=0.0,
        hi=0.999,
    )
    held: bool = param(
        True,
        'a level sensor (signal = "level") held on through an iteration fires in it (presence), not only '
        'on a rising edge; PIRs (signal = "edge") are unchanged',
    )

    def __post_init__(self) -> None:
        validate(self)
        cp = self.camera_position
        if cp is not None and not (
            isinstance(cp, (list, tuple))
            and len(cp) == 3
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in cp)
        ):
            raise ConfigError(f"IntruderConfig.camera_position = {cp!r}; expected [x, y, z] (3 finite numbers)")


@dataclass(frozen=True, kw_only=True)
class NaiveConfig:
    """``run.toml`` ``[intruder-naive]``: the baseline reports the room centre every iteration."""

    period: float = param(2.0, "t_P, seconds per iteration", lo=1e-6, unit="s")
    cell: float = length(1.0, "size of a cell (converted to site units; for the error in cells)", lo=1e-9)
    start: float | None = param(
        None, "time the intruder enters; unset = the start of the slot holding the first edge", unit="s"
    )
    end: float | None = param(None, "time it leaves; unset = the slot of the last edge", lo="start", unit="s")
    absent_after: float = param(
        ABSENT_AFTER_S, "no estimate inside a silent stretch this long (see [intruder])", lo=0.0, hi=1e12, unit="s"
    )

    def __post_init__(self) -> None:
        validate(self)


def available(site: Site) -> str | None:
    """Skip sites without motion sensors, and sites that declare more than one target: the
    paper's filter tracks a single intruder (``--trackers intruder`` cannot override this)."""
    if not site.motion_sensors:
        return "site has no motion sensors"
    if site.targets is not None and site.targets > 1:
        return f"site.toml declares {site.targets} targets; the filter tracks a single intruder"
    return None


def observations(
    motion: pl.DataFrame, site: Site, *, period: float, start: float | None, end: float | None, held: bool = False
):
    """``(fired, blind, t_end)``: ``(T, n)`` S_i and B_i per iteration and each iteration's end time.

    ``S_i`` is a rising edge in the iteration; with ``held``, a sensor whose ``signal`` is
    ``level`` (on while someone is under it) also fires in every iteration it is on at the
    start of (``on`` of :func:`onebit.readers.motion.motion_frames`): a person standing under
    a ceiling sensor is presence evidence, not absence.

    Iterations cover ``[start, end)``; ``start = None`` is the start of the slot (a multiple
    of ``period``) holding the first edge, so the slots span the data, wherever its time
    origin is (a log of Unix seconds read with an early ``epoch`` never builds slots from 1970).
    """
    ids = [m.id for m in site.motion_sensors]
    if start is None:
        first = motion["t"].min() if motion.height else None
        start = math.floor(first / period) * period if first is not None else (0.0 if end is None else min(0.0, end))
    motion = motion.filter(pl.col("t") >= start)
    if motion.height == 0 and end is None:  # nothing observed and no end given: no iteration to run
        return np.zeros((0, len(ids)), bool), np.zeros((0, len(ids)), bool), np.zeros(0)
    frames = motion_frames(motion, ids, period=period, t0=start, t1=end)
    if frames.height == 0:
        return np.zeros((0, len(ids)), bool), np.zeros((0, len(ids)), bool), np.zeros(0)
    st = refractory_state(frames, {m.id: m.refractory for m in site.motion_sensors}, period=period)
    order = pl.DataFrame({"sensor": ids, "_k": list(range(len(ids)))}, schema={"sensor": pl.String, "_k": pl.Int64})
    st = st.join(order, on="sensor").sort(["slot", "_k"])
    T = st["slot"].n_unique()
    fired = st["fired"].to_numpy().reshape(T, len(ids))
    if held:
        level = np.array([m.signal == "level" for m in site.motion_sensors], dtype=bool)
        on = st["on"].to_numpy().reshape(T, len(ids)).astype(bool)
        fired = fired | (on & level[None, :])
    blind = st["blind"].to_numpy().reshape(T, len(ids))
    t_end = start + (np.arange(T) + 1) * period
    return fired, blind, t_end


def coverage_table(dep: Deployment) -> pl.DataFrame:
    """The deployed grids q_ij as a long table (non-zero cells only)."""
    n, ny, nx = dep.q.shape
    s, iy, ix = np.nonzero(dep.q)
    g = dep.grid
    return pl.DataFrame(
        {
            "sensor": pl.Series(np.asarray(dep.ids, dtype=object)[s].tolist() if n else [], dtype=pl.String),
            "ix": ix.astype(np.int64),
            "iy": iy.astype(np.int64),
            "x": g.x0 + (ix + 0.5) * g.cell,
            "y": g.y0 + (iy + 0.5) * g.cell,
            "p_detect": dep.q[s, iy, ix],
        }
    )


def track_frame(tracker: str, t: np.ndarray, xy: np.ndarray) -> pl.DataFrame:
    return conform(
        pl.DataFrame({"tracker": tracker, "track": tracker, "t": t, "x": xy[:, 0], "y": xy[:, 1]}).with_columns(
            pl.col("tracker").cast(pl.String)
        ),
        TRACKS,
    )


def run(inputs: dict, site: Site, config: IntruderConfig) -> dict[str, pl.DataFrame]:
    """The ``intruder`` stage: PIR edges -> the SIR filter's estimated cell per iteration."""
    motion = check_schema(inputs["motion"], MOTION, name="motion")
    c = config.cell
    dep = deploy(site, c, false_alarm=config.false_alarm)
    fired, blind, t_end = observations(
        motion, site, period=config.period, start=config.start, end=config.end, held=config.held
    )
    room = Room(site.free_space)
    turn = config.v_max if config.turn_scale is None else config.turn_scale
    mot = Motion(config.period, config.v_max * c, config.speed_sigma * c, turn * c, config.max_retries)
    res = run_filter(
        fired,
        blind,
        dep,
        room,
        mot,
        n_particles=config.particles,
        half_w=config.box_width * c / 2,
        half_d=config.box_depth * c / 2,
        rng=np.random.default_rng(config.seed),
        resample=config.resample,
        resample_when=config.resample_when,
        ess_threshold=config.ess_threshold,
        log_particles=config.log_particles,
        progress=inputs.get(PROGRESS),
    )
    # the empty room: no estimate inside a stretch where every sensor is off and nothing fires
    tracks = outside_silence(
        track_frame(NAME, t_end, res.estimates), silent_stretches([motion], min_s=config.absent_after)
    )
    iterations = pl.DataFrame(
        {
            "t": t_end,
            "ess": res.ess,
            "redraws": res.redraws,
            "clamped": res.clamped,
            "resampled": res.resampled,
            "spread": res.spread,
            "fired": fired.sum(axis=1).astype(np.int64),
            "blind": blind.sum(axis=1).astype(np.int64),
            "cell": np.full(len(t_end), c),
        }
    )
    coverage = coverage_table(dep)
    extra = {}
    if config.camera_position is not None:
        ptz = pan_tilt_zoom(
            res.estimates,
            tuple(config.camera_position),
            width=config.box_width * c,
            depth=config.box_depth * c,
            height=config.box_height * c,
            fov_deg=config.camera_fov,
            aspect=config.camera_aspect,
        )
        extra["camera"] = pl.DataFrame({"t": t_end, "pan": ptz[:, 0], "tilt": ptz[:, 1], "zoom": ptz[:, 2]})
    artifacts = {
        "deployment": dep,
        "t_end": t_end,
        "fired": fired,
        "blind": blind,
        "particles_xy": res.logged_xy,
        "particles_w": res.logged_w,
        "estimates": res.estimates,
        "box": (config.box_width * c, config.box_depth * c),
    }
    return {"tracks": tracks, "iterations": iterations, "coverage": coverage, **extra, ARTIFACTS: artifacts}


def run_naive(inputs: dict, site: Site, config: NaiveConfig) -> dict[str, pl.DataFrame]:
    """The ``intruder-naive`` stage: the intruder is always at the centre of the room."""
    motion = check_schema(inputs["motion"], MOTION, name="motion")
    _, _, t_end = observations(motion, site, period=config.period, start=config.start, end=config.end)
    centre = site.boundary.centroid
    xy = np.tile([centre.x, centre.y], (len(t_end), 1)).reshape(-1, 2)
    tracks = outside_silence(track_frame(NAIVE, t_end, xy), silent_stretches([motion], min_s=config.absent_after))
    return {"tracks": tracks, "iterations": pl.DataFrame({"t": t_end, "cell": np.full(len(t_end), config.cell)})}


SPEC = TrackerSpec(
    name=NAME,
    needs=("motion",),
    config=IntruderConfig,
    run=run,
    available=available,
    help="SIR particle filter over PIR firings with refractory periods (Schiff & Goldberg)",
)
NAIVE_SPEC = TrackerSpec(
    name=NAIVE,
    needs=("motion",),
    config=NaiveConfig,
    run=run_naive,
    available=available,
    help="baseline: the intruder is always at the centre of the room",
)
