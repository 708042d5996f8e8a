"""The one truth-to-track association: optimal against brute force, pairing by nearest time."""

from __future__ import annotations

import itertools

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import OnebitError
from onebit.scoring.association import ASSOCIATION, associate, cost_table, pair_samples, truth_at


def _matchings(allowed: np.ndarray):
    """Every one-to-one partial matching among the allowed (track, target) entries."""
    K, G = allowed.shape

    def rec(k: int, used: frozenset):
        if k == K:
            yield ()
            return
        yield from rec(k + 1, used)  # track k unmatched
        for g in range(G):
            if allowed[k, g] and g not in used:
                for rest in rec(k + 1, used | {g}):
                    yield ((k, g), *rest)

    yield from rec(0, frozenset())


def _brute_force(C: np.ndarray, gate: float | None) -> tuple[float, float]:
    """Optimal (cardinality, cost) of the formulation, by enumeration.

    With a gate: min sum (C - gate) over matchings of entries with C <= gate.
    Without: max cardinality, then min sum C (over finite entries).
    """
    allowed = np.isfinite(C) if gate is None else np.isfinite(C) & (C <= gate)
    best = None
    for m in _matchings(allowed):
        total = sum(C[k, g] for k, g in m)
        key = (-len(m), total) if gate is None else (sum(C[k, g] - gate for k, g in m),)
        if best is None or key < best[0]:
            best = (key, len(m), total)
    return best[1], best[2]


@st.composite
def cost_tables(draw):
    K = draw(st.integers(0, 4))
    G = draw(st.integers(0, 4))
    present = np.array(draw(st.lists(st.booleans(), min_size=K * G, max_size=K * G)), dtype=bool).reshape(K, G)
    samples = draw(st.lists(st.lists(st.integers(0, 20), min_size=1, max_size=3), min_size=K * G, max_size=K * G))
    reduce = draw(st.sampled_from(["sum", "mean"]))
    gate = draw(st.one_of(st.none(), st.integers(0, 30).map(float)))
    return K, G, present, samples, reduce, gate


@settings(max_examples=300, deadline=None)
@given(cost_tables())
def test_associate_is_optimal_against_brute_force(table):
    K, G, present, samples, reduce, gate = table
    C = np.full((K, G), np.inf)
    rows = []
    for (k, g), s in zip(itertools.product(range(K), range(G)), samples):
        if present[k, g]:
            C[k, g] = float(np.sum(s)) if reduce == "sum" else float(np.mean(s))
            rows += [(f"k{k}", f"g{g}", float(c)) for c in s]
    pairs = pl.DataFrame(rows, schema={"track": pl.String, "target": pl.String, "cost": pl.Float64}, orient="row")
    out = associate(pairs, reduce=reduce, gate=gate)
    assert out.schema == ASSOCIATION
    # a one-to-one matching of paired entries, within the gate
    assert out["track"].is_unique().all() and out["target"].is_unique().all()
    ks = [int(t[1:]) for t in out["track"]]
    gs = [int(t[1:]) for t in out["target"]]
    assert np.all(np.isfinite(C[ks, gs]))
    if gate is not None:
        assert np.all(C[ks, gs] <= gate)
    np.testing.assert_allclose(out["cost"].to_numpy(), C[ks, gs])
    n, total = _brute_force(C, gate)
    if gate is None:
        assert out.height == n
        assert out["cost"].sum() == pytest.approx(total)
    else:
        assert float((out["cost"] - gate).sum()) == pytest.approx(total - n * gate)


def test_gate_leaves_a_far_track_unmatched_and_no_gate_matches_it():
    pairs = pl.DataFrame({"track": ["near", "far"], "target": ["a", "b"], "cost": [0.5, 9.0]})
    assert associate(pairs, gate=1.0)["track"].to_list() == ["near"]
    assert associate(pairs)["track"].to_list() == ["far", "near"]


def test_no_gate_prefers_more_matches_over_lower_cost():
    # k1-g1 alone is cheapest (1), but k1-g2 + k2-g1 matches both tracks (cost 10 + 10)
    pairs = pl.DataFrame({"track": ["k1", "k1", "k2"], "target": ["g1", "g2", "g1"], "cost": [1.0, 10.0, 10.0]})
    out = associate(pairs, reduce="sum")
    assert dict(zip(out["track"], out["target"])) == {"k1": "g2", "k2": "g1"}
    # with a gate of 6 each pair above 6 is worth less than leaving both unmatched
    assert dict(zip(*associate(pairs, gate=6.0).select("track", "target"))) == {"k1": "g1"}


