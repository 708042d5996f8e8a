"""Stage ``residents``: a one-resident log is one person without ``targets``, two residents in
two parts of a home are two, ``targets`` bounds the decoder, the tables keep their contracts."""

from __future__ import annotations

import dataclasses

import numpy as np
import polars as pl
import pytest

from onebit.core.errors import ConfigError
from onebit.core.site import site_from_dict
from onebit.core.tables import MOTION, TRACKS
from onebit.trackers.base import ARTIFACTS
from onebit.trackers.residents import ResidentsConfig, run
from onebit.trackers.residents.decode import attribution_cost
from onebit.trackers.residents.model import move_cost
from onebit.trackers.residents.stage import EVENTS


def corridor_home(n: int = 16, spacing: float = 1.5, *, targets: int | None = None, doors: tuple[str, ...] = ()):
    """``n`` ceiling motion sensors ``M01..`` in a line ``spacing`` metres apart, a chain graph."""
    ids = [f"M{k + 1:02d}" for k in range(n)]
    data = {
        "name": "corridor",
        "units": "m",
        "boundary": {"polygon": [[-2.0, -2.0], [spacing * n + 2.0, -2.0], [spacing * n + 2.0, 2.0], [-2.0, 2.0]]},
        "motion_sensors": [{"id": s, "position": [spacing * k, 0.0], "range": spacing / 2} for k, s in enumerate(ids)],
        "sensor_graph": {"edges": [[a, b] for a, b in zip(ids, ids[1:])], "entries": list(doors), "exits": list(doors)},
    }
    if targets is not None:
        data["targets"] = targets
    return site_from_dict(data, source="<corridor>"), ids


def motion_log(events: list[tuple[float, str]], hold: float = 1.0) -> pl.DataFrame:
    """A MOTION table: each ``(t, sensor)`` an ON edge and its OFF ``hold`` seconds later."""
    rows = [(t, s, True) for t, s in events] + [(t + hold, s, False) for t, s in events]
    return pl.DataFrame(rows, schema=MOTION, orient="row").sort("t", maintain_order=True)


def walk(rng, ids, lo: int, hi: int, *, t0: float, t1: float, start: int) -> list[tuple[float, str]]:
    """One person between sensors ``lo..hi``: one-hop steps every 1-3 s, and a third of the
    time a dwell (the same sensor again after 5-90 s of silence)."""
    out, t, k = [], t0, start
    while t < t1:
        out.append((round(t, 3), ids[k]))
        if rng.random() < 1 / 3:
            t += float(rng.uniform(5.0, 90.0))
        else:
            k = int(np.clip(k + rng.choice([-1, 1]), lo, hi))
            t += float(rng.uniform(1.0, 3.0))
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("beam", [1, 16])
def test_a_one_resident_log_is_one_person_without_targets(seed, beam):
    site, ids = corridor_home()
    ev = walk(np.random.default_rng(seed), ids, 0, len(ids) - 1, t0=0.0, t1=1800.0, start=3)
    out = run({"motion": motion_log(ev)}, site, ResidentsConfig(beam=beam, stay=0.7 if beam > 1 else 0.0))
    assert out["decoder"]["people"][0] == 1
    assert out["events"]["track"].drop_nulls().unique().to_list() == ["person1"]
    assert out["people"]["present"].max() == 1


def _two_residents(seed: int):
    site, ids = corridor_home()
    rng = np.random.default_rng(seed)
    a = walk(rng, ids, 0, 4, t0=0.0, t1=900.0, start=1)  # one resident at one end
    b = walk(rng, ids, 11, 15, t0=0.4, t1=900.0, start=13)  # the other 10 m away
    who = {e: "a" for e in a} | {e: "b" for e in b}
    ev = sorted(who)
    return site, motion_log(ev), who


@pytest.mark.parametrize("seed", [0, 1])
def test_two_residents_apart_are_two_people_and_every_event_goes_to_its_own(seed):
    site, motion, who = _two_residents(seed)
    out = run({"motion": motion}, site, ResidentsConfig())
    assert out["decoder"]["people"][0] == 2
    on = out["events"].join(
        motion.with_row_index("row").filter("on").select("t", "sensor"), on=["t", "sensor"], how="semi"
    )
    pairs = {(w, tr) for (t, s, tr) in on.rows() for w in [who[(t, s)]]}
    assert len(pairs) == 2 and len({tr for _, tr in pairs}) == 2  # one track per resident, no mixing


def test_targets_bounds_the_decoder_not_its_output():
    site, motion, _ = _two_residents(0)
    one = dataclasses.replace(site, targets=1)
    out = run({"motion": motion}, one, ResidentsConfig())
    assert out["decoder"]["people"][0] == 1  # decoded with one person, not two cut to one
    assert out["tracks"]["track"].unique().to_list() == ["person1"]
    many = run({"motion": motion}, site, ResidentsConfig(max_people=3))
    assert many["decoder"]["people"][0] == 2  # the bound is an upper bound


