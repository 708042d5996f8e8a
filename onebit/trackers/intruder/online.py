"""The ``intruder`` filter run online: one SIR iteration as soon as its slot is settled.

Schiff & Goldberg steer a pan-tilt-zoom camera onto the intruder while it moves: the filter is
sequential by nature, each iteration needs only the previous posterior and the firings of its
own slot. :class:`OnlineIntruder` keeps that state (particles and the random generator)
between calls; :func:`advance` steps it over the slots that became final and returns the new
rows. It never reads a file or a clock: the caller (``onebit follow``,
:mod:`onebit.pipeline.follow`) passes the accepted motion edges read so far and the
*horizon* ``h`` -- the log time up to which the log is known -- and measures delays itself.

When is iteration ``k`` (slot ``[start + k t_P, t_k)``, ``t_k = start + (k + 1) t_P``) final,
so that its row equals the batch run's (:func:`onebit.trackers.intruder.stage.run`)?

* its firings and refractory states are final: every edge before ``t_k`` is *settled*, i.e.
  ``h >= t_k + settle``, where ``settle`` covers the reader's look-ahead (rows up to 1 s out
  of order are sorted in, and the debounce rules suppress an edge when a later edge comes
  within ``chatter_window`` / ``min_on``);
* the batch run has it: with ``end = None`` the batch's iterations stop at the slot of the
  last edge, and an estimate strictly inside a silent stretch (every sensor off, no edge for
  ``absent_after`` s or more) is dropped. Both are decided once a settled edge at
  ``e >= t_k`` exists: that edge closes the gap around ``t_k``.

So iteration ``k`` runs when a settled edge at or after ``t_k`` has been seen, or when the log
has ended (``final = True``: every remaining batch iteration runs). The filter step is
:func:`onebit.trackers.intruder.filter.filter_step`, the reference loop body; with the same
seed it draws the same random numbers in the same order as the batch run, so the tracks are
equal (the compiled batch kernel gives the same estimates, tested in ``test_kernels``).
The delay of iteration ``k`` in log time is ``e - t_k + settle`` for the first edge ``e >= t_k``:
bounded by ``settle`` while someone moves (edges come every few seconds), longer while the
sensors are quiet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import polars as pl

from onebit.core.frames import outside_silence, silent_stretches
from onebit.core.site import Site
from onebit.models.motion import Motion, Particles, Room, prior
from onebit.models.pir import Deployment, deploy
from onebit.trackers.intruder.camera import pan_tilt_zoom
from onebit.trackers.intruder.filter import filter_step
from onebit.trackers.intruder.stage import NAME, IntruderConfig, observations, track_frame


@dataclass
class OnlineIntruder:
    """The online filter's state: the posterior after ``done`` iterations and the generator.

    Built by :func:`start`; advanced by :func:`advance` (which mutates it: the state is the
    filter's, passed explicitly, never global).
    """

    config: IntruderConfig
    site: Site
    dep: Deployment
    room: Room
    motion: Motion
    mask: np.ndarray
    rng: np.random.Generator
    particles: Particles | None = None
    start: float | None = None
    done: int = 0
    ended: bool = False
    stats: dict = field(default_factory=dict)


def start(site: Site, config: IntruderConfig) -> OnlineIntruder:
    """A fresh online filter for ``site`` (``config`` in the site's units, as the batch stage gets it)."""
    c = config.cell
    dep = deploy(site, c, false_alarm=config.false_alarm)  # as the batch stage deploys
    room = Room(site.free_space)
    turn = config.v_max if config.turn_scale is None else config.turn_scale
    mot = Motion(config.period, config.v_max * c, config.speed_sigma * c, turn * c, config.max_retries)
    cxs, cys = dep.grid.centres()
    mask = room.contains(cxs.ravel(), cys.ravel()).reshape(cxs.shape)
    return OnlineIntruder(config, site, dep, room, mot, mask, np.random.default_rng(config.seed))


def _empty(config: IntruderConfig) -> dict[str, pl.DataFrame]:
    out = {
        "tracks": track_frame(NAME, np.zeros(0), np.zeros((0, 2))),
        "iterations": pl.DataFrame(
            schema={
                "t": pl.Float64,
                "ess": pl.Float64,
                "redraws": pl.Int64,
                "clamped": pl.Int64,
                "resampled": pl.Boolean,
                "spread": pl.Float64,
                "fired": pl.Int64,
                "blind": pl.Int64,
                "cell": pl.Float64,
            }
        ),
    }
    if config.camera_position is not None:
        out["camera"] = pl.DataFrame(
            schema={"t": pl.Float64, "pan": pl.Float64, "tilt": pl.Float64, "zoom": pl.Float64}
        )
    return out


def _due_observations(state: OnlineIntruder, motion: pl.DataFrame, settled: pl.DataFrame, final: bool):
    """``(fired, blind, t_end, todo)``: the slots' observations and the number of iterations
    final now (every one the batch run has when the log has ended, which marks the state
    ended), or None when none is."""
    cfg = state.config
    if final:
        fired, blind, t_end = observations(
            motion, state.site, period=cfg.period, start=cfg.start, end=cfg.end, held=cfg.held
        )
        todo = len(t_end)
        state.ended = True
    else:
        if state.start is None:
            return None
        last = settled["t"].max() if settled.height else None
        if last is None:
            return None
        # iteration k runs when a settled edge lies at or after t_k = start + (k + 1) t_P
        todo = int(math.floor((last - state.start) / cfg.period + 1e-9))
        if cfg.end is not None:
            todo = min(todo, int(math.ceil((cfg.end - state.start) / cfg.period - 1e-9)))
        if todo <= state.done:
            return None
        # the slots' firings from the settled edges; every slot is closed by a later settled edge
        fired, blind, t_end = observations(
            settled,
            state.site,
            period=cfg.period,
            start=state.start,
            end=state.start + todo * cfg.period,
            held=cfg.held,
        )
        todo = min(todo, len(t_end))
    return fired, blind, t_end, todo


def _iterations(t: np.ndarray, rows: list, fired: np.ndarray, blind: np.ndarray, c: float) -> pl.DataFrame:
    """The ``iterations`` rows of the steps just run (``fired``/``blind`` their slots)."""
    return pl.DataFrame(
        {
            "t": t,
            "ess": np.array([r.ess for r in rows], dtype=np.float64),
            "redraws": np.array([r.redraws for r in rows], dtype=np.int64),
            "clamped": np.array([r.clamped for r in rows], dtype=np.int64),
            "resampled": np.array([r.resampled for r in rows], dtype=bool),
            "spread": np.array([r.spread for r in rows], dtype=np.float64),
            "fired": fired.sum(axis=1).astype(np.int64),
            "blind": blind.sum(axis=1).astype(np.int64),
            "cell": np.full(len(t), c),
        }
    )


def _camera(est: np.ndarray, t: np.ndarray, cfg) -> pl.DataFrame:
    """The PTZ ``camera`` commands that keep each estimate's box in view."""
    c = cfg.cell
    ptz = pan_tilt_zoom(
        est,
        tuple(cfg.camera_position),
        width=cfg.box_width * c,
        depth=cfg.box_depth * c,
        height=cfg.box_height * c,
        fov_deg=cfg.camera_fov,
        aspect=cfg.camera_aspect,
    )
    return pl.DataFrame({"t": t, "pan": ptz[:, 0], "tilt": ptz[:, 1], "zoom": ptz[:, 2]})


def advance(
    state: OnlineIntruder, motion: pl.DataFrame, *, horizon: float, settle: float, final: bool = False
) -> dict[str, pl.DataFrame]:
    """Run the iterations that became final; return their rows (``tracks``, ``iterations``
    and, with a camera, the PTZ ``camera`` commands), in the batch stage's schemas.

    Parameters
    ----------
    state
        From :func:`start`; mutated (posterior, generator, iterations done).
    motion
        Every accepted edge read so far (the MOTION table of the log's prefix).
    horizon
        Log time (s) up to which the log is known.
    settle
        The readers' look-ahead (s): an edge at ``e <= horizon - settle`` is final.
    final
        The log has ended: run every iteration the batch run has.
    """
    cfg = state.config
    out = _empty(cfg)
    if state.ended:
        return out
    settled = motion if final else motion.filter(pl.col("t") <= horizon - settle)
    if settled.height == 0 and cfg.start is None and not final:
        return out
    if state.start is None:
        if cfg.start is not None:
            state.start = cfg.start
        elif settled.height:
            state.start = math.floor(settled["t"].min() / cfg.period) * cfg.period
    due = _due_observations(state, motion, settled, final)
    if due is None:
        return out
    fired, blind, t_end, todo = due
    k0 = state.done
    if todo <= k0:
        return out
    if state.particles is None:
        state.particles = prior(cfg.particles, state.room, state.motion, state.rng)
    c = cfg.cell
    half_w, half_d = cfg.box_width * c / 2, cfg.box_depth * c / 2
    rows = []
    p = state.particles
    for k in range(k0, todo):  # sequential: each iteration needs the previous posterior
        p, step = filter_step(
            p,
            fired[k],
            blind[k],
            state.dep,
            state.room,
            state.motion,
            half_w=half_w,
            half_d=half_d,
            mask=state.mask,
            rng=state.rng,
            resample=cfg.resample,
            resample_when=cfg.resample_when,
            ess_threshold=cfg.ess_threshold,
        )
        rows.append(step)
    state.particles, state.done = p, todo
    t = t_end[k0:todo]
    est = np.array([r.estimate for r in rows], dtype=np.float64).reshape(-1, 2)
    tracks = outside_silence(track_frame(NAME, t, est), silent_stretches([settled], min_s=cfg.absent_after))
    out["tracks"] = tracks
    out["iterations"] = _iterations(t, rows, fired[k0:todo], blind[k0:todo], c)
    if cfg.camera_position is not None:
        out["camera"] = _camera(est, t, cfg)
    return out
