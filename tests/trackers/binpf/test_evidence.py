"""The evidence rule (``[binpf] evidence_ratio``, Eqs. (9)-(10)): a row's support is the chain
rule of Eq. (2), the window sum equals its loop, two close people keep two tracks, a second
track on one person and a track outliving its person are dropped."""

from __future__ import annotations

import numpy as np
import pytest

from onebit.core.errors import ConfigError
from onebit.trackers.binpf import evidence
from onebit.trackers.binpf.evidence import evidence_rows, row_support, window_support, window_support_reference
from onebit.trackers.binpf.footprint import frame_probability_off
from onebit.trackers.binpf.stage import BinPFConfig, run, start_follow
from tests.trackers.binpf.test_stage import XY, _frames, _site

# the split's dense array (docs/binpf-record.md): sensors every 0.5 m, footprints of 0.6 m
GRID = np.array([(0.5 * i, 0.5 * j) for i in range(9) for j in range(9)], dtype=float)
RADII = np.full(len(GRID), 0.6)
MODEL = {"pd": 0.95, "pf": 0.005, "edge": 0.1}


def _loglik(z: np.ndarray, people: np.ndarray) -> float:
    off = frame_probability_off(people.reshape(-1, 2), GRID, RADII, **MODEL)
    return float(np.where(z, np.log(1.0 - off), np.log(off)).sum())


