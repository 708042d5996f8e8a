"""Intruder particle filter: step time vs particles and sensors, memory per particle, and the
same model run through Stone Soup's ``ParticlePredictor`` / ``ParticleUpdater`` as the peer.

Input: one simulated ``pir14`` trajectory (4 s refractory) and ``beams22`` for the sensor
count sweep, slotted with the tracker's own code into ``fired`` / ``blind`` arrays.

* **ours**: :func:`onebit.trackers.intruder.filter.run_filter` (propagate with vectorised
  rejection sampling, likelihood over (sensors x particles x touched cells), box-filter
  estimate, systematic resampling), timed per iteration.
* **peer**: Stone Soup 1.x with a custom ``TransitionModel`` (the same speed / orientation
  noise and room rejection, written over Stone Soup's ``StateVectors``), a custom
  ``MeasurementModel`` whose ``logpdf`` is the paper's sensor model with the refractory
  branch (per sensor, vectorised over particles, as a Stone Soup user would write it), the
  ``SystematicResampler``, and the same box-filter estimate. Both filters get the same
  observations; the benchmark checks they reach similar accuracy (same model), then prints
  the time ratio.

Times are CPU seconds of this process (``time.process_time``; the filter is single-threaded
numpy), so the numbers do not depend on what else the machine runs.

Memory per particle: growth of the peak traced allocation (``tracemalloc``; the filter is
pure numpy, which reports to it) over one step, divided by the particle count.

Run with ``python -m benchmarks.bench_intruder``.
"""

from __future__ import annotations

import datetime
import math
import time
import tracemalloc

import numpy as np
import polars as pl

from onebit.core.site import site_from_dict
from onebit.datasets.pir_sim import simulate
from onebit.experiments.schiff import toggles_as_rows
from onebit.models.motion import Motion, Room
from onebit.models.pir import deploy, log_weights
from onebit.readers.motion import MotionConfig, read_motion, site_rules
from onebit.trackers.intruder.filter import estimate_cell, run_filter
from onebit.trackers.intruder.stage import observations

MOTION = Motion(period=2.0, v_max=4.0, speed_sigma=1.5, turn_scale=4.0, max_retries=50)
HALF = 1.0


def scenario(name: str, refractory: float, duration: float = 60.0, seed: int = 0):
    d, sim = simulate(name, seed=seed, duration=duration, refractory=refractory)
    site = site_from_dict(d)
    read = read_motion(
        toggles_as_rows(sim.toggles), [m.id for m in site.motion_sensors], rules=site_rules(site, MotionConfig())
    )
    fired, blind, t_end = observations(read.motion, site, period=2.0, start=0.0, end=duration)
    return site, deploy(site, 1.0), fired, blind, t_end, sim.truth


def ours(site, dep, fired, blind, n, seed=0):
    room = Room(site.free_space)
    t0 = time.process_time()
    res = run_filter(
        fired,
        blind,
        dep,
        room,
        MOTION,
        n_particles=n,
        half_w=HALF,
        half_d=HALF,
        rng=np.random.default_rng(seed),
        compiled=True,
    )
    return (time.process_time() - t0) / len(fired), res.estimates


def ours_step(site, dep, fired, blind, n, seed=0):
    """CPU seconds of one SIR step, as the peer is timed: without the prior and the run's set-up.

    ``run_filter`` draws the prior and allocates its arrays before the first step (at 10^6
    particles ~0.2 s, as much as a step), which :func:`ours` divides over the steps timed. Same
    seed, so the one-step run is the start of the ``k``-step run: their difference is steps
    2..k alone."""
    k = len(fired)
    if k < 2:
        raise ValueError(f"ours_step needs at least 2 iterations, got {k}")
    t1, _ = ours(site, dep, fired[:1], blind[:1], n, seed)
    tk, est = ours(site, dep, fired, blind, n, seed)
    return (tk * k - t1) / (k - 1), est


# --------------------------------------------------------------------------- the Stone Soup peer


