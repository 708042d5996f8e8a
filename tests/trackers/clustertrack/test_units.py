"""CLUSTERTRACK is unit-free: the same readings on a site drawn in m and in cm give the same run, scaled.

The number of draws per particle, ``m_t = round(m_o S_F(t))``, is exactly a half-integer on
the 2-D raster (``S_F = N (R/10)^2``, ``m_o R^2 = 50``: ``m_o S_F = N / 2``); the float product
carried noise that depends on the site's units and ``round`` let it pick the count (73 draws
per particle in m, 72 in cm), so every later random draw differed
(``tests/pipeline/test_units.py``, proximity-grid: mean error 0.133 R in m, 0.226 R in cm).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import box

from onebit.core.units import METRES_PER_UNIT
from onebit.trackers.clustertrack.algorithm import cluster_track, round_count, rules_of_thumb
from onebit.trackers.clustertrack.feasible import SensorArray
from onebit.trackers.clustertrack.space import FeasibleSpace

#: 2 x 2 proximity sensors of radius R = 1 m on a 2 m square; one target walking past them
XY = np.array([[0.5, 0.5], [1.5, 0.5], [0.5, 1.5], [1.5, 1.5]])
ON = np.array([[1, 0, 0, 0], [1, 1, 0, 0], [0, 1, 0, 0], [0, 1, 0, 1], [0, 0, 0, 1]], dtype=bool)


def tiny_space(k: float) -> tuple[FeasibleSpace, float]:
    """The tiny site with every length times ``k`` (``k = 100``: the same site in cm); ``(space, R)``."""
    R = 1.0 * k
    sa = SensorArray(("a", "b", "c", "d"), XY * k, np.full(4, R), np.full(4, R))
    sp = FeasibleSpace.build(ON, np.arange(len(ON), dtype=float), sa, box(0, 0, 2 * k, 2 * k), dim=2, cell=R / 10)
    return sp, R


def test_half_integer_counts_round_the_same_in_every_unit():
    # the case found: 145 cells of F; in m the product is 72.50000000000001, in cm 72.5
    assert 50.0 * (145 * 0.1**2) != 0.005 * (145 * 100.0)
    assert round_count(50.0 * (145 * 0.1**2)) == round_count(0.005 * (145 * 100.0)) == 72
    assert [round_count(v) for v in (2.4, 2.5, 3.5, 3.5000001, 7.49999, 0.0)] == [2, 2, 4, 4, 7, 0]


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 10**5), st.floats(0.05, 20.0), st.sampled_from(sorted(METRES_PER_UNIT)))
def test_raster_sample_count_is_exactly_half_the_cells(n, r_m, units):
    """``m_o S_F`` with ``m_o R^2 = 50`` and ``N`` cells of ``(R / 10)^2``, computed in site units
    as the tracker does, rounds as the exact ``N / 2`` does, whatever R and the units."""
    R = r_m / METRES_PER_UNIT[units]
    m_o = 50.0 / R**2
    size = n * (R / 10) ** 2
    assert round_count(m_o * size) == round(n / 2)


def test_tiny_2d_space_in_cm_runs_as_in_m():
    (sp_m, r_m), (sp_cm, r_cm) = tiny_space(1.0), tiny_space(100.0)
    np.testing.assert_array_equal(sp_m.masks, sp_cm.masks)  # the same raster and F
    assert np.any(sp_m.masks.sum(axis=1) % 2 == 1)  # an odd cell count: m_o S_F is a tie
    p_m = rules_of_thumb(sp_m, H=50, m_o=50.0 / r_m**2)
    p_cm = rules_of_thumb(sp_cm, H=50, m_o=50.0 / r_cm**2)
    assert (p_m.K, p_m.L, p_m.Q_hat) == (p_cm.K, p_cm.L, p_cm.Q_hat)
    a = cluster_track(sp_m, p_m, np.random.default_rng(0))
    b = cluster_track(sp_cm, p_cm, np.random.default_rng(0))
    # the same number of draws at every instant (it was 15 vs 14 per particle at the first)
    np.testing.assert_array_equal(a.candidates, b.candidates)
    np.testing.assert_array_equal(a.kept, b.kept)
    np.testing.assert_array_equal(a.clusters, b.clusters)
    assert a.tracks.shape == b.tracks.shape and a.tracks.shape[0] >= 1
    np.testing.assert_allclose(a.tracks * 100.0, b.tracks, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(a.costs * 100.0, b.costs, rtol=1e-9)
    # the odd counts went to the even number of draws (ties to even), in both units
    m_t = a.candidates[1:] // a.kept[:-1]
    n = sp_m.masks.sum(axis=1)[1:]
    np.testing.assert_array_equal(m_t, [round(v / 2) for v in n])


@pytest.mark.parametrize("k", [100.0, 1000.0, 1 / 0.3048])
def test_rules_of_thumb_scale_with_the_units(k):
    (sp_m, r_m), (sp_k, r_k) = tiny_space(1.0), tiny_space(k)
    p_m = rules_of_thumb(sp_m, H=50, m_o=50.0 / r_m**2)
    p_k = rules_of_thumb(sp_k, H=50, m_o=50.0 / r_k**2)
    assert (p_m.K, p_m.L, p_m.Q_hat) == (p_k.K, p_k.L, p_k.Q_hat)
    assert p_k.D0 == pytest.approx(p_m.D0 * k, rel=1e-12)
