"""Known residents (:mod:`onebit.trackers.residents.known`): the exact forward-backward against
enumeration, the profile's counts, and the residents stage decoding with a profile."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit._testing.oracles import posteriors_bruteforce
from onebit.core.errors import ConfigError, InputError
from onebit.core.tables import RESIDENTS_PROFILE
from onebit.scoring.identity import identity_scores
from onebit.trackers.residents import ResidentsConfig, run
from onebit.trackers.residents.known import (
    Chains,
    Clock,
    chains,
    clock_bonus,
    clock_of,
    learn_profile,
    posteriors,
)
from tests.trackers.residents.test_stage import corridor_home, motion_log


@settings(max_examples=60, deadline=None)
@given(
    k=st.integers(1, 3),
    s=st.integers(1, 4),
    n=st.integers(0, 6),
    seed=st.integers(0, 10_000),
    clock=st.booleans(),
)
def test_posteriors_equal_the_enumeration_of_every_firer_sequence(k, s, n, seed, clock):
    rng = np.random.default_rng(seed)
    ch = Chains(tuple(str(r) for r in range(k)), np.log(rng.dirichlet(np.ones(s), size=(k, s + 1))))
    node = rng.integers(0, s, n)
    bonus = rng.normal(size=(n, k)) if clock else None  # (K3): a factor per event and firer
    post, log_z = posteriors(node, ch, bonus)
    if n == 0:
        assert post.shape == (0, k)
        return
    ref, ref_z = posteriors_bruteforce(node, ch, bonus)
    np.testing.assert_allclose(post, ref, atol=1e-10)
    assert log_z == pytest.approx(ref_z, abs=1e-10)
    np.testing.assert_allclose(post.sum(axis=1), 1.0, atol=1e-10)


def _te(rows):
    return pl.DataFrame(rows, schema={"t": pl.Float64, "sensor": pl.String, "residents": pl.String}, orient="row")


def test_profile_counts_by_hand():
    a = _te([(0.0, "M1", "1"), (1.0, "M2", "2"), (2.0, "M2", "1;2"), (3.0, "M3", "1")])
    b = _te([(0.0, "M3", "1")])  # a new session: no transition from a's last event
    prof = learn_profile([a, b])
    assert prof.schema == RESIDENTS_PROFILE
    assert prof["bin"].null_count() == prof.height  # no clock asked: no binned rows
    got = {(r, f, t): c for r, f, t, c, _ in prof.iter_rows()}
    assert got == {
        ("1", None, "M1"): 1,
        ("1", None, "M2"): 1,
        ("1", None, "M3"): 2,
        ("1", "M1", "M2"): 1,
        ("1", "M2", "M3"): 1,
        ("2", None, "M2"): 2,
        ("2", "M2", "M2"): 1,
    }


def test_chains_are_distributions_and_fall_back_to_geometry():
    site, ids = corridor_home(4)
    from onebit.trackers.residents.stage import home_of

    home = home_of(site, "graph")
    prof = learn_profile([_te([(0.0, "M01", "1"), (1.0, "M02", "1"), (2.0, "X9", "1")])])  # X9: not in the home
    ch = chains(prof, home.nodes, home.dist, spread=1.5, prior=2.0)
    np.testing.assert_allclose(np.exp(ch.log_t).sum(axis=2), 1.0)
    t = np.exp(ch.log_t[0])
    kern = np.exp(-home.dist / 1.5)
    kern /= kern.sum(axis=1, keepdims=True)
    assert t[0, 1] == pytest.approx((1 + 2.0 * kern[0, 1]) / (1 + 2.0))  # (K1): one M01 -> M02 seen
    assert t[0, 2] == pytest.approx(2.0 * kern[0, 2] / 3.0)
    assert t[3, 2] > t[3, 0]  # never seen from M04: the kernel, nearer is likelier
    assert t[4].argmax() in (0, 1)  # a first event: by habit (M01, M02 once each)


def _habit_walk(rng, ids, homes, t1):
    """Two residents who share the middle of a corridor but each has their own end and pace."""
    ev, who = [], {}
    for r, (lo, hi, start) in homes.items():
        t, k = float(r) * 0.37, start
        while t < t1:
            ev.append((round(t, 3), ids[k]))
            who[(round(t, 3), ids[k])] = r
            k = int(np.clip(k + rng.choice([-1, 1]), lo, hi))
            t += float(rng.uniform(1.0, 4.0))
    return sorted(ev), who


@pytest.mark.parametrize("seed", [0, 1])
def test_a_profile_from_one_day_attributes_the_next_one(seed):
    site, ids = corridor_home(10, targets=2)
    homes = {1: (0, 6, 1), 2: (3, 9, 8)}  # sensors M04-M07 are both residents'
    train, who_tr = _habit_walk(np.random.default_rng(100 + seed), ids, homes, 1200.0)
    prof = learn_profile([_te([(t, s, str(who_tr[(t, s)])) for t, s in train])])
    test, who = _habit_walk(np.random.default_rng(seed), ids, homes, 900.0)
    truth = _te([(t, s, str(who[(t, s)])) for t, s in test])
    motion = motion_log(test, hold=0.5)
    known = run({"motion": motion, "residents_profile": prof}, site, ResidentsConfig())
    blind = run({"motion": motion}, site, ResidentsConfig())
    assert set(known["events"]["track"].drop_nulls()) <= {"resident1", "resident2"}
    acc_known = identity_scores(truth, known["events"]).accuracy
    acc_blind = identity_scores(truth, blind["events"]).accuracy
    assert acc_known > 0.85 and acc_known > acc_blind
    off = run({"motion": motion, "residents_profile": prof}, site, ResidentsConfig(profile=False))
    assert off["events"].equals(blind["events"])  # profile = false: the unsupervised decoder


def test_the_clocks_bins():
    t = np.array([0.0, 10.0, 50.0, 99.0, 100.0])
    assert Clock("session", 4).bin(t, epoch=None).tolist() == [0, 0, 2, 3, 3]  # phase first -> last event
    day = Clock("day", 24).bin(np.array([0.0, 3600.0, 23 * 3600.0]), epoch="2024-01-01T22:30:00")
    assert day.tolist() == [22, 23, 21]  # 22:30, 23:30, 21:30 the next day
    with pytest.raises(ConfigError, match="no epoch"):
        Clock("day", 24).bin(t, epoch=None)
    for bad in (("week", 4), ("day", 0), ("day", 2.5)):
        with pytest.raises(ConfigError):
            Clock(*bad)


def test_a_clocked_profile_by_hand_and_its_factor():
    te = _te([(0.0, "M1", "1"), (5.0, "M2", "2"), (10.0, "M1", "1;2")])
    prof = learn_profile([te], clock=Clock("session", 2))
    binned = {(r, s, b): c for r, f, s, c, b in prof.iter_rows() if b is not None}
    assert binned == {
        ("1", "M1", "session 0/2"): 1,
        ("2", "M2", "session 1/2"): 1,
        ("1", "M1", "session 1/2"): 1,
        ("2", "M1", "session 1/2"): 1,
    }
    assert clock_of(prof) == Clock("session", 2)
    node = np.array([0, 1, 0])
    phi = clock_bonus(prof, ("1", "2"), ("M1", "M2"), node, np.array([0.0, 5.0, 10.0]), epoch=None, weight=1.0)
    # (K3): ln (h_r(s, b) + 1) / sum_u (h_u(s, b) + 1); event 0: M1 in bin 0 -> 1: 2/3, 2: 1/3
    np.testing.assert_allclose(np.exp(phi[0]), [2 / 3, 1 / 3])
    np.testing.assert_allclose(np.exp(phi[1]), [1 / 3, 2 / 3])  # M2 in bin 1: resident 2's
    np.testing.assert_allclose(np.exp(phi[2]), [1 / 2, 1 / 2])  # M1 in bin 1: both once
    assert clock_bonus(prof, ("1", "2"), ("M1", "M2"), node, np.zeros(3), epoch=None, weight=0.0) is None
    mixed = pl.concat([prof, prof.with_columns(pl.col("bin").str.replace("session", "day"))])
    with pytest.raises(InputError, match="mixes clocks"):
        clock_of(mixed)


@pytest.mark.parametrize("seed", range(6))
def test_compiled_turns_equal_their_reference(seed):
    from onebit.trackers.residents.known import _turns_kernel, turn_posteriors, turn_posteriors_reference

    rng = np.random.default_rng(seed)
    K, n = int(rng.integers(2, 4)), int(rng.integers(1, 80))
    log_e = np.log(rng.dirichlet(np.ones(K), size=n))
    t = np.cumsum(rng.exponential(60.0, n))
    want = turn_posteriors_reference(log_e, t, 120.0)
    e = np.exp(log_e - log_e.max(axis=1, keepdims=True))
    np.testing.assert_allclose(_turns_kernel(e, t, 120.0), want, atol=1e-10)
    np.testing.assert_allclose(turn_posteriors(log_e, t, 120.0), want, atol=1e-10)
    assert want.shape == (n, K) and np.allclose(want.sum(axis=1), 1.0)
