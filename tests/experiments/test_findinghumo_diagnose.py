"""The identity-swap diagnosis: swaps vs lags, meeting kinds, the identity-free floor, the study's files."""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.datasets.builtin import builtin_site
from onebit.experiments import findinghumo_diagnose as fd
from onebit.models.graph_hmm.eatg import hop_matrix
from onebit.pipeline.executors import SerialExecutor


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


def test_quick_study_writes_its_tables(tmp_path, monkeypatch):
    monkeypatch.setattr(fd, "FLOOR_DRAWS", 2)  # the tables, not the floor's value: 2 tie-breaks a seed, not 20
    out = fd.run(tmp_path / "d", quick=True, echo=lambda *_: None)
    res = pl.read_csv(out / "results.csv")
    assert set(res["tracker"]) == set(fd.TRACKERS) | {fd.FLOOR} and res.height == 2 * (len(fd.TRACKERS) + 1)
    assert (res["slot_error"] <= res["hop_error"] + 1e-9).all()  # the identity-free floor
    assert (res.filter(pl.col("tracker") == fd.FLOOR)["slot_error"] == 0).all()  # the model floor has exact positions
    swaps = pl.read_csv(out / "swaps.csv")
    assert set(swaps.columns) == set(fd.SWAPS)
    assert set(swaps["model"]) <= {"truth", "tie", "swap", "impossible"}
    assert (out / "diagnosis.md").read_text().startswith("Seeds 0-1")


def test_the_model_floor_is_zero_without_meetings_and_positive_at_a_shared_arrival():
    """With the true paths and no two users ever on one node nothing is relabelled; with two
    users arriving together and leaving apart the draw flips a coin (the model ties)."""
    from onebit.models.graph_hmm.eatg import layout_eatg
    from onebit.models.graph_hmm.likelihood import tie_relabelling

    idx, hops = _hallway()
    g = builtin_site("hallway").sensor_graph
    eatg = layout_eatg(g.nodes, hops)
    active = np.zeros((8, len(g.nodes)), bool)
    apart = _rows(idx, [[97, 96, 95, 99, 111, 110, 117, 117], [93, 93, 94, 96, 97, 104, 103, 103]])
    rng = np.random.default_rng(1)
    x, changed = tie_relabelling(apart, active, eatg, p_hit=0.9, p_false=0.05, rng=rng)
    assert changed == 0 and (x == apart).all()
    together = _rows(idx, [[95, 99, 111, 111, 110, 117, 117, 117], [95, 99, 111, 111, 114, 101, 101, 101]])
    drawn = [tie_relabelling(together, active, eatg, p_hit=0.9, p_false=0.05, rng=rng)[0] for _ in range(16)]
    swapped = [bool((d[0, 4:] == together[1, 4:]).all()) for d in drawn]
    assert any(swapped) and not all(swapped)
    assert fd.slot_error(together, drawn[swapped.index(True)], hops, 8) == 0.0  # positions stay exact


def test_issue_15_what_is_reached_on_the_first_20_seeds(monkeypatch):
    """Issue #15's setting (hallway, 3 users, 150 s, drop 0.02, seeds 0-19), measured: hmm1
    1.426, hmm2 0.628, findinghumo 0.598, findinghumo-flow 0.523 hops, and the model-ties floor
    (true positions, model-optimal labels, exact ties by chance) 0.455 here (0.439 with 5
    tie-breaks a seed) -- above the issue's 0.1, which is why that is not reached.
    findinghumo < hmm2 < hmm1 is the issue's order; on these 20 seeds findinghumo's lead over
    hmm2 is within noise (-0.030 +- 0.073; over 60 seeds -0.14 +- 0.05, docs/findinghumo.md).

    The floor is the mean over 2 random tie-breaks a seed here (the study draws 20; the floor
    is most of a seed's cost), so 40 draws in all, far enough above 0.3 for that; the seeds
    run in this process (the executors give equal tables, tests/experiments/test_executors.py)."""
    monkeypatch.setattr(fd, "FLOOR_DRAWS", 2)
    jobs = [(seed, fd.DURATION, fd.USERS, fd.DROP, "routes") for seed in range(20)]
    done = SerialExecutor().map(fd.diagnose_seed, jobs)
    assert all(d.error is None for d in done), [d.error for d in done]
    rows = [r for d in done for r in d.value[0]]
    mean = pl.DataFrame(rows).group_by("tracker").agg(pl.col("hop_error").mean())
    m = dict(zip(mean["tracker"], mean["hop_error"]))
    assert m["findinghumo"] < m["hmm2"] < m["hmm1"], m
    assert m["findinghumo-flow"] < m["hmm2"], m
    assert m["model-ties"] > 0.3, m  # the floor of any maximiser of the model: far above 0.1
