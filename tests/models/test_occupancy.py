"""The door-gated count model of a home (issue 34, item 2): the compiled Viterbi against its
oracle, the per-bin features of a hand-made log, additive statistics, and the count it decodes
on generated one-person, two-person and silent logs."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import polars as pl
import pytest

from onebit.core.site import site_from_dict
from onebit.core.tables import MOTION
from onebit.models.occupancy import (
    BINS,
    PEOPLE,
    CountModel,
    Features,
    OccupancyConfig,
    _viterbi_kernel,
    estimate,
    features,
    learn_stats,
    out_of_place,
    site_features,
    stats,
    viterbi,
    viterbi_reference,
)
from onebit.models.walks import clock_tick, far_pairs, lifted_sensors, one_walker

# -- Viterbi ------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(12))
def test_compiled_viterbi_equals_the_reference(seed):
    rng = np.random.default_rng(seed)
    K = int(rng.integers(0, 5))
    B = int(rng.choice([0, 1, 2, 50, 300]))
    N = K + 1

    def logp(*shape):
        p = rng.dirichlet(np.ones(shape[-1]), size=shape[:-1]) if len(shape) > 1 else rng.dirichlet(np.ones(shape[0]))
        return np.log(p)

    ll = np.log(rng.uniform(0.01, 1.0, size=(B, N)))
    door = rng.random(B) < 0.2
    model = CountModel(
        log_start=logp(N),
        log_door=logp(N, N),
        log_quiet=logp(N, N),
        log_active=None,
        log_far=np.zeros((N, 2)),
        log_hour=None,
    )
    want = viterbi_reference(ll, door, model.log_door, model.log_quiet, model.log_start)
    got = _viterbi_kernel(ll, door, model.log_door, model.log_quiet, model.log_start)  # the compiled kernel itself
    assert got.dtype == np.int64 and got.shape == (B,)
    assert got.tolist() == want.tolist()
    assert viterbi(ll, door, model).tolist() == want.tolist()  # whichever path the dispatcher takes


# -- features of a hand-made log ----------------------------------------------------------

SENSORS = ["d", "a", "b", "c", "f"]


def _motion(rows) -> pl.DataFrame:
    return pl.DataFrame(rows, schema=MOTION, orient="row")


HAND = _motion(
    [
        (5.0, "d", True),  # bin 0: the door, not activity
        (6.0, "d", False),
        (70.0, "a", True),  # bin 1: a and c 0.5 s apart, far apart: far
        (70.5, "c", True),
        (75.0, "a", False),
        (80.0, "c", False),
        (130.0, "a", True),  # bin 2: a then b, near: not far
        (135.0, "b", True),
        (140.0, "a", False),
        (141.0, "b", False),
        (200.0, "f", True),  # bin 3: a level sensor on until 330 (bin 5): held in bins 3-5
        (330.0, "f", False),
        (400.0, "c", True),  # bin 6: c then a 2 s apart: beyond the window
        (402.0, "a", True),
        (403.0, "zz", True),  # not one of the sensors: ignored
    ]
)


def _far() -> np.ndarray:
    far = np.zeros((5, 5), dtype=bool)
    far[1, 3] = far[3, 1] = True  # a - c
    return far


def _features(**kw) -> Features:
    args = dict(bin_s=60.0, window_s=1.0, held=True, epoch_seconds_of_day=None)
    args.update(kw)
    return features(HAND, SENSORS, {"d"}, {"f"}, _far(), **args)


def test_features_of_a_hand_made_log():
    f = _features()
    assert f.t0 == 0.0 and f.bins == 7
    assert f.door.tolist() == [True, False, False, False, False, False, False]
    assert f.active.tolist() == [False, True, True, True, True, True, True]
    assert f.far.tolist() == [False, True, False, False, False, False, False]
    fired = {b: sorted(SENSORS[j] for j in np.flatnonzero(f.fired[b])) for b in range(f.bins)}
    assert fired == {0: ["d"], 1: ["a", "c"], 2: ["a", "b"], 3: ["f"], 4: [], 5: [], 6: ["a", "c"]}
    assert f.held[:, 4].tolist() == [False, False, False, True, True, True, False]
    assert not f.held[:, :4].any()  # only level sensors are held
    assert (f.hour == -1).all()


def test_features_without_held_and_with_a_clock():
    f = _features(held=False, epoch_seconds_of_day=23 * 3600.0)
    assert f.active.tolist() == [False, True, True, True, False, False, True]
    assert (f.hour == 23).all()


# -- statistics ---------------------------------------------------------------------------


def _cut(f: Features, lo: int, hi: int) -> Features:
    s = slice(lo, hi)
    return replace(
        f,
        t0=f.t0 + lo * f.bin_s,
        door=f.door[s],
        active=f.active[s],
        far=f.far[s],
        fired=f.fired[s],
        held=f.held[s],
        hour=f.hour[s],
        firings=None if f.firings is None else f.firings[s],
        strays=None if f.strays is None else f.strays[s],
    )


def _as_dict(df: pl.DataFrame) -> dict:
    g = df.group_by("term", "state", "key").agg(pl.col("count").sum())
    return {(a, b, c): v for a, b, c, v in g.iter_rows() if v != 0}


@pytest.mark.parametrize("k", [1, 3, 5])
def test_stats_are_additive_but_for_the_boundary(k):
    f = _features(epoch_seconds_of_day=0.0)
    y = np.array([1, 1, 2, 2, -1, 1, 0])
    whole = _as_dict(stats(f, y))
    parts = pl.concat([stats(_cut(f, 0, k), y[:k]), stats(_cut(f, k, f.bins), y[k:])])
    extra = []
    if y[k - 1] >= 0 and y[k] >= 0:  # the transition across the cut
        extra.append(("door" if f.door[k] else "quiet", int(y[k - 1]), str(int(y[k])), 1.0))
    first2 = next((int(v) for v in y[k:] if v >= 0), None)
    if first2 is not None:  # the second part's start row
        extra.append(("start", first2, "", -1.0))
    summed = pl.concat([parts, pl.DataFrame(extra, schema=parts.schema, orient="row")]) if extra else parts
    assert _as_dict(summed) == whole


def test_learn_stats_of_two_days_sum_to_their_concatenation():
    site = _line_site()
    cfg = OccupancyConfig()
    m1 = _one_person(np.random.default_rng(1), hours=3.0)
    m2 = _one_person(np.random.default_rng(2), hours=3.0).with_columns(pl.col("t") + 86_400.0)
    t1 = pl.DataFrame({"t": [0.0], "end": [3 * 3600.0], "count": [1]})
    t2 = pl.DataFrame({"t": [86_400.0], "end": [86_400.0 + 3 * 3600.0], "count": [1]})
    s1, s2 = learn_stats(m1, t1, site, cfg), learn_stats(m2, t2, site, cfg)
    assert s1.filter(pl.col("term") == "bins")["count"].sum() == 180
    assert _as_dict(pl.concat([s1, s2]))[("bins", 1, "")] == 360
    assert _as_dict(pl.concat([s1, s2]))[("start", 1, "")] == 2


# -- the count on generated logs ----------------------------------------------------------

N_LINE = 10


def _line_site(door: bool = False):
    """Ten sensors on a line 2 m apart, a chain sensor graph; ``s9`` a level (force) sensor."""
    ids = [f"s{i}" for i in range(N_LINE)]
    graph = {"edges": [[ids[i], ids[i + 1]] for i in range(N_LINE - 1)]}
    if door:
        graph |= {"entries": ["s0"], "exits": ["s0"]}
    return site_from_dict(
        {
            "name": "line",
            "units": "m",
            "epoch": "2000-01-01T00:00:00",
            "boundary": {"polygon": [[-1, -1], [20, -1], [20, 1], [-1, 1]]},
            "sensor_types": {"force": {"signal": "level"}},
            "motion_sensors": [
                {"id": s, "position": [2.0 * i, 0.0], "range": 1.0, **({"type": "force"} if i == 9 else {})}
                for i, s in enumerate(ids)
            ],
            "sensor_graph": graph,
        }
    )


def _pulse(rows, t, s, hold):
    rows.append((t, s, True))
    rows.append((t + hold, s, False))


def _one_person(rng, *, hours: float, silence: tuple[float, float] = (600.0, 2700.0)) -> pl.DataFrame:
    """One person walking the chain: a pulse at each sensor reached, lingering at some (the
    sensor re-fires while they stay, and fires once more after they left), sitting on the
    force sensor ``s9`` for up to an hour (held on), and now and then a silence of ``silence``
    seconds (asleep, or reading where no sensor sees)."""
    rows: list = []
    t, pos, end = 0.0, int(rng.integers(0, N_LINE)), hours * 3600.0
    while t < end:
        u = rng.random()
        if u < 0.005:  # a silence
            t += rng.uniform(*silence)
            continue
        if pos == 9 and u < 0.2:  # sits down: the force sensor held
            hold = rng.uniform(600.0, 3600.0)
            _pulse(rows, t, "s9", hold)
            t += hold + 1.0
        else:
            _pulse(rows, t, f"s{pos}", rng.uniform(1.0, 4.0))
            if rng.random() < 0.3:  # lingering: the sensor re-fires while they stay
                for _ in range(int(rng.integers(1, 6))):
                    t += rng.uniform(5.0, 40.0)
                    _pulse(rows, t, f"s{pos}", rng.uniform(1.0, 4.0))
            t += rng.exponential(30.0) + 1.0
        prev = pos
        pos = int(np.clip(pos + rng.choice([-1, 1]), 0, N_LINE - 1))
        if rng.random() < 0.1:  # the sensor left behind fires once more
            _pulse(rows, t + rng.uniform(0.2, 3.0), f"s{prev}", 2.0)
    df = pl.DataFrame(rows, schema=MOTION, orient="row").filter(pl.col("t") < end).sort("t")
    return df


@pytest.mark.parametrize("seed", [7, 8])
def test_one_person_with_lingering_sensors_and_silences_is_one(seed):
    """Silences of 10-45 minutes (no door in the site), a force sensor held up to an hour,
    sensors that re-fire: one person in >= 95 % of the day's bins, never two."""
    site = _line_site()
    motion = _one_person(np.random.default_rng(seed), hours=24.0)
    assert motion.height > 500
    bins, people = estimate(motion, site, OccupancyConfig())
    assert bins.schema == BINS and people.schema == PEOPLE
    n = bins["present"].to_numpy()
    assert (~bins["active"].to_numpy()).mean() > 0.05  # the silences are there
    assert (n == 1).mean() >= 0.95, np.bincount(n)
    assert n.max() == 1


