"""The identity-swap diagnosis: swaps vs lags, meeting kinds, the identity-free floor, the study's files."""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.datasets.builtin import builtin_site
from onebit.experiments import findinghumo_diagnose as fd
from onebit.models.graph_hmm.eatg import hop_matrix


def _hallway():
    g = builtin_site("hallway").sensor_graph
    idx = {n: i for i, n in enumerate(g.nodes)}
    return idx, hop_matrix(g.nodes, g.edges)


def _rows(idx, seqs):
    return np.array([[idx[str(n)] for n in s] for s in seqs], dtype=np.int64)


def test_a_lag_is_not_a_swap_and_a_swap_is():
    idx, hops = _hallway()
    true = _rows(idx, [[97, 96, 95, 99, 111, 110, 117, 117, 117, 117], [117, 110, 111, 99, 95, 96, 97, 97, 97, 97]])
    # track 0 follows user 0 a slot late through the crossing: a lag
    lag = _rows(idx, [[97, 97, 96, 95, 99, 111, 110, 117, 117, 117], [117, 117, 110, 111, 99, 95, 96, 97, 97, 97]])
    a = fd.slot_assignments(true, lag, hops, 8)
    assert (a == a[0]).all()
    # the tracks bounce back at the kitchen: from there on they follow the other user
    bounce = _rows(idx, [[97, 96, 95, 99, 95, 96, 97, 97, 97, 97], [117, 110, 111, 99, 111, 110, 117, 117, 117, 117]])
    b = fd.slot_assignments(true, bounce, hops, 8)
    changes = np.flatnonzero((b[1:] != b[:-1]).any(axis=1)) + 1
    assert changes.size == 1 and b[-1].tolist() == [1, 0]
    assert fd.slot_error(true, bounce, hops, 8) == 0.0  # positions right, identities wrong
    assert fd.slot_error(true, lag, hops, 8) > 0.0


def test_meeting_kinds():
    idx, hops = _hallway()
    crossing = _rows(idx, [[97, 96, 95, 99, 111, 110, 117], [117, 110, 111, 99, 95, 96, 97]])
    assert fd.meeting_kind(crossing, (0, 1), 3, hops) == (True, "crossing")
    together = _rows(idx, [[97, 96, 95, 99, 111, 110, 117], [97, 97, 96, 95, 99, 111, 110]])
    assert fd.meeting_kind(together, (0, 1), 3, hops) == (True, "co-walk")
    apart = _rows(idx, [[97, 97, 97, 97, 97, 97, 97], [117, 117, 117, 117, 117, 117, 117]])
    assert fd.meeting_kind(apart, (0, 1), 3, hops) == (False, "none")


def test_quick_study_writes_its_tables(tmp_path):
    out = fd.run(tmp_path / "d", quick=True, echo=lambda *_: None)
    res = pl.read_csv(out / "results.csv")
    assert set(res["tracker"]) == set(fd.TRACKERS) and res.height == 2 * len(fd.TRACKERS)
    assert (res["slot_error"] <= res["hop_error"] + 1e-9).all()  # the identity-free floor
    swaps = pl.read_csv(out / "swaps.csv")
    assert set(swaps.columns) == set(fd.SWAPS)
    assert (out / "diagnosis.md").read_text().startswith("Seeds 0-1")
