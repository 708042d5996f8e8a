"""binpf's joint update of close tracks (``joint.py``, Eqs. (11)-(13)): each equation against a
brute-force enumeration, and the filter on generated close pairs and on one person."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from onebit.core.errors import ConfigError
from onebit.trackers.binpf.config import BinPFConfig
from onebit.trackers.binpf.filter import (
    FilterParams,
    footprint_probability,
    frame_probability_off,
    observation_update,
    run_filter,
)
from onebit.trackers.binpf.joint import (
    close_pairs,
    met_matrix,
    met_update,
    order_swaps,
    pair_existence,
    pair_likelihoods,
)

# the split's dense array (tests/trackers/binpf/test_filter.py): sensors every 0.5 m, footprints 0.6 m
DENSE = np.stack(np.meshgrid(np.arange(0, 4.01, 0.5), np.arange(0, 3.01, 0.5)), -1).reshape(-1, 2)
DENSE_R = np.full(len(DENSE), 0.6)
DENSE_LO, DENSE_HI = np.array([0.0, 0.0]), np.array([4.0, 3.0])
SENSOR_MODEL = {"pd": 0.95, "pf": 0.002, "edge": 0.1}


def _brute_pair(xa, xb, m, z, sensors, radii, silent, p):
    """Eq. (11) with silence by enumeration: each present person silent or not, the frame's
    probability sensor by sensor, relative to nobody present."""

    def frame_prob(people):
        off = m.copy()
        for x in people:
            off = off * frame_probability_off(x[None], sensors, radii, pd=p.pd, pf=0.0, edge=p.edge)
        return np.prod(np.where(z, 1.0 - off, off))

    def present(people):
        total = 0.0
        for quiet in itertools.product([False, True], repeat=len(people)):
            w = np.prod([silent if q else 1.0 - silent for q in quiet])
            total += w * frame_prob([x for x, q in zip(people, quiet) if not q])
        return total / frame_prob([])

    return present([xa, xb]), present([xa]), present([xb])


@pytest.mark.parametrize("seed", range(4))
def test_pair_likelihoods_equal_the_enumeration_of_who_is_silent(seed):
    rng = np.random.default_rng(seed)
    p = FilterParams(**SENSOR_MODEL)
    sensors, radii = DENSE[:12], DENSE_R[:12]
    z = rng.random(len(sensors)) < 0.4
    m = (1.0 - p.pf) * rng.uniform(0.5, 1.0, len(sensors))  # the other tracks' miss
    xa, xb = rng.uniform(0, 2, (3, 2)), rng.uniform(0, 2, (3, 2))
    silent = [0.0, 0.2, 0.3, 0.6][seed]
    da = footprint_probability(xa, sensors, radii, pd=p.pd, edge=p.edge)
    db = footprint_probability(xb, sensors, radii, pd=p.pd, edge=p.edge)
    got = pair_likelihoods(da, db, m, z, silent)
    for n in range(3):
        want = _brute_pair(xa[n], xb[n], m, z, sensors, radii, silent, p)
        np.testing.assert_allclose([g[n] for g in got], want, rtol=1e-9)


def test_pair_existence_is_the_bernoulli_update_when_the_partner_is_absent():
    """Eq. (12) with r_b = 0 is Eq. (5) of a track alone."""
    rng = np.random.default_rng(3)
    p = FilterParams(**SENSOR_MODEL, silent=0.3)
    z = rng.random(len(DENSE)) < 0.2
    x = np.c_[rng.uniform(0, 3, (1, 50, 2)), np.zeros((1, 50, 2))]
    _, r_alone = observation_update(x, np.array([0.4]), z, DENSE, DENSE_R, p)
    d = footprint_probability(x[0, :, :2], DENSE, DENSE_R, pd=p.pd, edge=p.edge)
    lam = pair_likelihoods(d, d[::-1], np.full(len(DENSE), 1.0 - p.pf), z, p.silent)
    ra, rb = pair_existence(0.4, 0.0, *lam)
    assert ra == pytest.approx(r_alone[0], rel=1e-9) and rb == 0.0
    # symmetric in the two tracks
    ra2, rb2 = pair_existence(0.7, 0.2, *lam)
    rb3, ra3 = pair_existence(0.2, 0.7, lam[0], lam[2], lam[1])
    assert (ra2, rb2) == pytest.approx((ra3, rb3))


def test_close_pairs_take_confirmed_tracks_first_then_the_closest_each_once():
    means = np.array([[0.0, 0.0], [0.9, 0.0], [0.3, 0.0], [5.0, 0.0], [5.5, 0.0]])
    assert close_pairs(means, 1.0) == [(0, 2), (3, 4)]
    confirmed = np.array([True, True, False, False, False])
    assert close_pairs(means, 1.0, first=confirmed) == [(0, 1), (3, 4)]
    assert close_pairs(means, 1.0, skip=np.array([False, False, False, True, False])) == [(0, 2)]
    assert close_pairs(means, 0.2) == [] and close_pairs(means[:1], 1.0) == []


def test_ordering_puts_each_member_on_its_tracks_side_of_the_pairs_line():
    rng = np.random.default_rng(0)
    left, right = np.array([1.75, 1.5]), np.array([2.25, 1.5])
    flip = rng.random(200) < 0.5  # the joint particles hold the two people in either order
    xa = np.where(flip[:, None], right, left) + 0.05 * rng.standard_normal((200, 2))
    xb = np.where(flip[:, None], left, right) + 0.05 * rng.standard_normal((200, 2))
    swap = order_swaps(xa - xb, side=np.array([-0.1, 0.3]))  # track a a little left (and above)
    a = np.where(swap[:, None], xb, xa)
    b = np.where(swap[:, None], xa, xb)
    assert np.abs(a.mean(axis=0) - left).max() < 0.05 and np.abs(b.mean(axis=0) - right).max() < 0.05


def _meeting(T=36, seed=0):
    """Two people 2.5 m apart walk towards each other for 12 frames, then stand 0.5 m apart;
    levels from Eq. (2) on the dense array."""
    rng = np.random.default_rng(seed)
    t = np.clip(np.arange(T) / 11, 0, 1)
    people = np.stack([np.c_[0.75 + t, np.full(T, 1.5)], np.c_[3.25 - t, np.full(T, 1.5)]], axis=1)
    p_off = np.stack([frame_probability_off(people[k], DENSE, DENSE_R, **SENSOR_MODEL) for k in range(T)])
    return people, rng.random(p_off.shape) > p_off


def _run(on, seed, **kw):
    p = FilterParams(**SENSOR_MODEL, particles=200, period=0.5, max_out=3, max_tracks=4, **kw)
    res = run_filter(on, DENSE, DENSE_R, DENSE_LO, DENSE_HI, p, seed=seed)
    return res, np.bincount(res.frame[res.reported], minlength=len(on))


@pytest.mark.parametrize("met", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_two_people_who_meet_half_a_metre_apart_stay_two_tracks(seed, met):
    """The mean-field filter merges the two tracks once the people stand 0.5 m apart; the joint
    update keeps both, each within 0.4 m of a person, for most of the 24 frames -- also when only
    pairs that met are joint (``joint_met``, Eq. (14): both tracks were confirmed 2.5 m apart)."""
    people, on = _meeting(seed=seed)
    _, without = _run(on, seed)
    assert (without[12:] == 2).sum() == 0  # the limitation the joint update removes
    res, count = _run(on, seed, joint_distance=1.5, joint_ratio=2.0, joint_met=met)
    assert count.max() <= 2
    held = 0
    for k in range(12, len(on)):
        m = (res.frame == k) & res.reported
        if m.sum() == 2:
            est = np.c_[res.x[m], res.y[m]]
            d = np.sqrt(((people[k][:, None] - est[None]) ** 2).sum(-1))
            held += int(d.min(axis=1).max() < 0.4)
    assert held >= 18


@pytest.mark.parametrize("seed", range(3))
def test_one_person_stays_one_track_with_the_joint_update(seed):
    rng = np.random.default_rng(seed)
    p_off = frame_probability_off(np.array([[2.0, 1.5]]), DENSE, DENSE_R, **SENSOR_MODEL)
    on = rng.random((30, len(DENSE))) > p_off[None, :]
    _, count = _run(on, seed, joint_distance=1.5, joint_ratio=2.0)
    assert count.max() == 1 and (count == 1).sum() >= 25


def test_the_joint_update_is_batch_only():
    with pytest.raises(ConfigError, match="joint_distance"):
        BinPFConfig(joint_distance=1.5, commit_lag=6)
    assert BinPFConfig(joint_distance=1.5).joint_ratio == 2.0
    with pytest.raises(ConfigError, match="joint_ratio"):
        BinPFConfig(joint_ratio=0.5)


def test_the_stage_runs_the_joint_update_and_follow_refuses_it():
    from onebit.core.tables import TRACKS
    from onebit.trackers.binpf.stage import run, start_follow
    from tests.trackers.binpf.test_stage import _frames, _site

    frames, _ = _frames(T=30)
    out = run({"proximity_frames": frames}, _site(3), BinPFConfig(particles=80, joint_distance=1.5))
    assert out["tracks"].schema == TRACKS and out["tracks"].height > 0
    assert out["tracks"].group_by("t").len()["len"].max() <= 3
    with pytest.raises(ConfigError, match="joint_distance"):
        start_follow(_site(2), BinPFConfig(joint_distance=1.5))


@pytest.mark.parametrize("seed", range(3))
def test_two_people_standing_half_a_metre_apart_are_mostly_two_tracks(seed):
    """Born as one group, the pair gets a second track from a newborn beside the first that the
    joint update keeps; without it one track explains both (test_filter's split case)."""
    rng = np.random.default_rng(seed)
    p_off = frame_probability_off(np.array([[1.75, 1.5], [2.25, 1.5]]), DENSE, DENSE_R, **SENSOR_MODEL)
    on = rng.random((30, len(DENSE))) > p_off[None, :]
    _, without = _run(on, seed)
    assert without.max() == 1
    _, count = _run(on, seed, joint_distance=1.5, joint_ratio=2.0)
    assert count.max() <= 2 and (count == 2).sum() >= 15


def test_close_pairs_take_only_the_allowed_pairs():
    means = np.array([[0.0, 0.0], [0.3, 0.0], [0.9, 0.0]])
    allow = np.zeros((3, 3), bool)
    allow[0, 2] = allow[2, 0] = True
    assert close_pairs(means, 1.0) == [(0, 1)]
    assert close_pairs(means, 1.0, allow=allow) == [(0, 2)]
    assert close_pairs(means, 1.0, allow=np.zeros((3, 3), bool)) == []


def test_a_pair_meets_only_when_confirmed_and_apart_before_it_came_close():
    """Eq. (14): tracks 0 and 1 confirmed 2 m apart, then 0.5 m: met. Track 2 born 0.5 m from 0
    and confirmed later, then 2 m away and back: never met. A dead label leaves the sets."""
    labels = np.array([0, 1, 2])
    conf = np.array([True, True, False])
    far, near = met_update(labels, np.array([[0.0, 0], [2.0, 0], [0.5, 0]]), conf, 1.0, set(), set())
    assert far == {frozenset((0, 1))} and near == {frozenset((0, 2))}
    conf = np.array([True, True, True])
    far, near = met_update(labels, np.array([[0.0, 0], [0.5, 0], [2.5, 0]]), conf, 1.0, far, near)
    assert frozenset((0, 1)) in far and frozenset((0, 2)) in near and frozenset((1, 2)) in far
    far, near = met_update(labels, np.array([[0.0, 0], [0.5, 0], [0.3, 0]]), conf, 1.0, far, near)
    met = met_matrix(labels, far)
    assert met[0, 1] and met[1, 0] and not met[0, 2] and met[1, 2] and not met.diagonal().any()
    far, near = met_update(np.array([0, 2]), np.array([[0.0, 0], [3.0, 0]]), conf[:2], 1.0, far, near)
    assert far == set() and near == {frozenset((0, 2))}
    # two tentative tracks apart are not a meeting
    far, near = met_update(labels, np.array([[0.0, 0], [2.0, 0], [4.0, 0]]), np.zeros(3, bool), 1.0, set(), set())
    assert far == set() and near == set()


# a sparse array like the real one: sensors every 0.8 m, footprints 0.8 m with a soft edge
SPARSE = np.stack(np.meshgrid(np.arange(0, 8.01, 0.8), np.arange(0, 4.01, 0.8)), -1).reshape(-1, 2)
SPARSE_R = np.full(len(SPARSE), 0.8)
SOFT = {"pd": 0.75, "pf": 0.005, "edge": 0.3}


def _sluggish_walk(T=40, seed=0):
    """One person walking to and fro at 0.8 m/s; a sensor stays on a frame after the person
    passed (the real array's sluggish sensors), so two or three sensors fire, one behind."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) * 0.5
    x = 1.0 + (0.8 * t) % 12
    x = np.where(x > 7, 14 - x, x)
    pos = np.c_[x, 2.0 + 0.3 * np.sin(t / 3)]
    off = np.stack([frame_probability_off(pos[k][None], SPARSE, SPARSE_R, **SOFT) for k in range(T)])
    off[1:] *= np.stack([frame_probability_off(pos[k - 1][None], SPARSE, SPARSE_R, **SOFT) for k in range(1, T)])
    return rng.random(off.shape) > off


@pytest.mark.parametrize("seed", range(3))
def test_one_walker_firing_two_sensors_keeps_one_track_with_joint_met(seed):
    """The joint update of every close pair keeps a newborn beside the walker as a second track
    (measured: two tracks in 27-28 of the 40 frames); with ``joint_met`` the newborn never met the
    walker's track and the filter is the mean field's (two tracks in at most 8 frames, as without
    the joint update)."""
    on = _sluggish_walk(seed=seed)

    def two(**kw):
        p = FilterParams(**SOFT, particles=200, period=0.5, max_out=3, max_tracks=4, **kw)
        res = run_filter(on, SPARSE, SPARSE_R, np.array([0.0, 0.0]), np.array([8.0, 4.0]), p, seed=seed)
        return int((np.bincount(res.frame[res.reported], minlength=len(on)) >= 2).sum())

    without = two()
    assert two(joint_distance=1.5, joint_ratio=2.0) >= 20  # the failure joint_met removes
    assert two(joint_distance=1.5, joint_ratio=2.0, joint_met=True) == without <= 10


def test_joint_met_needs_the_joint_update():
    with pytest.raises(ConfigError, match="joint_met"):
        BinPFConfig(joint_met=True)
    assert BinPFConfig(joint_met=True, joint_distance=1.1).joint_met
