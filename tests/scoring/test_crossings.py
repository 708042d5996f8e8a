"""Beams agents matched to true agents by shared crossings (the one association, cost -1 each)."""

from __future__ import annotations

import polars as pl
import pytest

from onebit.scoring.crossings import assignment_scores


def test_agents_take_the_true_agent_they_share_most_crossings_with():
    matched = pl.DataFrame({"target": ["A", "A", "B", "B", "B", None, "A"]})
    assignment = pl.DataFrame({"track": ["x", "x", "y", "y", "x", "y", None]})
    acc, mapping = assignment_scores(matched, assignment)
    assert mapping == {"x": "A", "y": "B"}
    assert acc == pytest.approx(4 / 7)  # x-A twice, y-B twice, of 7 crossings


def test_an_agent_sharing_no_crossing_stays_unmatched():
    matched = pl.DataFrame({"target": ["A", "A", None]})
    assignment = pl.DataFrame({"track": ["x", "x", "z"]})
    acc, mapping = assignment_scores(matched, assignment)
    assert mapping == {"x": "A"} and acc == pytest.approx(2 / 3)


def test_no_crossing_and_no_true_target():
    assert assignment_scores(pl.DataFrame({"target": []}, schema={"target": pl.String}), pl.DataFrame({"track": []}, schema={"track": pl.String})) == (1.0, {})
    assert assignment_scores(pl.DataFrame({"target": [None]}, schema={"target": pl.String}), pl.DataFrame({"track": ["x"]})) == (0.0, {})


@pytest.mark.parametrize("seed", range(5))
def test_vectorised_region_scores_equal_the_row_by_row_reference(building, seed):
    """Random truth (some samples outside every region, ties in time) against random region
    tracks (some regions missing): the vectorised scores equal the reference's, bit for bit."""
    import numpy as np

    from onebit.scoring.crossings import region_scores, region_scores_reference

    site, rg = building
    rng = np.random.default_rng(seed)
    minx, miny, maxx, maxy = site.boundary.bounds
    n = 3000
    truth = pl.DataFrame(
        {
            "t": np.sort(rng.integers(0, 400, n)).astype(float) / 4.0,
            "target": rng.choice(["A", "B", "C"], n),
            "x": rng.uniform(minx, maxx, n),
            "y": rng.uniform(miny, maxy, n),
        }
    )
    k = 600
    names = np.array(list(rg.names) + [None], dtype=object)
    tracks = pl.DataFrame(
        {
            "track": rng.choice(["x", "y", "z"], k),
            "t": np.sort(rng.uniform(-5, 100, k)).round(1),
            "region": pl.Series(names[rng.integers(0, len(names), k)].tolist(), dtype=pl.String),
        }
    )
    mapping = {"x": "A", "y": "B", "z": "D"}
    a = region_scores(tracks, truth, mapping, rg, tracker="beams")
    b = region_scores_reference(tracks, truth, mapping, rg, tracker="beams")
    assert a.height > 0 and a.equals(b)
