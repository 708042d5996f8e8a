"""``onebit follow`` runs binpf online: a replay of a simulated proximity grid publishes the
tracks frame by frame, after the commit lag, and they equal ``onebit run``'s with the same
``[binpf]`` settings; the live report gives the delay."""

from __future__ import annotations

import math

import polars as pl
import pytest

from onebit.datasets.catalogue import get_scenario
from onebit.pipeline.follow import FollowConfig, follow, read_live_table
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from tests.pipeline.test_follow import SimClock


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    root = tmp_path_factory.mktemp("grid")
    return get_scenario("proximity-grid").write(
        root / "d", seed=2, duration=60.0, agents=None, drop=0.0, camera=False, params={}
    )


def test_follow_binpf_equals_run_with_the_same_lag(grid, tmp_path):
    config = {"binpf": {"particles": 100, "commit_lag": 5, "log_particles": 0}}
    clock = SimClock()
    res = follow(
        grid,
        tmp_path / "out",
        trackers=("binpf",),
        config=config,
        options=FollowConfig(replay=10.0, poll=0.5),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    assert res.run.ok, res.run.status
    batch = run_pipeline(grid, tmp_path / "batch", trackers=("binpf",), config=config, progress=False)
    ref = pl.read_parquet(batch.out / "tables" / "binpf_tracks.parquet")
    live = read_live_table(res.live, "binpf_tracks")
    assert ref.height > 20
    key = ["track", "t"]
    assert live.select(ref.columns).sort(key).equals(ref.sort(key))
    assert metric(res.report, "binpf/online_equals_batch") == 1.0
    p50, p99 = metric(res.report, "binpf/delay_p50"), metric(res.report, "binpf/delay_p99")
    # published after the lag (5 frames of 1 s, 0.5 s at 10x), not at the end of the replay
    assert 0.5 <= p50 <= p99 and math.isfinite(p99)
    assert p99 < 0.3 * 60.0 / 10.0
    parts = sorted((res.live / "tables" / "binpf_tracks").glob("part-*.parquet"))
    assert len(parts) >= 5


def test_follow_binpf_default_lag_reports_the_difference(grid, tmp_path):
    """With commit_lag = 0 the batch run looks at the whole log: the follow still publishes
    (after DEFAULT_COMMIT_LAG frames) and its report says whether the rows agree."""
    clock = SimClock()
    res = follow(
        grid,
        tmp_path / "out",
        trackers=("binpf",),
        config={"binpf": {"particles": 100, "log_particles": 0}},
        options=FollowConfig(replay=10.0, poll=0.5),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    assert res.run.ok, res.run.status
    assert metric(res.report, "binpf/online_estimates") > 20
    assert metric(res.report, "binpf/online_equals_batch") in (0.0, 1.0)
    assert math.isfinite(metric(res.report, "binpf/delay_p99"))
