"""The sensor model of binpf's filter (:mod:`onebit.trackers.binpf.filter`): how people at
known places trigger an array of binary sensors, and particles drawn in sensors' footprints.

Model
-----
Sensor :math:`s` at :math:`p_s` with footprint radius :math:`R_s` reports a level
:math:`z_s \\in \\{0, 1\\}` every frame (a sensor held on is presence, not only its rising
edge). A person at :math:`x` triggers it with the soft footprint probability

.. math::

    d_s(x) = p_d \\, \\sigma\\!\\left(\\frac{R_s - \\lVert x - p_s \\rVert}{w}\\right),
    \\qquad \\sigma(u) = \\frac{1}{1 + e^{-u}}                                     \\tag{1}

(:math:`w \\to 0` is the hard disk of radius :math:`R_s`). People trigger independently and
the sensor fires on its own with the false-alarm rate :math:`p_f` (noisy-OR):

.. math::

    P(z_s = 0 \\mid x_1..x_n) = (1 - p_f) \\prod_i \\big(1 - d_s(x_i)\\big).        \\tag{2}
"""

from __future__ import annotations

import numpy as np

from onebit.trackers.binpf.config import FilterParams

#: Floor of a probability before its log (a frame's likelihood never zero).
TINY = 1e-12


def footprint_probability(
    xy: np.ndarray, sensors: np.ndarray, radii: np.ndarray, *, pd: float, edge: float
) -> np.ndarray:
    """Eq. (1): ``d[..., s]`` for positions ``xy (..., 2)``, sensors ``(S, 2)``, radii ``(S,)``."""
    dist = np.sqrt(((xy[..., None, :] - sensors) ** 2).sum(-1))
    if edge <= 0:
        return np.where(dist <= radii, pd, 0.0)
    u = np.clip((radii - dist) / edge, -50.0, 50.0)
    return pd / (1.0 + np.exp(-u))


def frame_probability_off(
    positions: np.ndarray, sensors: np.ndarray, radii: np.ndarray, *, pd: float, pf: float, edge: float
) -> np.ndarray:
    """Eq. (2): ``P(z_s = 0 | positions (n, 2))`` for every sensor, ``(S,)``."""
    d = footprint_probability(positions, sensors, radii, pd=pd, edge=edge)
    return (1.0 - pf) * np.prod(1.0 - d, axis=0)


def birth_particles(
    group: np.ndarray, sensors: np.ndarray, radii: np.ndarray, rng: np.random.Generator, p: FilterParams
) -> np.ndarray:
    """``(N, 4)`` particles uniform in the footprints of ``group``'s sensors, velocities
    :math:`\\mathcal N(0, \\sigma_b^2)`."""
    N = p.particles
    which = group[rng.integers(0, len(group), N)]
    rad = radii[which] * np.sqrt(rng.random(N))
    ang = rng.random(N) * 2 * np.pi
    xy = sensors[which] + np.c_[rad * np.cos(ang), rad * np.sin(ang)]
    v = p.birth_speed * rng.standard_normal((N, 2))
    return np.c_[xy, v]
