"""``onebit import aras`` (issue 34, item 1) on a tiny generated house folder in the ARAS format.

The fixture house has six sensor columns (a house door contact, a force sensor, an IR, two
photocells, a temperature sensor) and two day files: day 1 full (86 400 lines), day 2 short
(1 000 lines) with three bad lines. Every expected row below is worked out by hand from the
arrays the fixture writes.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit.cli import main
from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.datasets.aras import DAY_S, import_aras, parse_days, read_day, read_readme
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline

README = """\
ARAS Human Activity Recognition Dataset -- House X (a test fixture in the format of the README)

Sensor Explanations
-------------------
Column\tSensor ID\tSensor Type\tPlace
1\tCo1\tContact Sensor\tHouse door
2\tFo1\tForce Sensor\tCouch
3\tIr1\tIR\tKitchen
4\tPh1\tPhotocell\tBathroom drawer
5\tPh2\tPhotocell\tWardrobe
6\tTe1\tTemperature Sensor\tKitchen

Activity Explanations
---------------------
ID\tACTIVITY
1\tOther
2\tGoing Out
11\tSleeping
16\tNapping
"""

CO1, FO1, IR1, PH1, PH2, TE1 = range(6)
R1, R2 = 6, 7
SHORT = 1000


def _day1() -> np.ndarray:
    """Day 1, one row per second: 6 levels then the two residents' activities."""
    a = np.zeros((DAY_S, 8), dtype=np.int64)
    a[:, R1] = a[:, R2] = 1  # Other
    a[0:10, PH2] = 1  # on at the first second: an ON at t = 0
    a[100:105, CO1] = 1  # the house door
    a[200:210, IR1] = 1  # both awake and home: unlabelled
    a[1000:2000, R2] = 2  # resident 2 out
    a[1500:1503, IR1] = 1  # -> resident 1
    a[3000:4000, R1] = 11  # resident 1 asleep
    a[3500:3501, PH1] = 1  # -> resident 2
    a[5000:6000, R2] = 16  # resident 2 napping
    a[5500:5502, IR1] = 1  # -> resident 1
    a[7000:8000, R1] = a[7000:8000, R2] = 11  # both asleep
    a[7500:7501, PH1] = 1  # nobody awake: unlabelled
    a[8000:8100, TE1] = 1  # temperature: other.csv
    a[86000:, FO1] = 1  # held over midnight
    a[86000:, R1] = 2  # resident 1 out over midnight
    return a


def _day2() -> np.ndarray:
    a = np.zeros((SHORT, 8), dtype=np.int64)
    a[:, R1] = a[:, R2] = 1
    a[:10, FO1] = 1  # off at second 10 of day 2
    a[:5, PH2] = 1  # on exactly at midnight: an ON at 86 400
    a[:50, R1] = 2  # back at second 50
    a[18, IR1] = 1  # line 19; lines 20-22 bad (they hold it), line 23 (second 22) off
    return a


def _write(path: Path, a: np.ndarray) -> None:
    path.write_text("\n".join(" ".join(map(str, r)) for r in a.tolist()) + "\n")


def write_house(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "README").write_text(README)
    _write(folder / "DAY_1.txt", _day1())
    folder_day2 = folder / "DAY_2.txt"
    _write(folder_day2, _day2())
    text = folder_day2.read_text().splitlines()
    text[19] = "0 0 0 0 0 0 1"  # line 20: 7 fields
    text[20] = "0 0 0 2 0 0 1 1"  # line 21: a level 2
    text[21] = "0 0 0 0 0 0 99 1"  # line 22: activity 99
    folder_day2.write_text("\n".join(text) + "\n")
    return folder


@pytest.fixture(scope="module")
def house(tmp_path_factory) -> Path:
    return write_house(tmp_path_factory.mktemp("aras") / "HouseX")


