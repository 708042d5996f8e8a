"""Every multi-person tracker writes ``<tracker>_people`` (issue 34, item 2), and
:func:`people_from_tracks` on hand-made tracks."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest

from onebit.datasets.catalogue import get_scenario
from onebit.models.occupancy import PEOPLE
from onebit.pipeline.homes import people_from_tracks
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import TRACKERS

#: scenario -> duration, as the tracker contract runs them (tests/trackers/test_contract.py)
DURATIONS = {"beams-lab": 40.0, "hallway": 40.0, "istate-room": 20.0, "proximity-line": None, "proximity-grid": None}
COUNTING = {e.name: e.scenario for e in TRACKERS if e.spec.counts_people}


def test_the_multi_person_trackers_are_the_ones_expected():
    assert set(COUNTING) >= {"beams", "clustertrack", "binpf", "findinghumo", "istate", "residents"}
    assert set(COUNTING.values()) <= set(DURATIONS)


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("people")
    out = {}
    for scenario in sorted(set(COUNTING.values())):
        data = get_scenario(scenario).write(
            root / scenario, seed=3, duration=DURATIONS[scenario], agents=None, drop=0.0, camera=False, params={}
        )
        trackers = tuple(t for t, s in COUNTING.items() if s == scenario)
        res = run_pipeline(data, root / f"{scenario}-run", trackers=trackers, rrd=False)
        for t in trackers:
            assert res.status[t].startswith("ok"), (t, res.status[t])
        out[scenario] = root / f"{scenario}-run"
    return out


@pytest.mark.parametrize("name", sorted(COUNTING))
def test_every_multi_person_tracker_writes_people(runs, name):
    p = runs[COUNTING[name]] / "tables" / f"{name}_people.parquet"
    assert p.exists(), name
    people = pl.read_parquet(p)
    assert people.schema == PEOPLE, (name, people.schema)
    assert people.height >= 1
    assert (people["present"] >= 0).all()
    assert people["t"].is_sorted()
    tracks = pl.read_parquet(runs[COUNTING[name]] / "tables" / f"{name}_tracks.parquet")
    if tracks.height:  # someone was tracked: someone is counted at some time
        assert people["present"].max() >= 1, name


def _tracks(rows) -> pl.DataFrame:
    return pl.DataFrame(rows, schema={"track": pl.String, "t": pl.Float64}, orient="row")


def test_people_from_two_overlapping_tracks_with_a_gap():
    # steps of 1 s; track a: 0-4 then (a gap of 5 s) 10-12; track b: 2-6
    rows = [("a", float(t)) for t in (0, 1, 2, 3, 4, 10, 11, 12)] + [("b", float(t)) for t in (2, 3, 4, 5, 6)]
    got = people_from_tracks(_tracks(rows))
    assert got.schema == PEOPLE
    # a: [0, 5) and [10, 13); b: [2, 7)  (each run until one step after its last row)
    assert got.rows() == [(0.0, 1), (2.0, 2), (5.0, 1), (7.0, 0), (10.0, 1), (13.0, 0)]


def test_people_from_tracks_touching_runs_do_not_blink():
    # b starts exactly when a ends: the count stays 1, no row of 0 between
    rows = [("a", 0.0), ("a", 1.0), ("b", 2.0), ("b", 3.0)]
    assert people_from_tracks(_tracks(rows)).rows() == [(0.0, 1), (4.0, 0)]


@pytest.mark.parametrize("tracks", [None, _tracks([])])
def test_no_tracks_is_one_row_of_nobody(tracks):
    got = people_from_tracks(tracks)
    assert got.schema == PEOPLE and got.rows() == [(0.0, 0)]