def stonesoup_filter(site, dep, fired, blind, n, seed=0):
    from stonesoup.base import Property
    from stonesoup.models.measurement.base import MeasurementModel
    from stonesoup.models.transition.base import TransitionModel
    from stonesoup.predictor.particle import ParticlePredictor
    from stonesoup.resampler.particle import SystematicResampler
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.state import ParticleState, StateVectors
    from stonesoup.updater.particle import ParticleUpdater

    room = Room(site.free_space)
    rng = np.random.default_rng(seed)
    np.random.seed(seed)

    class PaperTransition(TransitionModel):
        """Schiff & Goldberg's intruder model with room rejection, over StateVectors (x, y, theta, v)."""

        period: float = Property(default=2.0)

        @property
        def ndim_state(self):
            return 4

        def function(self, state, noise=False, **kwargs):
            sv = np.asarray(state.state_vector, dtype=float)
            x, y, th, v = sv
            out = sv.copy()
            out[3] = 0.0
            todo = np.arange(sv.shape[1])
            for _ in range(MOTION.max_retries):
                if len(todo) == 0:
                    break
                nv = v[todo] + rng.normal(0.0, MOTION.speed_sigma, len(todo))
                sig = np.minimum(math.pi, MOTION.turn_scale / np.maximum(v[todo], 1e-9))
                nth = th[todo] + rng.normal(0.0, 1.0, len(todo)) * sig
                px = x[todo] + nv * self.period * np.cos(nth)
                py = y[todo] + nv * self.period * np.sin(nth)
                ok = (nv >= 0) & (nv <= MOTION.v_max) & room.contains(px, py)
                acc = todo[ok]
                out[0, acc], out[1, acc], out[2, acc], out[3, acc] = px[ok], py[ok], nth[ok], nv[ok]
                todo = todo[~ok]
            return StateVectors(out)

        def rvs(self, num_samples=1, **kwargs):
            raise NotImplementedError("noise is drawn inside function()")

        def pdf(self, state1, state2, **kwargs):
            raise NotImplementedError("not needed by the bootstrap particle filter")

    class PaperSensors(MeasurementModel):
        """The sensor model of section VII-B.2 with the refractory branch (per sensor)."""

        @property
        def ndim_meas(self):
            return len(dep.ids)

        def function(self, state, noise=False, **kwargs):
            raise NotImplementedError

        def rvs(self, num_samples=1, **kwargs):
            raise NotImplementedError

        def pdf(self, measurement, state, **kwargs):
            return np.exp(self.logpdf(measurement, state, **kwargs))

        def logpdf(self, measurement, state, **kwargs):
            sv = np.asarray(state.state_vector, dtype=float)
            f = np.asarray(measurement.state_vector, dtype=bool).ravel()
            b = measurement.metadata["blind"]
            return log_weights(sv[0], sv[1], f, b, dep, HALF, HALF)

    predictor = ParticlePredictor(PaperTransition(period=MOTION.period))
    updater = ParticleUpdater(PaperSensors(ndim_state=4, mapping=(0, 1)), resampler=SystematicResampler())
    x, y = room.uniform(n, rng)
    t0 = datetime.datetime(2000, 1, 1)
    state = ParticleState(
        StateVectors(np.vstack([x, y, rng.uniform(0, 2 * math.pi, n), rng.uniform(0, MOTION.v_max, n)])),
        log_weight=np.full(n, -math.log(n)),
        timestamp=t0,
    )
    est = np.zeros((len(fired), 2))
    started = time.process_time()
    for k in range(len(fired)):
        ts = t0 + datetime.timedelta(seconds=2.0 * (k + 1))
        pred = predictor.predict(state, timestamp=ts)
        det = Detection(StateVectors(fired[k].astype(float)[:, None]), timestamp=ts, metadata={"blind": blind[k]})
        state = updater.update(SingleHypothesis(pred, det))
        sv = np.asarray(state.state_vector, dtype=float)
        est[k] = estimate_cell(sv[0], sv[1], np.exp(np.asarray(state.log_weight, float)), dep.grid, HALF, HALF)
    return (time.process_time() - started) / len(fired), est


# --------------------------------------------------------------------------- main


def mean_error(est, truth, t_end):
    tr = truth.filter(pl.col("t").is_in(t_end.tolist())).sort("t")
    return float(np.hypot(est[:, 0] - tr["x"].to_numpy(), est[:, 1] - tr["y"].to_numpy()).mean())


def memory_per_particle(site, dep, fired, blind, n):
    tracemalloc.start()
    run_filter(
        fired[:2],
        blind[:2],
        dep,
        Room(site.free_space),
        MOTION,
        n_particles=n,
        half_w=HALF,
        half_d=HALF,
        rng=np.random.default_rng(0),
        compiled=True,
    )
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / n


def main() -> None:
    site, dep, fired, blind, t_end, truth = scenario("pir14", 4.0, duration=60.0)
    print(f"pir14, 4 s refractory, {len(t_end)} iterations of 2 s, {len(dep.ids)} sensors")
    print(
        f"{'particles':>10} {'ours ms/step':>13} {'stonesoup ms/step':>18} {'ratio':>7} {'ours err':>9} {'peer err':>9}"
    )
    for n in (1_000, 10_000, 100_000):
        reps = fired if n < 100_000 else fired[:5]
        to, eo = ours(site, dep, reps, blind[: len(reps)], n)
        tp, ep = stonesoup_filter(site, dep, reps, blind[: len(reps)], n)
        e_o = mean_error(eo, truth, t_end[: len(reps)])
        e_p = mean_error(ep, truth, t_end[: len(reps)])
        print(f"{n:>10} {to * 1e3:>13.2f} {tp * 1e3:>18.2f} {tp / to:>6.1f}x {e_o:>9.2f} {e_p:>9.2f}", flush=True)
        if n == 1_000:
            assert abs(e_o - e_p) < 1.5, "ours and the Stone Soup peer disagree on the same model"
    print("\nours alone, step time vs particles (pir14):")
    base = None
    for n in (1_000, 10_000, 100_000, 1_000_000):
        k = 20 if n < 100_000 else 3
        to, _ = ours(site, dep, fired[:k], blind[:k], n)
        base = base or to / n
        print(
            f"  {n:>9} particles: {to * 1e3:9.2f} ms/step  ({to / n * 1e9:7.1f} ns/particle, x{to / n / base:4.2f} of 10^3's per-particle cost)",
            flush=True,
        )
    print("\nstep time vs sensors (10^4 particles):")
    for name in ("pir4", "pir8", "pir14", "beams22"):
        s2, d2, f2, b2, _, _ = scenario(name, 4.0, duration=20.0)
        to, _ = ours(s2, d2, f2, b2, 10_000)
        print(f"  {name:8s} {len(d2.ids):3d} sensors: {to * 1e3:8.2f} ms/step")
    for n in (10_000, 100_000):
        print(
            f"memory: {memory_per_particle(site, dep, fired, blind, n):.0f} bytes per particle at {n} particles (peak traced, one step)"
        )


if __name__ == "__main__":
    main()
