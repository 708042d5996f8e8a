"""The simulators' compiled loop against its plain reference on random on-periods."""

from __future__ import annotations

import numpy as np
import pytest

from onebit._testing.oracles import pir_refractory_reference
from onebit.datasets import kernels
from onebit.datasets.from_truth import _runs


@pytest.mark.parametrize("seed", range(6))
def test_pir_refractory_equals_the_reference(seed):
    rng = np.random.default_rng(seed)
    K, m = int(rng.integers(1, 400)), int(rng.integers(1, 6))
    dt = float(rng.choice([0.05, 0.1, 0.5]))
    times = 3.0 + dt * np.arange(K)
    on = rng.random((K, m)) < rng.uniform(0.05, 0.9)
    refr = rng.choice([0.0, 0.3, 1.0, 4.0], m)
    col, start, end = _runs(on)
    want = pir_refractory_reference(col, start, end, times, refr, dt)
    got = kernels.pir_refractory(col, start, end, times, refr, dt)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    # the rule itself: a kept period never starts before its sensor is ready again
    kept = want[0]
    assert kept.any() and (want[1][kept] >= start[kept]).all() and (want[1][kept] < end[kept]).all()
    if (refr == 0).all():
        assert kept.all()
