"""The SIR particle filter of Schiff & Goldberg, section VII, vectorised over particles and sensors.

State of particle ``p``: ``(x, y, theta, v)`` -- position (world units), orientation (rad)
and speed (world units / s). One iteration tau (``t_P`` seconds):

1. **Intruder model** (:func:`propagate`, section VII-B.1)::

       v'     = v + N(0, sigma_v^2)
       theta' = theta + N(0, sigma_theta^2),  sigma_theta = min(pi, c_turn / v)   (inversely
                                                                                   proportional to speed)
       x'     = x + v' t_P cos(theta'),  y' = y + v' t_P sin(theta')              (Euler)

   accepted when ``0 <= v' <= v_max`` and ``(x', y')`` is in the room (rejection sampling, von
   Neumann): only the rejected particles are redrawn from their old state, at most
   ``max_retries`` rounds; a particle still rejected then stays where it was with speed 0
   (counted as ``clamped``).

2. **Sensor model** (:func:`sensor_likelihood`, section VII-B.2), independent sensors::

       P(E | x) = prod_i P(S_i = s_i | x)
       B_i = 1:  P(S_i = 1 | x) = P(S_i = 1 | B_i = 1) = rho_i                   (refractory branch)
       B_i = 0:  P(S_i = 0 | x) = prod_{k in R_i} L(1 - p0_i, 1 - q_ik, V_k(x)),
                 L(a, b, V) = a + V (b - a)

   ``R_i`` is the sensor's detection region: the ``xi_i`` cells with ``q_ik > 0`` (section
   VI). The paper writes the product over all ``m`` cells, but derives
   ``p0_i = 1 - (1 - h)^(1 / xi_i)`` from "the ``xi`` cells where q > 0 are independent", so
   that with nobody in the region ``P(S_i = 1) = 1 - (1 - p0_i)^xi_i = h`` -- the paper's
   definition of h, ``P(S_i = 1 | O_1 = ... = O_m = 0, B_i = 0)`` (section VIII-D). A cell
   outside ``R_i`` is outside the sensor's detection region and does not influence it
   (factor 1); over all ``m`` cells the empty-room firing rate would be
   ``1 - (1 - h)^(m / xi)`` (0.41-0.54 instead of 0.25 for the imperfect PIRs).
   ``V_k(x)`` is the fraction of cell ``k`` covered by the intruder's bounding box (width x
   depth, centred on ``x``). Cells of ``R_i`` the box does not touch give ``L = 1 - p0_i``,
   so the product is ``(1 - p0_i)^xi_i * prod_{k touched, in R_i} L / (1 - p0_i)`` with only
   the ``K <= (ceil(w/c)+1) (ceil(d/c)+1)`` touched cells computed. ``q_ik`` is raised to at
   least ``p0_i`` (being in a cell never makes a firing less likely than being elsewhere).
   Probabilities are clipped to ``[1e-12, 1]`` and weights kept in log space.

3. **Estimate** (:func:`estimate_cell`, section VII-C): the cell whose centre maximises the
   (weighted) number of particles inside the bounding box centred there -- a box filter over
   the particles, computed exactly as a 2-D difference array over cell centres
   (``np.add.at`` + two cumulative sums, O(N + m)).

4. **Resampling** (:func:`systematic_resample`): systematic, every iteration (the paper's
   SIR), or only when the effective sample size ``1 / sum w^2`` falls below
   ``ess_threshold * N``.

The loop over iterations is inherently sequential (each step needs the previous posterior),
and so is the rejection sampling of step 1. :func:`run_filter` runs them as one compiled
kernel (:mod:`onebit.trackers.intruder.kernels`: propagate, likelihood, estimate and
resampling fused per particle, the same random numbers in the same order); the named numpy
steps above, run by :func:`run_filter_reference` (vectorised over particles and sensors), are
its plain reference and the test oracle. The prior is uniform in position (over the room),
orientation and speed; every sensor starts out of its refractory period.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from onebit.core.params import kernel_tuple
from onebit.models.motion import Motion, Particles, Room, prior, propagate
from onebit.models.pir import PROB_FLOOR, Deployment, WorldGrid, log_weights
from onebit.trackers.intruder import kernels

#: Particle-iterations from which :func:`run_filter` runs the compiled kernel by default.
COMPILED_MIN = 500_000

#: Particles kept for the recordings over a whole run (all iterations together): 4 M particles
#: = 96 MB of positions and weights. A 2-day log (10^5 iterations) would otherwise keep 10^8.
LOG_BUDGET = 4_000_000


def normalise(logw: np.ndarray) -> np.ndarray:
    w = np.exp(logw - logw.max())
    return w / w.sum()


def effective_sample_size(w: np.ndarray) -> float:
    return float(1.0 / np.sum(w * w))


def systematic_resample(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices of a systematic resample of normalised weights ``w`` (one uniform draw)."""
    n = len(w)
    u = (rng.random() + np.arange(n)) / n
    return np.minimum(np.searchsorted(np.cumsum(w), u), n - 1)