def test_one_person_through_silences_of_hours_is_one():
    motion = _one_person(np.random.default_rng(7), hours=24.0, silence=(2 * 3600.0, 3 * 3600.0))
    bins, _ = estimate(motion, _line_site(), OccupancyConfig())
    n = bins["present"].to_numpy()
    assert n.max() == 1  # never two (this part holds)
    assert (n == 1).mean() >= 0.95, np.bincount(n)


def test_silences_of_hours_never_make_two():
    motion = _one_person(np.random.default_rng(9), hours=24.0, silence=(2 * 3600.0, 3 * 3600.0))
    bins, _ = estimate(motion, _line_site(), OccupancyConfig())
    assert bins["present"].max() == 1


def test_a_silent_log_gives_no_people():
    bins, people = estimate(pl.DataFrame(schema=MOTION), _line_site(), OccupancyConfig())
    assert bins.height == 0 and people.height == 0
    assert bins.schema == BINS and people.schema == PEOPLE


def _two_people_far_apart() -> pl.DataFrame:
    """Two people at the two ends of the chain (7+ hops apart), often firing within a second."""
    rng = np.random.default_rng(3)
    rows: list = []
    t = 0.0
    while t < 4 * 3600.0:
        a, b = int(rng.integers(0, 3)), int(rng.integers(7, 9))
        _pulse(rows, t, f"s{a}", 2.0)
        _pulse(rows, t + rng.uniform(0.0, 0.8), f"s{b}", 2.0)
        t += rng.exponential(40.0) + 5.0
    return pl.DataFrame(rows, schema=MOTION, orient="row").sort("t")


