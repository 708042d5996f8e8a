"""Intruder scoring: the one association by mean error, errors in cells."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.tables import SCORES
from onebit.scoring.intruder import error_rows, match_errors, score
from onebit.scoring.serve import CannotServe, targets_at_once


def _truth():
    t = np.arange(0.0, 10.5, 0.5)
    return pl.DataFrame(
        {"t": np.r_[t, t], "target": ["a"] * t.size + ["b"] * t.size, "x": np.r_[t, t], "y": np.r_[t * 0, t * 0 + 5.0]}
    )


def test_the_track_is_scored_against_the_target_of_least_mean_error():
    tracks = pl.DataFrame(
        {"tracker": "intruder", "track": "k", "t": [2.0, 4.0, 6.0], "x": [2.0, 4.0, 6.0], "y": [4.0, 4.5, None]}
    )
    sc = match_errors(tracks, _truth(), tolerance=0.25)
    assert sc.schema == SCORES
    assert sc["target"].unique().to_list() == ["b"] and sc["error"].to_list() == pytest.approx([1.0, 0.5])


def test_error_rows_are_in_cells(hallway_site):
    tracks = pl.DataFrame({"tracker": "intruder", "track": "k", "t": [2.0, 4.0], "x": [2.0, 4.0], "y": [3.0, 4.0]})
    it = pl.DataFrame({"t": [2.0, 4.0], "cell": [0.5, 0.5]})
    truth = _truth().filter(pl.col("target") == "b")  # one intruder: the filter's model
    rows, made = score("intruder", {"intruder_tracks": tracks, "intruder_iterations": it, "truth": truth}, hallway_site)
    m = {r[1]: r[2] for r in rows}
    assert m["mean_error_cells"] == pytest.approx((2.0 + 1.0) / 2 / 0.5)
    assert m["within_2"] == 0.5 and m["scored_iterations"] == 2
    assert error_rows(made["intruder_scores"].clear(), stage="intruder", cell=1.0) == []


def test_several_targets_at_once_cannot_be_served(hallway_site):
    """Issue 12 item 7: the single-target filter on multi-user data says so, with no number."""
    tracks = pl.DataFrame({"tracker": "intruder", "track": "k", "t": [2.0, 4.0], "x": [2.0, 4.0], "y": [3.0, 4.0]})
    assert targets_at_once(_truth()) == 2
    with pytest.raises(CannotServe, match="2 targets at once"):
        score("intruder", {"intruder_tracks": tracks, "truth": _truth()}, hallway_site)
    # people who come one after the other are one at a time: served
    one_by_one = _truth().with_columns(
        pl.when(pl.col("target") == "b").then(pl.col("t") + 20.0).otherwise(pl.col("t")).alias("t")
    )
    assert targets_at_once(one_by_one) == 1
    rows, _ = score("intruder", {"intruder_tracks": tracks, "truth": one_by_one}, hallway_site)
    assert {r[1] for r in rows} >= {"mean_error_cells", "scored_iterations"}
