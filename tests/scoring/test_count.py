"""The per-minute count scores and their baselines (issue 34, item 2), against counts worked
out by hand (docs/metrics.md, "People count")."""

from __future__ import annotations

import polars as pl
import pytest

from onebit.models.occupancy import PEOPLE
from onebit.scoring.count import baseline_counts, baseline_rows, count_scores, minute_grid, step_average

TC = pl.Schema({"t": pl.Float64, "end": pl.Float64, "count": pl.Int64})


def truth(*rows) -> pl.DataFrame:
    return pl.DataFrame(list(rows), schema=TC, orient="row")


def people(*rows) -> pl.DataFrame:
    return pl.DataFrame(list(rows), schema=PEOPLE, orient="row")


def test_three_minutes_with_a_change_mid_minute():
    # truth: 1 over [0, 90), 2 over [90, 180): minute 1 averages 1.5 -> 2 (half up)
    tc = truth((0, 90, 1), (90, 180, 2))
    minutes, true = minute_grid(tc)
    assert minutes.tolist() == [0.0, 60.0, 120.0]
    assert true.tolist() == [1, 2, 2]
    # estimate: 1 from 0, 2 from 100: minute 1 averages (40 + 2 x 20) / 60 = 1.33 -> 1
    est = people((0, 1), (100, 2))
    assert step_average(est, minutes).tolist() == [1, 1, 2]
    s = count_scores(tc, est)
    assert s.minutes == 3
    assert s.count_error == pytest.approx(1 / 3)
    assert s.count_accuracy == pytest.approx(2 / 3)
    assert s.occupancy_accuracy == 1.0


def test_rounding_is_half_up():
    minutes, _ = minute_grid(truth((0, 120, 1)))
    # 0.5 -> 1 in minute 0; 1.5 -> 2 in minute 1 (0.5 of 1 then 0.5 of 2)
    assert step_average(people((30, 1), (90, 2)), minutes).tolist() == [1, 2]
    # just under a half rounds down: 29 s of 1 -> 0.483
    assert step_average(people((31, 1), (60, 0)), minutes).tolist() == [0, 0]


def test_the_last_row_holds_to_the_end_and_nothing_before_the_first():
    minutes, _ = minute_grid(truth((0, 240, 1)))
    assert step_average(people((120, 3)), minutes).tolist() == [0, 0, 3, 3]


def test_minutes_covered_less_than_half_are_not_scored():
    # minute 0: 29 s of truth; minute 1: 20 s; minute 2: all of it
    tc = truth((0, 29, 1), (100, 180, 0))
    _, true = minute_grid(tc)
    assert true.tolist() == [-1, -1, 0]
    s = count_scores(tc, people((0, 5)))
    assert s.minutes == 1 and s.count_error == 5.0 and s.occupancy_accuracy == 0.0
    # exactly half is scored
    assert minute_grid(truth((0, 30, 1)))[1].tolist() == [1]


def test_no_scored_minute_gives_nan_and_zero_minutes():
    s = count_scores(truth((0, 10, 1)), people((0, 1)))
    assert s.minutes == 0 and s.count_error != s.count_error


@pytest.mark.parametrize("silent", [None, pl.DataFrame(schema=PEOPLE), people((0, 0))])
def test_a_silent_tracker_scores_its_misses(silent):
    tc = truth((0, 60, 1), (60, 120, 2), (120, 240, 0))
    s = count_scores(tc, silent)
    assert s.minutes == 4
    assert s.count_error == pytest.approx(3 / 4)
    assert s.count_accuracy == pytest.approx(2 / 4)
    assert s.occupancy_accuracy == pytest.approx(2 / 4)  # the share of empty minutes


def test_baselines_by_hand():
    # 70 minutes of 2, 60 of 0, 50 of 1; one motion row at t = 100
    tc = truth((0, 4200, 2), (4200, 7800, 0), (7800, 10800, 1))
    motion = pl.DataFrame({"t": [100.0], "sensor": ["a"], "on": [True]})
    base = baseline_counts(tc, motion)
    assert set(base) == {"count-commonest", "count-recent-60min"}
    assert base["count-commonest"].tolist() == [2] * 180
    # a motion row in [end - 3600, end): minutes 1..60 (ends 120 .. 3660), at the commonest non-zero count
    assert base["count-recent-60min"].tolist() == [0] + [2] * 60 + [0] * 119
    rows = {(s, m): v for s, m, v, _ in baseline_rows(tc, motion)}
    assert rows[("count-commonest", "count_error")] == pytest.approx((2 * 60 + 1 * 50) / 180)
    assert rows[("count-commonest", "count_accuracy")] == pytest.approx(70 / 180)
    assert rows[("count-commonest", "occupancy_accuracy")] == pytest.approx(120 / 180)
    # recent: wrong by 2 in minute 0 and minutes 61-69, by 1 in the 50 minutes of 1
    assert rows[("count-recent-60min", "count_error")] == pytest.approx((2 + 2 * 9 + 50) / 180)
    assert rows[("count-recent-60min", "count_accuracy")] == pytest.approx(120 / 180)
    assert rows[("count-recent-60min", "occupancy_accuracy")] == pytest.approx(120 / 180)
    assert rows[("count-recent-60min", "count_minutes")] == 180.0


def test_recent_baseline_without_motion_says_nobody():
    tc = truth((0, 180, 1))
    assert baseline_counts(tc, None)["count-recent-60min"].tolist() == [0, 0, 0]
    assert baseline_counts(truth(), None) == {}