def _levels(people_per_frame: list[np.ndarray], seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    off = np.stack([frame_probability_off(p.reshape(-1, 2), GRID, RADII, **MODEL) for p in people_per_frame])
    return rng.random(off.shape) > off


@pytest.mark.parametrize("silent", [0.0, 0.3])
def test_row_support_is_the_chain_rule_of_eq_2(silent):
    rng = np.random.default_rng(1)
    T, n = 6, 3
    frame = np.repeat(np.arange(T), n)
    r = rng.random(T * n)
    xy = rng.uniform(0.0, 4.0, (T * n, 2))
    on = rng.random((T, len(GRID))) < 0.2
    got = row_support(frame, r, xy, on, GRID, RADII, silent=silent, **MODEL)
    for k in range(T):
        rows = np.flatnonzero(frame == k)
        rows = rows[np.argsort(-r[rows], kind="stable")]
        for j, i in enumerate(rows):
            ratio = _loglik(on[k], xy[rows[: j + 1]]) - _loglik(on[k], xy[rows[:j]])
            want = np.log((1 - silent) * np.exp(ratio) + silent) if silent else ratio
            assert got[i] == pytest.approx(want, rel=1e-9, abs=1e-9)
        if not silent:  # the rows of a frame sum to all of them against none
            assert got[rows].sum() == pytest.approx(_loglik(on[k], xy[rows]) - _loglik(on[k], xy[:0]), rel=1e-9)


def test_row_support_is_the_same_in_small_blocks(monkeypatch):
    rng = np.random.default_rng(2)
    frame = np.sort(rng.integers(0, 30, 120))
    r, xy = rng.random(120), rng.uniform(0, 4, (120, 2))
    on = rng.random((30, len(GRID))) < 0.2
    whole = row_support(frame, r, xy, on, GRID, RADII, silent=0.3, **MODEL)
    monkeypatch.setattr(evidence, "BLOCK_CELLS", 3 * len(GRID))  # blocks of about 3 rows, ended on frames
    np.testing.assert_allclose(row_support(frame, r, xy, on, GRID, RADII, silent=0.3, **MODEL), whole, rtol=1e-12)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("h", [0, 1, 3])
def test_window_support_equals_the_loop(seed, h):
    rng = np.random.default_rng(seed)
    n = 60
    label = rng.integers(0, 5, n)
    frame = rng.integers(0, 25, n)
    keep = np.unique(np.c_[label, frame], axis=0, return_index=True)[1]  # one row per label and frame
    label, frame = label[keep], frame[keep]
    delta = rng.normal(size=label.size)
    np.testing.assert_allclose(
        window_support(frame, label, delta, h), window_support_reference(frame, label, delta, h), atol=1e-12
    )


def _select(frame, label, r, xy, on, **kw):
    return evidence_rows(
        frame, label, r, xy, on, GRID, RADII, candidates=np.ones(frame.size, bool), ratio=kw.get("ratio", 3.0),
        window=kw.get("window", 2), silent=0.3, max_out=kw.get("max_out", 0), **MODEL,
    )  # fmt: skip


@pytest.mark.parametrize("seed", range(3))
def test_two_people_half_a_metre_apart_keep_two_tracks(seed):
    T = 12
    a, b = np.array([2.0, 2.0]), np.array([2.5, 2.0])
    on = _levels([np.stack([a, b])] * T, seed)
    frame = np.repeat(np.arange(T), 2)
    label = np.tile([0, 1], T)
    r = np.tile([0.99, 0.9], T)
    xy = np.tile(np.stack([a, b]), (T, 1))
    rep = _select(frame, label, r, xy, on)
    assert rep[label == 0].all()
    assert rep[label == 1].mean() >= 0.9  # the second person's own firings support its track


@pytest.mark.parametrize("seed", range(3))
def test_a_second_track_on_one_person_is_dropped(seed):
    T = 12
    a = np.array([2.0, 2.0])
    on = _levels([a] * T, seed)
    frame = np.repeat(np.arange(T), 2)
    label = np.tile([0, 1], T)
    r = np.tile([0.99, 0.9], T)
    xy = np.tile(np.stack([a, a + [0.15, 0.0]]), (T, 1))
    rep = _select(frame, label, r, xy, on)
    assert rep[label == 0].all()
    assert not rep[label == 1].any()


def test_a_track_outliving_its_person_stops_window_frames_after_the_firings():
    T, left, h = 20, 10, 2
    a = np.array([2.0, 2.0])
    on = _levels([a] * T, 0)
    on[left:] = False  # the person left: every sensor off
    frame, label, r = np.arange(T), np.zeros(T, int), np.linspace(1.0, 0.6, T)
    rep = _select(frame, label, r, np.tile(a, (T, 1)), on, window=h)
    assert rep[:left].all()
    assert not rep[left + h :].any()


def test_at_most_max_out_rows_a_frame_the_largest_existence_first():
    T = 8
    people = np.array([[1.0, 1.0], [3.0, 3.0], [1.0, 3.0]])
    on = _levels([people] * T, 0)
    frame, label = np.repeat(np.arange(T), 3), np.tile([0, 1, 2], T)
    r = np.tile([0.7, 0.99, 0.8], T)
    rep = _select(frame, label, r, np.tile(people, (T, 1)), on, max_out=2)
    assert rep[label != 0].all()
    assert not rep[label == 0].any()


def test_rows_outside_the_candidates_are_never_reported_nor_counted():
    T = 6
    a = np.array([2.0, 2.0])
    on = _levels([a] * T, 0)
    frame, label = np.repeat(np.arange(T), 2), np.tile([0, 1], T)
    r = np.tile([0.5, 0.99], T)  # the non-candidate track would rank first and explain the firings
    xy = np.tile(np.stack([a, a]), (T, 1))
    cand = label == 0
    rep = evidence_rows(frame, label, r, xy, on, GRID, RADII, candidates=cand, ratio=3.0, window=2, silent=0.3, **MODEL)
    assert rep[cand].all() and not rep[~cand].any()


def test_the_evidence_rule_is_batch_only_and_its_ratio_positive():
    with pytest.raises(ConfigError, match="evidence_ratio"):
        BinPFConfig(evidence_ratio=3.0, commit_lag=6)
    with pytest.raises(ConfigError, match="evidence_ratio"):
        start_follow(_site(2), BinPFConfig(evidence_ratio=3.0))
    with pytest.raises(ValueError, match="ratio"):
        evidence_rows(
            np.zeros(1, int), np.zeros(1, int), np.ones(1), np.zeros((1, 2)), np.zeros((1, len(GRID)), bool),
            GRID, RADII, candidates=np.ones(1, bool), ratio=0.0, window=2, silent=0.3, **MODEL,
        )  # fmt: skip


def test_the_stage_reports_the_rows_the_rule_selects_within_the_bound():
    """The stage tests' three walkers, two reported at most: the filter's rows are the rule's off."""
    frames, _ = _frames(T=30)
    off = run({"proximity_frames": frames}, _site(2), BinPFConfig(particles=80))
    on = run({"proximity_frames": frames}, _site(2), BinPFConfig(particles=80, evidence_ratio=1e3, evidence_window=0))
    ex_off, ex = off["existence"], on["existence"]
    assert ex.drop("reported").equals(ex_off.drop("reported"))  # the filter itself is unchanged
    once = ex["track"].is_in(ex_off.filter("reported")["track"].unique().implode()).to_numpy()
    lv = frames.sort("slot", "sensor").pivot(on="sensor", index="slot", values="on").drop("slot")
    levels = lv.select([f"s{k}" for k in range(len(XY))]).to_numpy()
    want = evidence_rows(
        ex["frame"].to_numpy(), ex["track"].to_numpy().astype(str), ex["r"].to_numpy(),
        ex.select("x", "y").to_numpy(), levels, XY, np.ones(len(XY)), candidates=once, ratio=1e3, window=0,
        pd=0.75, pf=0.01, edge=0.3, silent=0.3, max_out=2,
    )  # fmt: skip
    np.testing.assert_array_equal(ex["reported"].to_numpy(), want)
    assert on["tracks"].group_by("t").len()["len"].max() <= 2
    assert not np.array_equal(ex["reported"].to_numpy(), ex_off["reported"].to_numpy())