def test_two_people_firing_far_apart_at_once_are_two():
    """Two people at the two ends of the chain (7+ hops apart), often firing within a second."""
    motion = _two_people_far_apart()
    bins, _ = estimate(motion, _line_site(), OccupancyConfig())
    n = bins["present"].to_numpy()
    assert (n == 2).mean() >= 0.9, np.bincount(n)


# -- one walker or two (eq. W1-W2, O3) ------------------------------------------------------


def _chain_hops(n: int) -> np.ndarray:
    i = np.arange(n)
    return np.abs(i[:, None] - i[None, :]).astype(float)


def test_one_walker_by_hand():
    """Sensors on a chain (hops = index difference), 0.5 s per hop, 2 hops of slack."""
    hops = _chain_hops(10)
    t = np.array([0.0, 1.0, 1.2, 2.0, 30.0, 30.1])
    k = np.array([0, 1, 9, 2, 9, 0])
    # 9 at 1.2 s is 8 hops from 1 (needs 3 s) and 9 from 0: a stray; 9 at 30 s is reachable
    # from 2 (7 hops in 28 s); 0 at 30.1 s is 9 hops from that 9: the longer path skips one of them
    on = one_walker(t, k, hops, walk_s=0.5, walk_slack=2.0)
    assert on[:2].all() and not on[2] and on[3]
    assert on[4:].sum() == 1
    assert one_walker(np.zeros(0), np.zeros(0, np.int64), hops, walk_s=0.5, walk_slack=2.0).size == 0