def multinomial_resample(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    n = len(w)
    return np.minimum(np.searchsorted(np.cumsum(w), rng.random(n)), n - 1)


def box_counts(x, y, w, grid: WorldGrid, half_w: float, half_d: float) -> np.ndarray:
    """``(ny, nx)`` weighted count of particles within the box centred on each cell centre.

    Particle ``p`` is inside the box of cell ``(i, j)`` iff ``|x_p - cx_i| <= w/2`` and
    ``|y_p - cy_j| <= d/2``, i.e. ``i`` in ``[ceil((x - w/2 - x0)/c - 1/2), floor((x + w/2 - x0)/c - 1/2)]``
    (same for ``j``): a rectangle of cells per particle, added with a 2-D difference array.
    """
    c = grid.cell
    ilo = np.clip(np.ceil((x - half_w - grid.x0) / c - 0.5 - 1e-12), 0, grid.nx).astype(np.int64)
    ihi = np.clip(np.floor((x + half_w - grid.x0) / c - 0.5 + 1e-12), -1, grid.nx - 1).astype(np.int64)
    jlo = np.clip(np.ceil((y - half_d - grid.y0) / c - 0.5 - 1e-12), 0, grid.ny).astype(np.int64)
    jhi = np.clip(np.floor((y + half_d - grid.y0) / c - 0.5 + 1e-12), -1, grid.ny - 1).astype(np.int64)
    ok = (ilo <= ihi) & (jlo <= jhi)
    ilo, ihi, jlo, jhi, w = ilo[ok], ihi[ok], jlo[ok], jhi[ok], w[ok]
    d = np.zeros((grid.ny + 1, grid.nx + 1))
    np.add.at(d, (jlo, ilo), w)
    np.add.at(d, (jlo, ihi + 1), -w)
    np.add.at(d, (jhi + 1, ilo), -w)
    np.add.at(d, (jhi + 1, ihi + 1), w)
    return d.cumsum(axis=0).cumsum(axis=1)[: grid.ny, : grid.nx]


def estimate_cell(x, y, w, grid: WorldGrid, half_w: float, half_d: float, mask: np.ndarray | None = None):
    """Centre ``(x, y)`` of the cell maximising :func:`box_counts` (first cell on ties)."""
    counts = box_counts(x, y, w, grid, half_w, half_d)
    if mask is not None:
        counts = np.where(mask, counts, -np.inf)
    j, i = np.unravel_index(int(np.argmax(counts)), counts.shape)
    return grid.x0 + (i + 0.5) * grid.cell, grid.y0 + (j + 0.5) * grid.cell


@dataclass
class FilterResult:
    estimates: np.ndarray  # (T, 2)
    ess: np.ndarray  # (T,) effective sample size after weighting
    redraws: np.ndarray  # (T,) rejected proposals
    clamped: np.ndarray  # (T,) particles left in place after max_retries
    resampled: np.ndarray  # (T,) bool
    logged_xy: np.ndarray  # (T, L, 2) particles after weighting (L evenly strided ones)
    logged_w: np.ndarray  # (T, L) their normalised weights
    spread: np.ndarray  # (T,) weighted RMS distance of particles from their mean


#: Slices of the iterations a box-room run is cut into when progress is reported.
PROGRESS_CHUNKS = 100


def run_filter(
    fired: np.ndarray,
    blind: np.ndarray,
    dep: Deployment,
    room: Room,
    motion: Motion,
    *,
    n_particles: int,
    half_w: float,
    half_d: float,
    rng: np.random.Generator,
    resample: str = "systematic",
    resample_when: str = "always",
    ess_threshold: float = 0.5,
    log_particles: int = 0,
    progress: Callable[[int, int], None] | None = None,
    compiled: bool | None = None,
) -> FilterResult:
    """Run the SIR filter over ``T`` iterations: ``fired``, ``blind`` are ``(T, n)`` booleans.

    Sequential over iterations by nature: one compiled kernel per run in a box room (every
    step fused per particle, :mod:`onebit.trackers.intruder.kernels`); in any other room
    the propagation's rejection test needs shapely, so :func:`~onebit.models.motion.propagate`
    runs in numpy and the kernel does the rest of each iteration. Same result as
    :func:`run_filter_reference` for the same ``rng`` (the test oracle). Memory is the particles
    and the recordings' sample, ``log_particles`` per iteration within :data:`LOG_BUDGET` for the
    whole run (:func:`logged_per_iteration`), so it does not grow with the log beyond ``O(T)``.

    ``compiled=None`` runs the kernel from :data:`COMPILED_MIN` particle-iterations on and
    :func:`run_filter_reference` below (a short run costs less in numpy than numba's start in
    a fresh process, ~0.3-1 s once); the result is the same either way.

    ``progress(done, total)``, when given, is called with the iterations done so far (in a
    box room the kernel then runs in :data:`PROGRESS_CHUNKS` consecutive slices of the
    iterations: the state lives in the particle arrays and ``rng``, and the weights after a
    resampling are exactly ``1/N``, so the result is the same).
    """
    T = fired.shape[0]
    if not (T * n_particles >= COMPILED_MIN if compiled is None else compiled):
        return run_filter_reference(
            fired,
            blind,
            dep,
            room,
            motion,
            n_particles=n_particles,
            half_w=half_w,
            half_d=half_d,
            rng=rng,
            resample=resample,
            resample_when=resample_when,
            ess_threshold=ess_threshold,
            log_particles=log_particles,
            progress=progress,
        )
    p = prior(n_particles, room, motion, rng)
    L = logged_per_iteration(log_particles, n_particles, T)
    res = empty_result(T, L)
    if T == 0:
        return res
    pick = np.linspace(0, n_particles - 1, L).round().astype(np.int64) if L else np.zeros(0, np.int64)
    model = kernel_model(dep, room, half_w, half_d)
    rs = kernels.Resampling(resample == "systematic", resample_when == "always", float(ess_threshold), pick)
    parts = tuple(np.ascontiguousarray(c, dtype=np.float64) for c in (p.x, p.y, p.theta, p.v, p.w))
    fired = np.ascontiguousarray(fired, dtype=np.bool_)
    blind = np.ascontiguousarray(blind, dtype=np.bool_)
    run = _run_box_room if room.is_box else _run_any_room
    run(parts, fired, blind, room, motion, rng, model, rs, res, progress)
    return res


def empty_result(T: int, L: int) -> FilterResult:
    """A :class:`FilterResult` of ``T`` iterations of zeros, ``L`` particles logged per iteration."""
    return FilterResult(
        np.zeros((T, 2)),
        np.zeros(T),
        np.zeros(T, np.int64),
        np.zeros(T, np.int64),
        np.zeros(T, bool),
        np.zeros((T, L, 2)),
        np.zeros((T, L)),
        np.zeros(T),
    )


def kernel_model(dep: Deployment, room: Room, half_w: float, half_d: float) -> kernels.Model:
    """The compiled kernel's sensor model: the cells' lists of sensors, ``p0``, ``xi``, the box
    and the mask of the cells whose centre is in the room."""
    cxs, cys = dep.grid.centres()
    mask = np.ascontiguousarray(room.contains(cxs.ravel(), cys.ravel()).reshape(cxs.shape))
    g = dep.grid
    grid = np.array([g.x0, g.y0, g.cell, g.nx, g.ny], dtype=np.float64)
    ptr, sensor, q = kernels.cell_lists(dep.q)
    p0 = np.asarray(dep.p0, dtype=np.float64)
    # 1 - p0 as the reference divides by it: exp(log1p(-p0)) (math.exp, as log_p_silent)
    a = np.array([math.exp(v) for v in np.log1p(-np.minimum(p0, 1 - PROB_FLOOR))], dtype=np.float64)
    xi = np.asarray(dep.xi, dtype=np.float64)
    return kernels.Model(grid, ptr, sensor, q, p0, xi, a, float(half_w), float(half_d), mask)


def _outputs(res: FilterResult) -> kernels.Outputs:
    return kernels.Outputs(res.estimates, res.ess, res.resampled, res.logged_xy, res.logged_w, res.spread)


def _run_box_room(parts, fired, blind, room, motion, rng, model, rs, res, progress) -> None:
    """Every iteration in one compiled kernel (box room), in :data:`PROGRESS_CHUNKS` slices when
    ``progress`` is given; fills ``res``."""
    T = fired.shape[0]
    x, y, theta, v, w = parts
    outs = _outputs(res)
    mot = kernel_tuple(kernels.MotionParams, **{n: getattr(motion, n) for n in kernels.MotionParams._fields})
    step = T if progress is None else max(1, -(-T // PROGRESS_CHUNKS))
    for k0 in range(0, T, step):
        k1 = min(k0 + step, T)
        kernels._run_box(
            x, y, theta, v, w, rng, fired[k0:k1], blind[k0:k1], mot, np.asarray(room.bounds, dtype=np.float64),
            model, rs, kernels.Outputs(*(o[k0:k1] for o in outs)), res.redraws[k0:k1], res.clamped[k0:k1],
        )  # fmt: skip
        if progress is not None:
            progress(k1, T)


def _run_any_room(parts, fired, blind, room, motion, rng, model, rs, res, progress) -> None:
    """Any room: the propagation in numpy (its rejection test needs shapely), the rest of each
    iteration compiled; fills ``res``."""
    x, y, theta, v, w = parts
    outs = _outputs(res)
    uniform = False
    for k in range(fired.shape[0]):  # sequential: each iteration needs the previous posterior
        p, res.redraws[k], res.clamped[k] = propagate(Particles(x, y, theta, v, w), room, motion, rng)
        x, y, theta, v, w = (np.ascontiguousarray(c, dtype=np.float64) for c in (p.x, p.y, p.theta, p.v, p.w))
        uniform = kernels._update_one(k, x, y, theta, v, w, uniform, rng, fired[k], blind[k], model, rs, outs)
        if progress is not None:
            progress(k + 1, fired.shape[0])


def logged_per_iteration(log_particles: int, n_particles: int, iterations: int) -> int:
    """Particles kept per iteration for the recordings: ``log_particles`` (at most the
    particles), fewer on long runs so that all iterations together keep at most
    :data:`LOG_BUDGET` (memory bounded whatever the log's length; at least one per iteration)."""
    L = min(log_particles, n_particles)
    if L and iterations * L > LOG_BUDGET:
        L = max(1, LOG_BUDGET // iterations)
    return L


def run_filter_reference(
    fired: np.ndarray,
    blind: np.ndarray,
    dep: Deployment,
    room: Room,
    motion: Motion,
    *,
    n_particles: int,
    half_w: float,
    half_d: float,
    rng: np.random.Generator,
    resample: str = "systematic",
    resample_when: str = "always",
    ess_threshold: float = 0.5,
    log_particles: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> FilterResult:
    """The SIR filter step by step with the named numpy functions of this module: the plain
    reference (and test oracle) of :func:`run_filter`, same arguments and same result.

    Sequential over iterations by nature; vectorised over particles and sensors within one.
    """
    T = fired.shape[0]
    cxs, cys = dep.grid.centres()
    mask = room.contains(cxs.ravel(), cys.ravel()).reshape(cxs.shape)
    p = prior(n_particles, room, motion, rng)
    L = logged_per_iteration(log_particles, n_particles, T)
    res = empty_result(T, L)
    pick = np.linspace(0, n_particles - 1, L).round().astype(np.int64) if L else np.zeros(0, np.int64)
    for k in range(T):
        p, step = filter_step(
            p,
            fired[k],
            blind[k],
            dep,
            room,
            motion,
            half_w=half_w,
            half_d=half_d,
            mask=mask,
            rng=rng,
            resample=resample,
            resample_when=resample_when,
            ess_threshold=ess_threshold,
            pick=pick,
        )
        res.estimates[k], res.ess[k], res.redraws[k], res.clamped[k] = (
            step.estimate,
            step.ess,
            step.redraws,
            step.clamped,
        )
        res.spread[k], res.resampled[k] = step.spread, step.resampled
        if L:
            res.logged_xy[k], res.logged_w[k] = step.logged_xy, step.logged_w
        if progress is not None:
            progress(k + 1, T)
    return res


@dataclass
class Step:
    """What one iteration of :func:`filter_step` reports (a row of :class:`FilterResult`)."""

    estimate: tuple[float, float]
    ess: float
    redraws: int
    clamped: int
    resampled: bool
    spread: float
    logged_xy: np.ndarray
    logged_w: np.ndarray


def filter_step(
    p: Particles,
    fired_k: np.ndarray,
    blind_k: np.ndarray,
    dep: Deployment,
    room: Room,
    motion: Motion,
    *,
    half_w: float,
    half_d: float,
    mask: np.ndarray,
    rng: np.random.Generator,
    resample: str = "systematic",
    resample_when: str = "always",
    ess_threshold: float = 0.5,
    pick: np.ndarray | None = None,
) -> tuple[Particles, Step]:
    """One SIR iteration (steps 1-4 of the module docstring) on the posterior ``p`` of the
    previous one: the loop body of :func:`run_filter_reference`, and the online tracker's step
    (:mod:`onebit.trackers.intruder.online`). Returns the new posterior and the iteration's row."""
    n_particles = len(p.x)
    p, redraws, clamped = propagate(p, room, motion, rng)
    lw = np.log(np.maximum(p.w, 1e-300)) + log_weights(p.x, p.y, fired_k, blind_k, dep, half_w, half_d)
    p.w = normalise(lw)
    ess = effective_sample_size(p.w)
    estimate = estimate_cell(p.x, p.y, p.w, dep.grid, half_w, half_d, mask)
    mx, my = float(np.dot(p.w, p.x)), float(np.dot(p.w, p.y))
    spread = math.sqrt(float(np.dot(p.w, (p.x - mx) ** 2 + (p.y - my) ** 2)))
    pick = np.zeros(0, np.int64) if pick is None else pick
    logged_xy, logged_w = np.c_[p.x[pick], p.y[pick]], p.w[pick]
    resampled = resample_when == "always" or ess < ess_threshold * n_particles
    if resampled:
        draw = systematic_resample if resample == "systematic" else multinomial_resample
        idx = draw(p.w, rng)
        p = Particles(p.x[idx], p.y[idx], p.theta[idx], p.v[idx], np.full(n_particles, 1.0 / n_particles))
    return p, Step(estimate, ess, redraws, clamped, resampled, spread, logged_xy, logged_w)
