"""The CASAS variants of issue 22 item 1: date/time in one field or two, resident/task pairs,
activity labels, named sensors, pymrt events.csv, lost OFFs, malformed lines; truth_events."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit.readers.casas import hold_times, read_casas, repair_lost_offs
from onebit.readers.tables_csv import read_truth_events_csv

# the ADL multi-resident format: TAB-separated date, time, sensor, then "VALUE res task [res task]"
ADLMR = (
    "2008-11-10\t14:28:17.986759\tM22\tON 2 2\n"  # 1
    "2008-11-10\t14:28:18.78605\tM19\tON 1 1\n"  # 2
    "2008-11-10\t14:28:22.025769\tD07\tOPEN 1 1\n"  # 3: a cupboard
    "2008-11-10\t14:28:22.23544\tM19\tOFF 1 1\n"  # 4
    "2008-11-10\t14:28:23.05\tM22\tOFF 2 7 1 6\n"  # 5: two pairs
    "2008-11-10\t14:28:24.0\tM17\tOFF  211\n"  # 6: an annotation that is no pairs (kept, problem listed)
    "2008-11-10\t14:28:25.0\tM17\tON\n"  # 7: no annotation
    "2008-11-10\t14:28:26.0\tI04\tABSENT 1 1\n"  # 8: an item
    "2008-11-10\t14:28:27.0\tM22\n"  # 9: no value (malformed)
    "2008-11-10\t14:28:28\tM22\tMAYBE 2 2\n"  # 10: not a motion value (malformed)
    "2008-11-10\t14:2x:29\tM22\tON 2 2\n"  # 11: bad time (malformed)
)


def _write(tmp_path: Path, text: str, name: str = "log.txt") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_resident_task_pairs_are_parsed(tmp_path):
    log = read_casas(_write(tmp_path, ADLMR))
    assert log.lines == 11 and log.events.height + log.rejects.height == 11
    ev = {r["line"]: r for r in log.events.iter_rows(named=True)}
    assert (ev[1]["residents"], ev[1]["tasks"], ev[1]["value"]) == ("2", "2", "ON")
    assert (ev[5]["residents"], ev[5]["tasks"]) == ("1;2", "7;6")  # ids sorted, tasks in pair order
    assert ev[3]["kind"] == "contact" and ev[3]["on"] is True and ev[3]["residents"] == "1"
    assert ev[8]["kind"] == "item" and ev[8]["on"] is False
    assert ev[6]["residents"] is None and ev[6]["on"] is False  # the event is sound, its annotation is not
    assert (
        log.annotation_problems["line"].to_list() == [6]
        and "not resident/task pairs" in log.annotation_problems["reason"][0]
    )
    assert ev[7]["residents"] is None and ev[7]["annotation"] is None
    rej = dict(zip(log.rejects["line"].to_list(), log.rejects["reason"].to_list()))
    assert set(rej) == {9, 10, 11}
    assert (
        "too few fields" in rej[9] and "'MAYBE' is not a motion value" in rej[10] and "not a date and time" in rej[11]
    )


def test_date_and_time_in_one_field_or_two(tmp_path):
    text = (
        "2011-06-15 08:00:00.5\tM001\tON\n"  # two fields, a space
        "2011-06-15\t08:00:01.5\tM001\tOFF\n"  # two fields, a tab
        "2011-06-15T08:00:02.5 M002 ON\n"  # one field, T
        "2011-06-15_08:00:03.5 M002 OFF\n"  # one field, _
        "2011-06-15T10:00:04.5+02:00 M003 ON\n"  # one field with a zone: 10:00 at +02:00 = 08:00 UTC
        "2011-06-15 08:00:05.5Z M003 OFF\n"  # a zone after a two-field stamp (naive stamps are UTC)
    )
    log = read_casas(_write(tmp_path, text))
    assert log.rejects.height == 0
    assert log.events.sort("line")["t"].round(6).to_list() == [0.5, 1.5, 2.5, 3.5, 4.5, 5.5]


def test_named_sensors_and_activity_labels(tmp_path):
    text = (
        "2011-06-15 08:00:00 Bedroom Bedroom ON Sleep begin\n"  # the name twice
        "2011-06-15 08:00:02 Bedroom OFF\n"  # once
        '2011-06-15 08:00:03 Fridge Fridge OPEN Meal_Preparation="begin"\n'
        "2011-06-15 08:00:04 Fridge CLOSE\n"
        "2011-06-15 08:00:05 M021 Kitchen Kitchen ON 1 3\n"  # an id, its location twice
        "2011-06-15 08:00:06 Thermo 21.5\n"
        "2011-06-15 08:00:07 Bedroom ON Sleep end\n"
        "2011-06-15 08:00:08 Bedroom 17\n"  # a number from a motion sensor: rejected, never reclassified
    )
    log = read_casas(_write(tmp_path, text))
    ev = {r["line"]: r for r in log.events.iter_rows(named=True)}
    assert ev[1]["sensor"] == "Bedroom" and ev[1]["kind"] == "motion" and ev[1]["on"] is True
    assert (ev[1]["activity"], ev[1]["activity_edge"]) == ("Sleep", "begin") and (
        ev[7]["activity"],
        ev[7]["activity_edge"],
    ) == ("Sleep", "end")
    assert ev[3]["kind"] == "contact" and ev[3]["activity"] == "Meal_Preparation" and ev[3]["activity_edge"] == "begin"
    assert (ev[5]["sensor"], ev[5]["location"], ev[5]["residents"], ev[5]["kind"]) == ("M021", "Kitchen", "1", "motion")
    assert ev[6]["kind"] == "analog" and ev[6]["on"] is None
    assert log.rejects["line"].to_list() == [8] and "not a motion value" in log.rejects["reason"][0]
    # a layout's kind wins: Bedroom declared a door
    log2 = read_casas(_write(tmp_path, text), kinds={"Bedroom": "door"})
    assert set(log2.events.filter(pl.col("sensor") == "Bedroom")["kind"]) == {"door"}


def test_pymrt_events_csv_with_and_without_header(tmp_path):
    body = (
        "2009-06-10 03:20:59.087874-07:00,M037,ON,R1,Sleep\n"
        "2009-06-10 03:21:01.087874-07:00,M037,OFF,R2;R1,\n"
        "2009-06-10 03:21:02-07:00,D002,OPEN,,Leave_Home\n"
        "2009-06-10 03:21:03-07:00,M037\n"  # too few fields
        "not a time,M037,ON,R1,\n"
    )
    for name, text in (("events.csv", "time,sensor,message,residents,activity\n" + body), ("nohead.csv", body)):
        log = read_casas(_write(tmp_path, text, name))
        assert log.origin.as_dict()["origin"] == "2009-06-10T10:20:59Z"  # the zone: converted to UTC
        ev = log.events.sort("t")
        assert ev["residents"].to_list() == ["R1", "R1;R2", None]
        assert ev["activity"].to_list() == ["Sleep", None, "Leave_Home"]
        assert ev["kind"].to_list() == ["motion", "motion", "contact"]
        assert ev["t"].round(6).to_list() == [0.087874, 2.087874, 3.0]
        assert log.events.height + log.rejects.height == log.lines == 5, name
        assert sorted(log.rejects["reason"].str.slice(0, 12).to_list()) == ["field 'time'", "too few fiel"]


def test_lost_off_repair_by_hold_time():
    """A repeated ON more than the sensor's hold time after the last ON gets an OFF at t + hold
    (hold: the median on-duration when there are enough, else the default); within it, none."""
    ons = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0]
    rows = [(t, "A", True) for t in ons] + [(t + d, "A", False) for t, d in zip(ons, (2.0, 3.0, 4.0, 3.0, 2.0, 3.0))]
    rows += [(100.0, "A", True), (200.0, "A", True), (201.0, "A", True)]  # lost OFF, then a re-trigger
    rows += [(0.0, "B", True), (60.0, "B", True), (62.0, "B", True)]  # B: too few on-durations: default hold 5 s
    ev = pl.DataFrame(rows, schema={"t": pl.Float64, "sensor": pl.String, "on": pl.Boolean}, orient="row").sort("t")
    h = dict(hold_times(ev, default_hold_s=5.0, min_samples=5).select("sensor", "hold_s").iter_rows())
    assert h == {"A": 3.0, "B": 5.0}
    out, rep = repair_lost_offs(ev, default_hold_s=5.0, min_samples=5)
    assert sorted(rep.select("sensor", "t_off").rows()) == [("A", 103.0), ("B", 5.0)]
    assert out.height == ev.height + 2 and out["repaired"].sum() == 2 and out["t"].is_sorted()
    ins = out.filter("repaired")
    assert not ins["on"].any()
    # after the repair no sensor has an ON followed by an ON more than its hold apart
    seq = out.sort("sensor", "t")
    gap = seq.with_columns(nt=pl.col("t").shift(-1).over("sensor"), non=pl.col("on").shift(-1).over("sensor"))
    bad = gap.filter(
        pl.col("on")
        & pl.col("non").fill_null(False)
        & (pl.col("nt") - pl.col("t") > pl.col("sensor").replace_strict(h))
    )
    assert bad.height == 0


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    events=st.lists(
        st.tuples(
            st.sampled_from(["M001", "M02", "D07", "Bedroom"]),
            st.booleans(),
            st.lists(st.tuples(st.integers(1, 3), st.integers(1, 15)), min_size=0, max_size=2),
            st.sampled_from(["two", "one", "tab"]),
            st.booleans(),
        ),
        min_size=1,
        max_size=25,
    )
)
def test_every_written_variant_reads_back(tmp_path, events):
    """Any mix of the variants reads back every event with its value and residents, nothing rejected."""
    lines, want = [], []
    for k, (sensor, on, pairs, form, twice) in enumerate(events):
        stamp = f"2012-03-01 10:{k:02d}:{k % 60:02d}.{k:06d}"  # increasing, minutes apart (a day's gap would cut a lone stamp off)
        d, t = stamp.split(" ")
        when = {"two": f"{d} {t}", "one": f"{d}T{t}", "tab": f"{d}\t{t}"}[form]
        value = ("OPEN" if on else "CLOSE") if sensor.startswith("D") else ("ON" if on else "OFF")
        name = f"{sensor} {sensor}" if twice and sensor == "Bedroom" else sensor
        ann = " ".join(f"{r} {task}" for r, task in pairs)
        lines.append(f"{when}\t{name}\t{value}" + (f" {ann}" if ann else ""))
        want.append((k + 1, sensor, on, ";".join(sorted({str(r) for r, _ in pairs})) or None))
    p = tmp_path / "variants.txt"
    p.write_text("\n".join(lines) + "\n")
    log = read_casas(p)
    assert log.rejects.height == 0, log.rejects["reason"].to_list()
    got = log.events.sort("line").select("line", "sensor", "on", "residents").rows()
    assert got == want


def test_truth_events_reader(tmp_path):
    p = _write(
        tmp_path,
        "t,sensor,residents\n0.5,M1,2\n1.0,M2,2;1\n1.5,M3, 1 ; 2 \n2.0,M1,\nx,M1,1\n1.0,M2,1\n",
        "truth_events.csv",
    )
    te, rej = read_truth_events_csv(p, epoch=None)
    assert te.schema == pl.Schema({"t": pl.Float64, "sensor": pl.String, "residents": pl.String})
    assert te.rows() == [(0.5, "M1", "2"), (1.0, "M2", "1;2"), (1.5, "M3", "1;2")]
    reasons = dict(zip(rej["line"].to_list(), rej["reason"].to_list()))
    assert set(reasons) == {5, 6, 7} and "no resident" in reasons[5] and "duplicate" in reasons[7]


@pytest.mark.parametrize("doors", [(), ("D07",)])
def test_import_writes_the_identity_truth_and_no_cupboard_doors(tmp_path, doors):
    from onebit.core.site import load_site
    from onebit.datasets.importers import import_casas

    log = _write(
        tmp_path,
        ADLMR
        + "".join(
            f"2008-11-10\t14:29:{k:02d}.0\tM{19 + k % 4}\t{'ON' if k % 2 == 0 else 'OFF'} 1 1\n" for k in range(40)
        ),
    )
    s = import_casas(log, tmp_path / f"ds{len(doors)}", doors=doors)
    te = pl.read_csv(tmp_path / f"ds{len(doors)}" / "truth_events.csv")
    assert te.columns == ["t", "sensor", "residents"]
    ev = read_casas(log).events
    want = ev.filter(
        pl.col("kind").is_in(["motion", "contact", "door"]) & pl.col("on") & pl.col("residents").is_not_null()
    )
    assert te.height == want.height == s.counts["truth_events"]
    assert set(te["residents"].cast(pl.String)) <= {"1", "2", "1;2"}
    site = load_site(tmp_path / f"ds{len(doors)}" / "site.toml")
    assert set(site.sensor_graph.entries) == set(doors)  # the cupboard D07 is a way out only when declared


def test_logs_info_counts_labels_and_lost_offs(tmp_path):
    from onebit.readers.loginfo import log_info

    text = ADLMR + "2008-11-10\t14:40:00.0\tM22\tON 2 2\n2008-11-10\t14:50:00.0\tM22\tON 2 2\n"  # a lost OFF between
    by = {r["source"]: r for r in log_info(_write(tmp_path, text)).iter_rows(named=True)}
    assert (
        by["log.txt:resident-labelled"]["rows"] == 8 and by["log.txt:resident-labelled"]["sensors"] == 3
    )  # "1", "2", "1;2"
    assert by["log.txt:annotation-problems"]["rows"] == 1
    assert by["log.txt:lost-off"]["rows"] == 1  # the second ON of M22 ten minutes later
    csv = _write(
        tmp_path,
        "time,sensor,message,residents,activity\n2009-06-10 03:20:59-07:00,M037,ON,R1,\n2009-06-10 03:21:00-07:00,M037,OFF,R1,\n",
        "events.csv",
    )
    by = {r["source"]: r for r in log_info(csv).iter_rows(named=True)}
    assert by["events.csv"]["rows"] == 2 and by["events.csv:motion"]["sensors"] == 1