def test_lingering_and_late_refires_are_one_walker():
    hops = _chain_hops(10)
    t = np.array([0.0, 5.0, 10.0, 11.0, 11.5, 12.0, 40.0])
    k = np.array([3, 3, 3, 4, 3, 5, 5])  # re-fires at 3, a step to 4, 3 fires once more behind them
    assert one_walker(t, k, hops, walk_s=0.5, walk_slack=2.0).all()


def test_strays_per_bin_in_the_features():
    f = _features(hops=_chain_hops(5), walk_s=0.5, walk_slack=0.0)
    assert f.firings.tolist() == [0, 2, 2, 1, 0, 0, 2]
    # bin 1: a (1) and c (3) 0.5 s apart: 2 hops > 1 hop in 0.5 s, one of them a stray
    assert f.strays.tolist() == [0, 1, 0, 0, 0, 0, 0]
    assert _features().strays is None  # no walker without hops


def test_one_walker_explains_nearly_all_of_one_persons_firings():
    site = _line_site()
    motion = _one_person(np.random.default_rng(7), hours=3.0)
    f = site_features(motion, site, OccupancyConfig(), None)
    assert f.strays is not None and f.strays.sum() < 0.05 * f.firings.sum()


def test_two_walkers_at_once_leave_many_strays_and_are_two():
    """Two people at the two halves of the chain, each walking their own half (a step every
    2-20 s) at the same time: one walker leaves more than a tenth of the firings unexplained."""
    rng = np.random.default_rng(4)
    rows: list = []
    for lo in (0, 5):
        t, pos = 0.0, lo
        while t < 2 * 3600.0:
            _pulse(rows, t, f"s{pos}", 2.0)
            pos = int(np.clip(pos + rng.choice([-1, 1]), lo, lo + 3))
            t += rng.uniform(2.0, 20.0)
    motion = pl.DataFrame(rows, schema=MOTION, orient="row").sort("t")
    f = site_features(motion, _line_site(), OccupancyConfig(), None)
    assert f.strays.sum() > 0.1 * f.firings.sum()  # one person: < 0.05 (above)
    bins, _ = estimate(motion, _line_site(), OccupancyConfig())
    n = bins["present"].to_numpy()
    assert (n == 2).mean() >= 0.9, np.bincount(n)
    # the strays carry it: without them (walk_s = 0) and with far pairs made no evidence, one
    neutral, _ = estimate(motion, _line_site(), OccupancyConfig(walk_s=0.0, far_noise=0.5, far_rate=0.5))
    assert (neutral["present"].to_numpy() == 2).mean() < 0.5


# -- a polled log's clock (eq. W0) -----------------------------------------------------------


def test_clock_tick_by_hand():
    # phases 0, 0 and half a period: |(1 + 1 - 1) / 3| = 1/3 < 0.9, not polled
    assert clock_tick(np.array([0.0, 1.0, 2.5]), clock_s=1.0, tick_phase=0.9) == 0.0
    # one phase (+0.01..+0.03 s after the second): R = 0.998, polled, half the period of slack
    assert clock_tick(np.array([0.01, 3.02, 7.03]), clock_s=1.0, tick_phase=0.9) == 0.5
    assert clock_tick(np.array([0.01, 3.02, 7.03]), clock_s=0.0, tick_phase=0.9) == 0.0
    assert clock_tick(np.array([5.0]), clock_s=1.0, tick_phase=0.9) == 0.0


def test_one_walker_with_a_tick_by_hand():
    """Two firings of one poll 0.01 s apart, 3 hops: beyond 2 hops of slack + 0.02 hops of
    time, but within 2 + (0.01 + 0.5) / 0.5 = 3.02 with half a 1 s poll."""
    hops = _chain_hops(10)
    t, k = np.array([0.0, 0.01]), np.array([0, 3])
    assert one_walker(t, k, hops, walk_s=0.5, walk_slack=2.0).sum() == 1
    assert one_walker(t, k, hops, walk_s=0.5, walk_slack=2.0, tick=0.5).all()