def test_tables_follow_their_schemas_and_off_edges_follow_their_on():
    site, motion, _ = _two_residents(1)
    out = run({"motion": motion}, site, ResidentsConfig())
    assert out["tracks"].schema == TRACKS and out["events"].schema == EVENTS
    assert out["events"].height == motion.height and out["events"]["track"].null_count() == 0
    ev = out["events"].with_columns(on=motion["on"])
    for _s, g in ev.group_by("sensor"):
        g = g.sort("t")
        on_track = g.filter("on")["track"].to_list()
        off_track = g.filter(~pl.col("on"))["track"].to_list()
        assert off_track == on_track  # every ON is followed by its OFF in this log
    tracks = out["tracks"]
    assert tracks["node"].null_count() == 0 and tracks["x"].null_count() == 0
    # a person is present from their first event to the end (no door in this home)
    t_end = motion.filter("on")["t"].max()
    assert (tracks.group_by("track").agg(pl.col("t").max())["t"] >= t_end - 1.0).all()  # to the last grid time
    assert np.allclose(np.diff(np.unique(tracks["t"].to_numpy())), 1.0)  # one grid of ``period`` for everyone


def test_a_person_whose_last_event_is_at_a_door_leaves():
    site, ids = corridor_home(doors=("M01",))
    ev = [(float(k), ids[4 - k]) for k in range(5)] + [
        (300.0, ids[10]),
        (302.0, ids[11]),
    ]  # walks out at M01; later someone far inside
    out = run({"motion": motion_log(ev)}, site, ResidentsConfig(exit_after_s=30.0, birth_inside=2.0))
    tr = out["tracks"]
    first = tr.filter(pl.col("track") == "person1")
    assert 30.0 <= first["t"].max() <= 4.0 + 30.0 + 1e-9  # gone 30 s after its last event at the door


def test_a_person_who_left_through_the_door_is_absent_until_they_come_back():
    site, ids = corridor_home(doors=("M01",))
    ev = [(float(k), ids[4 - k]) for k in range(5)]  # walks out through the door M01 at t = 4
    ev += [(200.0, ids[0]), (201.0, ids[1]), (202.0, ids[2]), (400.0, ids[2])]  # back in at t = 200
    out = run({"motion": motion_log(ev)}, site, ResidentsConfig(exit_after_s=30.0))
    assert out["decoder"]["people"][0] == 1  # the same person came back through the door
    t = out["tracks"]["t"].to_numpy()
    assert t.max() == pytest.approx(400.0) and not np.any((t > 34.0 + 1e-9) & (t < 200.0 - 1e-9))  # away in between
    people = out["people"]
    assert people.filter(pl.col("t") == 200.0)["present"][0] == 1


def test_empty_motion_gives_empty_tables():
    site, _ = corridor_home()
    out = run({"motion": pl.DataFrame(schema=MOTION)}, site, ResidentsConfig())
    assert out["tracks"].height == 0 and out["tracks"].schema == TRACKS
    assert out["events"].height == 0 and out["events"].schema == EVENTS
    assert out["decoder"]["people"][0] == 0


@pytest.mark.parametrize(
    "field,value", [("l0", 0.0), ("beam", -1), ("distance", "manhattan"), ("stay", 1.0), ("max_people", 0)]
)
def test_config_errors_name_the_field(field, value):
    with pytest.raises(ConfigError, match=field):
        ResidentsConfig(**{field: value})


@pytest.mark.parametrize("seed", [0, 1])
def test_habits_keep_two_residents_apart_and_report_the_cost_of_their_attribution(seed):
    site, motion, who = _two_residents(seed)
    cfg = ResidentsConfig(habits=True, meet=30.0)  # every event a cut: each one oriented by habit alone
    out = run({"motion": motion}, site, cfg)
    on = out["events"].join(
        motion.with_row_index("row").filter("on").select("t", "sensor"), on=["t", "sensor"], how="semi"
    )
    pairs = {(who[(t, s)], tr) for (t, s, tr) in on.rows()}
    assert len(pairs) == 2 and len({tr for _, tr in pairs}) == 2  # the two ends' habits differ: still no mixing
    # the decoder's cost is that of the attribution it reports (eq. 1), not the one before re-orientation
    art = out[ARTIFACTS]
    t, node, track = art["t"], art["node"], art["track"]
    ids = list(art["nodes"])
    pos = {m.id: m.position for m in site.motion_sensors}
    D = np.abs(np.subtract.outer([pos[i][0] for i in ids], [pos[i][0] for i in ids]))
    pred = np.full(len(t), -1)
    for p in np.unique(track):
        mine = np.flatnonzero(track == p)
        pred[mine[1:]] = mine[:-1]
    birth = np.where(t - t[0] <= cfg.start_window_s, cfg.birth_door, cfg.birth_inside)

    def move(j, i):
        return float(
            move_cost(D, node[[j]], node[[i]], t[[i]] - t[[j]], l0=cfg.l0, v=0.0, l_max=cfg.l_max, w=0.0, tau=1.0)[0]
        )

    assert out["decoder"]["cost"][0] == pytest.approx(attribution_cost(pred, move, birth), rel=1e-9)


@pytest.mark.parametrize(
    "field,value", [("meet", -1.0), ("habit_alpha", 0.0), ("habit_restarts", -1), ("habit_switch", -0.5)]
)
def test_habit_config_errors_name_the_field(field, value):
    with pytest.raises(ConfigError, match=field):
        ResidentsConfig(**{field: value})
