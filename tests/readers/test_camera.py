"""Overhead camera: render a synthetic video of the lab site, read it back, check it."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import polars as pl
import pytest

from onebit.core.errors import InputError
from onebit.core.tables import REJECTS, TRUTH
from onebit.datasets.builtin import builtin_site
from onebit.datasets.camera_render import render_overhead_video
from onebit.readers.camera import link_tracks, match_frames, read_camera, truth_error

RADIUS = 0.15  # ft
SECONDS = 20.0


@pytest.fixture(scope="module")
def site():
    return builtin_site("lab")


def lab_truth(site, seconds: float = SECONDS) -> pl.DataFrame:
    """Two agents in the lab's free space, far apart at all times.

    ``a`` walks back and forth along the top corridor (y = 3.5 ft, x in [0.5, 5.0]);
    ``b`` circles in the right-hand room (centre (4.6, 1.2) ft, radius 0.6 ft, period 8 s).
    """
    cam = site.camera
    t = cam.t0 + np.arange(round(seconds * cam.fps)) / cam.fps
    ax = 0.5 + 4.5 * np.abs((t / 10.0) % 2.0 - 1.0)
    phase = 2 * np.pi * t / 8.0
    a = pl.DataFrame({"t": t, "target": "a", "x": ax, "y": np.full_like(t, 3.5)})
    b = pl.DataFrame({"t": t, "target": "b", "x": 4.6 + 0.6 * np.cos(phase), "y": 1.2 + 0.6 * np.sin(phase)})
    return pl.concat([a, b]).sort("t", "target")


@pytest.fixture(scope="module")
def rendered(site, tmp_path_factory):
    truth = lab_truth(site)
    path = tmp_path_factory.mktemp("cam") / "camera.mp4"
    n = render_overhead_video(path, site, truth, seed=7, radius=RADIUS)
    return path, truth, n


@pytest.fixture(scope="module")
def result(site, rendered):
    return read_camera(rendered[0], site)


def decoded(path) -> np.ndarray:
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        frames.append(img)
    cap.release()
    return np.stack(frames)


# --------------------------------------------------------------------------- round trip


def test_all_frames_written_and_read(rendered, result):
    path, truth, n = rendered
    assert n == truth["t"].n_unique() == 200
    assert result.frames == n
    assert result.rejects.height == 0


def test_schemas(result):
    assert result.truth.schema == TRUTH
    assert result.rejects.schema == REJECTS
    assert dict(result.detections.schema) == {
        "frame": pl.Int64,
        "t": pl.Float64,
        "x": pl.Float64,
        "y": pl.Float64,
        "area": pl.Int64,
    }
    assert result.truth["t"].is_sorted()
    assert result.truth["region"].null_count() == result.truth.height


def test_error_small_relative_to_diagonal(site, rendered, result):
    err = truth_error(result.truth, rendered[1], diagonal=site.diagonal)
    assert err["rel"] < 0.02
    assert err["rel"] == pytest.approx(err["mean"] / site.diagonal)
    assert err["matched"] == rendered[1].height
    assert err["missed"] == 0
    assert err["extra"] == 0


def test_track_count_equals_agent_count(rendered, result):
    assert sorted(result.truth["target"].unique()) == ["cam1", "cam2"]
    assert result.truth["target"].n_unique() == rendered[1]["target"].n_unique()


def test_identities_are_stable(rendered, result):
    m = match_frames(result.truth, rendered[1]).drop_nulls()
    pairs = m.select("camera", "target").unique()
    assert pairs["camera"].is_unique().all()
    assert pairs["target"].is_unique().all()
    # birth order: cam1 is the first blob in raster order at t=0 (agent a, top corridor)
    assert dict(zip(pairs["camera"], pairs["target"])) == {"cam1": "a", "cam2": "b"}


def test_detection_times_are_frame_times(site, result):
    d = result.detections
    assert np.allclose(d["t"].to_numpy(), site.camera.t0 + d["frame"].to_numpy() / site.camera.fps)


# --------------------------------------------------------------------------- determinism


def test_video_is_deterministic_for_a_seed(site, rendered, tmp_path):
    again = tmp_path / "again.mp4"
    other = tmp_path / "other.mp4"
    truth = rendered[1].filter(pl.col("t") < 3.0)
    render_overhead_video(again, site, truth, seed=7, radius=RADIUS)
    render_overhead_video(other, site, truth, seed=8, radius=RADIUS)
    first = tmp_path / "first.mp4"
    render_overhead_video(first, site, truth, seed=7, radius=RADIUS)
    assert np.array_equal(decoded(first), decoded(again))
    assert first.read_bytes() == again.read_bytes()
    assert not np.array_equal(decoded(first), decoded(other))


def test_render_leaves_no_temp_file(rendered):
    assert [p.name for p in rendered[0].parent.iterdir()] == ["camera.mp4"]


# --------------------------------------------------------------------------- bad input


def test_random_bytes_is_input_error(site, tmp_path):
    path = tmp_path / "noise.mp4"
    path.write_bytes(np.random.default_rng(0).integers(0, 256, 50_000, dtype=np.uint8).tobytes())
    with pytest.raises(InputError, match="noise.mp4"):
        read_camera(path, site)


def test_truncated_mp4_is_input_error(site, rendered, tmp_path):
    path = tmp_path / "cut.mp4"
    data = rendered[0].read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="cut.mp4"):
        read_camera(path, site)


def test_missing_file_is_input_error(site, tmp_path):
    with pytest.raises(InputError, match="absent.mp4.*not found"):
        read_camera(tmp_path / "absent.mp4", site)


def test_zero_frame_video_is_input_error(site, tmp_path):
    path = tmp_path / "empty.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (330, 254))
    writer.release()
    if not path.exists():
        path.write_bytes(b"")
    with pytest.raises(InputError, match="empty.mp4"):
        read_camera(path, site)


def test_decode_failure_part_way_keeps_frames_and_rejects(site, tmp_path):
    # AVI can be read without its trailing index, so a truncated AVI decodes part way.
    full = tmp_path / "full.avi"
    truth = lab_truth(site, seconds=5.0)
    n = render_overhead_video(full, site, truth, seed=1, radius=RADIUS)
    cut = tmp_path / "cut.avi"
    data = full.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    res = read_camera(cut, site)
    assert 0 < res.frames < n
    assert res.rejects.height == 1
    row = res.rejects.row(0, named=True)
    assert row["source"] == "cut.avi"
    assert row["line"] == res.frames
    assert "decoding stopped" in row["reason"]
    assert res.truth["t"].max() < truth["t"].max()


@pytest.mark.parametrize(("field", "value"), [("width", 320), ("height", 240)])
def test_size_mismatch_is_refused(site, rendered, field, value):
    other = dataclasses.replace(site, camera=dataclasses.replace(site.camera, **{field: value}))
    with pytest.raises(InputError, match=f"camera.{field}") as info:
        read_camera(rendered[0], other)
    assert info.value.field == f"camera.{field}"
    assert "camera.mp4" in str(info.value)


def test_render_refuses_empty_truth(site, tmp_path):
    empty = pl.DataFrame(schema={"t": pl.Float64, "target": pl.String, "x": pl.Float64, "y": pl.Float64})
    with pytest.raises(InputError):
        render_overhead_video(tmp_path / "x.mp4", site, empty, seed=0, radius=RADIUS)
    assert not (tmp_path / "x.mp4").exists()


# --------------------------------------------------------------------------- pieces


def test_link_tracks_births_gaps_and_deaths():
    # one target moving +0.1 per frame, absent in frames 3-4 (gap 3 <= max_gap) then
    # absent for frames 10-19 (gap 11 > max_gap): a new track is born at frame 20.
    frames = np.array([0, 1, 2, 5, 6, 7, 8, 9, 20, 21])
    xy = np.c_[0.1 * frames, np.zeros(len(frames))]
    track = link_tracks(frames, xy, gate=0.15, max_gap=5)
    assert track.tolist() == [0, 0, 0, 0, 0, 0, 0, 0, 1, 1]


def test_link_tracks_assignment_resolves_close_pairs():
    # two targets 0.2 apart moving in parallel; greedy nearest would be ambiguous at frame 1
    frames = np.array([0, 0, 1, 1])
    xy = np.array([[0.0, 0.0], [0.0, 0.2], [0.09, 0.11], [0.09, 0.3]])
    assert link_tracks(frames, xy, gate=0.2, max_gap=5).tolist() == [0, 1, 0, 1]


def test_truth_error_counts_missed(site, rendered, result):
    dropped = result.truth.filter(~((pl.col("target") == "cam2") & (pl.col("t") < 1.0)))
    err = truth_error(dropped, rendered[1], diagonal=site.diagonal)
    assert err["missed"] == 10
    assert err["matched"] == rendered[1].height - 10


def test_video_without_agents_gives_empty_tables(site, tmp_path):
    path = tmp_path / "empty_scene.mp4"
    t = np.arange(20) / site.camera.fps
    outside = pl.DataFrame({"t": t, "target": "ghost", "x": np.full_like(t, -50.0), "y": np.full_like(t, -50.0)})
    assert render_overhead_video(path, site, outside, seed=3, radius=RADIUS) == 20
    res = read_camera(path, site)
    assert res.frames == 20
    assert res.truth.height == 0 and res.truth.schema == TRUTH
    assert res.detections.height == 0


def test_streamed_reader_equals_the_whole_stack_pipeline(site, rendered):
    """read_camera decodes twice and never holds the video; the helpers on the whole stack
    (decode_frames, frame_gains, background_model, noise_threshold, find_blobs) give the
    same detections."""
    from onebit.readers.camera import background_model, decode_frames, find_blobs, frame_gains, noise_threshold

    path, _, _ = rendered
    res = read_camera(path, site)
    stack, rejects = decode_frames(path, site.camera)
    gains = frame_gains(stack)
    bg = background_model(stack, gains)
    frame, uv, area = find_blobs(stack, gains, bg, noise_threshold(stack, gains, bg))
    keep = area >= max(6, 0.25 * float(np.median(area)))
    assert res.frames == len(stack) and res.rejects.equals(rejects)
    np.testing.assert_array_equal(res.detections["frame"].to_numpy(), frame[keep])
    np.testing.assert_array_equal(res.detections["area"].to_numpy(), area[keep])
