"""The peer a user would try first on a binary sensor array: Stone Soup with point detections.

An optional extra: ``pip install 'onebit[bench]'`` installs Stone Soup; without it
:func:`missing` says so and ``onebit experiment ceiling`` skips these rows (the rest runs).

Every sensor that is on in a frame is one point detection at the sensor's position; Stone
Soup tracks them with a Kalman filter on a nearly-constant-velocity model and global
nearest-neighbour (GNN, 2-D assignment) or JPDA association (exact JPDA marginals by
Efficient Hypothesis Management, ``JPDAwithEHM``: the plain ``JPDA`` enumerates every joint
hypothesis and took 499 s on r1-easy for the same tracks). The tracks are scored by the same
onebit scorer as every onebit tracker (:func:`onebit.scoring.mot.metric_gate_rows`).

Model (state ``[x, vx, y, vy]``, site units, ``dt`` = frame gap)::

    x_k = F x_{k-1} + w,  F = blockdiag([[1, dt], [0, 1]] x 2),  w ~ N(0, Q(q))   (ConstantVelocity, q per axis)
    z_k = H x_k + v,      H picks (x, y),                        v ~ N(0, r^2 I)
    r = footprint radius / 2 (a firing sensor says: someone within its footprint)

Association: Mahalanobis distance, gate ``missed_distance`` (GNN) or a PDA hypothesiser with
``prob_detect`` and a clutter density of ``clutter_per_frame`` / room area (JPDA). A track is
born from ``min_points`` detections in a row (MultiMeasurementInitiator) and deleted after
``delete_after`` frames without an update. Not tuned on any recording: the defaults are the
footprint and a walking speed.

``python -m onebit.experiments.peers DATASET [--jpda]`` prints its scores on an
imported dataset (``onebit import irtracking``).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import importlib
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.site import Site, load_site
from onebit.core.tables import FRAMES, TRACKS, conform
from onebit.core.units import to_site_units
from onebit.readers.frames import read_frames_csv
from onebit.readers.tables_csv import read_truth_csv
from onebit.scoring.mot import metric_gate_rows

EPOCH = _dt.datetime(2000, 1, 1)
#: What a user installs to get this peer.
EXTRA = "pip install 'onebit[bench]'"


def missing() -> str | None:
    """Why the peer cannot run here (Stone Soup not installed), or None when it can."""
    try:
        importlib.import_module("stonesoup")
    except ImportError:
        return f"Stone Soup is not installed: the Stone Soup rows need the bench extra ({EXTRA})"
    return None


@dataclass(frozen=True, kw_only=True)
class StoneSoupConfig:
    """Parameters of the baseline (lengths in metres; converted to the site's units).

    q : process noise of the constant-velocity model, m^2/s^3 per axis.
    meas_sd : standard deviation of a detection about the person, m (0 = half the footprint).
    missed_distance : Mahalanobis gate of GNN.
    prob_detect : JPDA's probability of detection.
    clutter_per_frame : JPDA's expected false detections per frame.
    min_points : detections a tentative track needs before it is confirmed.
    delete_after : frames without an update before a track is deleted.
    """

    q: float = 0.5
    meas_sd: float = 0.0
    missed_distance: float = 3.0
    prob_detect: float = 0.8
    clutter_per_frame: float = 0.5
    min_points: int = 2
    delete_after: int = 3

    def __post_init__(self) -> None:
        for name in ("q", "missed_distance", "clutter_per_frame"):
            if not getattr(self, name) > 0:
                raise ValueError(f"StoneSoupConfig.{name} = {getattr(self, name)!r}; must be > 0")
        if not self.meas_sd >= 0:
            raise ValueError(f"StoneSoupConfig.meas_sd = {self.meas_sd!r}; must be >= 0")
        if not 0 < self.prob_detect < 1:
            raise ValueError(f"StoneSoupConfig.prob_detect = {self.prob_detect!r}; must be in (0, 1)")
        for name in ("min_points", "delete_after"):
            if not (isinstance(getattr(self, name), int) and getattr(self, name) >= 1):
                raise ValueError(f"StoneSoupConfig.{name} = {getattr(self, name)!r}; must be an integer >= 1")


def detections_of(levels: pl.DataFrame, site: Site) -> list[tuple[float, np.ndarray]]:
    """Per frame (time order), the positions ``(n, 2)`` of the sensors that are on."""
    pos = {r.sensor: r.position for r in site.detection_regions.values()}
    on = levels.filter("on").select("t", "sensor")
    xy = np.array([pos[s] for s in on["sensor"].to_list()], dtype=float).reshape(-1, 2)
    times = levels["t"].unique().sort().to_numpy()
    t_on = on["t"].to_numpy()
    out = []
    for t in times:  # the trackers' interface is frame by frame
        out.append((float(t), xy[t_on == t]))
    return out


def _footprint(site: Site) -> float:
    r = [reg.radius for reg in site.detection_regions.values() if reg.radius]
    return float(np.median(r)) if r else float(to_site_units(1.0, "m", site.units))


def track(
    levels: pl.DataFrame,
    site: Site,
    config: StoneSoupConfig = StoneSoupConfig(),
    *,
    jpda: bool = False,
    name: str = "stonesoup",
) -> pl.DataFrame:
    """Stone Soup GNN (or JPDA) Kalman tracks of the firing sensors (module docstring): TRACKS
    rows of every state of every confirmed track (updates and the predictions between them)."""
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.dataassociator.probability import JPDAwithEHM
    from stonesoup.deleter.time import UpdateTimeStepsDeleter
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.initiator.simple import MultiMeasurementInitiator
    from stonesoup.measures import Mahalanobis
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker
    from stonesoup.types.detection import Detection
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import KalmanUpdater

    levels = conform(levels, FRAMES)
    u = float(to_site_units(1.0, "m", site.units))  # site units per metre
    q = config.q * u * u
    sd = config.meas_sd * u if config.meas_sd > 0 else _footprint(site) / 2
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])
    measurement = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2) * sd * sd)
    predictor = KalmanPredictor(transition)
    updater = KalmanUpdater(measurement)
    minx, miny, maxx, maxy = site.boundary.bounds
    prior = GaussianState(
        [[(minx + maxx) / 2], [0.0], [(miny + maxy) / 2], [0.0]],
        np.diag([(maxx - minx) ** 2, (1.5 * u) ** 2, (maxy - miny) ** 2, (1.5 * u) ** 2]),
    )
    deleter = UpdateTimeStepsDeleter(time_steps_since_update=config.delete_after)
    init_hyp = DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=config.missed_distance)
    initiator = MultiMeasurementInitiator(
        prior_state=prior,
        measurement_model=measurement,
        deleter=deleter,
        data_associator=GNNWith2DAssignment(init_hyp),
        updater=updater,
        min_points=config.min_points,
    )
    frames = detections_of(levels, site)
    scans = [
        (
            EPOCH + _dt.timedelta(seconds=t),
            {
                Detection(
                    np.array([[x], [y]]), timestamp=EPOCH + _dt.timedelta(seconds=t), measurement_model=measurement
                )
                for x, y in xy
            },
        )
        for t, xy in frames
    ]
    if jpda:
        density = config.clutter_per_frame / max(site.free_space.area, 1e-9)
        hyp = PDAHypothesiser(predictor, updater, clutter_spatial_density=density, prob_detect=config.prob_detect)
        tracker = MultiTargetMixtureTracker(
            initiator=initiator, deleter=deleter, detector=scans, data_associator=JPDAwithEHM(hyp), updater=updater
        )
    else:
        hyp = DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=config.missed_distance)
        tracker = MultiTargetTracker(
            initiator=initiator,
            deleter=deleter,
            detector=scans,
            data_associator=GNNWith2DAssignment(hyp),
            updater=updater,
        )
    every: set = set()
    for _, tracks in tracker:  # Stone Soup's trackers iterate over the scans
        every |= tracks
    rows = []
    for k, tr in enumerate(sorted(every, key=lambda tr: (tr.states[0].timestamp, tr.id))):
        for st in tr.states:
            rows.append(
                (
                    name,
                    f"{name}-{k}",
                    (st.timestamp - EPOCH).total_seconds(),
                    float(st.state_vector[0, 0]),
                    float(st.state_vector[2, 0]),
                )
            )
    df = pl.DataFrame(
        rows,
        schema={"tracker": pl.String, "track": pl.String, "t": pl.Float64, "x": pl.Float64, "y": pl.Float64},
        orient="row",
    )
    return conform(df.unique(["track", "t"], keep="last", maintain_order=True).sort("t", "track"), TRACKS)


def main(argv: list[str] | None = None) -> int:

    ap = argparse.ArgumentParser(prog="python -m onebit.experiments.peers", description=__doc__.splitlines()[0])
    ap.add_argument("dataset", help="a dataset folder with frames.csv and truth.csv (onebit import irtracking)")
    ap.add_argument("--jpda", action="store_true")
    args = ap.parse_args(argv)
    why = missing()
    if why is not None:
        print(why, file=sys.stderr)
        return 2
    ds = Path(args.dataset)
    site = load_site(ds / "site.toml")
    ids = list(dict.fromkeys([m.id for m in site.motion_sensors] + [p.id for p in site.proximity_sensors]))
    levels = read_frames_csv(ds / "frames.csv", ids).levels
    truth, _ = read_truth_csv(ds / "truth.csv")
    name = "stonesoup-jpda" if args.jpda else "stonesoup-gnn"
    tracks = track(levels, site, jpda=args.jpda, name=name)
    for _, metric, value, unit in metric_gate_rows(name, tracks, truth, site, (1.0, 1.5)):
        print(f"{name:16s} {metric:24s} {value:10.4g} {unit}")
    return 0
