"""binpf's filter: each equation against a brute-force version on tiny cases, and the run's
invariants (bounded counts, existences in [0, 1], determinism, no tracks from silence)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from onebit.trackers.binpf.filter import (
    FilterParams,
    birth_groups,
    count_births,
    footprint_probability,
    frame_probability_off,
    local_map_people,
    observation_update,
    others_miss,
    predict,
    run_filter,
    systematic_resample,
)

SENSORS = np.array([[0.0, 0.0], [1.5, 0.0], [3.0, 0.0], [0.0, 1.5], [1.5, 1.5], [3.0, 1.5]])
RADII = np.full(len(SENSORS), 1.0)
LO, HI = np.array([-1.0, -1.0]), np.array([4.0, 2.5])


def test_footprint_is_the_hard_disk_without_an_edge_and_halves_at_the_radius():
    xy = np.array([[0.0, 0.0], [0.99, 0.0], [1.01, 0.0]])
    hard = footprint_probability(xy, SENSORS[:1], RADII[:1], pd=0.9, edge=0.0)[:, 0]
    assert hard.tolist() == [0.9, 0.9, 0.0]
    soft = footprint_probability(np.array([[1.0, 0.0]]), SENSORS[:1], RADII[:1], pd=0.9, edge=0.3)
    assert soft[0, 0] == pytest.approx(0.45)
    d = np.linspace(0, 4, 50)
    prof = footprint_probability(np.c_[d, np.zeros_like(d)], SENSORS[:1], RADII[:1], pd=0.8, edge=0.3)[:, 0]
    assert np.all(np.diff(prof) <= 0) and prof.max() <= 0.8


def test_frame_probability_off_equals_the_enumeration_of_who_triggers():
    people = np.array([[0.2, 0.1], [1.2, 0.4], [2.9, 1.4]])
    pd, pf, edge = 0.7, 0.05, 0.3
    d = footprint_probability(people, SENSORS, RADII, pd=pd, edge=edge)
    got = frame_probability_off(people, SENSORS, RADII, pd=pd, pf=pf, edge=edge)
    for s in range(len(SENSORS)):
        p_off = 0.0  # sum over every outcome (each person, and the false alarm, triggers or not)
        for bits in itertools.product([0, 1], repeat=len(people) + 1):
            probs = [d[i, s] if b else 1 - d[i, s] for i, b in enumerate(bits[:-1])] + [pf if bits[-1] else 1 - pf]
            if not any(bits):
                p_off += float(np.prod(probs))
        assert got[s] == pytest.approx(p_off)


def test_others_miss_is_the_product_over_the_other_tracks_even_with_zeros():
    rng = np.random.default_rng(1)
    q = rng.random((4, 5))
    q[1, 2] = 0.0
    q[3, 2] = 0.0
    m = others_miss(q, 0.1)
    for i in range(4):
        ref = 0.9 * np.prod(np.delete(q, i, axis=0), axis=0)
        np.testing.assert_allclose(m[i], ref)
    assert others_miss(q[:1], 0.1).tolist() == [[0.9] * 5]


def _brute_update(x, r, z, p):
    """Eqs. (4), (4'), (5) with explicit loops over tracks, particles and sensors."""
    I, N = x.shape[:2]
    S = len(z)
    ell = np.zeros((I, N))
    r_new = np.zeros(I)
    d = np.array(
        [
            [
                [
                    footprint_probability(x[i, n, :2][None], SENSORS[s][None], RADII[s : s + 1], pd=p.pd, edge=p.edge)[
                        0, 0
                    ]
                    for s in range(S)
                ]
                for n in range(N)
            ]
            for i in range(I)
        ]
    )
    for i in range(I):
        ell0 = 0.0
        for s in range(S):
            m = 1 - p.pf
            for j in range(I):
                if j != i:
                    m *= 1 - r[j] * d[j, :, s].mean()
            ell0 += np.log(1 - m if z[s] else m)
            for n in range(N):
                off = m * (1 - d[i, n, s])
                ell[i, n] += np.log(1 - off if z[s] else off)
        like = (1 - p.silent) * np.exp(ell[i]) + p.silent * np.exp(ell0)
        ell[i] = np.log(like)
        L = np.mean(like) / np.exp(ell0)
        r_new[i] = r[i] * L / (r[i] * L + 1 - r[i])
    return ell, r_new


@pytest.mark.parametrize("silent", [0.0, 0.2])
def test_observation_update_equals_the_loops(silent):
    rng = np.random.default_rng(3)
    p = FilterParams(pd=0.8, pf=0.02, edge=0.3, silent=silent)
    x = np.concatenate([rng.uniform([-0.5, -0.5], [3.5, 2.0], (3, 4, 2)), rng.normal(size=(3, 4, 2))], axis=-1)
    r = np.array([0.3, 0.9, 0.6])
    z = np.array([True, False, False, True, False, True])
    ell, r_new = observation_update(x, r, z, SENSORS, RADII, p)
    ell_ref, r_ref = _brute_update(x, r, z, p)
    np.testing.assert_allclose(r_new, r_ref, rtol=1e-9)
    # weights are defined up to a per-track constant
    np.testing.assert_allclose(ell - ell.max(1, keepdims=True), ell_ref - ell_ref.max(1, keepdims=True), atol=1e-9)


def test_a_contradicting_frame_lowers_existence_by_at_most_the_silent_factor():
    """Eq. (4'): every sensor over a sure track off (or a far firing) cannot zero it."""
    p = FilterParams(pd=0.99, pf=1e-6, edge=0.0, silent=0.2)
    x = np.zeros((1, 20, 4))
    x[0, :, :2] = [0.1, 0.1]  # under sensor 0
    z = np.zeros(len(SENSORS), bool)
    z[2] = True  # only a far sensor fires
    _, r = observation_update(x, np.array([0.9]), z, SENSORS, RADII, p)
    assert r[0] >= 0.9 * 0.2 / (0.9 * 0.2 + 0.1) - 1e-12
    _, r0 = observation_update(
        x, np.array([0.9]), z, SENSORS, RADII, FilterParams(pd=0.99, pf=1e-6, edge=0.0, silent=0.0)
    )
    assert r0[0] < 0.1  # without it the one reading all but empties the track (L = 1 - p_d)


def test_systematic_resampling_keeps_counts_within_one_of_the_weights():
    rng = np.random.default_rng(0)
    w = np.array([[0.5, 0.25, 0.125, 0.125], [1.0, 0.0, 0.0, 0.0]])
    idx = systematic_resample(np.log(np.maximum(w, 1e-300)), rng)
    for i in range(2):
        counts = np.bincount(idx[i], minlength=4)
        assert np.all(np.abs(counts - 4 * w[i]) < 1)


def test_prediction_stays_in_the_box_and_decays_existence():
    rng = np.random.default_rng(0)
    x = np.zeros((2, 100, 4))
    x[..., 2:] = 50.0  # far too fast: clipped at the wall
    x2, r2 = predict(x, np.array([1.0, 0.5]), rng, FilterParams(survival=0.9), LO, HI)
    assert np.all(x2[..., :2] >= LO) and np.all(x2[..., :2] <= HI)
    np.testing.assert_allclose(r2, [0.9, 0.45])


def test_birth_groups_join_unexplained_neighbours_only():
    z = np.array([True, True, False, False, False, True])
    groups = birth_groups(z, np.ones((0, 6)), SENSORS, FilterParams(birth_link=1.6))
    assert sorted(map(sorted, (g.tolist() for g in groups))) == [[0, 1], [5]]
    q = np.ones((1, 6))
    q[0, 5] = 0.1  # a track triggers sensor 5 with probability 0.9: explained
    groups = birth_groups(z, q, SENSORS, FilterParams(birth_link=1.6, birth_explained=0.5))
    assert sorted(map(sorted, (g.tolist() for g in groups))) == [[0, 1]]


def _walk(T=40, seed=0, pd=0.95, pf=0.002):
    """Two people walking along the two rows of sensors in opposite directions; levels from Eq. (2)."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) / (T - 1)
    people = np.stack([np.c_[3.0 * t, np.zeros(T)], np.c_[3.0 * (1 - t), np.full(T, 1.5)]], axis=1)  # (T, 2, 2)
    p_off = np.stack([frame_probability_off(people[k], SENSORS, RADII, pd=pd, pf=pf, edge=0.1) for k in range(T)])
    return people, rng.random(p_off.shape) > p_off


def test_two_walkers_are_followed_and_the_count_is_bounded():
    people, on = _walk()
    p = FilterParams(particles=200, pd=0.95, pf=0.002, edge=0.1, period=0.5, max_out=2, max_tracks=6)
    res = run_filter(on, SENSORS, RADII, LO, HI, p, seed=1)
    assert np.all((res.r >= 0) & (res.r <= 1))
    rep_per_frame = np.bincount(res.frame[res.reported], minlength=len(on))
    assert rep_per_frame.max() <= 2 and res.live.max() <= 6
    hits = 0
    for k in range(10, len(on)):
        m = (res.frame == k) & res.reported
        est = np.c_[res.x[m], res.y[m]]
        if len(est):
            d = np.sqrt(((people[k][:, None] - est[None]) ** 2).sum(-1))
            hits += int((d.min(axis=1) < 1.0).sum())
    assert hits >= 0.7 * 2 * (len(on) - 10)


def test_the_bound_holds_with_more_people_than_targets():
    people, on = _walk(seed=2)
    res = run_filter(on, SENSORS, RADII, LO, HI, FilterParams(particles=100, max_out=1, max_tracks=3), seed=0)
    assert np.bincount(res.frame[res.reported], minlength=len(on)).max() <= 1
    assert res.live.max() <= 3


def test_silence_gives_no_tracks_and_empty_input_no_rows():
    res = run_filter(np.zeros((10, 6), bool), SENSORS, RADII, LO, HI, FilterParams(particles=50), seed=0)
    assert res.label.size == 0 and res.births.sum() == 0 and res.live.tolist() == [0] * 10
    res = run_filter(np.zeros((0, 6), bool), SENSORS, RADII, LO, HI, FilterParams(particles=50), seed=0)
    assert res.frame.size == 0 and res.live.size == 0


def test_same_seed_same_result():
    _, on = _walk(T=20)
    a = run_filter(on, SENSORS, RADII, LO, HI, FilterParams(particles=50), seed=4)
    b = run_filter(on, SENSORS, RADII, LO, HI, FilterParams(particles=50), seed=4)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.label, b.label)


@pytest.mark.parametrize("seed", range(15))
def test_birth_groups_are_scipys_connected_components_in_its_order(seed):
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(seed)
    sensors = rng.uniform(0, 10, (int(rng.integers(1, 25)), 2))
    z = rng.random(len(sensors)) < 0.6
    p = FilterParams(birth_link=float(rng.uniform(0.5, 4.0)))
    groups = birth_groups(z, np.ones((0, len(sensors))), sensors, p)
    cand = np.flatnonzero(z)
    if cand.size == 0:
        assert groups == []
        return
    adj = np.sqrt(((sensors[cand][:, None] - sensors[cand][None]) ** 2).sum(-1)) <= p.birth_link
    k, lab = connected_components(csr_matrix(adj), directed=False)
    assert [g.tolist() for g in groups] == [cand[lab == g].tolist() for g in range(k)]


# a dense array with overlapping footprints: sensors every 0.5 m, footprint radius 0.6 m
DENSE = np.stack(np.meshgrid(np.arange(0, 4.01, 0.5), np.arange(0, 3.01, 0.5)), -1).reshape(-1, 2)
DENSE_R = np.full(len(DENSE), 0.6)
DENSE_LO, DENSE_HI = np.array([0.0, 0.0]), np.array([4.0, 3.0])


def _standing(people, T=30, seed=0):
    """Levels from Eq. (2) of people standing at ``people (n, 2)`` for ``T`` frames."""
    rng = np.random.default_rng(seed)
    p_off = frame_probability_off(people, DENSE, DENSE_R, pd=0.95, pf=0.002, edge=0.1)
    return rng.random((T, len(DENSE))) > p_off[None, :]


def _reported_per_frame(on, split_ratio, seed, count_ratio=0.0):
    p = FilterParams(
        particles=200, pd=0.95, pf=0.002, edge=0.1, period=0.5, max_out=3, max_tracks=4, split_ratio=split_ratio,
        count_ratio=count_ratio,
    )  # fmt: skip
    res = run_filter(on, DENSE, DENSE_R, DENSE_LO, DENSE_HI, p, seed=seed)
    return res, np.bincount(res.frame[res.reported], minlength=len(on))


@pytest.mark.parametrize("seed", range(3))
def test_two_people_half_a_metre_apart_are_two_tracks_with_the_split(seed):
    """Two people 0.5 m apart under overlapping footprints fire ~7.5 sensors a frame against ~5
    for one: the split's twin and the couple's joint update (Eq. 6) keep two tracks, each near
    a person; the mean-field filter alone explains the pair with one track."""
    people = np.array([[1.75, 1.5], [2.25, 1.5]])
    on = _standing(people, seed=seed)
    _, without = _reported_per_frame(on, 0.0, seed)
    assert without.max() == 1  # the limitation the split removes
    res, count = _reported_per_frame(on, 1.5, seed)
    assert (count == 2).sum() >= 20 and count.max() <= 2
    for k in range(10, len(on)):
        m = (res.frame == k) & res.reported
        if m.sum() == 2:
            est = np.c_[res.x[m], res.y[m]]
            d = np.sqrt(((people[:, None] - est[None]) ** 2).sum(-1))
            assert d.min(axis=1).max() < 0.6  # each person has a track within 0.6 m


@pytest.mark.parametrize("seed", range(3))
def test_one_person_is_not_split_in_two(seed):
    on = _standing(np.array([[2.0, 1.5]]), seed=seed)
    _, count = _reported_per_frame(on, 1.5, seed)
    assert count.max() == 1 and (count == 1).sum() >= 25


COUNT = FilterParams(pd=0.95, pf=0.002, edge=0.1, count_ratio=10.0)


def _expected_levels(people):
    """The levels a frame most probably shows (each sensor on iff Eq. (2) says on is likelier)."""
    return frame_probability_off(people, DENSE, DENSE_R, pd=0.95, pf=0.002, edge=0.1) < 0.5


def test_the_local_map_count_finds_two_people_half_a_metre_apart_and_one_alone():
    """Eq. (7) on the dense array: the firings of two people 0.5 m apart (a wider spread) are
    two people, each placed within a grid step or so of one; one person's are one."""
    two = np.array([[1.75, 1.5], [2.25, 1.5]])
    Y = local_map_people(_expected_levels(two), DENSE, DENSE_R, COUNT)[0][-1]
    assert len(Y) == 2
    d = np.sqrt(((two[:, None] - Y[None]) ** 2).sum(-1))
    assert d.min(axis=1).max() <= 0.3 and d.min(axis=0).max() <= 0.3
    one = np.array([[2.0, 1.5]])
    assert len(local_map_people(_expected_levels(one), DENSE, DENSE_R, COUNT)[0][-1]) == 1
    assert len(local_map_people(np.zeros(len(DENSE), bool), DENSE, DENSE_R, COUNT)[0][-1]) == 0


def test_count_births_adds_only_the_people_no_track_takes_and_only_where_seen_twice():
    two = np.array([[1.75, 1.5], [2.25, 1.5]])
    z = _expected_levels(two)
    once = FilterParams(pd=0.95, pf=0.002, edge=0.1, count_ratio=10.0, count_persist=1)
    assert len(count_births(z, np.zeros((0, 2)), DENSE, DENSE_R, once)[0]) == 2
    born, _ = count_births(z, np.array([[2.0, 1.5]]), DENSE, DENSE_R, once)  # one track between them
    assert len(born) == 1
    assert len(count_births(z, two, DENSE, DENSE_R, once)[0]) == 0  # both tracked: nobody new
    far = np.array([[0.0, 3.0]])  # a track under no firing of the cluster does not count
    assert len(count_births(z, far, DENSE, DENSE_R, once)[0]) == 2
    # count_persist = 2 (the default): a place is born only if the frame before had one near it
    born, places = count_births(z, np.array([[2.0, 1.5]]), DENSE, DENSE_R, COUNT)
    assert len(born) == 0 and len(places) == 1
    born, _ = count_births(z, np.array([[2.0, 1.5]]), DENSE, DENSE_R, COUNT, places)
    assert len(born) == 1
    assert len(count_births(z, np.array([[2.0, 1.5]]), DENSE, DENSE_R, COUNT, np.array([[0.0, 3.0]]))[0]) == 0


@pytest.mark.parametrize("seed", range(3))
def test_one_person_stays_one_track_with_the_count(seed):
    on = _standing(np.array([[2.0, 1.5]]), seed=seed)
    _, count = _reported_per_frame(on, 0.0, seed, count_ratio=3.0)
    assert count.max() == 1 and (count == 1).sum() >= 25