@pytest.fixture(scope="module")
def imported(house, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("aras-ds") / "ds"
    assert main(["import", "aras", str(house), str(out)]) == 0
    return out


def _rows(path: Path) -> list[tuple]:
    return pl.read_csv(path).rows()


def test_motion_holds_exactly_the_level_changes(imported):
    m = pl.read_csv(imported / "motion.csv")
    assert m.columns == ["t", "sensor", "value"]
    d2 = float(DAY_S)
    expected = [
        (0.0, "Ph2", 1),
        (10.0, "Ph2", 0),
        (100.0, "Co1", 1),
        (105.0, "Co1", 0),
        (200.0, "Ir1", 1),
        (210.0, "Ir1", 0),
        (1500.0, "Ir1", 1),
        (1503.0, "Ir1", 0),
        (3500.0, "Ph1", 1),
        (3501.0, "Ph1", 0),
        (5500.0, "Ir1", 1),
        (5502.0, "Ir1", 0),
        (7500.0, "Ph1", 1),
        (7501.0, "Ph1", 0),
        (86000.0, "Fo1", 1),
        # day 2 starts at 86 400: no edge at midnight (Fo1 stays on), off at its second 10
        (d2, "Ph2", 1),
        (d2 + 5, "Ph2", 0),
        (d2 + 10, "Fo1", 0),
        # line 19 (second 18) on; lines 20-22 rejected hold it; line 23 (second 22) off
        (d2 + 18, "Ir1", 1),
        (d2 + 22, "Ir1", 0),
    ]
    assert [(float(t), s, int(v)) for t, s, v in m.rows()] == expected


def test_temperature_goes_to_other_csv(imported):
    o = pl.read_csv(imported / "other.csv")
    assert o.columns == ["t", "sensor", "kind", "value"]
    assert o.rows() == [(8000.0, "Te1", "temperature", 1), (8100.0, "Te1", "temperature", 0)]


def test_truth_count_intervals(imported):
    got = [(float(t), float(e), int(c)) for t, e, c in _rows(imported / "truth_count.csv")]
    assert got == [
        (0.0, 1000.0, 2),
        (1000.0, 2000.0, 1),  # resident 2 going out
        (2000.0, 86000.0, 2),
        (86000.0, DAY_S + 50.0, 1),  # resident 1 out over midnight: one interval
        (DAY_S + 50.0, DAY_S + SHORT, 2),  # the short day's truth ends at its last line
    ]


def test_annotations_per_resident(imported):
    a = pl.read_csv(imported / "annotations.csv")
    assert a.columns == ["t", "end", "resident", "activity", "name"]
    r2 = [(float(t), float(e), int(act), n) for t, e, _, act, n in a.filter(pl.col("resident") == 2).rows()]
    assert r2 == [
        (0.0, 1000.0, 1, "Other"),
        (1000.0, 2000.0, 2, "Going Out"),
        (2000.0, 5000.0, 1, "Other"),
        (5000.0, 6000.0, 16, "Napping"),
        (6000.0, 7000.0, 1, "Other"),
        (7000.0, 8000.0, 11, "Sleeping"),
        (8000.0, DAY_S + SHORT, 1, "Other"),
    ]


def test_truth_events_rule(imported):
    """Other out / asleep / napping and this one not -> this one; both awake or both asleep -> none."""
    got = [(float(t), s, str(r)) for t, s, r in _rows(imported / "truth_events.csv")]
    assert got == [
        (1500.0, "Ir1", "1"),  # resident 2 out
        (3500.0, "Ph1", "2"),  # resident 1 asleep
        (5500.0, "Ir1", "1"),  # resident 2 napping
        (86000.0, "Fo1", "2"),  # resident 1 out
        (DAY_S, "Ph2", "2"),  # resident 1 still out at midnight
        (DAY_S + 18.0, "Ir1", "2"),  # resident 1 still out on day 2
    ]
    # left unlabelled: the door at 100 and Ir1 at 200 (both awake), Ph1 at 7500 (both asleep)


def test_bad_lines_and_short_day_are_counted(imported, house):
    rej = pl.read_csv(imported / "rejects.csv")
    day2 = str(house / "DAY_2.txt")
    assert rej["source"].to_list() == [day2] * 3
    assert rej["line"].to_list() == [20, 21, 22]
    reasons = rej["reason"].to_list()
    assert "expected 8 fields" in reasons[0]
    assert "level" in reasons[1] and "0 or 1" in reasons[1]
    assert "activity" in reasons[2]
    info = tomllib.loads((imported / "import.toml").read_text())
    assert info["counts"]["rejected"] == 3
    assert info["counts"]["short_days"] == 1
    assert info["counts"]["lines"] == DAY_S + SHORT
    assert info["counts"]["days"] == 2
    assert info["counts"]["doors"] == 1


def test_the_site_loads(imported):
    site = load_site(imported / "site.toml")
    assert sorted(m.id for m in site.motion_sensors) == ["Co1", "Fo1", "Ir1", "Ph1", "Ph2"]
    assert set(site.sensor_graph.entries) == {"Co1"} and set(site.sensor_graph.exits) == {"Co1"}
    assert site.epoch.startswith("2000-01-01")


def test_days_option(house, tmp_path):
    res = import_aras(house, tmp_path / "d2", days=parse_days("2"))
    assert res.counts["days"] == 1
    m = pl.read_csv(tmp_path / "d2" / "motion.csv")
    # day 2 alone: Fo1 held on at its first second is written as an ON at 86 400
    assert (float(m["t"][0]), m["sensor"][0], int(m["value"][0])) == (DAY_S, "Fo1", 1)
    assert pl.read_csv(tmp_path / "d2" / "truth_count.csv")["t"][0] == DAY_S


@pytest.mark.parametrize("text", ["x", "3-1", "0-2", "1-", "1-2-3", "-2", ""])
def test_days_parsing_errors(text):
    with pytest.raises(InputError, match="--days"):
        parse_days(text)


def test_days_parsing():
    assert parse_days("8-15") == (8, 15)
    assert parse_days(" 3 ") == (3, 3)
    assert parse_days(None) is None


def test_a_missing_day_is_an_error(house, tmp_path):
    with pytest.raises(InputError, match=r"day\(s\) \[3\]"):
        import_aras(house, tmp_path / "x", days=(1, 3))
    assert main(["import", "aras", str(house), str(tmp_path / "y"), "--days", "5-4"]) != 0


def test_a_missing_readme_names_the_file(tmp_path):
    folder = tmp_path / "nohouse"
    folder.mkdir()
    _write(folder / "DAY_1.txt", _day2())
    with pytest.raises(InputError) as e:
        import_aras(folder, tmp_path / "out")
    assert str(folder / "README") in str(e.value)
    assert not (tmp_path / "out").exists()


def test_readme_without_a_sensor_table(tmp_path):
    (tmp_path / "README").write_text("nothing here\n")
    with pytest.raises(InputError, match="no sensor table"):
        read_readme(tmp_path / "README")


# -- read_day on random lines -------------------------------------------------------------

S = 3


@st.composite
def day_lines(draw):
    """Lines of a 3-sensor day file, each valid or one of the ways to be bad."""
    kinds = draw(st.lists(st.sampled_from(["ok", "ok", "ok", "fields", "level", "act", "text", "blank"]), max_size=40))
    lines, good = [], []
    for k in kinds:
        lv = draw(st.lists(st.integers(0, 1), min_size=S, max_size=S))
        act = draw(st.lists(st.integers(1, 27), min_size=2, max_size=2))
        if k == "fields":
            n = draw(st.integers(0, S + 4).filter(lambda n: n != S + 2))
            vals = (lv + act + [1, 1, 1])[:n] if n else []
        elif k == "level":
            lv[draw(st.integers(0, S - 1))] = draw(st.sampled_from([2, -1, 7]))
            vals = lv + act
        elif k == "act":
            act[draw(st.integers(0, 1))] = draw(st.sampled_from([0, 28, 99, -2]))
            vals = lv + act
        elif k == "text":
            vals = [*lv, "x", act[1]]
        elif k == "blank":
            vals = []
        else:
            vals = lv + act
        sep = draw(st.sampled_from([" ", "  ", "\t"]))
        lines.append(sep.join(map(str, vals)))
        good.append((lv, act) if k == "ok" else None)
    return lines, good


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=day_lines())
def test_read_day_rejects_every_bad_line_and_holds_the_second_before(tmp_path, data):
    lines, good = data
    path = tmp_path / "DAY_1.txt"
    path.write_text("".join(line + "\n" for line in lines))
    bad = [i + 1 for i, g in enumerate(good) if g is None]
    if lines and len(bad) == len(lines):
        with pytest.raises(InputError, match="no usable line"):
            read_day(path, 1, S)
        return
    day = read_day(path, 1, S)
    assert day.lines == len(lines)
    assert day.rejects["line"].to_list() == bad
    assert day.rejects.height + sum(g is not None for g in good) == len(lines)
    assert day.levels.shape == (len(lines), S) and day.activities.shape == (len(lines), 2)
    first = next((g for g in good if g is not None), None)
    held = first
    for i, g in enumerate(good):
        held = g if g is not None else held
        assert day.levels[i].tolist() == held[0], i
        assert day.activities[i].tolist() == held[1], i


