"""The EATG's co-activation counts and the exit test read from the end of a path, against
their plain definitions on random data."""

from __future__ import annotations

import numpy as np
import pytest

from onebit.models.graph_hmm.adaptive import _exits, _last_two
from onebit.models.graph_hmm.eatg import lag_counts


@pytest.mark.parametrize("seed", range(6))
def test_lag_counts_equal_the_dense_product(seed):
    rng = np.random.default_rng(seed)
    x = rng.random((int(rng.integers(2, 400)), int(rng.integers(1, 12)))) < rng.uniform(0.01, 0.5)
    for lag in range(1, 6):
        if lag < x.shape[0]:
            dense = x[:-lag].astype(float).T @ x[lag:].astype(float)
            np.testing.assert_array_equal(lag_counts(x, lag), dense)


def _exits_plain(row, after, signatures):
    """The definition: over the whole path, the last node and the last different one."""
    valid = row[row >= 0]
    if valid.size < 2:
        return False
    end = valid[-1]
    moved = valid[valid != end]
    if moved.size == 0:
        return False
    return any(end == o and moved[-1] == i and not after[:, o].any() for o, i in signatures)


@pytest.mark.parametrize("seed", range(10))
def test_exits_read_from_the_end_equal_the_definition(seed):
    rng = np.random.default_rng(seed)
    n = 5
    for _ in range(200):
        d = int(rng.integers(0, 700))
        row = rng.integers(0, n, d)
        if rng.random() < 0.5:  # long dwells and absences: the last change far back
            row[rng.integers(0, d + 1) :] = rng.integers(0, n)
        row[rng.random(d) < rng.uniform(0, 0.9)] = -1
        after = rng.random((3, n)) < 0.3
        sigs = [(int(a), int(b)) for a, b in rng.integers(0, n, (3, 2))]
        if d and row[row >= 0].size >= 2:
            valid = row[row >= 0]
            moved = valid[valid != valid[-1]]
            if moved.size:
                sigs.append((int(valid[-1]), int(moved[-1])))  # one signature that matches
        assert _exits(row, after, sigs) == _exits_plain(row, after, sigs)
    assert _last_two(np.array([-1, 3, 3, -1, 2, 2, -1])) == (2, 3)
    assert _last_two(np.array([-1, 4, -1])) == (4, -1) and _last_two(np.array([], np.int64)) == (-1, -1)
