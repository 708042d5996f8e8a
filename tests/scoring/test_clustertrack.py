"""CLUSTERTRACK scoring: error in units of R, targets found within D0 by the one association."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.tables import SCORES
from onebit.scoring.clustertrack import match_tracks, score


def _tables(track_x: dict[str, float], R=1.0, D0=0.5):
    t = np.arange(5.0)
    truth = pl.DataFrame({"t": np.tile(t, 2), "target": ["T1"] * 5 + ["T2"] * 5, "x": np.r_[t, t + 10], "y": 0.0})
    tracks = pl.concat(
        pl.DataFrame({"track": k, "t": t, "x": t + dx, "y": None}, schema_overrides={"y": pl.Float64})
        for k, dx in track_x.items()
    )
    params = pl.DataFrame(
        {
            "R": [R],
            "D0": [D0],
            "count_lower_bound": [2],
            "count_consensus": [2],
            "tracks": [len(track_x)],
            "reruns": [0],
        }
    )
    return {"truth": truth, "clustertrack_tracks": tracks, "clustertrack_params": params}


def test_a_spurious_track_beyond_d0_is_not_a_found_target(hallway_site):
    # c1 follows T1 at 0.2; c2 is 3 away from T1 and 7 from T2: no target within D0
    rows, made = score("clustertrack", _tables({"c1": 0.2, "c2": 3.0}), hallway_site)
    m = {r[1]: r[2] for r in rows}
    assert m["targets_true"] == 2 and m["targets_found"] == 1 and m["spurious_tracks"] == 1
    # the paper's error: each target's nearest track, mean over targets, in R
    assert m["mean_error_R"] == pytest.approx((0.2 + 7.0) / 2)
    sc = made["clustertrack_scores"]
    assert sc.schema == SCORES and set(sc["track"]) == {"c1"} and sc["error"].to_list() == pytest.approx([0.2] * 5)
    assert m["error_mean_matched"] == pytest.approx(0.2)


def test_match_tracks_is_the_mean_distance_of_the_cost_table():
    targets, names, D, pairs = match_tracks(
        _tables({"c1": 0.2, "c2": 3.0})["truth"], _tables({"c1": 0.2, "c2": 3.0})["clustertrack_tracks"]
    )
    assert targets == ["T1", "T2"] and names == ["c1", "c2"]
    np.testing.assert_allclose(D, [[0.2, 3.0], [9.8, 7.0]])
    assert pairs.height == 2 * 10