def test_read_day_carries_the_day_before(tmp_path):
    path = tmp_path / "DAY_2.txt"
    path.write_text("0 0 9 1 1\n1 0 0 1 2\n")
    carry = (np.array([1, 1, 1], np.int8), np.array([2, 11], np.int16))
    day = read_day(path, 2, S, carry=carry)
    # the day's own seconds: line 1 (bad: the day before's last second held), then line 2
    assert day.levels.tolist() == [[1, 1, 1], [1, 0, 0]]
    assert day.activities.tolist() == [[2, 11], [1, 2]]
    assert day.rejects["line"].to_list() == [1]


# -- a run on the imported house ----------------------------------------------------------


def test_run_writes_people_occupancy_and_count_scores(imported, tmp_path):
    res = run_pipeline(imported, tmp_path / "run", trackers=("residents",), rrd=False)
    assert res.status["residents"].startswith("ok"), res.status["residents"]
    tables = tmp_path / "run" / "tables"
    people = pl.read_parquet(tables / "residents_people.parquet")
    assert people.columns == ["t", "present"] and people.height >= 1
    for name in ("occupancy_people", "occupancy_bins", "truth_count"):
        assert (tables / f"{name}.parquet").exists(), name
    for stage in ("residents", "occupancy", "count-commonest", "count-recent-60min"):
        for m in ("count_error", "occupancy_accuracy"):
            v = metric(res.report, f"{stage}/{m}")
            assert v is not None and np.isfinite(v), (stage, m)
    # the fixture is home (1 or 2 people) in every minute: commonest (2) is never wrong on occupancy
    assert metric(res.report, "count-commonest/occupancy_accuracy") == 1.0