def _polled(rows, rng) -> pl.DataFrame:
    """Events (true time, sensor) as a 1 Hz logger stamps them: at the next whole second plus
    0.01-0.04 s, the events of one poll in a random order, each a 2 s pulse."""
    stamped = sorted((np.ceil(t) + 0.01 + 0.03 * rng.random(), rng.random(), s) for t, s in rows)
    out = [r for st, _, s in stamped for r in ((st, s, True), (st + 2.0, s, False))]
    return pl.DataFrame(out, schema=MOTION, orient="row").sort("t", maintain_order=True)


def test_a_polled_one_person_log_is_one():
    """One person crossing 3 hops of the graph every 0.3-0.6 s in bursts (a graph whose hops
    are short, as a learned one's), stamped by a 1 Hz logger: one poll's firings 3 hops apart
    look simultaneous. Without the clock's slack a quarter of them are strays: two people."""
    rng = np.random.default_rng(0)
    rows, t, pos = [], 0.0, 0
    while t < 2 * 3600.0:
        for _ in range(int(rng.integers(2, 7))):
            rows.append((t, f"s{pos}"))
            pos = int(np.clip(pos + 3 * rng.choice([-1, 1]), 0, N_LINE - 2))
            t += rng.uniform(0.3, 0.6)
        t += rng.uniform(5.0, 60.0)
    motion = _polled(rows, rng)
    bins, _ = estimate(motion, _line_site(), OccupancyConfig())
    assert (bins["present"].to_numpy() == 1).mean() >= 0.95
    blind, _ = estimate(motion, _line_site(), OccupancyConfig(clock_s=0.0))
    assert (blind["present"].to_numpy() == 2).mean() >= 0.9


def test_a_polled_two_walker_log_is_still_two():
    """The two walkers of the chain's halves (above), stamped by a 1 Hz logger."""
    rng = np.random.default_rng(4)
    rows: list = []
    for lo in (0, 5):
        t, pos = 0.0, lo
        while t < 2 * 3600.0:
            rows.append((t, f"s{pos}"))
            pos = int(np.clip(pos + rng.choice([-1, 1]), lo, lo + 3))
            t += rng.uniform(2.0, 20.0)
    bins, _ = estimate(_polled(rows, rng), _line_site(), OccupancyConfig())
    assert (bins["present"].to_numpy() == 2).mean() >= 0.9


def test_a_site_with_a_door_sensor_gets_no_clock_slack():
    rng = np.random.default_rng(1)
    rows = [(float(t), f"s{int(rng.integers(0, 9))}") for t in np.cumsum(rng.uniform(0.1, 3.0, 2000))]
    motion = _polled(rows, rng)
    site = _line_site(door=True)
    got = site_features(motion, site, OccupancyConfig(), None)
    want = site_features(motion, site, OccupancyConfig(clock_s=0.0), None)
    assert got.strays.tolist() == want.strays.tolist()
    free = site_features(motion, _line_site(), OccupancyConfig(), None)
    assert free.strays.sum() < site_features(motion, _line_site(), OccupancyConfig(clock_s=0.0), None).strays.sum()


def test_the_learned_model_keeps_its_far_pairs_and_has_no_stray_term():
    site = _line_site()
    cfg = OccupancyConfig()
    motion = _one_person(np.random.default_rng(1), hours=3.0)
    truth = pl.DataFrame({"t": [0.0], "end": [3 * 3600.0], "count": [1]})
    st = learn_stats(motion, truth, site, cfg)
    assert not st.filter(pl.col("term").is_in(["firings", "strays"])).height
    bins, _ = estimate(motion, site, cfg, st)
    assert (bins["present"].to_numpy() == 1).mean() >= 0.95


# -- sensors out of place (eq. F1) ----------------------------------------------------------


@pytest.mark.parametrize("seed", range(6))
def test_far_pairs_equal_every_pair_by_hand(seed):
    rng = np.random.default_rng(seed)
    n, S = int(rng.integers(0, 60)), 6
    ts = np.sort(rng.uniform(0.0, 30.0, n))
    ks = rng.integers(0, S, n)
    far = rng.random((S, S)) < 0.4
    got = set(zip(*(a.tolist() for a in far_pairs(ts, ks, far, 1.5))))
    want = {(i, j) for i in range(n) for j in range(i + 1, n) if ts[j] - ts[i] <= 1.5 and far[ks[i], ks[j]]}
    assert got == want


