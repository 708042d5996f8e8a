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

The loop over iterations is inherently sequential (each step needs the previous posterior);
everything inside an iteration is numpy over particles and sensors. The prior is uniform in
position (over the room), orientation and speed; every sensor starts out of its refractory
period.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from onebit.trackers.intruder.sensors import Deployment, WorldGrid

PROB_FLOOR = 1e-12
#: Particles per chunk of the likelihood (bounds the (n, chunk, K) temporaries).
CHUNK = 1 << 15


@dataclass
class Particles:
    """Arrays of shape (N,): position, orientation, speed; and normalised weights."""

    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    v: np.ndarray
    w: np.ndarray

    def __len__(self) -> int:
        return len(self.x)


@dataclass(frozen=True)
class Motion:
    """Intruder-model parameters in world units."""

    period: float
    v_max: float
    speed_sigma: float
    turn_scale: float
    max_retries: int


class Room:
    """Membership test of the room (the site's free space), vectorised over points."""

    def __init__(self, polygon) -> None:
        self.polygon = polygon
        shapely.prepare(polygon)
        self.bounds = polygon.bounds
        self.is_box = bool(polygon.equals(shapely.box(*self.bounds)))

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        if self.is_box:
            x0, y0, x1, y1 = self.bounds
            return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
        return shapely.intersects_xy(self.polygon, x, y)

    def uniform(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """``n`` points uniform in the room (rejection from the bounding box, vectorised)."""
        x0, y0, x1, y1 = self.bounds
        xs = np.empty(n)
        ys = np.empty(n)
        todo = np.arange(n)
        for _ in range(1000):
            if len(todo) == 0:
                break
            px = rng.uniform(x0, x1, len(todo))
            py = rng.uniform(y0, y1, len(todo))
            ok = self.contains(px, py)
            xs[todo[ok]], ys[todo[ok]] = px[ok], py[ok]
            todo = todo[~ok]
        if len(todo):
            raise ValueError("room too thin to sample a uniform prior")
        return xs, ys


def prior(n: int, room: Room, motion: Motion, rng: np.random.Generator) -> Particles:
    """P(X_0): uniform position in the room, orientation in [0, 2 pi), speed in [0, v_max]."""
    x, y = room.uniform(n, rng)
    theta = rng.uniform(0.0, 2 * math.pi, n)
    v = rng.uniform(0.0, motion.v_max, n)
    return Particles(x, y, theta, v, np.full(n, 1.0 / n))


def propagate(p: Particles, room: Room, motion: Motion, rng: np.random.Generator) -> tuple[Particles, int, int]:
    """One step of the intruder model with rejection sampling against the room.

    Returns ``(particles, redraws, clamped)``: redraws = proposals rejected in total,
    clamped = particles that stayed put after ``max_retries`` rounds.
    """
    n = len(p)
    nx, ny, nth, nv = p.x.copy(), p.y.copy(), p.theta.copy(), np.zeros(n)
    todo = np.arange(n)
    redraws = 0
    for _ in range(motion.max_retries):
        if len(todo) == 0:
            break
        v = p.v[todo] + rng.normal(0.0, motion.speed_sigma, len(todo))
        sig = np.minimum(math.pi, motion.turn_scale / np.maximum(p.v[todo], 1e-9))
        th = p.theta[todo] + rng.normal(0.0, 1.0, len(todo)) * sig
        px = p.x[todo] + v * motion.period * np.cos(th)
        py = p.y[todo] + v * motion.period * np.sin(th)
        ok = (v >= 0.0) & (v <= motion.v_max) & room.contains(px, py)
        acc = todo[ok]
        nx[acc], ny[acc], nth[acc], nv[acc] = px[ok], py[ok], th[ok], v[ok]
        redraws += int((~ok).sum())
        todo = todo[~ok]
    clamped = len(todo)
    # the rest stay at their old (valid) position with speed 0
    nv[todo] = 0.0
    return Particles(nx, ny, np.mod(nth, 2 * math.pi), nv, p.w.copy()), redraws, clamped


def box_cells(x: np.ndarray, y: np.ndarray, grid: WorldGrid, half_w: float, half_d: float):
    """Cells touched by the bounding box centred on each particle and the covered fractions.

    Returns ``(iy, ix, V)``, each ``(N, K)``: cell indices (clipped into the grid) and
    ``V_k(x)`` = covered area / cell area (0 for cells outside the grid).
    """
    c = grid.cell
    kx = int(math.ceil(2 * half_w / c)) + 1
    ky = int(math.ceil(2 * half_d / c)) + 1
    ix0 = np.floor((x - half_w - grid.x0) / c).astype(np.int64)
    iy0 = np.floor((y - half_d - grid.y0) / c).astype(np.int64)
    ix = ix0[:, None] + np.arange(kx)[None, :]  # (N, kx)
    iy = iy0[:, None] + np.arange(ky)[None, :]  # (N, ky)
    left = grid.x0 + ix * c
    bottom = grid.y0 + iy * c
    ox = np.clip(np.minimum(x[:, None] + half_w, left + c) - np.maximum(x[:, None] - half_w, left), 0.0, c) / c
    oy = np.clip(np.minimum(y[:, None] + half_d, bottom + c) - np.maximum(y[:, None] - half_d, bottom), 0.0, c) / c
    ox = np.where((ix >= 0) & (ix < grid.nx), ox, 0.0)
    oy = np.where((iy >= 0) & (iy < grid.ny), oy, 0.0)
    V = (oy[:, :, None] * ox[:, None, :]).reshape(len(x), -1)
    IY = np.broadcast_to(np.clip(iy, 0, grid.ny - 1)[:, :, None], (len(x), ky, kx)).reshape(len(x), -1)
    IX = np.broadcast_to(np.clip(ix, 0, grid.nx - 1)[:, None, :], (len(x), ky, kx)).reshape(len(x), -1)
    return IY, IX, V


def log_p_silent(x: np.ndarray, y: np.ndarray, dep: Deployment, half_w: float, half_d: float) -> np.ndarray:
    """``(n, N)`` log P(S_i = 0 | x, B_i = 0) = log prod_{k in R_i} L(1 - p0_i, 1 - q_ik, V_k(x)).

    ``R_i`` = the ``xi_i`` cells with ``q_ik > 0``. Sensor by sensor (a loop over sensors,
    vectorised over particles): only particles whose box reaches the bounding box of the
    sensor's non-zero cells are computed; for the others no touched cell is in ``R_i`` and
    the value is exactly ``xi_i log(1 - p0_i) = log(1 - h_i)``.
    """
    n = len(dep.ids)
    out = np.empty((n, len(x)))
    if n == 0:
        return out
    g = dep.grid
    log_a = np.log1p(-np.minimum(dep.p0, 1 - PROB_FLOOR))  # (n,)
    out[:] = (dep.xi * log_a)[:, None]
    qf = dep.q.reshape(n, -1)
    bbox = dep.cell_bounds()  # (n, 4): x0, y0, x1, y1 of the non-zero cells
    for s in range(0, len(x), CHUNK):
        xs, ys = x[s : s + CHUNK], y[s : s + CHUNK]
        iy, ix, V = box_cells(xs, ys, g, half_w, half_d)
        flat = iy * g.nx + ix
        for i in range(n):
            bx0, by0, bx1, by1 = bbox[i]
            sel = np.flatnonzero((xs + half_w > bx0) & (xs - half_w < bx1) & (ys + half_d > by0) & (ys - half_d < by1))
            if sel.size == 0:
                continue
            p0 = dep.p0[i]
            qk = qf[i][flat[sel]]  # (c, K)
            q = np.maximum(qk, p0)
            L = (1.0 - p0) - V[sel] * (q - p0)  # L(1 - p0, 1 - q, V)
            np.maximum(L, PROB_FLOOR, out=L)
            # touched cells of R_i replace their (1 - p0) factor by L; cells outside R_i give 1.
            # (A touched cell clipped in from outside the grid has V = 0, so L = 1 - p0 and the
            # replacement changes nothing.)
            ratio = np.where(qk > 0, L / math.exp(log_a[i]), 1.0)
            out[i, s + sel] = dep.xi[i] * log_a[i] + np.log(ratio).sum(axis=1)
    return out


def sensor_likelihood(
    x: np.ndarray,
    y: np.ndarray,
    fired: np.ndarray,
    blind: np.ndarray,
    dep: Deployment,
    half_w: float,
    half_d: float,
) -> np.ndarray:
    """``(n, N)`` P(S_i = s_i | X = x) for every sensor and particle (section VII-B.2).

    ``fired`` and ``blind`` are ``(n,)`` booleans (S_i and B_i of this iteration). A blind
    sensor's row is ``rho_i`` (fired) or ``1 - rho_i`` (silent) for every particle.
    """
    p_silent = np.exp(log_p_silent(x, y, dep, half_w, half_d))
    live = np.where(fired[:, None], 1.0 - p_silent, p_silent)
    refr = np.where(fired, dep.rho, 1.0 - dep.rho)[:, None]
    return np.clip(np.where(blind[:, None], refr, live), PROB_FLOOR, 1.0)


def log_weights(x, y, fired, blind, dep, half_w, half_d) -> np.ndarray:
    """``(N,)`` log P(E | x) = sum_i log P(S_i = s_i | x); blind sensors add a constant and are left out."""
    live = ~blind
    if not live.any():
        return np.zeros(len(x))
    sub = Deployment(
        tuple(np.asarray(dep.ids)[live]), dep.grid, dep.q[live], dep.p0[live], dep.rho[live],
        dep.refractory[live], dep.xi[live], (),
    )  # fmt: skip
    ls = log_p_silent(x, y, sub, half_w, half_d)
    f = fired[live][:, None]
    p_fire = -np.expm1(ls)
    logp = np.where(f, np.log(np.clip(p_fire, PROB_FLOOR, 1.0)), np.maximum(ls, math.log(PROB_FLOOR)))
    return logp.sum(axis=0)


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
) -> FilterResult:
    """Run the SIR filter over ``T`` iterations: ``fired``, ``blind`` are ``(T, n)`` booleans.

    Sequential over iterations by nature; vectorised over particles and sensors within one.
    """
    T = fired.shape[0]
    cxs, cys = dep.grid.centres()
    mask = room.contains(cxs.ravel(), cys.ravel()).reshape(cxs.shape)
    p = prior(n_particles, room, motion, rng)
    L = min(log_particles, n_particles)
    res = FilterResult(
        np.zeros((T, 2)), np.zeros(T), np.zeros(T, np.int64), np.zeros(T, np.int64), np.zeros(T, bool),
        np.zeros((T, L, 2)), np.zeros((T, L)), np.zeros(T),
    )  # fmt: skip
    pick = np.linspace(0, n_particles - 1, L).round().astype(np.int64) if L else np.zeros(0, np.int64)
    draw = systematic_resample if resample == "systematic" else multinomial_resample
    for k in range(T):
        p, redraws, clamped = propagate(p, room, motion, rng)
        lw = np.log(np.maximum(p.w, 1e-300)) + log_weights(p.x, p.y, fired[k], blind[k], dep, half_w, half_d)
        p.w = normalise(lw)
        res.ess[k] = effective_sample_size(p.w)
        res.redraws[k], res.clamped[k] = redraws, clamped
        res.estimates[k] = estimate_cell(p.x, p.y, p.w, dep.grid, half_w, half_d, mask)
        mx, my = float(np.dot(p.w, p.x)), float(np.dot(p.w, p.y))
        res.spread[k] = math.sqrt(float(np.dot(p.w, (p.x - mx) ** 2 + (p.y - my) ** 2)))
        if L:
            res.logged_xy[k] = np.c_[p.x[pick], p.y[pick]]
            res.logged_w[k] = p.w[pick]
        if resample_when == "always" or res.ess[k] < ess_threshold * n_particles:
            idx = draw(p.w, rng)
            p = Particles(p.x[idx], p.y[idx], p.theta[idx], p.v[idx], np.full(n_particles, 1.0 / n_particles))
            res.resampled[k] = True
    return res
