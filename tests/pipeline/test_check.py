"""``onebit check``: trackers that can run, what is missing, sensors that look like non-person sensors."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.cli import main
from onebit.datasets.hallway_sim import write_hallway_dataset
from onebit.datasets.skeleton import init_dataset
from onebit.pipeline.check import SuspectConfig, check_dataset, suspect_sensors
from tests.models.test_occupancy import _line_site, _one_person, _with_a_misplaced_sensor

FLICKER = "92"


@pytest.fixture(scope="module")
def flickering(tmp_path_factory):
    """The hallway walked for 120 s, then an hour of an empty floor in which sensor 92 (the
    printer room) keeps toggling every 15-25 s: a sensor that is not about people."""
    data = write_hallway_dataset(tmp_path_factory.mktemp("hw") / "data", seed=2, duration=120.0, users=2)
    motion = pl.read_csv(data / "motion.csv", schema_overrides={"sensor": pl.String})
    motion = motion.filter(pl.col("sensor") != FLICKER)
    rng = np.random.default_rng(0)
    ons = np.cumsum(rng.uniform(15.0, 25.0, 180))
    t = np.sort(np.r_[ons, ons + 2.0])
    flicker = pl.DataFrame({"t": t.round(3), "sensor": FLICKER, "value": np.tile([1, 0], ons.size)})
    pl.concat([motion, flicker.cast(motion.schema)]).sort("t").write_csv(data / "motion.csv")
    return data


def test_check_names_the_flickering_sensor_and_only_it(flickering, capsys):
    res = check_dataset(flickering)
    assert set(res.suspects["sensor"]) == {FLICKER}
    assert set(res.suspects["reason"]) == {"flicker in empty periods", "never co-fires with its neighbours"}
    assert main(["check", str(flickering)]) == 0
    out = capsys.readouterr().out
    assert f"  {FLICKER}: flicker in empty periods" in out


def test_check_says_which_trackers_run_and_why_others_cannot(flickering):
    res = check_dataset(flickering)
    assert {"findinghumo", "hmm1", "hmm2", "residents"} <= set(res.runs)
    assert "crossings" in res.cannot["beams"]  # no beams.csv
    assert "proximity" in res.cannot["binpf"]
    assert res.missing == []  # positions, graph, targets and truth are all there


def test_check_of_an_init_skeleton_names_what_is_missing(tmp_path, capsys):
    log = tmp_path / "motion.csv"
    log.write_text("t,sensor,value\n0,a,1\n2,a,0\n3,b,1\n4,b,0\n")
    init_dataset(tmp_path / "ds", [log])
    log.rename(tmp_path / "ds" / "motion.csv")
    res = check_dataset(tmp_path / "ds")
    text = " | ".join(res.missing)
    for word in ("positions: 2 sensors", "graph:", "targets:", "truth:"):
        assert word in text
    assert "sensor_graph" in res.cannot["hmm1"]
    assert "targets" in res.cannot["istate"]
    assert "intruder" in res.runs


def test_quiet_sensors_are_not_judged():
    ons = pl.DataFrame({"t": [0.0, 1.0, 2.0], "sensor": ["a", "b", "a"]})
    from onebit.core.site import site_from_dict

    site = site_from_dict({"boundary": {"polygon": [[0, 0], [4, 0], [4, 4], [0, 4]]}})
    assert suspect_sensors(ons, site, SuspectConfig(min_ons=5)).height == 0


def _line_dataset(folder, motion: pl.DataFrame):
    """A dataset of the count model's test line (ten sensors 2 m apart, a chain graph) with a
    floor plan's run.toml (far pairs, no walker)."""
    site = _line_site()
    folder.mkdir()
    lines = ['name = "line"', 'units = "m"', "[boundary]", "polygon = [[-1, -1], [20, -1], [20, 1], [-1, 1]]"]
    for m in site.motion_sensors:
        lines += [
            "[[motion_sensors]]",
            f'id = "{m.id}"',
            f"position = [{m.position[0]}, {m.position[1]}]",
            "range = 1.0",
        ]
    edges = ", ".join(f'["{a}", "{b}"]' for a, b in site.sensor_graph.edges)
    lines += ["[sensor_graph]", f"edges = [{edges}]"]
    (folder / "site.toml").write_text("\n".join(lines) + "\n")
    (folder / "run.toml").write_text("[occupancy]\nwalk_s = 0.0\n")
    motion.with_columns(value=pl.col("on").cast(pl.Int64)).select("t", "sensor", "value").write_csv(
        folder / "motion.csv"
    )
    return folder


def test_check_names_a_sensor_out_of_place_on_the_plan(tmp_path, capsys):
    rng = np.random.default_rng(7)
    data = _line_dataset(tmp_path / "line", _with_a_misplaced_sensor(_one_person(rng, hours=12.0), rng))
    res = check_dataset(data)
    assert res.out_of_place["sensor"].to_list() == ["s8"]
    assert main(["check", str(data)]) == 0
    out = capsys.readouterr().out
    assert "sensors out of place on the plan?" in out and "  s8: " in out


def test_check_finds_no_sensor_out_of_place_without_one(tmp_path, flickering):
    rng = np.random.default_rng(7)
    assert check_dataset(_line_dataset(tmp_path / "line", _one_person(rng, hours=12.0))).out_of_place.height == 0
    assert check_dataset(flickering).out_of_place.height == 0  # a learned walker's strays count there