def test_mean_and_sum_differ_for_tracks_of_different_lengths():
    # "short" is near target a for 1 sample (error 2); "long" for 4 samples (error 1 each)
    pairs = pl.DataFrame({"track": ["short"] + ["long"] * 4, "target": ["a"] * 5, "cost": [2.0, 1.0, 1.0, 1.0, 1.0]})
    assert associate(pairs, reduce="mean")["track"].to_list() == ["long"]
    assert associate(pairs, reduce="sum")["track"].to_list() == ["short"]


def test_bad_arguments_name_what_is_wrong():
    pairs = pl.DataFrame({"track": ["k"], "target": ["g"], "err": [1.0]})
    with pytest.raises(OnebitError, match="'cost'"):
        associate(pairs)
    with pytest.raises(OnebitError, match="reduce='median'"):
        cost_table(pairs, cost="err", reduce="median")
    with pytest.raises(OnebitError, match="gate=inf"):
        associate(pairs, cost="err", gate=float("inf"))


def test_empty_pairs_give_an_empty_matching():
    empty = pl.DataFrame(schema={"track": pl.String, "target": pl.String, "cost": pl.Float64})
    assert associate(empty).schema == ASSOCIATION
    assert associate(empty).height == 0


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("tolerance", [None, 0.3])
def test_pair_samples_takes_each_targets_truth_nearest_in_time(seed, tolerance):
    rng = np.random.default_rng(seed)
    truth = pl.DataFrame(
        {
            "t": np.r_[np.sort(rng.uniform(0, 10, 15)), np.sort(rng.uniform(2, 8, 9))],
            "target": ["a"] * 15 + ["b"] * 9,
            "x": rng.random(24),
            "y": rng.random(24),
        }
    )
    tracks = pl.DataFrame(
        {"track": ["k2"] * 7 + ["k1"] * 6, "t": rng.uniform(0, 10, 13), "x": rng.random(13), "y": rng.random(13)}
    )
    pairs = pair_samples(tracks, truth, tolerance=tolerance)
    expect = []
    for tk, t, x, y in tracks.iter_rows():  # brute force, a few rows
        for g in ("a", "b"):
            tg = truth.filter(pl.col("target") == g)
            i = int(np.argmin(np.abs(tg["t"].to_numpy() - t)))
            if tolerance is None or abs(tg["t"][i] - t) <= tolerance:
                expect.append((tk, g, t, tg["t"][i], x, y, tg["x"][i], tg["y"][i]))
    want = pl.DataFrame(expect, schema=pairs.schema, orient="row").sort("t", "track", "target")
    assert pairs.equals(want)


def test_complete_pairs_add_the_slots_a_track_misses():
    truth = pl.DataFrame({"t": [0.0, 1.0, 2.0], "target": ["a"] * 3, "x": [0.0, 1.0, 2.0], "y": [0.0] * 3})
    tracks = pl.DataFrame(
        {"track": ["k1", "k1", "k1", "k2"], "t": [0.0, 1.0, 2.0, 1.0], "x": [0.0, 1.0, 2.0, 5.0], "y": [0.0] * 4}
    )
    full = pair_samples(tracks, truth, tolerance=0.1, complete=True)
    assert full.height == 6  # 3 slots x 2 tracks
    missing = full.filter(pl.col("x").is_null())
    assert missing.select("track", "t").rows() == [("k2", 0.0), ("k2", 2.0)]
    assert pair_samples(tracks, truth, tolerance=0.1).height == 4


def test_truth_at_drops_times_without_a_truth_sample_within_tolerance():
    truth = pl.DataFrame({"t": [0.0, 10.0], "target": ["a", "a"], "x": [1.0, 2.0], "y": [0.0, 0.0]})
    out = truth_at(pl.Series([0.2, 5.0, 9.9]), truth, tolerance=0.5)
    assert out.select("t", "true_x").rows() == [(0.2, 1.0), (9.9, 2.0)]
    assert truth_at(pl.Series([1.0]), truth.clear(), tolerance=None).height == 0