def test_lifted_sensors_by_hand():
    # firings: sensor 0 x4, 1 x4, 2 x2 (N = 10); far pairs (0,2) (1,2) (0,2): ends 0 x2, 1 x1, 2 x3 (2P = 6)
    ks = np.array([0, 0, 0, 0, 1, 1, 1, 1, 2, 2])
    first, second = np.array([0, 4, 1]), np.array([8, 9, 8])
    # lambda = (p / 6) / (n / 10): sensor 0 (2/6)/(4/10) = 0.83, 1 (1/6)/(4/10) = 0.42, 2 (3/6)/(2/10) = 2.5
    assert lifted_sensors(ks, first, second, 4, lift=2.0, least=1).tolist() == [False, False, True, False]
    assert lifted_sensors(ks, first, second, 4, lift=2.0, least=4).tolist() == [False, False, False, False]
    assert lifted_sensors(ks, first, second, 4, lift=0.8, least=1).tolist() == [True, False, True, False]


def _with_a_misplaced_sensor(
    motion: pl.DataFrame, rng, *, near=("s1", "s2", "s3"), odd="s8", share=0.3
) -> pl.DataFrame:
    """The plan puts ``odd`` at the far end of the line, but it sees the place by ``near``: a
    ``share`` of the ON edges there fire it too, within half a second. (F1) finds it while its
    firings are a small share of all (``lambda <= 0.5 N / n_odd``: not at a quarter or more)."""
    at = motion.filter(pl.col("on") & pl.col("sensor").is_in(list(near)))
    at = at.filter(pl.Series(rng.random(at.height) < share))
    rows: list = []
    for t in (at["t"].to_numpy() + rng.uniform(0.0, 0.5, at.height)).tolist():
        _pulse(rows, t, odd, 2.0)
    extra = pl.DataFrame(rows, schema=MOTION, orient="row")
    return pl.concat([motion, extra]).sort("t")


PLAN = dict(walk_s=0.0)  # a floor plan's run.toml: far pairs F, no walker


@pytest.mark.parametrize("seed", [7, 11])
def test_one_person_beside_a_sensor_out_of_place_is_one(seed):
    rng = np.random.default_rng(seed)
    motion = _with_a_misplaced_sensor(_one_person(rng, hours=12.0), rng)
    site = _line_site()
    off, _ = estimate(motion, site, OccupancyConfig(**PLAN, far_lift=0.0))
    on, _ = estimate(motion, site, OccupancyConfig(**PLAN))
    assert (off["present"].to_numpy() >= 2).mean() > 0.15  # without (F1) the far pairs make two
    assert (on["present"].to_numpy() == 1).mean() >= 0.95, np.bincount(on["present"].to_numpy())


def test_two_people_far_apart_stay_two_with_sensors_out_of_place_left_out():
    """Two people's far pairs fall on the sensors they use in proportion: no sensor is out of place."""
    motion = _two_people_far_apart()
    site = _line_site()
    f = site_features(motion, site, OccupancyConfig(**PLAN), None)
    assert f.far.sum() == site_features(motion, site, OccupancyConfig(**PLAN, far_lift=0.0), None).far.sum()
    bins, _ = estimate(motion, site, OccupancyConfig(**PLAN))
    assert (bins["present"].to_numpy() == 2).mean() >= 0.9


def test_a_learned_model_keeps_the_far_pairs_of_sensors_out_of_place():
    rng = np.random.default_rng(7)
    motion = _with_a_misplaced_sensor(_one_person(rng, hours=6.0), rng)
    site, cfg = _line_site(), OccupancyConfig(**PLAN)
    unlearned = site_features(motion, site, cfg, None).far.sum()
    learned = site_features(motion, site, cfg, None, learned=True).far.sum()
    assert learned == site_features(motion, site, replace(cfg, far_lift=0.0), None).far.sum()
    assert learned > unlearned


def test_out_of_place_names_the_misplaced_sensor_where_far_pairs_count():
    rng = np.random.default_rng(7)
    motion = _with_a_misplaced_sensor(_one_person(rng, hours=12.0), rng)
    site = _line_site()
    odd = out_of_place(motion, site, OccupancyConfig(**PLAN))
    assert odd["sensor"].to_list() == ["s8"]
    assert odd["lift"][0] >= 2.0 and odd["far_ends"][0] >= 5
    assert out_of_place(motion, site, OccupancyConfig()).height == 0  # the walker's strays count there, not far pairs
    assert out_of_place(motion, site, OccupancyConfig(**PLAN, far_lift=0.0)).height == 0
    assert out_of_place(_two_people_far_apart(), site, OccupancyConfig(**PLAN)).height == 0
