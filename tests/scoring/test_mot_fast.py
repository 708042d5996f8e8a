"""The fast MOT scorer equals motmetrics and TrackEval driven frame by frame
(:func:`onebit.scoring.mot.mot_metrics_libraries`) on random small scenes: ties at the gate,
integer (hop) distances, appearing and disappearing ids, frames with no estimate or no truth,
pairs with no distance; its compiled kernels equal their plain Python."""

from __future__ import annotations

import math

import numpy as np
import polars as pl
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.scoring import mot_kernels
from onebit.scoring.mot import clear_counts, frame_arrays, hota_curves, mot_metrics, mot_metrics_libraries

#: distances drawn from: exact ties, the gate itself (1.0), beyond it, far beyond the HOTA range
LEVELS = (0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0)


@st.composite
def scenes(draw, hops: bool):
    n_frames = draw(st.integers(1, 14))
    n_targets = draw(st.integers(1, 4))
    n_tracks = draw(st.integers(0, 5))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    p_obj, p_hyp, p_missing = draw(st.floats(0.2, 1.0)), draw(st.floats(0.0, 1.0)), draw(st.floats(0.0, 0.3))
    obj, hyp, dist = [], [], []
    for f in range(n_frames):
        t = float(f) / 2
        o = [f"g{g}" for g in range(n_targets) if rng.random() < p_obj]
        h = [f"k{k}" for k in range(n_tracks) if rng.random() < p_hyp]
        obj += [(t, g) for g in o]
        hyp += [(t, k) for k in h]
        for g in o:
            for k in h:
                if rng.random() < p_missing:
                    continue  # no distance: cannot match
                d = float(rng.choice(LEVELS)) if hops or rng.random() < 0.4 else float(rng.uniform(0, 2.5))
                dist.append((t, g, k, d))
    objects = pl.DataFrame(obj, schema={"t": pl.Float64, "target": pl.String}, orient="row")
    hypotheses = pl.DataFrame(hyp, schema={"t": pl.Float64, "track": pl.String}, orient="row")
    distances = pl.DataFrame(
        dist, schema={"t": pl.Float64, "target": pl.String, "track": pl.String, "distance": pl.Float64}, orient="row"
    )
    gate = draw(st.sampled_from([0.5, 1.0, 2.0]))
    return objects, hypotheses, distances, gate


def assert_same(fast: dict, ref: dict) -> None:
    assert fast.keys() == ref.keys()
    for k in fast:
        a, b = fast[k], ref[k]
        assert (math.isnan(a) and math.isnan(b)) or abs(a - b) <= 1e-9, (k, a, b)


@settings(max_examples=50, deadline=None, derandomize=True)
@given(scenes(hops=True))
def test_equals_the_libraries_on_scenes_full_of_ties(scene):
    objects, hypotheses, distances, gate = scene
    assert_same(
        mot_metrics(objects, hypotheses, distances, gate=gate),
        mot_metrics_libraries(objects, hypotheses, distances, gate=gate),
    )


@settings(max_examples=50, deadline=None, derandomize=True)
@given(scenes(hops=False))
def test_equals_the_libraries_on_scenes_with_continuous_distances(scene):
    objects, hypotheses, distances, gate = scene
    assert_same(
        mot_metrics(objects, hypotheses, distances, gate=gate),
        mot_metrics_libraries(objects, hypotheses, distances, gate=gate),
    )


@settings(max_examples=60, deadline=None, derandomize=True)
@given(scenes(hops=True))
def test_the_compiled_kernels_equal_their_plain_python(scene):
    objects, hypotheses, distances, gate = scene
    fa = frame_arrays(objects, hypotheses, distances)
    fast, fast_sum = clear_counts(fa, gate)
    plain, plain_sum = clear_counts(fa, gate, compiled=False)
    assert fast.tolist() == plain.tolist() and fast_sum == plain_sum
    fast, plain = hota_curves(fa, gate), hota_curves(fa, gate, compiled=False)
    for k in fast:
        np.testing.assert_array_equal(fast[k], plain[k])


def test_a_silent_tracker_misses_every_target_frame():
    objects = pl.DataFrame({"t": [0.0, 0.0, 1.0, 2.0], "target": ["a", "b", "a", "b"]})
    none = pl.DataFrame(schema={"t": pl.Float64, "track": pl.String})
    dist = pl.DataFrame(schema={"t": pl.Float64, "target": pl.String, "track": pl.String, "distance": pl.Float64})
    m = mot_metrics(objects, none, dist, gate=1.0)
    assert m["misses"] == 4 and m["mota"] == 0.0 and m["hota"] == 0.0 and m["idf1"] == 0.0
    assert_same(m, mot_metrics_libraries(objects, none, dist, gate=1.0))


def test_crowded_frames_are_handed_to_the_solvers_and_still_equal():
    """10 targets and 10 tracks all within the gate of each other: too many matchings to
    enumerate, so every frame goes to the libraries' own solvers."""
    rng = np.random.default_rng(3)
    rows = [
        (float(t), f"g{g}", f"k{k}", float(rng.uniform(0, 0.9))) for t in range(6) for g in range(10) for k in range(10)
    ]
    distances = pl.DataFrame(rows, schema=["t", "target", "track", "distance"], orient="row")
    objects = distances.select("t", "target").unique()
    hypotheses = distances.select("t", "track").unique()
    fa = frame_arrays(objects, hypotheses, distances)
    choice = np.empty(10, np.int64)
    w = fa.d[fa.d_ptr[0] : fa.d_ptr[1]]
    status = mot_kernels.best_matching(w, w <= 1.0, 10, 10, True, choice)
    assert status == mot_kernels.TOO_LARGE
    assert_same(
        mot_metrics(objects, hypotheses, distances, gate=1.0),
        mot_metrics_libraries(objects, hypotheses, distances, gate=1.0),
    )


def test_best_matching_finds_the_optimum_and_reports_ties():
    choice = np.empty(2, np.int64)
    w = np.array([0.2, 0.9, 0.8, 0.1])  # rows x cols 2x2: diagonal (0.3) beats anti-diagonal (1.7)
    assert mot_kernels.best_matching(w, np.ones(4, bool), 2, 2, True, choice) == mot_kernels.UNIQUE
    assert choice.tolist() == [0, 1]
    tie = np.array([1.0, 1.0, 1.0, 1.0])
    assert mot_kernels.best_matching(tie, np.ones(4, bool), 2, 2, True, choice) == mot_kernels.AMBIGUOUS
    # by count: two pairs at 1.9 beat one pair at 0.1
    w = np.array([0.1, 0.9, 1.0, np.inf])
    ok = np.isfinite(w)
    assert mot_kernels.best_matching(w, ok, 2, 2, True, choice) == mot_kernels.UNIQUE
    assert choice.tolist() == [1, 0]
    # by weight (HOTA): one pair of 0.9 beats two pairs of 0.4 + 0.4
    w = np.array([0.4, 0.9, 0.0, 0.4])
    assert mot_kernels.best_matching(w, w > 0, 2, 2, False, choice) == mot_kernels.UNIQUE
    assert choice.tolist() == [1, -1]
    assert mot_kernels.best_matching.py_func(w, w > 0, 2, 2, False, choice) == mot_kernels.UNIQUE
    assert choice.tolist() == [1, -1]
