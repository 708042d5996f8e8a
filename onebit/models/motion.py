"""The intruder motion model of Schiff & Goldberg (section VII-B.1), shared by the particle
filter (:mod:`onebit.trackers.intruder.filter`) and the PIR simulator
(:mod:`onebit.datasets.pir_sim`).

The state is position, orientation and speed; one step of length ``t_P``::

    v'     = v + N(0, sigma_v^2),            rejected unless 0 <= v' <= v_max
    theta' = theta + N(0, 1) * min(pi, turn_scale / v)
    x'     = x + v' t_P cos theta',  y' = y + v' t_P sin theta'   rejected unless in the room

rejection-sampled (at most ``max_retries`` rounds; a particle that never lands stays in place
with speed 0). The prior is uniform in position over the room, orientation in [0, 2 pi) and
speed in [0, v_max].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely


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
