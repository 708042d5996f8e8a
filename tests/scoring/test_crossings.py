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
