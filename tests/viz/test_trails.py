"""onebit.viz.trails: markers now, trails of the recent past, whole paths -- and recordings that
grow linearly with their duration (nothing re-logs a growing history)."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
import rerun as rr

from onebit.core import tables
from onebit.viz import inspect as rrd
from onebit.viz import (
    log_point_tracks,
    log_region_tracks,
    log_scores,
    log_truth,
    paths,
    stage_recording,
)
from onebit.viz.trails import log_moving, marker_size, segments

RUN_ID = "run-trails-0001"
HZ = 10.0


@pytest.fixture(autouse=True)
def strict_rerun():
    before = rr.strict_mode()
    rr.set_strict_mode(True)
    yield
    rr.set_strict_mode(before)


def walk(duration: float, *, targets: int = 2, seed: int = 0) -> pl.DataFrame:
    """A deterministic random walk per target inside [0, 5] x [0, 4], sampled at HZ."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / HZ)
    frames = []
    for k in range(targets):
        xy = np.cumsum(rng.normal(0.0, 0.05, (len(t), 2)), axis=0)
        xy = np.abs((xy + [2.5, 2.0]) % [10.0, 8.0] - [5.0, 4.0])  # fold into the box
        frames.append(pl.DataFrame({"t": t, "target": f"target{k + 1}", "x": xy[:, 0], "y": xy[:, 1]}))
    return pl.concat(frames).sort("t")


def record(tmp_path, duration: float, lab) -> int:
    """Bytes of one recording holding truth, point tracks, region tracks and scores of ``duration`` s."""
    site, region_graph = lab
    truth = walk(duration)
    tracks = truth.rename({"target": "track"}).with_columns(tracker=pl.lit("est"), x=pl.col("x") + 0.1)
    regions = tables.conform(
        truth.filter(pl.col("target") == "target1")
        .with_columns(
            tracker=pl.lit("beams"),
            track=pl.lit("agent1"),
            region=pl.Series([region_graph.names[int(i) % len(region_graph.names)] for i in range(truth.height // 2)]),
        )
        .select("tracker", "track", "t", "region"),
        tables.TRACKS,
    )
    scores = tracks.select("track", "t", error=pl.col("x") * 0.0 + 0.1, target=pl.col("track"))
    out = tmp_path / f"d{int(duration)}"
    with stage_recording(out, "all", RUN_ID) as rec:
        log_truth(rec, truth, diagonal=site.diagonal)
        log_point_tracks(rec, "est", tracks)
        log_region_tracks(rec, "beams", regions, region_graph)
        log_scores(rec, "est", scores)
    return (out / "rrd" / "all.rrd").stat().st_size


def test_recording_size_grows_linearly_with_duration(tmp_path, lab):
    """Doubling the duration adds as many bytes as the previous doubling did: no term grows
    faster than the number of samples (the old "path so far" grew with its square)."""
    sizes = {d: record(tmp_path, d, lab) for d in (60.0, 120.0, 240.0, 480.0)}
    step1 = sizes[120.0] - sizes[60.0]  # 60 s more
    step2 = (sizes[240.0] - sizes[120.0]) / 2  # per 60 s
    step3 = (sizes[480.0] - sizes[240.0]) / 4  # per 60 s
    assert step1 > 0
    for step in (step2, step3):
        assert 0.8 < step / step1 < 1.2, sizes
    per_sample = step3 / (60.0 * HZ * 2)  # two targets, two tracks, one region track, scores
    assert per_sample < 400, f"{per_sample:.0f} bytes per sample and target"


def test_trail_is_one_segment_per_sample_and_the_path_is_whole(tmp_path):
    t = np.arange(0.0, 30.0, 0.5)
    xy = np.c_[t, np.sin(t)]
    with stage_recording(tmp_path, "m", RUN_ID) as rec:
        log_moving(rec, "est/tracks/a", t, xy, label="track 1", color=(255, 0, 0, 255))
    f = tmp_path / "rrd" / "m.rrd"
    assert rrd.entity_paths(f) >= {"est/tracks/a", "est/tracks/a/trail", "est/tracks/a/path"}
    strips = rrd.component_rows(f, "est/tracks/a/trail", "LineStrips2D:strips")
    assert len(strips) == len(t) - 1 and all(len(row) == 1 and len(row[0]) == 2 for row in strips)
    assert np.allclose(strips[-1][0], xy[-2:])  # the newest segment ends at the newest sample
    path = rrd.component_rows(f, "est/tracks/a/path", "LineStrips2D:strips")
    assert len(path) == 1 and np.allclose(path[0][0], xy)  # one static strip: the whole path
    assert rrd.component_rows(f, "est/tracks/a", "Points2D:labels") == [["track 1"]]


def test_segments_shapes():
    assert segments(np.zeros((0, 2))).shape == (0, 2, 2)
    assert segments(np.zeros((1, 2))).shape == (0, 2, 2)
    s = segments(np.arange(6.0).reshape(3, 2))
    assert s.shape == (2, 2, 2) and (s[0, 1] == s[1, 0]).all()


def test_marker_size_follows_the_site():
    assert marker_size(np.zeros((3, 2)), diagonal=10.0) == pytest.approx(0.12)
    assert marker_size(np.array([[0.0, 0.0], [3.0, 4.0]])) == pytest.approx(0.06)


def test_truth_is_a_neutral_ring_and_an_estimate_a_dot_in_its_tracker_colour(tmp_path):
    truth = walk(5.0, targets=1)
    with stage_recording(tmp_path, "c", RUN_ID) as rec:
        log_truth(rec, truth)
        log_point_tracks(rec, "beams", truth.rename({"target": "track"}))
    f = tmp_path / "rrd" / "c.rrd"
    ring = rrd.entity_archetypes(f)[paths.truth("target1")]
    assert "Ellipses2D" in ring  # hollow
    truth_rgba = rrd.component_rows(f, "truth/target1", "Ellipses2D:colors")[0][0]
    est_rgba = rrd.component_rows(f, "beams/tracks/target1", "Points2D:colors")[0][0]
    assert truth_rgba != est_rgba
    # same id, different names: the estimate does not pretend to be the target
    assert rrd.component_rows(f, "beams/tracks/target1", "Points2D:labels") == [["beams estimate"]]
    assert rrd.component_rows(f, "truth/target1", "Points2D:labels") == [["target1"]]


def test_an_ended_track_is_cleared_one_step_after_its_last_row(tmp_path):
    """binpf's map kept 40-150 stale ``track N`` labels while one track was alive: a track's
    dot (and so its label) is cleared when it ends; a track alive to the end is cleared after."""
    walks = walk(6.0, targets=2).rename({"target": "track"})
    tracks = walks.filter((pl.col("track") == "target2") | (pl.col("t") < 2.0))  # target1 ends at 1.9 s
    with stage_recording(tmp_path, "c", RUN_ID) as rec:
        log_point_tracks(rec, "binpf", tracks)
    f = tmp_path / "rrd" / "c.rrd"
    first = rrd.timed_rows(f, "binpf/tracks/target1", "Clear:is_recursive")
    assert [(round(t, 6), v) for t, v in first] == [(2.0, [False])]  # one step (0.1 s) after 1.9 s
    last = rrd.timed_rows(f, "binpf/tracks/target2", "Clear:is_recursive")
    assert [round(t, 6) for t, _ in last] == [round(float(walks["t"].max()) + 0.1, 6)]
    assert rrd.timed_rows(f, "binpf/tracks/target1/path", "Clear:is_recursive") == []  # the whole path stays
